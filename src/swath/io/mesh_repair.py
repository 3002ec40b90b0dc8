"""Pure, vectorised cleaning steps on ``(vertices, faces)`` arrays: merging, degenerate, duplicate
and unreferenced elements, edges and non-manifold repair."""

from __future__ import annotations

import numpy as np


def merge_vertices(vertices: np.ndarray, faces: np.ndarray, *, tolerance: float = 0.0):
    """Merge vertices closer than ``tolerance``.

    Parameters
    ----------
    vertices : (n, 3) float
        Positions, m.
    faces : (m, 3) int
        Triangles.
    tolerance : float
        Merge distance, m (0 merges exact duplicates only).

    Returns
    -------
    vertices : (k, 3) float
        The merged vertices (the first of each group), k <= n.
    faces : (m, 3) int
        Faces re-indexed to them.
    """
    vertices = np.asarray(vertices, dtype=float)
    first, inverse = group_rows(vertices)
    uniq = vertices[first]
    if tolerance > 0 and len(uniq) > 1:
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components
        from scipy.spatial import cKDTree

        pairs = cKDTree(uniq).query_pairs(tolerance, output_type="ndarray")
        if len(pairs):
            k = len(uniq)
            graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(k, k))
            _, lab = connected_components(graph, directed=False)
            # relabel groups by their first member so the order stays the file's
            first_of = np.full(lab.max() + 1, k)
            np.minimum.at(first_of, lab, np.arange(k))
            order = np.argsort(first_of, kind="stable")
            newlab = np.empty_like(order)
            newlab[order] = np.arange(len(order))
            uniq = uniq[first_of[order]]
            inverse = newlab[lab[inverse]]
    return uniq, inverse[np.asarray(faces)]


def degenerate_faces(vertices: np.ndarray, faces: np.ndarray, *, scale: float = 1.0) -> np.ndarray:
    """(m,) bool: faces with a repeated vertex or an area below ``1e-14 · scale²``."""
    f = np.asarray(faces)
    repeated = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 2] == f[:, 0])
    return repeated | (face_areas(vertices, f) <= 1e-14 * scale**2)


def duplicate_faces(faces: np.ndarray) -> np.ndarray:
    """(m,) bool: faces using the same three vertices as an earlier face (either winding)."""
    first, _ = group_rows(np.sort(np.asarray(faces), axis=1))
    dup = np.ones(len(faces), dtype=bool)
    dup[first] = False
    return dup


def remove_unreferenced(vertices: np.ndarray, faces: np.ndarray):
    """Drop vertices no face uses; returns ``(vertices (k, 3), faces (m, 3))`` re-indexed."""
    used, inverse = np.unique(np.asarray(faces), return_inverse=True)
    return np.asarray(vertices)[used], inverse.reshape(-1, 3)


def edge_table(faces: np.ndarray):
    """Undirected edges of a triangle mesh.

    Returns
    -------
    edge_of : (3m,) int
        Edge id of each half-edge ``(f0,f1), (f1,f2), (f2,f0)`` of each face, face-major.
    counts : (e,) int
        Number of faces on each edge.
    forward : (3m,) bool
        Whether the half-edge runs from the lower to the higher vertex index.
    """
    f = np.asarray(faces, dtype=np.int64)
    half = f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    lo, hi = np.minimum(half[:, 0], half[:, 1]), np.maximum(half[:, 0], half[:, 1])
    key = lo * (int(f.max()) + 1 if len(f) else 1) + hi
    _, edge_of, counts = np.unique(key, return_inverse=True, return_counts=True)
    return edge_of.ravel(), counts, half[:, 0] < half[:, 1]


def nonmanifold_faces(vertices: np.ndarray, faces: np.ndarray, areas: np.ndarray, *,
                      max_edges: int | None = None):
    """Faces to drop so that no edge has more than two faces, keeping the surface that continues.

    On each edge shared by more than two faces the pair of faces that bends least across the edge
    is kept (their in-plane directions away from the edge are the most nearly opposite: a flat
    continuation scores -1, a fin standing at right angles 0); ties go to the larger pair by area.
    The others are dropped, and so is every sheet (faces joined by ordinary two-face edges) that
    touches the over-shared edges only through dropped faces: a fin goes as a whole, not just its
    first row of triangles.

    Parameters
    ----------
    vertices : (n, 3) float
        Positions, m.
    faces : (m, 3) int
        Triangles, without duplicates.
    areas : (m,) float
        Face areas, m² (tie-break).
    max_edges : int, optional
        When more edges than this are non-manifold, nothing is chosen (``drop`` all False): the
        caller refuses such a mesh, and the per-edge choice would only cost time.

    Returns
    -------
    drop : (m,) bool
        Faces to drop.
    n_bad : int
        Number of non-manifold edges (more than two faces).
    n_edges : int
        Number of edges.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    f = np.asarray(faces, dtype=np.int64)
    v = np.asarray(vertices, dtype=float)
    edge_of, counts, _ = edge_table(f)
    drop = np.zeros(len(f), dtype=bool)
    n_bad = int((counts > 2).sum())
    if not n_bad or (max_edges is not None and n_bad > max_edges):
        return drop, n_bad, len(counts)
    bad_half = np.flatnonzero(counts[edge_of] > 2)
    face_of = bad_half // 3
    corner = bad_half % 3
    a, b, c = f[face_of, corner], f[face_of, (corner + 1) % 3], f[face_of, (corner + 2) % 3]
    along = v[b] - v[a]
    along /= np.maximum(np.linalg.norm(along, axis=1, keepdims=True), 1e-300)
    wing = v[c] - v[a]
    wing -= np.einsum("ij,ij->i", wing, along)[:, None] * along
    wing /= np.maximum(np.linalg.norm(wing, axis=1, keepdims=True), 1e-300)
    order = np.argsort(edge_of[bad_half], kind="stable")
    groups = np.split(order, np.flatnonzero(np.diff(edge_of[bad_half][order])) + 1)
    touches_bad = np.zeros(len(f), dtype=bool)
    touches_bad[face_of] = True
    for group in groups:
        dots = wing[group] @ wing[group].T
        pair_area = areas[face_of[group]][:, None] + areas[face_of[group]][None, :]
        i, j = np.triu_indices(len(group), k=1)
        best = np.lexsort((-pair_area[i, j], np.round(dots[i, j], 9)))[0]
        keep = np.zeros(len(group), dtype=bool)
        keep[[i[best], j[best]]] = True
        drop[face_of[group][~keep]] = True
    # sheets: faces joined across ordinary (two-face) edges
    half = np.flatnonzero(counts[edge_of] == 2)
    pair = half[np.argsort(edge_of[half], kind="stable")]
    fi, fj = pair[0::2] // 3, pair[1::2] // 3
    m = len(f)
    _, sheet = connected_components(coo_matrix((np.ones(len(fi)), (fi, fj)), shape=(m, m)), directed=False)
    sheet_keeps = np.bincount(sheet, weights=touches_bad & ~drop, minlength=sheet.max() + 1) > 0
    sheet_drops = np.bincount(sheet, weights=drop, minlength=sheet.max() + 1) > 0
    drop |= (sheet_drops & ~sheet_keeps)[sheet]
    return drop, n_bad, len(counts)

def group_rows(a: np.ndarray):
    """Group equal rows of ``a`` (k, d).

    Returns ``first`` (g,) the index of each group's first row, groups in order of first
    appearance, and ``inverse`` (k,) the group of each row (``a[first][inverse] == a``).
    """
    a = np.asarray(a)
    if len(a) == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    order = np.lexsort(a.T[::-1])                  # stable: a group's first member comes first
    sa = a[order]
    new = np.r_[True, (sa[1:] != sa[:-1]).any(axis=1)]
    first = order[new]
    rank = np.argsort(first, kind="stable")
    group_of_sorted = np.cumsum(new) - 1
    relabel = np.empty_like(rank)
    relabel[rank] = np.arange(len(rank))
    inverse = np.empty(len(a), dtype=np.int64)
    inverse[order] = relabel[group_of_sorted]
    return first[rank], inverse


def face_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    tri = np.asarray(vertices)[np.asarray(faces)]
    return 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)


def face_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    tri = np.asarray(vertices)[np.asarray(faces)]
    c = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    return c / np.maximum(np.linalg.norm(c, axis=1, keepdims=True), 1e-300)
