"""A rotary positioner: one external axis that turns the part in front of the robot.

The positioner's axis is a line in the robot base frame, a point ``axis_point`` on it and a unit
``axis_direction``.  Its faceplate frame has its origin at ``axis_point`` and its z-axis along the
direction; at axis angle 0 its x-axis is the base frame's +z made orthogonal to the axis (the base's
+x when the axis is within 25° of vertical).  The axis turns the faceplate by ``theta`` about its
z-axis (right-handed about ``axis_direction``), and the part sits on the faceplate at
``part2faceplate``, so the part's pose in the base frame is

``part2base(theta) = faceplate2base(theta) @ part2faceplate``  (pytransform3d: ``p_B = A2B @ p_A``).

In a cell file (lengths take ``mm``/``m``/``in``, bare numbers are metres; angles ``deg``/``rad``, bare
numbers degrees)::

    [positioner]
    name = "STN1"                         # the mechanical unit's name on the controller
    axis_point = ["900mm", "0", "300mm"]  # a point on the axis, robot base frame
    axis_direction = [0, 1, 0]            # its direction (any length), robot base frame
    limits = ["-3600deg", "3600deg"]      # lower and upper axis angle
    max_speed = "180deg/s"
    max_accel = "720deg/s2"
    part2faceplate = "0,0,0,0,0,0"        # the part's pose on the faceplate
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..units import parse_quantity
from .frames import check_transform, format_pose, parse_pose

__all__ = ["Positioner", "positioner_from_mapping", "rotation_about"]

_KEYS = {"name", "axis_point", "axis_direction", "limits", "max_speed", "max_accel", "part2faceplate"}


def rotation_about(axis, angle) -> np.ndarray:
    """(n, 3, 3) rotations by ``angle`` (n,) rad about the unit ``axis`` (3,) (Rodrigues)."""
    k = np.asarray(axis, dtype=float)
    a = np.atleast_1d(np.asarray(angle, dtype=float))
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    s, c = np.sin(a)[:, None, None], np.cos(a)[:, None, None]
    return np.eye(3) + s * kx + (1.0 - c) * (kx @ kx)


@dataclass(frozen=True, eq=False)
class Positioner:
    """A one-axis rotary positioner (external axis), lengths m, angles rad.

    Attributes
    ----------
    axis_point : (3,) float
        A point on the axis in the robot base frame, m.
    axis_direction : (3,) float
        Unit direction of the axis in the robot base frame (the axis angle turns right-handed about it).
    limits : (2,) float
        Lower and upper axis angle, rad.
    max_speed : float
        Largest axis speed, rad/s.
    max_accel : float
        Largest axis acceleration, rad/s².
    part2faceplate : (4, 4) float
        The part's pose in the faceplate frame.
    name : str
        The mechanical unit's name (programs and messages).
    """

    axis_point: np.ndarray
    axis_direction: np.ndarray
    limits: tuple = (-20 * math.pi, 20 * math.pi)
    max_speed: float = math.pi
    max_accel: float = 4 * math.pi
    part2faceplate: np.ndarray = field(default_factory=lambda: np.eye(4))
    name: str = "STN1"

    def __post_init__(self):
        p = np.asarray(self.axis_point, dtype=float)
        d = np.asarray(self.axis_direction, dtype=float)
        if p.shape != (3,) or not np.isfinite(p).all():
            raise InputError(f"positioner axis_point: expected three finite lengths (x, y, z), got {self.axis_point!r}")
        if d.shape != (3,) or not np.isfinite(d).all() or np.linalg.norm(d) < 1e-9:
            raise InputError(f"positioner axis_direction: expected a non-zero direction (x, y, z), "
                             f"got {self.axis_direction!r}")
        lo, hi = (float(v) for v in self.limits)
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise InputError(f"positioner limits: expected lower < upper, both finite, got "
                             f"{math.degrees(lo):.6g} and {math.degrees(hi):.6g} deg")
        for key in ("max_speed", "max_accel"):
            v = float(getattr(self, key))
            if not (math.isfinite(v) and v > 0):
                raise InputError(f"positioner {key} must be positive and finite, got {v!r}")
            object.__setattr__(self, key, v)
        object.__setattr__(self, "axis_point", p)
        object.__setattr__(self, "axis_direction", d / np.linalg.norm(d))
        object.__setattr__(self, "limits", (lo, hi))
        object.__setattr__(self, "part2faceplate", check_transform(self.part2faceplate, name="part2faceplate"))

    @property
    def faceplate_zero2base(self) -> np.ndarray:
        """(4, 4) the faceplate's pose in the base frame at axis angle 0."""
        z = self.axis_direction
        up = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < math.cos(math.radians(25.0)) else np.array([1.0, 0.0, 0.0])
        x = up - np.dot(up, z) * z
        x /= np.linalg.norm(x)
        out = np.eye(4)
        out[:3, :3] = np.column_stack([x, np.cross(z, x), z])
        out[:3, 3] = self.axis_point
        return out

    def faceplate2base(self, theta) -> np.ndarray:
        """(n, 4, 4) the faceplate's pose in the base frame at axis angles ``theta`` (n,) rad."""
        theta = np.atleast_1d(np.asarray(theta, dtype=float))
        zero = self.faceplate_zero2base
        out = np.repeat(zero[None], len(theta), axis=0)
        out[:, :3, :3] = rotation_about(self.axis_direction, theta) @ zero[:3, :3]
        return out

    def part2base(self, theta) -> np.ndarray:
        """(n, 4, 4) the part's pose in the base frame at axis angles ``theta`` (n,) rad."""
        return self.faceplate2base(theta) @ self.part2faceplate

    def base2part(self, theta) -> np.ndarray:
        """(n, 4, 4) the inverse of :meth:`part2base` (the base's pose in the part frame)."""
        p2b = self.part2base(theta)
        out = np.repeat(np.eye(4)[None], len(p2b), axis=0)
        rt = np.transpose(p2b[:, :3, :3], (0, 2, 1))
        out[:, :3, :3] = rt
        out[:, :3, 3] = -np.einsum("nij,nj->ni", rt, p2b[:, :3, 3])
        return out

    def axis_in_part(self) -> tuple[np.ndarray, np.ndarray]:
        """The axis line in the part frame: a point (3,) and a unit direction (3,), m (angle-independent)."""
        faceplate2part = np.linalg.inv(self.part2faceplate)
        return faceplate2part[:3, 3].copy(), faceplate2part[:3, 2].copy()

    def as_record(self) -> dict:
        """Record for metrics/JSON (SI units in the keys; ``part2faceplate`` as pose text in mm and deg)."""
        return {"name": self.name, "axis_point_m": [float(v) for v in self.axis_point],
                "axis_direction": [float(v) for v in self.axis_direction],
                "limits_rad": [float(v) for v in self.limits],
                "max_speed_rad_per_s": self.max_speed, "max_accel_rad_per_s2": self.max_accel,
                "part2faceplate": format_pose(self.part2faceplate)}


def _rate(value, key: str, order: int) -> float:
    """An angular rate (``order`` 1: per s, 2: per s²) from text such as ``"180deg/s"``; bare numbers deg/s^order."""
    text = str(value).strip().replace(" ", "")
    for suffix in ("/s^2", "/s2", "/s²") if order == 2 else ("/s",):
        if text.endswith(suffix):
            text = text[: -len(suffix)]
            break
    try:
        return parse_quantity(text, "angle", default_unit="deg")
    except InputError:
        example = '"720deg/s2"' if order == 2 else '"180deg/s"'
        raise InputError(f"{key}: expected an angular {'acceleration' if order == 2 else 'speed'} such as "
                         f"{example}, got {value!r}") from None


def positioner_from_mapping(data, *, where: str = "positioner") -> Positioner:
    """A :class:`Positioner` from the cell file's ``[positioner]`` table (see the module docstring).

    Raises
    ------
    InputError
        Unknown or missing keys, a zero direction, limits out of order, a non-positive speed or
        acceleration, a pose that is not rigid — naming the key and the fix.
    """
    if not isinstance(data, dict):
        raise InputError(f"{where}: [positioner] must be a table with axis_point, axis_direction, limits, max_speed, "
                         f"max_accel and part2faceplate, got {data!r}")
    unknown = set(data) - _KEYS
    if unknown:
        raise InputError(f"{where}: unknown key(s) {', '.join(sorted(unknown))}; known: {', '.join(sorted(_KEYS))}")
    for key in ("axis_point", "axis_direction"):
        if key not in data:
            raise InputError(f"{where}: the positioner needs `{key}` (three values in the robot base frame)")
    point, direction = data["axis_point"], data["axis_direction"]
    if not isinstance(point, list) or len(point) != 3:
        raise InputError(f"{where}.axis_point: expected three lengths [x, y, z], got {point!r}")
    if not isinstance(direction, list) or len(direction) != 3:
        raise InputError(f"{where}.axis_direction: expected three numbers [x, y, z], got {direction!r}")
    try:
        d = [float(v) for v in direction]
    except (TypeError, ValueError):
        raise InputError(f"{where}.axis_direction: expected three numbers [x, y, z], got {direction!r}") from None
    limits = data.get("limits", ["-3600deg", "3600deg"])
    if not isinstance(limits, list) or len(limits) != 2:
        raise InputError(f"{where}.limits: expected two angles [lower, upper], got {limits!r}")
    return Positioner(
        axis_point=np.array([parse_quantity(v, "length") for v in point]), axis_direction=np.array(d),
        limits=tuple(parse_quantity(v, "angle", default_unit="deg") for v in limits),
        max_speed=_rate(data.get("max_speed", "180deg/s"), f"{where}.max_speed", 1),
        max_accel=_rate(data.get("max_accel", "720deg/s2"), f"{where}.max_accel", 2),
        part2faceplate=parse_pose(data.get("part2faceplate", "0,0,0,0,0,0"), name=f"{where}.part2faceplate"),
        name=str(data.get("name", "STN1")))
