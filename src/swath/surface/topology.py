"""Mesh topology: the one edge table every stage uses, boundary edges and loops, connected
components, and splitting vertices where two sheets touch.  Pure functions on ``faces`` ``(m, 3)``."""

from __future__ import annotations

import numpy as np

from . import cells
from .cells import jit


def mesh_edges(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Undirected edges of a triangle mesh.

    Parameters
    ----------
    faces : (m, 3) int

    Returns
    -------
    edges : (e, 2) int
        Vertex pairs, smaller index first.
    face_edges : (m, 3) int
        Edge id of face edges ``(v0, v1), (v1, v2), (v2, v0)``.
    """
    f = np.asarray(faces, np.int64).reshape(-1, 3)
    # corner k to corner k + 1 of each face, smaller index first
    a, b = f.ravel(), f[:, [1, 2, 0]].ravel()
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    if len(lo) == 0 or not cells.AVAILABLE or lo.min() < 0:
        n = np.int64(hi.max() + 1) if len(hi) else np.int64(1)
        keys, inverse = np.unique(lo * n + hi, return_inverse=True)
        return np.stack([keys // n, keys % n], axis=1), inverse.reshape(-1, 3)
    # The sorted unique (lo, hi) pairs and each corner's index among them, as np.unique of the keys
    # lo * n + hi gives them (the same arrays: both are defined by the pairs alone), from a counting
    # sort on lo and a short sort of each vertex's few neighbours in place of a sort of every key.
    edges, inverse = _unique_pairs(lo, hi, int(hi.max()) + 1)
    return edges, inverse.reshape(-1, 3)


@jit()
def _unique_pairs(lo, hi, n):   # pragma: no cover - compiled
    m = len(lo)
    start = np.zeros(n + 1, np.int64)
    for i in range(m):
        start[lo[i] + 1] += 1
    for v in range(n):
        start[v + 1] += start[v]
    slot = np.empty(n, np.int64)
    for v in range(n):
        slot[v] = start[v]
    order = np.empty(m, np.int64)
    for i in range(m):                       # the corners grouped by lo, each group sorted by hi
        order[slot[lo[i]]] = i
        slot[lo[i]] += 1
    for v in range(n):
        _shell_sort_by(order, start[v], start[v + 1], hi)
    inverse = np.empty(m, np.int64)
    edges = np.empty((m, 2), np.int64)
    e = 0
    for v in range(n):
        last = -1
        for r in range(start[v], start[v + 1]):
            i = order[r]
            if hi[i] != last:
                edges[e, 0] = v
                edges[e, 1] = hi[i]
                last = hi[i]
                e += 1
            inverse[i] = e - 1
    return edges[:e].copy(), inverse


@jit()
def _shell_sort_by(items, a, b, key):   # pragma: no cover - compiled
    # ``items[a:b]`` in place by ``key[items]`` (the order of equal keys does not matter to the
    # caller); a plain loop compiles in a fraction of the time numba takes for np.argsort
    n = b - a
    gap = 1
    while gap < n // 3:
        gap = 3 * gap + 1
    while gap > 0:
        for i in range(a + gap, b):
            item = items[i]
            k = key[item]
            j = i
            while j >= a + gap and key[items[j - gap]] > k:
                items[j] = items[j - gap]
                j -= gap
            items[j] = item
        gap //= 3


def edge_face_counts(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The edge table with how many faces use each edge: ``(edges (e, 2), face_edges (m, 3), count (e,))``."""
    edges, face_edges = mesh_edges(faces)
    return edges, face_edges, np.bincount(face_edges.ravel(), minlength=len(edges))


def boundary_edges(faces: np.ndarray) -> np.ndarray:
    """Edges ``(b, 2)`` used by exactly one face, oriented as in that face."""
    F = np.asarray(faces, np.int64)
    if len(F) == 0:
        return np.zeros((0, 2), np.int64)
    _, face_edges, count = edge_face_counts(F)
    directed = np.stack([F, np.roll(F, -1, axis=1)], axis=2).reshape(-1, 2)
    return directed[count[face_edges.ravel()] == 1]


def boundary_loops(faces: np.ndarray) -> list[np.ndarray]:
    """Closed boundary loops as vertex-index arrays ``(k,) int``, longest first.

    Edges are chained head to tail; at a vertex where the boundary touches itself (a bow-tie) the
    chain takes the first unused edge, so every boundary edge ends up in exactly one loop.
    """
    bnd = boundary_edges(faces)
    if len(bnd) == 0:
        return []
    nxt: dict[int, list[int]] = {}
    for i, a in enumerate(bnd[:, 0].tolist()):
        nxt.setdefault(a, []).append(i)
    used = np.zeros(len(bnd), bool)
    loops = []
    heads, tails = bnd[:, 0].tolist(), bnd[:, 1].tolist()
    for start in range(len(bnd)):
        if used[start]:
            continue
        loop: list[int] = []
        e: int | None = start
        while e is not None and not used[e]:
            used[e] = True
            loop.append(heads[e])
            cand = [j for j in nxt.get(tails[e], []) if not used[j]]
            e = cand[0] if cand else None
        loops.append(np.asarray(loop, np.int64))
    loops.sort(key=len, reverse=True)
    return loops


def vertex_components(n_vertices: int, faces: np.ndarray) -> tuple[int, np.ndarray]:
    """Connected components of the vertices (through faces): count and label ``(n,) int`` per vertex."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    faces = np.asarray(faces, np.int64)
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]]])
    g = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n_vertices, n_vertices))
    return connected_components(g, directed=False)


def split_nonmanifold_vertices(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Give every fan of faces round a vertex its own copy of the vertex.

    A vertex where two sheets of faces touch only at that vertex (a bow-tie, common in scans)
    makes a mesh non-manifold, which fast marching refuses.  Corners of the same vertex are
    joined when their faces share an edge through it; each group of joined corners becomes one
    vertex.  The geometry is unchanged.

    Parameters
    ----------
    faces : (m, 3) int

    Returns
    -------
    faces : (m, 3) int
        Faces on the new vertex numbering.
    source : (n',) int
        The original vertex of each new vertex (``vertices[source]`` are the new positions).
    """
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    F = np.asarray(faces, np.int64)
    m = len(F)
    _, face_edges = mesh_edges(F)
    inc_edge = face_edges.ravel()
    order = np.argsort(inc_edge, kind="stable")
    e_sorted = inc_edge[order]
    first = np.flatnonzero(np.r_[True, e_sorted[1:] != e_sorted[:-1]])
    count = np.diff(np.r_[first, len(e_sorted)])
    pairs = first[count == 2]
    i1, i2 = order[pairs], order[pairs + 1]                 # incidences (face * 3 + slot)
    f1, s1, f2, s2 = i1 // 3, i1 % 3, i2 // 3, i2 % 3
    a, b = F[f1, s1], F[f1, (s1 + 1) % 3]
    a_in_2 = np.where(F[f2, s2] == a, s2, (s2 + 1) % 3)
    b_in_2 = np.where(F[f2, s2] == b, s2, (s2 + 1) % 3)
    rows = np.r_[f1 * 3 + s1, f1 * 3 + (s1 + 1) % 3]
    cols = np.r_[f2 * 3 + a_in_2, f2 * 3 + b_in_2]
    g = sp.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(3 * m, 3 * m))
    _, corner_label = connected_components(g, directed=False)
    # Joined corners share their vertex, so a corner group is one (vertex, fan) pair.
    _, first_corner, inverse = np.unique(corner_label, return_index=True, return_inverse=True)
    return inverse.reshape(m, 3), F.ravel()[first_corner]


