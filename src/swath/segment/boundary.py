"""The boundary of a scanned or meshed surface: Wang's modified alpha shape (§1).

The points are projected onto their best-fit plane and triangulated (Delaunay, ``O(N log N)``);
triangles that cannot belong to the sampled surface — an edge longer than ``alpha`` (they bridge a
hole or a concave bay) — are dropped; the boundary is the set of edges used by exactly one kept
triangle, walked into closed loops.  Unlike the classic alpha shape (every point pair tested,
``O(N^3)``) only the Delaunay edges are examined.  A triangulated surface has its own boundary
(:attr:`Surface.boundary_loops`); :func:`surface_boundary` uses it unless told otherwise.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError


def best_fit_plane(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centroid ``(3,)`` and orthonormal axes ``(3, 3)`` (rows; the last is the plane normal) of
    ``points`` ``(n, 3)`` (m)."""
    p = np.asarray(points, float)
    c = p.mean(axis=0)
    _, _, vt = np.linalg.svd(p - c, full_matrices=False)
    return c, vt


def alpha_boundary(points: np.ndarray, *, alpha: float | None = None, min_points: int = 8) -> list[np.ndarray]:
    """Boundary loops of a sampled surface by the modified alpha shape.

    Parameters
    ----------
    points : (n, 3) or (n, 2) float
        Samples of the surface, m; 3-D points are projected onto their best-fit plane.
    alpha : float, optional
        Longest edge a kept triangle may have, m.  Default: 3 times the median Delaunay edge (a
        hole must be wider than that to be found).
    min_points : int
        Loops with fewer points are dropped (pin holes between scan points; Wang's ``n_min``).

    Returns
    -------
    list of (k,) int
        Closed loops of point indices (first point not repeated), longest first.  Where the kept
        triangles touch at a single point the walk takes the turn that keeps the loops simple.

    Raises
    ------
    InputError
        On fewer than 3 points, non-finite coordinates or a non-positive ``alpha``.
    """
    from scipy.spatial import Delaunay

    p = np.asarray(points, float)
    if p.ndim != 2 or p.shape[1] not in (2, 3) or len(p) < 3 or not np.isfinite(p).all():
        raise InputError(f"expected finite points of shape (n>=3, 2 or 3), got {p.shape}")
    if p.shape[1] == 3:
        c, axes = best_fit_plane(p)
        p = (p - c) @ axes[:2].T
    tri = Delaunay(p).simplices
    edge_len = np.linalg.norm(p[tri] - p[np.roll(tri, -1, axis=1)], axis=2)
    if alpha is None:
        alpha = 3.0 * float(np.median(edge_len))
    if not (np.isfinite(alpha) and alpha > 0):
        raise InputError(f"alpha must be a positive length in m, got {alpha!r}")
    tri = tri[edge_len.max(axis=1) <= alpha]
    return [lp for lp in _loops_of_single_edges(tri, p) if len(lp) >= min_points]


def _loops_of_single_edges(tri: np.ndarray, p2: np.ndarray) -> list[np.ndarray]:
    """Walk the edges used by one triangle only into loops (triangles counter-clockwise in ``p2``)."""
    if len(tri) == 0:
        return []
    a, b, c = p2[tri[:, 0]], p2[tri[:, 1]], p2[tri[:, 2]]
    ccw = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]) > 0
    tri = np.where(ccw[:, None], tri, tri[:, ::-1])
    directed = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    key = np.sort(directed, axis=1)
    _, inv, count = np.unique(key[:, 0] * (len(p2) + 1) + key[:, 1], return_inverse=True, return_counts=True)
    border = directed[count[inv] == 1]                 # directed with the surface on the left
    out_edges: dict[int, list[int]] = {}
    for u, v in border.tolist():
        out_edges.setdefault(u, []).append(v)
    loops = []
    used = set()
    for u0, v0 in border.tolist():
        if (u0, v0) in used:
            continue
        loop, u, v = [u0], u0, v0
        used.add((u, v))
        while v != u0:
            loop.append(v)
            nxt = [w for w in out_edges.get(v, []) if (v, w) not in used]
            if not nxt:
                break
            if len(nxt) > 1:                           # pinch point: take the sharpest right turn
                d_in = p2[v] - p2[u]
                ang = [np.arctan2(d_in[0] * (p2[w] - p2[v])[1] - d_in[1] * (p2[w] - p2[v])[0], np.dot(d_in, p2[w] - p2[v]))
                       for w in nxt]
                w = nxt[int(np.argmin(ang))]
            else:
                w = nxt[0]
            used.add((v, w))
            u, v = v, w
        loops.append(np.array(loop))
    loops.sort(key=lambda lp: -_perimeter(p2, lp))
    return loops


def _perimeter(p2, loop) -> float:
    q = p2[np.r_[loop, loop[:1]]]
    return float(np.linalg.norm(np.diff(q, axis=0), axis=1).sum())


def surface_boundary(surface, *, method: str = "mesh", alpha: float | None = None) -> list[np.ndarray]:
    """Boundary loops (vertex indices) of a surface: its mesh boundary (``"mesh"``) or the modified
    alpha shape of its vertices (``"alpha"``, for ragged scans whose triangulation has slivers and
    pin holes)."""
    if method == "mesh":
        return list(surface.boundary_loops)
    if method == "alpha":
        return alpha_boundary(surface.vertices, alpha=alpha)
    raise InputError(f"unknown boundary method {method!r}; choose 'mesh' or 'alpha'")
