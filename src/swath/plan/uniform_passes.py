"""Pieces of the uniform planner's passes: level-set pieces smoothed and cut at sharp turns, the area they touch, and touch-up passes across pockets the pad rode over."""

from __future__ import annotations

import logging
import math

import numpy as np

from ..core import Pass
from ..surface.geometry import normalize
from ..surface.polyline import resample_uniform
from .slicing import resample, slice_mesh

log = logging.getLogger(__name__)


#: Passes are smoothed by a moving average this many pad radii long: level sets on the working mesh
#: zig-zag at its edge scale, and every zig-zag turns the tool (slowing it under an angular-speed limit).
SMOOTHING_WINDOW = 1.0


def _finished(ctx, pieces, step, min_length: float, cut: bool = True) -> list[np.ndarray]:
    """:func:`_finish_piece` over level-set ``pieces``, keeping the parts at least ``min_length`` m long."""
    return [c for p in pieces for c in _finish_piece(ctx, p, step, cut) if _length(c) >= min_length]


def _finish_piece(ctx, pl, step, cut: bool = True) -> list[np.ndarray]:
    """Resample, smooth and project a pass piece and (if ``cut``) cut it at sharp turns; return its
    parts, each (k, 3) points, m."""
    pts = pl if isinstance(pl, np.ndarray) else resample(pl, step).points
    if len(pts) < 3:
        return []
    # A short piece or a small loop would shrink under the full window: keep it to a sixth of the
    # piece (a loop's radius), which moves a loop's points in by under 4 %.
    window = min(SMOOTHING_WINDOW * ctx.tool.pad_radius, _length(pts) / 6.0) / step
    pts = _smooth(pts, window=max(3, int(round(window))))
    pts, nrm = ctx.project(pts)
    out = []
    limit = ctx.max_turn_curvature if cut else math.inf
    for part in _cut_sharp_turns(pts, nrm, limit, ctx.tool.pad_radius / 8):
        if len(part) >= 3:
            out.append(part)
    return out


def turn_curvature(pts: np.ndarray, normals: np.ndarray, arm: float) -> np.ndarray:
    """(k,) curvature (1/m) of the polyline ``pts`` ``(k, 3)`` within the tangent planes ``normals``:
    the turn between the chords to the points ``arm`` metres behind and ahead, over their mean
    length.  This is the geodesic curvature a pass has on the surface; at feed v the tool turns
    about its axis at v times it.  A closed polyline (ends within two steps) wraps round."""
    k = len(pts)
    steps = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    if k < 3 or steps.sum() <= 0:
        return np.zeros(k)
    m = max(1, int(round(arm / max(float(np.median(steps)), 1e-12))))
    closed = _is_closed(pts)
    i = np.arange(k)
    if closed:
        ring = k - 1                              # the last point repeats the first
        back, ahead = pts[(i - m) % ring], pts[(i + m) % ring]
    else:
        back, ahead = pts[np.maximum(i - m, 0)], pts[np.minimum(i + m, k - 1)]
    c1, c2 = pts - back, ahead - pts
    c1 = c1 - np.einsum("ij,ij->i", c1, normals)[:, None] * normals
    c2 = c2 - np.einsum("ij,ij->i", c2, normals)[:, None] * normals
    l1, l2 = np.linalg.norm(c1, axis=1), np.linalg.norm(c2, axis=1)
    ok = (l1 > 1e-12) & (l2 > 1e-12)
    cos = np.einsum("ij,ij->i", c1, c2) / np.maximum(l1 * l2, 1e-300)
    angle = np.arccos(np.clip(cos, -1.0, 1.0))
    return np.where(ok, angle / np.maximum(0.5 * (l1 + l2), 1e-12), 0.0)


def _cut_sharp_turns(pts, normals, max_curvature: float, arm: float) -> list[np.ndarray]:
    """Split the polyline ``pts`` where it turns in its tangent plane by more than ``max_curvature``
    (1/m, measured over chords ``arm`` long); the sharp stretches themselves are dropped."""
    if not math.isfinite(max_curvature):
        return [pts]
    sharp = turn_curvature(pts, normals, arm) > max_curvature
    if not sharp.any():
        return [pts]
    closed = len(pts) > 3 and _is_closed(pts)
    if closed:
        # Start the loop at a sharp point so the smooth runs do not straddle the seam.
        first = int(np.flatnonzero(sharp)[0])
        pts = np.vstack([pts[first:-1], pts[:first + 1]])
        sharp = np.concatenate([sharp[first:-1], sharp[:first + 1]])
    keep = ~sharp
    edges = np.flatnonzero(np.diff(np.concatenate([[0], keep.astype(np.int8), [0]])))
    return [pts[a:b] for a, b in zip(edges[::2], edges[1::2])]


#: A closed loop a generation keeps whole (no part of it turns gently enough to keep) is laid as a
#: straight pass across its middle instead when it fits within this many pad radii across: the pad
#: there covers what the loop encloses, and a straight pass does not turn the tool.  Run as a loop,
#: the tool turns a full circle about its axis: at 1 rad/s that takes 6.3 s however small the
#: loop, and it dwells on one spot the while.  On noether_wavy_mesh_with_hole six such loops (2 to
#: 17 mm across, 10 to 38 mm long) held the tool at 2 mm/s for about 4 s each and removed 20 times
#: the median depth beside them (interior removal CoV 1.65 at constant feed).
LOOP_CHORD_EXTENT = 1.0


def _chord_if_small_loop(ctx, pts: np.ndarray, step: float, min_length: float) -> np.ndarray:
    """``pts`` ``(k, 3)``, or, where it is a closed loop at most :data:`LOOP_CHORD_EXTENT` pad radii
    across, the straight pass across its middle along its longest extent (at least ``min_length``
    long, points ``step`` apart, dropped onto the surface).  A loop round a hole is kept: the chord
    would cross it (a point of the chord farther than two working-mesh edges from the mesh)."""
    if len(pts) < 4 or not _is_closed(pts):
        return pts
    centre = pts.mean(axis=0)
    axis = np.linalg.svd(pts - centre, full_matrices=False)[2][0]
    along = (pts - centre) @ axis
    R = ctx.tool.pad_radius
    # its spread along the longest axis first (cheap), then the widest pair of points
    if np.ptp(along) > LOOP_CHORD_EXTENT * R or \
            np.max(np.linalg.norm(pts[:, None, :] - pts[None, :, :], axis=2)) > LOOP_CHORD_EXTENT * R:
        return pts
    lo, hi = float(along.min()), float(along.max())
    mid, half = 0.5 * (lo + hi), max(0.5 * (hi - lo), 0.5 * min_length)
    n = max(3, int(math.ceil(2.0 * half / step)) + 1)
    line = centre + (mid + np.linspace(-half, half, n))[:, None] * axis
    # a loop round a hole smaller than the pad: its chord would cross the hole (its points no
    # nearer the surface than the hole's rim); the loop is kept
    gap, _ = ctx.tree.query(line)
    if np.max(gap) > 2.0 * ctx.work_spacing:
        return pts
    return ctx.project(line)[0]


def _is_closed(pts) -> bool:
    """Whether the polyline ``pts`` ``(k, 3)`` is a loop: its ends within two median steps."""
    steps = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    return bool(np.linalg.norm(pts[-1] - pts[0]) <= 2.0 * np.median(steps))


def _smooth(pts, window):
    """Moving-average smoothing of a polyline ``(k, 3)`` over ``window`` points: an open one with
    its ends held, a closed one (ends within two point steps) all the way round."""
    k = len(pts)
    if k < 5 or window < 3:
        return pts
    window = min(window | 1, k - (1 - k % 2))
    if window < 3:
        return pts
    kernel = np.ones(window) / window
    half = window // 2
    closed = _is_closed(pts)
    if closed:
        padded = np.vstack([pts[-half - 1:-1], pts, pts[1:half + 1]])
    else:
        padded = np.vstack([np.repeat(pts[:1], half, 0), pts, np.repeat(pts[-1:], half, 0)])
    out = np.stack([np.convolve(padded[:, j], kernel, mode="valid") for j in range(3)], axis=1)
    if not closed:
        out[0], out[-1] = pts[0], pts[-1]
    return out


def _touched_by(ctx, pieces) -> np.ndarray:
    """(n,) bool: working vertices the pad touches along any of ``pieces`` (each (k, 3) points, m)."""
    gained = np.zeros(len(ctx.work.vertices), bool)
    for pts in pieces:
        gained |= ctx.touched(pts)
    return gained


def _length(pts) -> float:
    return float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())


def _area(W, mask) -> float:
    return float(W.vertex_areas[mask].sum())


def _touch_up(ctx, passes: list[np.ndarray], covered: np.ndarray, step: float, min_pass_length: float,
              rounds: int = 2) -> tuple[np.ndarray, list[np.ndarray]]:
    """Check the pockets the passes seem to miss, and cross the ones they really miss.

    Where the surface is concave more tightly than the pad can follow (waves or dimples narrower
    than the pad), the pad rides on the crests and touches a trough's bottom only with its rim, at
    the moment its centre is about a pad radius away.  Those rim contacts are thin, so the pockets
    left uncovered by the generation loop (whose poses are R/8 apart) are first re-checked with a pose
    at every pass point (``step`` apart).  A pocket (at least 1 % and at most 100 % of the pad's area)
    still untouched gets a short pass across it
    along its most concave principal direction, reaching a pad radius beyond it on both sides, so
    the rim sweeps its bottom on the way in and out; it is kept only if it touches new area.

    Parameters
    ----------
    passes : list of (k, 3) float
        The passes so far, points ``step`` apart, m.
    covered : (n,) bool
        Working vertices touched so far.

    Returns
    -------
    covered : (n,) bool
        Updated.
    touch_ups : list of (k, 3) float
        The added passes.
    """
    W, R = ctx.work, ctx.tool.pad_radius
    min_area = max(1e-4 * W.area, 0.01 * math.pi * R * R)
    pad_area = math.pi * R * R
    big = _uncovered_pockets(ctx, covered, pad_area * (1 + 1e-9))
    if big:           # larger than the pad: not a pocket between passes (max_passes, or passes dropped)
        log.info("uniform: %d uncovered regions larger than the pad (%.4f m2 in all) left as they are",
                    len(big), sum(_area(W, b) for b in big))
    blobs = _uncovered_pockets(ctx, covered, min_area, pad_area)
    if not blobs:
        return covered, []
    from scipy.spatial import cKDTree

    near_tree = cKDTree(W.vertices[np.concatenate(blobs)])
    for pts in passes:
        close = np.isfinite(near_tree.query(pts, distance_upper_bound=1.2 * R)[0])
        if close.any():
            covered = covered | ctx.touched_at(pts[close])
    added = []
    c = ctx.widths.curvature
    for _ in range(rounds):
        blobs = _uncovered_pockets(ctx, covered, min_area, pad_area)
        if not blobs:
            break
        grew = False
        for blob in blobs:
            centre = W.vertices[blob].T @ W.vertex_areas[blob] / W.vertex_areas[blob].sum()
            v = blob[np.argmin(np.linalg.norm(W.vertices[blob] - centre, axis=1))]
            n = W.normals[v]
            across = normalize((c.d2[v] - (c.d2[v] @ n) * n)[None])[0]
            reach = float(np.max(np.linalg.norm(W.vertices[blob] - W.vertices[v], axis=1))) + 1.1 * R
            pieces = slice_mesh(W.vertices, W.faces, np.cross(n, across), [float(W.vertices[v] @ np.cross(n, across))],
                                edges=ctx.edges)
            best = None
            for pl in pieces:
                pts = resample(pl, step).points
                if len(pts) < 3:
                    continue
                dist = np.linalg.norm(pts - W.vertices[v], axis=1)
                k = int(np.argmin(dist))
                if best is None or dist[k] < best[1]:
                    best = (pts, dist[k], k, dist)
            if best is None or best[1] > ctx.work_spacing:
                continue
            pts, _, k, dist = best
            lo, hi = k, k
            while lo > 0 and dist[lo - 1] <= reach:
                lo -= 1
            while hi < len(pts) - 1 and dist[hi + 1] <= reach:
                hi += 1
            pts = pts[lo:hi + 1]
            if _length(pts) < min_pass_length:
                continue
            pts, _ = ctx.project(pts)
            gained = ctx.touched_at(pts) & ~covered
            if _area(W, gained) <= 0.0:
                continue
            covered = covered | gained
            added.append(pts)
            grew = True
        if not grew:
            break
    if added:
        log.info("uniform: %d touch-up passes across pockets the passes missed (%.2f m)", len(added),
                 sum(_length(p) for p in added))
    return covered, added


def _uncovered_pockets(ctx, covered: np.ndarray, min_area: float, max_area: float = math.inf) -> list[np.ndarray]:
    """Connected groups of uncovered working vertices (edges of ``ctx.edges``) whose area is
    within [``min_area``, ``max_area``] m²."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    W = ctx.work
    free = ~covered
    e = ctx.edges[0]
    e = e[free[e[:, 0]] & free[e[:, 1]]]
    n = len(W.vertices)
    _, label = connected_components(coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n)), directed=False)
    ids = np.flatnonzero(free)
    area = np.bincount(label[ids], weights=W.vertex_areas[ids], minlength=n)
    order = np.argsort(label[ids], kind="stable")
    groups = np.split(ids[order], np.flatnonzero(np.diff(label[ids][order])) + 1)
    return [g for g in groups if len(g) and min_area <= area[label[g[0]]] <= max_area]


def _insert_near(passes: list[np.ndarray], extra: list[np.ndarray]) -> list[np.ndarray]:
    """``passes`` with each of ``extra`` inserted right after the pass nearest to its middle."""
    out = list(passes)
    for e in extra:
        mid = e[len(e) // 2]
        k = int(np.argmin([np.min(np.linalg.norm(p - mid, axis=1)) for p in out]))
        out.insert(k + 1, e)
    return out


def _on_surface_pass(surface, pts, point_spacing, **tags) -> Pass:
    """Resample a pass at ``point_spacing`` and put every point on ``surface`` with its smooth normal."""
    _, res = resample_uniform(pts, point_spacing)
    closest, _, face = surface.closest_points(res)
    return Pass(closest, surface.interpolate_normals(closest, face), **tags)
