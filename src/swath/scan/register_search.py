"""Coarse global search of :mod:`swath.scan.register`: start poses (principal axes, the
icosahedral rotations, turns on a table) placed where they fit a distance field of the target."""

from __future__ import annotations

import logging

import numpy as np

from .register_result import rigid_matrix
from .register_settings import (
    COARSE_SPACING,
    MAX_CENTRES,
    MAX_FIELD_CELLS,
    PLACE_CHUNK,
    PLACE_CLIP,
    PLACE_KEEP,
    PLACE_POINTS,
)
from .register_target import _plane_axes, _right_handed_axes

log = logging.getLogger("swath.scan")
# --------------------------------------------------------------------------------------------
# start poses
# --------------------------------------------------------------------------------------------
def _pca_starts(src, tgt):
    """Source principal frame onto target principal frame, under all 24 proper axis swaps and
    sign flips (the 4 sign flips alone when the spreads are distinct; swaps for near-ties or
    clutter in the target)."""
    from scipy.spatial.transform import Rotation

    cs, As = _right_handed_axes(src.points, src.weights)
    ct, At = _right_handed_axes(tgt.points, None)
    out = []
    for g in Rotation.create_group("O").as_matrix():
        r = At.T @ g @ As
        out.append(rigid_matrix(r, ct - r @ cs))
    return out


def _rotation_starts(src, tgt):
    """The 60 rotations of the icosahedral group about the source centroid, centroids aligned."""
    from scipy.spatial.transform import Rotation

    out = []
    for r in Rotation.create_group("I").as_matrix():
        out.append(rigid_matrix(r, tgt.centroid - r @ src.centroid))
    return out


def _table_starts(src, tgt, init, k, fit_height, turns=24):
    """Turns about the table normal through the source centroid (after ``init``), with the
    centroids aligned in the table plane (and along the normal with ``fit_height``)."""
    from scipy.spatial.transform import Rotation

    out = []
    c0 = init[:3, :3] @ src.centroid + init[:3, 3]
    shift = tgt.centroid - c0
    if not fit_height:
        shift = shift - k * (shift @ k)
    for a in np.arange(turns) * 2 * np.pi / turns:
        r = Rotation.from_rotvec(a * k).as_matrix()
        step = rigid_matrix(r, c0 + shift - r @ c0)
        out.append(step @ init)
    return out


class _DistanceField:
    """Distance (m) to the nearest target point on a voxel grid: a lookup that costs nothing next
    to a kd-tree query, for scoring thousands of placements during the coarse search."""

    def __init__(self, points, spacing, margin):
        from scipy.ndimage import distance_transform_edt

        self.h = float(spacing)
        self.origin = points.min(axis=0) - margin
        shape = np.ceil((points.max(axis=0) + margin - self.origin) / self.h).astype(int) + 1
        cells = int(np.prod(shape))
        if cells > MAX_FIELD_CELLS:             # very flat or very large targets: coarser grid
            self.h *= (cells / MAX_FIELD_CELLS) ** (1 / 3)
            shape = np.ceil((points.max(axis=0) + margin - self.origin) / self.h).astype(int) + 1
        occupied = np.zeros(shape, bool)
        occupied[tuple(np.round((points - self.origin) / self.h).astype(int).T)] = True
        self.grid = (distance_transform_edt(~occupied) * self.h).astype(np.float32)
        self.shape = np.array(shape)

    def index(self, points):
        """Integer grid coordinates ``(..., 3)`` of points ``(..., 3)``."""
        return np.round((points - self.origin) / self.h).astype(np.int64)

    def at(self, idx):
        """Distances ``(...)`` at integer grid coordinates ``(..., 3)`` (clamped to the grid)."""
        idx = np.clip(idx, 0, self.shape - 1)
        return self.grid[idx[..., 0], idx[..., 1], idx[..., 2]]


def _place(src, tgt, starts, centres, rng):
    """For each start pose, move the source centroid to the candidate centre ``(m, 3)`` where the
    start's rotation fits the target best: the mean clipped squared distance of a few source
    points in a distance field of the target.  This replaces centroid alignment, which fails when
    the target holds more than the part (a scan with its table and fixtures)."""
    spacing = COARSE_SPACING * src.size
    field = _DistanceField(tgt.points, spacing, 0.6 * src.size)
    n = min(PLACE_POINTS, len(src.points))
    local = src.points[rng.choice(len(src.points), size=n, replace=False)] - src.centroid
    clip = PLACE_CLIP * spacing
    # centres snapped to the grid, so each placement is an integer shift of the rotated points
    cidx = field.index(centres)
    out, losses = [], []
    for m in starts:
        q = np.round((local @ m[:3, :3].T) / field.h).astype(np.int64)
        best, best_loss = 0, np.inf
        for lo in range(0, len(cidx), PLACE_CHUNK):
            dist = np.minimum(field.at(q[None] + cidx[lo:lo + PLACE_CHUNK, None]), clip)
            loss = np.einsum("cn,cn->c", dist, dist)
            i = int(np.argmin(loss))
            if loss[i] < best_loss:
                best, best_loss = lo + i, loss[i]
        # the candidate itself, not its snapped grid cell: on a table its height must stay exact
        out.append(rigid_matrix(m[:3, :3], centres[best] - m[:3, :3] @ src.centroid))
        losses.append(best_loss)
    # only the best placements go on to the (costlier) coarse ICP
    return [out[i] for i in np.argsort(losses, kind="stable")[:PLACE_KEEP]]


def _grid_centres(tgt, step, k=None, height=None):
    """Candidate positions ``(m, 3)`` for the source centroid over the target's extent, ``step`` m
    apart; on a table (``k`` given) a grid in the table plane, at ``height`` along ``k`` when
    given, else at heights over the target's extent along ``k``."""
    pts = tgt.points
    if k is None:
        axes = np.eye(3)
    else:
        axes = np.vstack([_plane_axes(k), k])
    coords = pts @ axes.T
    lo, hi = coords.min(axis=0), coords.max(axis=0)
    if height is not None:
        lo[2] = hi[2] = height
    count = np.prod(np.floor((hi - lo) / step) + 1)
    if count > MAX_CENTRES:                     # a target much larger than the part: coarser grid
        dims = 2 if height is not None else 3
        step *= (count / MAX_CENTRES) ** (1 / dims)
    ticks = [np.arange(a, b + step, step) for a, b in zip(lo, hi)]
    if height is not None:
        ticks[2] = np.array([height])
    grid = np.stack(np.meshgrid(*ticks, indexing="ij"), axis=-1).reshape(-1, 3)
    centroid = tgt.centroid @ axes.T
    if height is not None:
        centroid[2] = height
    return np.vstack([grid, centroid]) @ axes
