"""Pure, vectorised geometry on triangle meshes (no state, no caching)."""

from __future__ import annotations

import numpy as np


def face_normals_and_areas(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit normals ``(m, 3)`` (right-hand winding) and areas ``(m,)`` in m² of each triangle."""
    tri = vertices[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(cross, axis=1)
    normals = np.divide(cross, norm[:, None], out=np.zeros_like(cross), where=norm[:, None] > 0)
    return normals, 0.5 * norm


def vertex_areas(n_vertices: int, faces: np.ndarray, face_areas: np.ndarray) -> np.ndarray:
    """Area ``(n,)`` in m² attributed to each vertex: a third of each incident triangle."""
    return np.bincount(faces.ravel(), weights=np.repeat(face_areas / 3.0, 3), minlength=n_vertices)


def vertex_normals(n_vertices: int, faces: np.ndarray, face_normals: np.ndarray,
                   face_areas: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals ``(n, 3)``; a vertex with no faces gets ``(0, 0, 0)``."""
    weighted = np.repeat(face_normals * face_areas[:, None], 3, axis=0)
    return normalize(scatter_add(faces.ravel(), weighted, n_vertices))


def scatter_add(index: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    """Sum rows of ``values`` ``(k, d)`` into ``n`` bins by ``index`` ``(k,)`` (a fast ``np.add.at``)."""
    return np.stack([np.bincount(index, weights=values[:, j], minlength=n) for j in range(values.shape[1])], axis=1)


def normalize(v: np.ndarray) -> np.ndarray:
    """Rows of ``v`` scaled to unit length; zero rows stay zero."""
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.divide(v, norm, out=np.zeros_like(v, dtype=float), where=norm > 0)


def smooth_vertex_normals(vertices: np.ndarray, normals: np.ndarray, areas: np.ndarray,
                          radius: float, tree=None) -> np.ndarray:
    """Average unit normals over a ball of ``radius`` (m) around each vertex, area-weighted.

    Neighbours whose normal points away (negative dot product) are ignored, so the two sides of a
    thin part are not mixed.  ``radius <= 0`` returns ``normals`` unchanged.
    """
    if radius <= 0:
        return normals
    from . import cells

    if cells.AVAILABLE:                  # compiled ball sum on a cell grid; same pairs as below
        return normalize(cells.smooth_normals(vertices, normals, areas, radius))
    from scipy.spatial import cKDTree

    tree = tree if tree is not None else cKDTree(vertices)
    # All ordered pairs within the radius, each vertex with itself included.
    coo = tree.sparse_distance_matrix(tree, radius, output_type="coo_matrix")
    i, j = coo.row, coo.col
    same_side = np.einsum("ij,ij->i", normals[i], normals[j]) > 0
    i, j = i[same_side], j[same_side]
    acc = scatter_add(i, normals[j] * areas[j, None], len(vertices))
    return normalize(acc)


def principal_axes(vertices: np.ndarray, weights: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Centroid ``(3,)`` and principal axes ``(3, 3)`` (rows, largest spread first) of a weighted point set."""
    w = np.ones(len(vertices)) if weights is None else weights
    centroid = np.average(vertices, axis=0, weights=w)
    d = vertices - centroid
    cov = (d * w[:, None]).T @ d / w.sum()
    evals, evecs = np.linalg.eigh(cov)
    return centroid, evecs[:, ::-1].T


def area_principal_axes(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Area centroid ``(3,)`` and principal axes ``(3, 3)`` (rows, largest spread first) of a mesh.

    Uses the exact second moment of each triangle, ``∫ x xᵀ dA = A/12 (a aᵀ + b bᵀ + c cᵀ + s sᵀ)``
    with ``s = a + b + c``, so the result does not depend on how the surface is triangulated
    (lumped vertex areas follow the diagonals of a grid and tilt the axes).
    """
    v = np.asarray(vertices, float)
    origin = v.mean(axis=0)
    tri = v[faces] - origin
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    ssum = tri.sum(axis=1)
    second = (np.einsum("f,fki,fkj->ij", area, tri, tri) + np.einsum("f,fi,fj->ij", area, ssum, ssum)) / 12.0
    total = area.sum()
    mean = (area[:, None] * ssum).sum(axis=0) / (3.0 * total)
    cov = second / total - np.outer(mean, mean)
    _, vecs = np.linalg.eigh(cov)
    return origin + mean, vecs[:, ::-1].T
