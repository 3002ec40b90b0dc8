"""The robot cell: where the part sits in front of the robot and which tool is on the flange.

Frame names follow ``a2b`` = *the pose of frame b expressed in frame a*, a 4x4 transform that maps
b-coordinates to a-coordinates (``base2flange`` is the flange pose in the base frame):

* ``base2part`` — the part frame's placement in the robot base frame (``p_base = base2part @ p_part``).
  The issue calls it the part placement (``part2base`` in the brief); :attr:`Cell.part2base` is an
  alias of the same matrix.
* ``flange2tcp`` — the TCP frame (FORMATS.md tool frame: z into the part) in the flange frame.

Text form of a pose: ``"x,y,z,rx,ry,rz"``; lengths with units (``mm``, ``m``; bare numbers are
metres), angles with units (``deg``, ``rad``; bare numbers are degrees), rotation
``Rz(rz) Ry(ry) Rx(rx)`` (roll, pitch, yaw about the fixed x, y, z axes).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..units import parse_quantity
from .pose import invert, pose_from_xyzrpy, xyzrpy_from_pose


def parse_pose(text, *, length_unit: str = "m", angle_unit: str = "deg") -> np.ndarray:
    """A 4x4 transform from ``"x,y,z,rx,ry,rz"`` text, a 6-sequence or a 4x4 array.

    Parameters
    ----------
    text : str, sequence of 6, or (4, 4) array
        Position (length units allowed per value, e.g. ``"800mm"``) and roll/pitch/yaw (angle units
        allowed, e.g. ``"90deg"``).
    length_unit : str
        Unit of bare length numbers (default metres).
    angle_unit : str
        Unit of bare angle numbers (default degrees).

    Raises
    ------
    InputError
        If there are not six values, a unit is unknown, or a 4x4 is not a rigid transform.
    """
    if isinstance(text, np.ndarray) and text.shape == (4, 4):
        return _check_rigid(text)
    if isinstance(text, (list, tuple)) and len(text) == 4 and all(np.shape(r) == (4,) for r in text):
        return _check_rigid(np.asarray(text, dtype=float))
    parts = [p.strip() for p in text.split(",")] if isinstance(text, str) else list(text)
    if len(parts) != 6:
        raise InputError(f"a pose needs six values 'x,y,z,rx,ry,rz' (lengths, then angles), got {text!r}")
    xyz = [parse_quantity(p, "length", default_unit=length_unit) for p in parts[:3]]
    rpy = [parse_quantity(p, "angle", default_unit=angle_unit) for p in parts[3:]]
    return pose_from_xyzrpy(*xyz, *rpy)


def format_pose(transform) -> str:
    """``"x,y,z,rx,ry,rz"`` text (mm and deg) that :func:`parse_pose` reads back."""
    x, y, z, rx, ry, rz = xyzrpy_from_pose(transform)
    return (f"{x * 1e3:.4f}mm,{y * 1e3:.4f}mm,{z * 1e3:.4f}mm,"
            f"{np.degrees(rx):.6f}deg,{np.degrees(ry):.6f}deg,{np.degrees(rz):.6f}deg")


def _check_rigid(t) -> np.ndarray:
    t = np.asarray(t, dtype=float)
    r = t[:3, :3]
    if not (np.allclose(r.T @ r, np.eye(3), atol=1e-6) and np.linalg.det(r) > 0
            and np.allclose(t[3], [0, 0, 0, 1])):
        raise InputError("a 4x4 pose must be a rigid transform (orthonormal rotation, last row 0,0,0,1)")
    return t.copy()


@dataclass(frozen=True, eq=False)
class Cell:
    """Part placement and tool of a robot cell.

    Attributes
    ----------
    base2part : (4, 4) float
        Part frame in the robot base frame, m.
    flange2tcp : (4, 4) float
        TCP frame in the flange frame, m.  Default: the TCP on the flange face, axes aligned.
    """

    base2part: np.ndarray = field(default_factory=lambda: np.eye(4))
    flange2tcp: np.ndarray = field(default_factory=lambda: np.eye(4))

    @classmethod
    def from_text(cls, base: str | None = None, tcp: str | None = None) -> Cell:
        """A cell from ``--base`` and ``--tcp`` texts (see :func:`parse_pose`)."""
        return cls(base2part=np.eye(4) if base is None else parse_pose(base),
                   flange2tcp=np.eye(4) if tcp is None else parse_pose(tcp))

    @property
    def part2base(self) -> np.ndarray:
        """Alias of :attr:`base2part` (the name used in the issue's brief)."""
        return self.base2part

    def base2flange(self, part2tcp) -> np.ndarray:
        """(n, 4, 4) flange poses in the base frame for TCP poses ``part2tcp`` (n, 4, 4) in the part frame."""
        return self.base2part @ np.asarray(part2tcp) @ invert(self.flange2tcp)

    def part2tcp(self, base2flange) -> np.ndarray:
        """(n, 4, 4) TCP poses in the part frame for flange poses in the base frame."""
        return invert(self.base2part) @ np.asarray(base2flange) @ self.flange2tcp

    def with_base(self, base2part) -> Cell:
        return Cell(base2part=np.asarray(base2part, dtype=float), flange2tcp=self.flange2tcp)

    def as_record(self) -> dict:
        """Text record for metrics/JSON (mm, deg)."""
        return {"base2part": format_pose(self.base2part), "flange2tcp": format_pose(self.flange2tcp)}
