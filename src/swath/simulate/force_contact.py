"""Force against normal offset on the real part, per trajectory pose (the plant of the force loop).

The tool model of FORMATS.md gives, for a pose whose TCP is pushed ``δ`` along the tool axis beyond
its planned position, the pad force ``F(δ) = k · Σ_j w_j · max(δ − z_j, 0)``: ``z_j`` the height of
surface sample ``j`` (within the pad radius, facing the tool) along tool z from the planned TCP,
``w_j`` its area.  ``F`` is convex and piecewise linear in ``δ``; sorting the heights once per pose
and keeping the running sums ``W = Σ w`` and ``M = Σ w z`` makes ``F(δ) = k·(δ·W − M)`` exact for any
``δ`` with one bisection.  Its slope ``k·W`` (the contact stiffness, N/m) never exceeds
``k·π·R²``.

The *real* part is the planned one moved by a rigid registration error; rather than moving the
surface, each planned pose is moved by the inverse transform into the planned part's frame.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field

import numpy as np

from ..contact import Tool, solve_sink


@dataclass(frozen=True, eq=False)
class ContactCurves:
    """Exact pad force against normal offset for a sequence of poses.

    Attributes
    ----------
    start : (P + 1,) int
        Pose ``i`` owns entries ``start[i]:start[i+1]`` of the flat arrays.
    z : (N,) float
        Sample heights along tool z from the planned TCP, m, ascending within each pose.
    cum_w : (N,) float
        Running sum of sample areas, m².
    cum_wz : (N,) float
        Running sum of ``area · height``, m³.
    k : float
        Pad foundation stiffness, Pa/m.
    """

    start: np.ndarray
    z: np.ndarray
    cum_w: np.ndarray
    cum_wz: np.ndarray
    k: float
    # Python-list copies for bisect, filled in __post_init__.
    _z: list = field(init=False, repr=False, compare=False)
    _w: list = field(init=False, repr=False, compare=False)
    _m: list = field(init=False, repr=False, compare=False)
    _s: list = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        # Python lists: bisect on them is far cheaper per call than numpy scalar indexing.
        object.__setattr__(self, "_z", self.z.tolist())
        object.__setattr__(self, "_w", self.cum_w.tolist())
        object.__setattr__(self, "_m", self.cum_wz.tolist())
        object.__setattr__(self, "_s", self.start.tolist())

    def force(self, i: int, delta: float) -> tuple[float, float]:
        """Pad force (N) and its slope dF/dδ (N/m) of pose ``i`` at normal offset ``delta`` (m)."""
        lo, hi = self._s[i], self._s[i + 1]
        j = bisect.bisect_left(self._z, delta, lo, hi)
        if j == lo:
            return 0.0, 0.0
        w = self._w[j - 1]
        return self.k * (delta * w - self._m[j - 1]), self.k * w

    def offsets(self, force) -> np.ndarray:
        """(P,) normal offset (m) at which each pose carries ``force`` (N, scalar or ``(P,)``); NaN
        where the pad touches nothing (the force balance of :func:`swath.contact.solve_sink`)."""
        P = len(self.start) - 1
        counts = np.diff(self.start)
        group = np.repeat(np.arange(P), counts)
        w = np.diff(np.concatenate([[0.0], self.cum_w]))
        w[self.start[:-1][counts > 0]] = self.cum_w[self.start[:-1][counts > 0]]
        target = np.broadcast_to(np.asarray(force, float), (P,)) / self.k
        return solve_sink(self.z, w, group, np.ascontiguousarray(target))

    def first_touch(self, i: int) -> float:
        """Offset (m) at which pose ``i`` first touches (its lowest sample height); NaN if none."""
        lo, hi = self._s[i], self._s[i + 1]
        return self._z[lo] if hi > lo else math.nan


def rigid_offset(offset) -> tuple[np.ndarray, np.ndarray]:
    """Rotation matrix ``(3, 3)`` and translation ``(3,)`` of ``(dx, dy, dz, rx, ry, rz)``.

    Translation in m, rotation a rotation vector in rad (axis times angle).
    """
    from scipy.spatial.transform import Rotation

    o = np.asarray(offset, float)
    return Rotation.from_rotvec(o[3:6]).as_matrix(), o[:3].copy()


def contact_curves(samples, positions: np.ndarray, axes: np.ndarray, tool: Tool, *,
                   part2real: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
                   chunk: int = 2000) -> ContactCurves:
    """Force-offset curves of ``positions`` ``(P, 3)`` with tool axes ``axes`` ``(P, 3)`` on ``samples``.

    Parameters
    ----------
    samples : Surface
        The planned part surface, finely sampled (vertices, smooth normals, vertex areas).
    positions, axes : (P, 3) float
        Planned TCP positions (m) and unit tool z-axes (into the part), part frame.
    tool : Tool
    part2real : (R (3, 3), d (3,), c (3,)), optional
        The real part is the planned one rotated by ``R`` about the point ``c`` (m) and moved by
        ``d`` (m): ``q_real = R (q − c) + c + d``.  None = perfect registration.
    chunk : int
        Poses per vectorised batch.

    Returns
    -------
    ContactCurves
    """
    from scipy.spatial import cKDTree

    positions = np.asarray(positions, float)
    axes = np.asarray(axes, float)
    if part2real is not None:
        R, d, c = part2real
        # pose in the real part's frame, expressed on the planned geometry: p' = Rᵀ (p − c − d) + c
        positions = (positions - c - d) @ R + c
        axes = axes @ R
    # float32 geometry (as the removal simulation): half the memory traffic; heights keep ~1e-7 m.
    origin = samples.vertices.mean(axis=0)
    pts = (samples.vertices - origin).astype(np.float32)
    nrm, area = samples.normals.astype(np.float32), samples.vertex_areas
    positions = positions - origin
    tree = samples.kdtree
    Rp = tool.pad_radius
    zs, ws, starts = [], [], [0]
    for lo in range(0, len(positions), chunk):
        pos, ax = positions[lo:lo + chunk], axes[lo:lo + chunk]
        coo = cKDTree(pos + origin).sparse_distance_matrix(tree, math.hypot(Rp, 0.5 * Rp), output_type="coo_matrix")
        pose, sample = coo.row, coo.col
        rel = pts[sample] - pos.astype(np.float32)[pose]
        a = ax.astype(np.float32)[pose]
        z = np.einsum("ij,ij->i", rel, a)
        r2 = np.einsum("ij,ij->i", rel, rel) - z * z
        keep = (r2 <= Rp * Rp * (1 + 1e-6)) & (np.einsum("ij,ij->i", nrm[sample], a) < 0.0)
        pose, z, w = pose[keep], z[keep].astype(float), area[sample[keep]]
        order = np.lexsort((z, pose))
        pose, z, w = pose[order], z[order], w[order]
        counts = np.bincount(pose, minlength=len(pos))
        zs.append(z)
        ws.append(w)
        starts.extend((starts[-1] + np.cumsum(counts)).tolist())
    z = np.concatenate(zs) if zs else np.zeros(0)
    w = np.concatenate(ws) if ws else np.zeros(0)
    start = np.asarray(starts, dtype=np.int64)
    # running sums restart at every pose
    cw = np.cumsum(w)
    cwz = np.cumsum(w * z)
    first = start[:-1]
    has = start[1:] > first
    base_w = np.zeros(len(first))
    base_m = np.zeros(len(first))
    base_w[has] = np.where(first[has] > 0, cw[np.maximum(first[has] - 1, 0)], 0.0)
    base_m[has] = np.where(first[has] > 0, cwz[np.maximum(first[has] - 1, 0)], 0.0)
    counts = np.diff(start)
    cw -= np.repeat(base_w, counts)
    cwz -= np.repeat(base_m, counts)
    return ContactCurves(start, z, cw, cwz, tool.k)
