"""Sweep-line decomposition: split a surface into regions that every sweep line crosses in one piece.

Sweep lines are the surface's level sets of the height ``h = x · c`` along a cross direction ``c``
(the normal of the raster's cutting planes; the sweep, or feed, direction lies in the best-fit plane
at right angles to it).  Where a sweep line breaks into pieces — at a hole, a notch in the outline,
a saddle — the pad would lift off.  Wang (§1) clusters the sweep lines' segments by the overlap of
neighbouring lines; this module does the same clustering exactly, as a boustrophedon (Morse) cell
decomposition of the triangulated surface:

1. **critical heights**: the heights where the topology of the level sets can change — vertices
   whose link, walked round, changes between lower and higher neighbours other than twice (inside
   the surface; an extremum has 0 changes, a saddle 4 or more) or other than once (on the border:
   the tips of holes and of the outline).  Ties are broken by vertex index, as the slicer does;
2. **cut** every triangle that straddles a critical height along that level, so each triangle lies
   in one *band* between consecutive critical heights.  No critical point lies inside a band, so
   each connected piece of a band is a product (one sweep-line segment) x (an interval);
3. **chain** the pieces of consecutive bands that share an edge along the level between them.  A
   region is a chain with one piece per band, so each of its sweep lines is one unbroken segment.
   The fewest chains that cover all pieces is a maximum matching between each two consecutive
   bands (a minimum path cover of a layered graph); ties go to the longest shared border;
4. regions smaller than ``min_area`` are merged into the neighbour they share most border with
   (their sweep lines then have a second, short piece; see :func:`segment`).

Cost: ``O(m log m)`` for ``m`` triangles plus the cuts; the cut surface has a few more triangles
than the input (those straddling critical heights are split in three).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..surface import Surface
from ..surface.frames import feed_and_cross

log = logging.getLogger("swath.segment")

#: Feed angles (rad, from the first principal axis about the best-fit normal) tried for ``direction=None``.
AUTO_ANGLES = (0.0, math.pi / 4, math.pi / 2, 3 * math.pi / 4)
#: Default smallest outline wiggle cut at, m.
MIN_FEATURE = 5e-3
#: Default smallest region, m² (2 cm²).
MIN_AREA = 2e-4


@dataclass(frozen=True, eq=False)
class Region:
    """A part of a surface that parallel sweep lines cross without breaks.

    Attributes
    ----------
    id : int
        Index of the region in the list :func:`segment` returns.
    faces : (k,) int
        Faces of the parent surface that the region covers wholly or partly (faces cut at a region
        border appear in both regions).
    surface : Surface
        The region as a surface of its own: the parent's triangles, those on its border cut along
        the border level; every point of it lies on the parent surface.
    direction : (3,) float
        Unit sweep (feed) direction, part frame; the sweep lines are the level sets of the height
        along ``cross`` (cross = best-fit normal x direction).
    area : float
        Area, m².
    cross : (3,) float
        Unit normal of the sweep-line planes (the level sets are ``x · cross = const``); pass it to
        the raster planner as ``cross_direction`` so its cutting planes are these planes.
    """

    id: int
    faces: np.ndarray
    surface: Surface
    direction: np.ndarray
    area: float
    cross: np.ndarray


def sweep_frame(surface, *, angle: float = 0.0, direction=None) -> tuple[np.ndarray, np.ndarray]:
    """Unit feed direction ``(3,)`` and cross direction ``(3,)`` (the sweep lines' plane normal):
    :func:`swath.surface.frames.feed_and_cross`, the planners' rule."""
    return feed_and_cross(surface, angle=angle, direction=direction)


def critical_vertices(faces: np.ndarray, height: np.ndarray, *, loops=None, tolerance: float = 0.0) -> np.ndarray:
    """Indices of the vertices where the level sets of ``height`` ``(n,)`` may change topology.

    A vertex ``v`` is compared with its neighbours by (height, index); walking round its link, the
    number of changes between lower and higher neighbours is 2 at a regular interior vertex and 1 at
    a regular border vertex.  Everything else (extrema, saddles, border tips, non-manifold
    vertices) is returned.  With the border ``loops`` (vertex index arrays) and a ``tolerance`` (m),
    the border vertices are replaced by the loops' significant extrema (:func:`boundary_turns`):
    wiggles of the outline smaller than the tolerance then leave short extra pieces on a few sweep
    lines instead of a region each.
    """
    F = np.asarray(faces, np.int64)
    h = np.asarray(height, float)
    n = len(h)
    counts = np.zeros(n, np.int64)
    for k in range(3):
        v, a, b = F[:, k], F[:, (k + 1) % 3], F[:, (k + 2) % 3]
        low_a = (h[a] < h[v]) | ((h[a] == h[v]) & (a < v))
        low_b = (h[b] < h[v]) | ((h[b] == h[v]) & (b < v))
        counts += np.bincount(v, weights=(low_a != low_b), minlength=n).astype(np.int64)
    on_border = np.zeros(n, bool)
    edges = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    uniq, cnt = np.unique(edges, axis=0, return_counts=True)
    on_border[uniq[cnt == 1].ravel()] = True
    used = np.zeros(n, bool)
    used[F.ravel()] = True
    critical = np.where(on_border, counts != 1, counts != 2) & used
    if loops is not None and tolerance > 0:
        critical &= ~on_border
        for loop in loops:
            loop = np.asarray(loop, np.int64)
            critical[loop[boundary_turns(h[loop], tolerance)]] = True
    return np.flatnonzero(critical)


def boundary_turns(height_along_loop: np.ndarray, tolerance: float) -> np.ndarray:
    """Positions of the significant extrema of a height sampled round a closed loop ``(k,)``.

    A zig-zag filter (1-D persistence): starting from the highest point, a minimum (maximum) is kept
    once the height has risen (fallen) by at least ``tolerance`` from it, so wiggles smaller than
    ``tolerance`` — the ragged outline of a scan — are skipped.  A loop whose whole swing is below
    the tolerance (a pin hole) keeps its highest and lowest point.
    """
    h = np.asarray(height_along_loop, float)
    k = len(h)
    if k == 0:
        return np.zeros(0, np.int64)
    top = int(np.argmax(h))
    if np.ptp(h) < tolerance or tolerance <= 0:
        if tolerance <= 0:
            prev, nxt = np.roll(h, 1), np.roll(h, -1)
            return np.flatnonzero(((h >= prev) & (h >= nxt)) | ((h <= prev) & (h <= nxt)))
        return np.unique([top, int(np.argmin(h))])
    order = (top + np.arange(k)) % k
    turns = [top]
    going_down = True
    cand = top
    for i in order[1:]:
        if going_down:
            if h[i] < h[cand]:
                cand = i
            elif h[i] >= h[cand] + tolerance:
                turns.append(cand)
                going_down, cand = False, i
        else:
            if h[i] > h[cand]:
                cand = i
            elif h[i] <= h[cand] - tolerance:
                turns.append(cand)
                going_down, cand = True, i
    if not going_down and cand != top and h[cand] < h[top]:
        pass                                         # the last rise ends at the start (the top)
    elif going_down and cand != top:
        turns.append(cand)                           # the last fall's minimum before coming back up
    return np.unique(np.array(turns, np.int64))


def split_at_levels(vertices: np.ndarray, faces: np.ndarray, height: np.ndarray, levels):
    """Cut every triangle straddling a level ``height = L`` along it.

    Returns
    -------
    vertices : (n', 3) float
    faces : (m', 3) int
        Same winding as the triangle each comes from; no triangle has vertices strictly on both
        sides of a level.  Crossings on a shared edge are shared, so the mesh stays connected.
    height : (n',) float
    parent : (m',) int
        The input triangle each output triangle comes from.
    """
    V = np.asarray(vertices, float)
    F = np.asarray(faces, np.int64)
    h = np.asarray(height, float).copy()
    parent = np.arange(len(F))
    for L in np.sort(np.asarray(levels, float)):
        below = h[F] < L
        nb = below.sum(axis=1)
        cut = (nb == 1) | (nb == 2)
        if not cut.any():
            continue
        Fc = F[cut]
        lone = np.where(nb[cut] == 1, np.argmax(below[cut], axis=1), np.argmax(~below[cut], axis=1))
        rows = np.arange(len(Fc))[:, None]
        rolled = Fc[rows, (lone[:, None] + np.arange(3)) % 3]          # lone vertex first, winding kept
        a, b, c = rolled[:, 0], rolled[:, 1], rolled[:, 2]
        # crossings on edges (a, b) and (a, c), shared between the two triangles of an edge
        ends = np.concatenate([np.stack([a, b], 1), np.stack([a, c], 1)])
        key = np.sort(ends, axis=1)
        _, inv = np.unique(key[:, 0] * np.int64(len(V) + 1) + key[:, 1], return_inverse=True)
        first = np.unique(inv, return_index=True)[1]
        e0, e1 = ends[first, 0], ends[first, 1]
        t = (L - h[e0]) / (h[e1] - h[e0])
        node = np.where(t <= 0.0, e0, np.where(t >= 1.0, e1, -1))
        fresh = node < 0
        new_idx = len(V) + np.arange(int(fresh.sum()))
        node[fresh] = new_idx
        tf = t[fresh][:, None]
        V = np.vstack([V, V[e0[fresh]] + tf * (V[e1[fresh]] - V[e0[fresh]])])
        h = np.concatenate([h, np.full(int(fresh.sum()), L)])
        P = node[inv[:len(Fc)]]
        Q = node[inv[len(Fc):]]
        tris = np.concatenate([np.stack([a, P, Q], 1), np.stack([P, b, c], 1), np.stack([P, c, Q], 1)])
        par = np.tile(parent[cut], 3)
        ok = (tris[:, 0] != tris[:, 1]) & (tris[:, 1] != tris[:, 2]) & (tris[:, 0] != tris[:, 2])
        F = np.concatenate([F[~cut], tris[ok]])
        parent = np.concatenate([parent[~cut], par[ok]])
    return V, F, h, parent


def _face_pairs(F: np.ndarray):
    """Pairs of faces sharing an edge ``(p, 2)``, and the shared edge ``(p, 2)`` (vertex indices)."""
    e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    f = np.tile(np.arange(len(F)), 3)
    e = np.sort(e, axis=1)
    key = e[:, 0] * np.int64(F.max() + 1) + e[:, 1]
    order = np.argsort(key, kind="stable")
    k = key[order]
    same = np.flatnonzero(k[1:] == k[:-1])
    # an edge shared by more than two faces (non-manifold) joins each consecutive pair: enough here
    return np.stack([f[order][same], f[order][same + 1]], 1), e[order][same]


def decompose(surface, feed: np.ndarray, cross: np.ndarray, *, min_area: float = MIN_AREA,
              min_feature: float = 0.0) -> list[Region]:
    """Boustrophedon decomposition of ``surface`` for sweep lines normal to ``cross`` (see the module notes)."""
    import scipy.sparse as sp
    from scipy.optimize import linear_sum_assignment
    from scipy.sparse.csgraph import connected_components

    V0, F0 = surface.vertices, surface.faces
    h0 = V0 @ cross
    crit = critical_vertices(F0, h0, loops=surface.boundary_loops, tolerance=min_feature)
    levels = np.unique(h0[crit])
    V, F, h, parent = split_at_levels(V0, F0, h0, levels)
    tri = V[F]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    band = np.searchsorted(levels, h[F].mean(axis=1), side="right")
    pairs, shared = _face_pairs(F)
    same_band = band[pairs[:, 0]] == band[pairs[:, 1]]
    m = len(F)
    g = sp.coo_matrix((np.ones(int(same_band.sum())), (pairs[same_band, 0], pairs[same_band, 1])), shape=(m, m))
    n_comp, comp = connected_components(g, directed=False)
    comp_band = np.zeros(n_comp, np.int64)
    comp_band[comp] = band
    comp_area = np.bincount(comp, weights=area, minlength=n_comp)

    # pieces of consecutive bands sharing a border (edge lengths summed per piece pair)
    cross_pairs = pairs[~same_band]
    seg = np.linalg.norm(V[shared[~same_band, 0]] - V[shared[~same_band, 1]], axis=1)
    ca, cb = comp[cross_pairs[:, 0]], comp[cross_pairs[:, 1]]
    swap = comp_band[ca] > comp_band[cb]
    lo_c, hi_c = np.where(swap, cb, ca), np.where(swap, ca, cb)
    border: dict[tuple[int, int], float] = {}
    for u, v, w in zip(lo_c.tolist(), hi_c.tolist(), seg.tolist()):
        border[(u, v)] = border.get((u, v), 0.0) + w

    # maximum matching between each two consecutive bands (fewest chains), longest borders preferred
    up = np.full(n_comp, -1)
    down = np.full(n_comp, -1)
    by_band: dict[int, list[tuple[int, int, float]]] = {}
    for (u, v), w in border.items():
        if comp_band[v] == comp_band[u] + 1:
            by_band.setdefault(int(comp_band[u]), []).append((u, v, w))
    for edges in by_band.values():
        us = sorted({e[0] for e in edges})
        vs = sorted({e[1] for e in edges})
        iu = {u: i for i, u in enumerate(us)}
        iv = {v: i for i, v in enumerate(vs)}
        total = sum(e[2] for e in edges) + 1e-300
        cost = np.zeros((len(us), len(vs)))
        for u, v, w in edges:
            cost[iu[u], iv[v]] = -(1.0 + w / total)
        r, c = linear_sum_assignment(cost)
        for i, j in zip(r, c):
            if cost[i, j] < 0:
                up[us[i]] = vs[j]
                down[vs[j]] = us[i]
    label = np.full(n_comp, -1)
    n_reg = 0
    for start in np.flatnonzero(down < 0):
        node = start
        while node >= 0:
            label[node] = n_reg
            node = up[node]
        n_reg += 1

    # merge small regions into the neighbour sharing the longest border
    reg_area = np.bincount(label, weights=comp_area, minlength=n_reg)
    reg_border: dict[tuple[int, int], float] = {}
    for (u, v), w in border.items():
        a, b = int(label[u]), int(label[v])
        if a != b:
            reg_border[(a, b)] = reg_border.get((a, b), 0.0) + w
            reg_border[(b, a)] = reg_border.get((b, a), 0.0) + w
    alive = set(range(n_reg))
    merged_into = np.arange(n_reg)
    for r in np.argsort(reg_area):
        r = int(r)
        if reg_area[r] >= min_area or len(alive) <= 1:
            continue
        nbrs = {b: w for (a, b), w in reg_border.items() if a == r and b in alive and b != r}
        if not nbrs:
            continue
        target = max(nbrs, key=lambda b: nbrs[b])
        merged_into[merged_into == r] = target
        alive.discard(r)
        reg_area[target] += reg_area[r]
        for (a, b), w in list(reg_border.items()):
            if r in (a, b):
                del reg_border[(a, b)]
                a2, b2 = (target if a == r else a), (target if b == r else b)
                if a2 != b2:
                    reg_border[(a2, b2)] = reg_border.get((a2, b2), 0.0) + w
    label = merged_into[label]
    face_region = label[comp]
    out = []
    for new_id, r in enumerate(sorted(set(face_region.tolist()), key=lambda r: -reg_area[r])):
        sel = np.flatnonzero(face_region == r)
        fr = F[sel]
        used, inv = np.unique(fr, return_inverse=True)
        sub = Surface(V[used], inv.reshape(-1, 3), name=f"{surface.name}[region {new_id}]",
                      normal_smoothing=surface.normal_smoothing, curvature_neighbours=surface.curvature_neighbours)
        out.append(Region(new_id, np.unique(parent[sel]), sub, feed.copy(), float(area[sel].sum()), cross.copy()))
    log.info("segment %s: %d critical heights, %d band pieces, %d regions (%d merged below %.4g m²)",
             surface.name, len(levels), n_comp, len(out), n_reg - len(out), min_area)
    return out


def segment(surface, *, direction=None, min_area: float = MIN_AREA, min_feature: float = MIN_FEATURE,
            angles=AUTO_ANGLES) -> list[Region]:
    """Split ``surface`` into regions that every sweep line crosses in one unbroken segment.

    Parameters
    ----------
    surface : Surface
        The part (normals toward the tool).
    direction : (3,) float, optional
        Sweep (feed) direction, part frame; projected into the best-fit plane.  Default (None): the
        direction among ``angles`` (rad from the first principal axis) giving the fewest regions,
        ties to the earlier angle (counted before small regions are merged).
    min_area : float
        Regions smaller than this (m²) are merged into the neighbour sharing the longest border
        (default 2 cm²; a pad of 38 mm radius covers 45 cm²).  Inside a merged region the sweep
        lines through the small piece have a second, short segment; ``min_area=0`` keeps every
        region and the property exact.
    min_feature : float
        Wiggles of the outline whose height across the sweep lines is below this (m) are not cut
        at (default 5 mm: the ragged edge of a scan); 0 cuts at every border extremum.
    angles : sequence of float
        Candidate feed angles for ``direction=None``, rad.

    Returns
    -------
    list of Region
        Largest first, ``id`` = position; the regions' triangles tile the surface.

    Raises
    ------
    InputError
        On a bad direction or a negative ``min_area``.
    """
    if not (isinstance(min_area, (int, float)) and math.isfinite(min_area) and min_area >= 0):
        raise InputError(f"min_area must be an area >= 0 m², got {min_area!r}")
    if direction is not None:
        feed, cross = sweep_frame(surface, direction=direction)
        return decompose(surface, feed, cross, min_area=min_area, min_feature=min_feature)
    best: tuple[np.ndarray, np.ndarray] | None = None
    best_count: int | None = None
    for a in angles:
        feed, cross = sweep_frame(surface, angle=a)
        count = len(decompose(surface, feed, cross, min_area=0.0, min_feature=min_feature))
        if best_count is None or count < best_count:
            best, best_count = (feed, cross), count
    if best is None:
        raise InputError(f"segment needs at least one candidate angle (rad) when direction is None, got {angles!r}")
    return decompose(surface, *best, min_area=min_area, min_feature=min_feature)
