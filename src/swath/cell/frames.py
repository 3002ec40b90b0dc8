"""Rigid transforms of the cell, named by their frames (pytransform3d's convention).

``A2B`` is the (4, 4) transform that maps points in frame A to points in frame B,
``p_B = A2B @ p_A``; equivalently it is the pose of frame A expressed in frame B.  So
``part2base`` is the part's pose in the robot base frame and ``tcp2flange`` would be the TCP's pose
in the flange frame.  Transforms compose by matching names: ``part2base = flange2base @ tcp2flange
@ part2tcp``.

Text form of a pose: ``"x,y,z,rx,ry,rz"``; lengths with units (``mm``, ``m``; bare numbers are
metres), angles with units (``deg``, ``rad``; bare numbers are degrees), rotation
``Rz(rz) Ry(ry) Rx(rx)`` (roll, pitch, yaw about the fixed x, y, z axes).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..units import parse_quantity

#: Tolerance of the rigid-transform check: orthonormality of the rotation block.
RIGID_TOL = 1e-6


def check_transform(value, *, name: str = "transform") -> np.ndarray:
    """A validated copy of a (4, 4) rigid transform.

    Parameters
    ----------
    value : array_like
        The transform (m).
    name : str
        Its frame name (``"part2base"``), used in the error message.

    Raises
    ------
    InputError
        ``expected a (4, 4) rigid transform, got ...`` when the shape is wrong, a value is not
        finite, the rotation block is not orthonormal with determinant +1, or the last row is
        not ``0, 0, 0, 1``.
    """
    try:
        t = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected a (4, 4) rigid transform, got {value!r}") from None
    if t.shape != (4, 4):
        raise InputError(f"{name}: expected a (4, 4) rigid transform, got an array of shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise InputError(f"{name}: expected a (4, 4) rigid transform, got non-finite values")
    r = t[:3, :3]
    err = float(np.abs(r.T @ r - np.eye(3)).max())
    if err > RIGID_TOL or np.linalg.det(r) <= 0:
        raise InputError(f"{name}: expected a (4, 4) rigid transform, got a rotation block that is not a rotation "
                         f"(|R^T R - I| = {err:.3g}, det = {np.linalg.det(r):.4g})")
    if not np.allclose(t[3], [0, 0, 0, 1], atol=1e-12):
        raise InputError(f"{name}: expected a (4, 4) rigid transform, got last row {t[3].tolist()} "
                         "instead of [0, 0, 0, 1]")
    return t


def invert_transform(a2b) -> np.ndarray:
    """``b2a`` of rigid transforms ``a2b`` ``(..., 4, 4)``."""
    t = np.asarray(a2b, dtype=float)
    out = np.zeros_like(t)
    rt = np.swapaxes(t[..., :3, :3], -1, -2)
    out[..., :3, :3] = rt
    out[..., :3, 3] = -(rt @ t[..., :3, 3, None])[..., 0]
    out[..., 3, 3] = 1.0
    return out


def transform_from_xyzrpy(x, y, z, rx, ry, rz) -> np.ndarray:
    """(4, 4) transform with translation (m) and rotation ``Rz(rz) Ry(ry) Rx(rx)`` (rad)."""
    cx, sx, cy, sy, cz, sz = np.cos(rx), np.sin(rx), np.cos(ry), np.sin(ry), np.cos(rz), np.sin(rz)
    t = np.eye(4)
    t[:3, :3] = [[cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx],
                 [sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx],
                 [-sy, cy * sx, cy * cx]]
    t[:3, 3] = (x, y, z)
    return t


def xyzrpy_from_transform(transform) -> np.ndarray:
    """(6,) ``x, y, z`` (m) and ``rx, ry, rz`` (rad) of a transform (inverse of :func:`transform_from_xyzrpy`)."""
    t = np.asarray(transform, dtype=float)
    r = t[:3, :3]
    ry = np.arctan2(-r[2, 0], np.hypot(r[0, 0], r[1, 0]))
    if np.hypot(r[0, 0], r[1, 0]) < 1e-12:     # gimbal lock: put the whole turn on rz
        rx, rz = 0.0, np.arctan2(-r[0, 1], r[1, 1])
    else:
        rx, rz = np.arctan2(r[2, 1], r[2, 2]), np.arctan2(r[1, 0], r[0, 0])
    return np.array([*t[:3, 3], rx, ry, rz])


def parse_pose(text, *, name: str = "pose", length_unit: str = "m", angle_unit: str = "deg") -> np.ndarray:
    """A (4, 4) transform from ``"x,y,z,rx,ry,rz"`` text, a 6-sequence or a (4, 4) array.

    Parameters
    ----------
    text : str, sequence of 6, or (4, 4) array_like
        Position (length units allowed per value, e.g. ``"800mm"``) and roll/pitch/yaw (angle units
        allowed, e.g. ``"90deg"``), or the matrix itself (checked to be rigid).
    name : str
        Frame name for error messages (``"part2base"``).
    length_unit : str
        Unit of bare length numbers (default metres).
    angle_unit : str
        Unit of bare angle numbers (default degrees).

    Raises
    ------
    InputError
        If there are not six values, a unit is unknown, or a matrix is not a rigid transform.
    """
    if isinstance(text, np.ndarray) or (isinstance(text, (list, tuple)) and len(text) == 4):
        return check_transform(text, name=name)
    parts = [p.strip() for p in text.split(",")] if isinstance(text, str) else list(text)
    if len(parts) != 6:
        raise InputError(f"{name}: a pose needs six values 'x,y,z,rx,ry,rz' (lengths, then angles) or a (4, 4) "
                         f"rigid transform, got {text!r}")
    xyz = [parse_quantity(p, "length", default_unit=length_unit) for p in parts[:3]]
    rpy = [parse_quantity(p, "angle", default_unit=angle_unit) for p in parts[3:]]
    return transform_from_xyzrpy(*xyz, *rpy)


def format_pose(transform) -> str:
    """``"x,y,z,rx,ry,rz"`` text (mm and deg) that :func:`parse_pose` reads back."""
    x, y, z, rx, ry, rz = xyzrpy_from_transform(transform)
    return (f"{x * 1e3:.4f}mm,{y * 1e3:.4f}mm,{z * 1e3:.4f}mm,"
            f"{np.degrees(rx):.6f}deg,{np.degrees(ry):.6f}deg,{np.degrees(rz):.6f}deg")
