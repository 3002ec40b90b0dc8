"""Seed curves for geodesic-parallel passes: the side of a boundary loop that runs along the feed, and the band of vertices near a polyline with their distance to it."""

from __future__ import annotations

import logging
import math

import numpy as np

from ..surface.geometry import normalize

log = logging.getLogger(__name__)


#: Seed side: boundary whose tangent is within this angle of the feed direction (rad).
SEED_ANGLE = math.radians(45.0)


def polyline_band(vertices: np.ndarray, polylines, radius: float, *, tree=None) -> tuple[np.ndarray, np.ndarray]:
    """Vertices within ``radius`` of polylines and their straight-line distance to the nearest one.

    Parameters
    ----------
    vertices : (n, 3) float
    polylines : list of (k, 3) float
        Curves on (or very near) the surface, m; points at most about ``radius / 2`` apart.
    radius : float
        Band half-width, m; within a few mesh edges the straight-line distance to the curve is the
        geodesic distance to far below a micrometre on any part a pad can follow.
    tree : scipy.spatial.cKDTree, optional
        Tree over ``vertices``.

    Returns
    -------
    index : (s,) int
        Vertices in the band.
    distance : (s,) float
        Their distance to the nearest polyline segment, m.
    """
    from scipy.spatial import cKDTree

    V = np.asarray(vertices, float)
    tree = cKDTree(V) if tree is None else tree
    idx_all, d_all = [], []
    for pl in polylines:
        pl = np.asarray(pl, float).reshape(-1, 3)
        near = tree.query_ball_point(pl, r=radius)
        cand = np.unique(np.concatenate([np.asarray(c, np.int64) for c in near])) if len(pl) else np.zeros(0, np.int64)
        if len(cand) == 0:
            continue
        q = V[cand]
        _, j = cKDTree(pl).query(q)
        d = np.linalg.norm(q - pl[j], axis=1)
        for lo in (j - 1, j):                       # the two segments at the nearest point
            ok = (lo >= 0) & (lo + 1 < len(pl))
            a, b = pl[np.clip(lo, 0, len(pl) - 1)], pl[np.clip(lo + 1, 0, len(pl) - 1)]
            ab = b - a
            L2 = np.einsum("ij,ij->i", ab, ab)
            t = np.clip(np.divide(np.einsum("ij,ij->i", q - a, ab), L2, out=np.zeros(len(q)), where=L2 > 0), 0, 1)
            d = np.where(ok, np.minimum(d, np.linalg.norm(a + t[:, None] * ab - q, axis=1)), d)
        idx_all.append(cand)
        d_all.append(d)
    if not idx_all:
        return np.zeros(0, np.int64), np.zeros(0)
    idx, d = np.concatenate(idx_all), np.concatenate(d_all)
    order = np.lexsort((d, idx))
    idx, d = idx[order], d[order]
    first = np.r_[True, idx[1:] != idx[:-1]]
    return idx[first], d[first]


# ----------------------------------------------------------------------------------------------
# seeds
# ----------------------------------------------------------------------------------------------
def boundary_seed(vertices: np.ndarray, loop: np.ndarray, feed: np.ndarray, cross: np.ndarray, *,
                  window: float) -> np.ndarray:
    """The boundary side at the low end of ``cross``: a run of a boundary loop roughly along ``feed``.

    Parameters
    ----------
    vertices : (n, 3) float
    loop : (b,) int
        A closed boundary loop (vertex indices in order).
    feed, cross : (3,) float
        Unit feed and cross directions.
    window : float
        Arc-length half-window (m) over which the loop's tangent is averaged, so that a ragged
        scan boundary has a direction; gaps shorter than half of it are bridged inside a run.

    Returns
    -------
    (r,) int
        Loop vertices in loop order: the run whose averaged tangent stays within
        :data:`SEED_ANGLE` of the feed direction (measured in the feed-cross plane) and which
        holds the lowest such vertex along ``cross``.  When no part of the loop runs along the feed, the vertices within a window
        of the loop's lowest point.
    """
    loop = np.asarray(loop, np.int64)
    P = np.asarray(vertices, float)[loop]
    b = len(P)
    seg = np.linalg.norm(np.roll(P, -1, axis=0) - P, axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    total = float(s[-1])
    h = P @ np.asarray(cross, float)
    if b < 3 or total <= 0:
        return loop[[int(np.argmin(h))]]
    w = min(float(window), 0.25 * total)
    closed = np.vstack([P, P[:1]])

    def at(x):
        x = np.mod(x, total)
        return np.stack([np.interp(x, s, closed[:, j]) for j in range(3)], axis=1)

    feed, cross = np.asarray(feed, float), np.asarray(cross, float)

    def runs_along(t):
        # Angle to the feed measured in the (feed, cross) plane, so a boundary running down a
        # slope along the feed still counts; one running mostly along the normal does not.
        tf, tc = np.abs(t @ feed), np.abs(t @ cross)
        return (tf * math.tan(SEED_ANGLE) >= tc) & (tf >= 0.25)

    tangent = normalize(at(s[:-1] + w) - at(s[:-1] - w))
    along = runs_along(tangent)
    if not along.any():
        d = np.abs(s[:-1] - s[int(np.argmin(h))])
        return loop[np.minimum(d, total - d) <= w]
    if along.all():
        return loop
    # Runs of `along` vertices, in loop order starting at a vertex that is not along the feed.
    r0 = int(np.argmin(along))
    order = (np.arange(b) + r0) % b
    a = along[order].astype(int)
    pos = np.mod(s[:-1][order] - s[r0], total)
    edge = np.diff(np.concatenate([[0], a, [0]]))
    starts, ends = list(np.flatnonzero(edge == 1)), list(np.flatnonzero(edge == -1) - 1)
    bridge = 0.5 * w
    runs = [[starts[0], ends[0]]]
    for st, en in zip(starts[1:], ends[1:]):
        if pos[st] - pos[runs[-1][1]] <= bridge:
            runs[-1][1] = en
        else:
            runs.append([st, en])
    spans = [np.arange(st, en + 1) for st, en in runs]
    if len(spans) > 1 and total - pos[runs[-1][1]] + pos[runs[0][0]] <= bridge:   # wraps round
        spans[0] = np.concatenate([np.arange(runs[-1][0], b), np.arange(0, runs[0][1] + 1)])
        spans.pop()
    lowest = int(np.argmin(np.where(a > 0, h[order], np.inf)))
    span = order[next(sp for sp in spans if np.any(sp == lowest))]
    # The averaged tangent blurs a corner over the window: extend the run edge by edge while the
    # edges themselves still run along the feed (so it ends at the corner, not a window short).
    edge_along = runs_along(normalize(np.roll(P, -1, axis=0) - P))
    head: list[int] = []
    tail: list[int] = []
    grown = 0.0
    i = int(span[-1])
    while grown < w and edge_along[i] and len(span) + len(head) + len(tail) < b:
        grown += seg[i]
        i = (i + 1) % b
        tail.append(i)
    grown = 0.0
    i = int(span[0])
    while grown < w and edge_along[(i - 1) % b] and len(span) + len(head) + len(tail) < b:
        i = (i - 1) % b
        grown += seg[i]
        head.append(i)
    return loop[np.concatenate([head[::-1], span, tail]).astype(np.int64)]
