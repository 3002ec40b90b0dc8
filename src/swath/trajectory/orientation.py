"""Tool orientation along contact passes (FORMATS.md tool frame).

:func:`tool_frames` builds the frame ``(x, y, z) = (T, −B, −n)`` from the surface normal ``n`` and a
travel direction ``T`` — the Darboux frame ``(T, B = n × T, n)`` of the pass relabelled so that z
points into the part and ``y = z × x``.  :func:`swath.trajectory.time_path` passes a travel
direction smoothed over ``heading_scale`` (:func:`swath.trajectory.geometry.smoothed_directions`).
:func:`with_lead` tilts those frames by a lead angle about their y-axis (a deliberate tilt,
FORMATS.md: the pad's leading edge lifts off the part).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from ..surface.geometry import normalize


def pass_tangents(points: np.ndarray) -> np.ndarray:
    """Unit travel directions ``(k, 3)`` along a polyline ``(k, 3)``: central differences inside,
    one-sided at the ends."""
    return normalize(np.gradient(points, axis=0))


def tool_frames(normals: np.ndarray, tangents: np.ndarray) -> np.ndarray:
    """Rotation matrices ``(k, 3, 3)`` (columns x, y, z of the tool in the part frame).

    z = −normal (into the part); x = the travel direction projected onto the plane normal to z;
    y = z × x.  Where the travel direction is parallel to the normal (degenerate), the previous x is
    kept (or any perpendicular for the first sample).
    """
    z = -normalize(normals)
    x = tangents - np.einsum("ij,ij->i", tangents, z)[:, None] * z
    xn = np.linalg.norm(x, axis=1)
    bad = xn < 1e-9
    x = np.divide(x, xn[:, None], out=np.zeros_like(x), where=~bad[:, None])
    if bad.any():
        for i in np.flatnonzero(bad):
            prev = x[i - 1] if i > 0 else np.array([1.0, 0.0, 0.0])
            cand = prev - np.dot(prev, z[i]) * z[i]
            if np.linalg.norm(cand) < 1e-9:
                cand = np.cross(z[i], [0.0, 1.0, 0.0] if abs(z[i, 1]) < 0.9 else [1.0, 0.0, 0.0])
            x[i] = cand / np.linalg.norm(cand)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=2)


def with_lead(frames: np.ndarray, lead: float) -> np.ndarray:
    """The tool frames ``(k, 3, 3)`` turned by ``lead`` (rad) about their own y-axis:
    ``x' = cos θ x − sin θ z``, ``z' = sin θ x + cos θ z``.

    A positive lead lifts the pad's leading edge (``x'`` points out of the part) and leans the tool
    axis ``z'`` toward the travel direction, so the pad presses with its trailing part (half of it
    at ``Tool.half_pad_lead`` on a plane).  The same
    constant turn of every frame: the frames' angular velocity in the part frame is unchanged.
    """
    c, s = np.cos(lead), np.sin(lead)
    turn = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    return frames @ turn


def with_lead_ramped(frames: np.ndarray, lead: float, left: np.ndarray, ramp: float) -> np.ndarray:
    """The tool frames ``(k, 3, 3)`` of a pass turned by ``lead`` (rad) about their own y-axis
    (:func:`with_lead`), the turn falling linearly to none over the pass's last ``ramp`` metres:
    ``left`` ``(k,)`` is each frame's arc length (m) to the pass's end.  ``ramp`` 0: the same turn
    everywhere."""
    if not ramp > 0:
        return with_lead(frames, lead)
    theta = lead * np.clip(np.asarray(left, float) / ramp, 0.0, 1.0)
    c, s = np.cos(theta), np.sin(theta)
    turn = np.zeros((len(theta), 3, 3))
    turn[:, 0, 0], turn[:, 0, 2], turn[:, 1, 1], turn[:, 2, 0], turn[:, 2, 2] = c, s, 1.0, -s, c
    return frames @ turn


def quaternions_from_frames(frames: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(k, 4)``, scalar first, of rotation matrices ``(k, 3, 3)``, with signs
    chosen so consecutive quaternions lie in the same hemisphere (no sign flips in the file)."""
    q = Rotation.from_matrix(frames).as_quat(scalar_first=True)
    return make_continuous(q)


def make_continuous(q: np.ndarray) -> np.ndarray:
    """Flip signs of quaternions ``(k, 4)`` so each has a non-negative dot with its predecessor."""
    if len(q) < 2:
        return q
    dots = np.einsum("ij,ij->i", q[1:], q[:-1])
    flips = np.concatenate([[1.0], np.cumprod(np.where(dots < 0, -1.0, 1.0))])
    return q * flips[:, None]
