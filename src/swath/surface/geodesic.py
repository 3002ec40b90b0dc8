"""Geodesic machinery shared by the planners: conforming refinement, point location, per-face
gradients and geodesic distance fields (potpourri3d's fast marching or heat method, and the
compiled narrow-band fast marching :class:`BandDistance` that stops at a given distance)."""

from __future__ import annotations

import functools
import heapq
import logging

import numpy as np

from ..errors import InputError
from .cells import jit
from .geometry import normalize
from .topology import mesh_edges

log = logging.getLogger("swath.surface")

#: Distance methods accepted by :func:`distance_field`.
DISTANCE_METHODS = ("fmm", "heat")


def refine_mesh(vertices: np.ndarray, faces: np.ndarray, max_edge: float, *, values: np.ndarray | None = None,
                max_rounds: int = 40, max_vertices: int | None = None):
    """Split edges until none is longer than ``max_edge``, keeping the mesh conforming.

    Every edge longer than ``max_edge`` is cut at its midpoint in each round; a face then splits
    into 4 (three cut edges), 3 (two; the quadrilateral left is cut along its shorter diagonal) or
    2 (one) triangles, so neighbours always agree on the cut (no T-junctions, no cracks) and the
    winding is kept.  The refined mesh is the same piecewise-flat surface: every new vertex lies
    on an old edge, every new face inside an old face.

    Parameters
    ----------
    vertices : (n, 3) float
        Vertices, m.
    faces : (m, 3) int
        Triangles.
    max_edge : float
        Longest edge wanted, m.
    values : (n, q) float, optional
        Per-vertex values carried along (linear along each split edge, hence barycentric within
        each original face), e.g. smooth normals.
    max_rounds : int
        Upper bound on bisection rounds (each halves the longest edge at least every two rounds).
    max_vertices : int, optional
        Stop after the round in which the vertex count passes this (the result then still has
        edges longer than ``max_edge``; the caller can check).

    Returns
    -------
    vertices : (n', 3) float
        The original vertices first (same indices), then the new ones.
    faces : (m', 3) int
    values : (n', q) float or None
    parent : (m',) int
        The original face each new face lies in.
    """
    V = np.asarray(vertices, float)
    F = np.asarray(faces, np.int64)
    vals = None if values is None else np.asarray(values, float).reshape(len(V), -1)
    if isinstance(max_edge, bool) or not (isinstance(max_edge, (int, float, np.number)) and np.isfinite(max_edge)
                                          and max_edge > 0):
        raise InputError(f"max_edge must be a positive length in metres, got {max_edge!r}")
    parent = np.arange(len(F))
    for _ in range(int(max_rounds)):
        edges, face_edges = mesh_edges(F)
        length = np.linalg.norm(V[edges[:, 0]] - V[edges[:, 1]], axis=1)
        cut = length > max_edge
        if not cut.any():
            break
        mid = np.full(len(edges), -1, np.int64)
        mid[cut] = len(V) + np.arange(int(cut.sum()))
        V = np.concatenate([V, 0.5 * (V[edges[cut, 0]] + V[edges[cut, 1]])])
        if vals is not None:
            vals = np.concatenate([vals, 0.5 * (vals[edges[cut, 0]] + vals[edges[cut, 1]])])
        M = mid[face_edges]                   # midpoint on slot e = (v_e, v_e+1), or -1
        is_cut = M >= 0
        count = is_cut.sum(axis=1)
        new_faces, new_parent = [F[count == 0]], [parent[count == 0]]
        # four children
        r = np.flatnonzero(count == 3)
        v0, v1, v2 = F[r].T
        m01, m12, m20 = M[r].T
        new_faces.append(np.stack([np.stack([v0, m01, m20], 1), np.stack([v1, m12, m01], 1),
                                   np.stack([v2, m20, m12], 1), np.stack([m01, m12, m20], 1)], 1).reshape(-1, 3))
        new_parent.append(np.repeat(parent[r], 4))
        # two children: slot e cut, (a, b) = its ends, c opposite
        g = np.flatnonzero(count == 1)
        e = np.argmax(is_cut[g], axis=1)
        a, b, c, m = F[g, e], F[g, (e + 1) % 3], F[g, (e + 2) % 3], M[g, e]
        new_faces.append(np.stack([np.stack([a, m, c], 1), np.stack([m, b, c], 1)], 1).reshape(-1, 3))
        new_parent.append(np.repeat(parent[g], 2))
        # three children: slot u = (a, b) uncut, c opposite; corner at c, then the quad's shorter diagonal
        bl = np.flatnonzero(count == 2)
        u = np.argmin(is_cut[bl], axis=1)
        a, b, c = F[bl, u], F[bl, (u + 1) % 3], F[bl, (u + 2) % 3]
        mbc, mca = M[bl, (u + 1) % 3], M[bl, (u + 2) % 3]
        first = (np.linalg.norm(V[a] - V[mbc], axis=1) <= np.linalg.norm(V[b] - V[mca], axis=1))[:, None]
        t1 = np.stack([c, mca, mbc], 1)
        t2 = np.where(first, np.stack([a, b, mbc], 1), np.stack([a, b, mca], 1))
        t3 = np.where(first, np.stack([a, mbc, mca], 1), np.stack([b, mbc, mca], 1))
        new_faces.append(np.stack([t1, t2, t3], 1).reshape(-1, 3))
        new_parent.append(np.repeat(parent[bl], 3))
        F = np.concatenate(new_faces)
        parent = np.concatenate(new_parent)
        if max_vertices is not None and len(V) > max_vertices:
            break
    return V, F, vals, parent


def locate_points(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray, *, tree=None, candidates: int = 16):
    """The face holding each point (points on or near the mesh) and its barycentric coordinates.

    Parameters
    ----------
    vertices : (n, 3) float
    faces : (m, 3) int
    points : (k, 3) float
        Query points, m.
    tree : scipy.spatial.cKDTree, optional
        Tree over the face centroids (built when not given).
    candidates : int
        Nearest face centroids tested per point.

    Returns
    -------
    face : (k,) int
    bary : (k, 3) float
        Non-negative, summing to 1.
    distance : (k,) float
        Distance from each point to its located surface point, m.

    Notes
    -----
    Each candidate face's barycentric coordinates of the point's projection are clipped to the
    triangle; the candidate whose clipped point is nearest wins.  For a point on the mesh that is
    its own face (distance ~1e-16), provided it is among the ``candidates`` nearest centroids,
    which holds on any mesh without extreme slivers next to it.
    """
    from scipy.spatial import cKDTree

    V = np.asarray(vertices, float)
    F = np.asarray(faces, np.int64)
    P = np.asarray(points, float).reshape(-1, 3)
    k = min(int(candidates), len(F))
    if tree is None:
        tree = cKDTree(V[F].mean(axis=1))
    _, cand = tree.query(P, k=k)
    cand = cand.reshape(len(P), k)
    tri = V[F[cand]]                                           # (k_pts, k, 3, 3)
    e1, e2 = tri[..., 1, :] - tri[..., 0, :], tri[..., 2, :] - tri[..., 0, :]
    w = P[:, None, :] - tri[..., 0, :]
    d11, d12, d22 = (e1 * e1).sum(-1), (e1 * e2).sum(-1), (e2 * e2).sum(-1)
    w1, w2 = (w * e1).sum(-1), (w * e2).sum(-1)
    den = d11 * d22 - d12 ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        b1 = np.where(den > 0, (d22 * w1 - d12 * w2) / den, 1.0 / 3.0)
        b2 = np.where(den > 0, (d11 * w2 - d12 * w1) / den, 1.0 / 3.0)
    bary = np.stack([1.0 - b1 - b2, b1, b2], axis=-1)
    bary = np.clip(bary, 0.0, None)
    bary /= np.maximum(bary.sum(-1, keepdims=True), 1e-300)
    closest = np.einsum("pkj,pkjd->pkd", bary, tri)
    dist = np.linalg.norm(closest - P[:, None, :], axis=-1)
    best = np.argmin(dist, axis=1)
    rows = np.arange(len(P))
    return cand[rows, best], bary[rows, best], dist[rows, best]


class FaceGradient:
    """The gradient operator of piecewise-linear per-vertex fields on a triangle mesh, set up once.

    ``∇φ = Σ φ_i (n̂ × e_i) / 2A`` on each face, ``e_i`` the edge opposite corner ``i`` (CCW).

    Parameters
    ----------
    vertices : (n, 3) float
    faces : (m, 3) int
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray):
        V = np.asarray(vertices, float)
        self.faces = np.asarray(faces, np.int64)
        tri = V[self.faces]
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        area2 = np.linalg.norm(n, axis=1)
        nh = normalize(n)
        inv = np.divide(1.0, area2, out=np.zeros_like(area2), where=area2 > 0)[:, None]
        self.face_areas = 0.5 * area2
        self.n_vertices = len(V)
        self.basis = [np.cross(nh, tri[:, (i + 2) % 3] - tri[:, (i + 1) % 3]) * inv for i in range(3)]

    @functools.cached_property
    def stacked_basis(self) -> np.ndarray:
        """The three corner bases as one contiguous ``(3, m, 3)`` array (for compiled loops)."""
        return np.ascontiguousarray(np.stack(self.basis))

    def __call__(self, field: np.ndarray) -> np.ndarray:
        """Gradient ``(m, 3)`` of the per-vertex ``field`` ``(n,)`` on each face (in the face plane)."""
        f = np.asarray(field, float)[self.faces]
        return sum(f[:, i, None] * self.basis[i] for i in range(3))

    def vertex_directions(self, field: np.ndarray, normals: np.ndarray) -> np.ndarray:
        """Unit direction ``(n, 3)`` of increasing ``field`` at each vertex: the area-weighted mean of
        the adjacent faces' gradients, projected into the tangent plane of ``normals`` ``(n, 3)``."""
        g = self(field) * self.face_areas[:, None]
        acc = np.zeros((self.n_vertices, 3))
        for i in range(3):
            for j in range(3):
                acc[:, j] += np.bincount(self.faces[:, i], weights=g[:, j], minlength=self.n_vertices)
        acc -= np.einsum("ij,ij->i", acc, normals)[:, None] * normals
        return normalize(acc)


def face_gradients(vertices: np.ndarray, faces: np.ndarray, field: np.ndarray) -> np.ndarray:
    """Gradient ``(m, 3)`` of a piecewise-linear per-vertex field ``(n,)`` on each face (in the face plane)."""
    return FaceGradient(vertices, faces)(field)


def distance_field(vertices: np.ndarray, faces: np.ndarray, *, source_vertices, source_distances=None,
                   method: str = "fmm", solver=None) -> tuple[np.ndarray, str]:
    """Geodesic distance ``(n,)`` (m) from sources on a connected triangle mesh.

    Parameters
    ----------
    vertices : (n, 3) float
    faces : (m, 3) int
    source_vertices : (s,) int
        Source vertices.
    source_distances : (s,) float, optional
        Their initial distances, m (default 0): a curve between the vertices is given as the
        vertices near it with their distance to it (:func:`polyline_band`).
    method : {"fmm", "heat"}
        potpourri3d's fast marching (``MeshFastMarchingDistanceSolver``) or heat method
        (``MeshHeatMethodDistanceSolver``, robust intrinsic Laplacian, ``t = h²``).  Fast marching
        refuses non-manifold meshes and leaves pieces without a source at infinity; it then falls
        back to the heat method.  The heat method takes no initial distances: the sources nearest
        the curve (the lowest 30 % of the initial distances) are used as distance 0.
    solver : potpourri3d.MeshFastMarchingDistanceSolver, optional
        A fast-marching solver already built on this mesh (saves its set-up on repeated solves).

    Returns
    -------
    distance : (n,) float
    method : str
        The method that produced it.
    """
    import potpourri3d as pp3d

    if method not in DISTANCE_METHODS:
        raise InputError(f"distance method must be one of {', '.join(DISTANCE_METHODS)}, got {method!r}")
    V = np.ascontiguousarray(vertices, float)
    F = np.ascontiguousarray(faces, np.int64)
    sv = np.asarray(source_vertices, np.int64).ravel()
    sd = np.zeros(len(sv)) if source_distances is None else np.asarray(source_distances, float).ravel()
    if len(sv) == 0 or len(sd) != len(sv):
        raise InputError(f"a distance field needs sources with one distance each, got {len(sv)} and {len(sd)}")
    if method == "fmm":
        curves: list[list[tuple[int, list]]] = [[(int(i), [])] for i in sv]
        try:
            fmm = solver if solver is not None else pp3d.MeshFastMarchingDistanceSolver(V, F)
            d = np.asarray(fmm.compute_distance(curves, [[float(x)] for x in sd], False)).ravel()
            if np.isfinite(d).all():
                return d, "fmm"
            log.info("fast marching left %d vertices without a distance; using the heat method",
                     int((~np.isfinite(d)).sum()))
        except RuntimeError as exc:
            log.info("fast marching refused the mesh (%s); using the heat method", exc)
    src = np.unique(sv[sd <= sd.min() + 0.3 * (sd.max() - sd.min())])
    d = np.asarray(pp3d.MeshHeatMethodDistanceSolver(V, F, 1.0, True).compute_distance_multisource(src.tolist()))
    d = d.ravel() - d.ravel()[src].min()
    return d, "heat"


#: Smallest corner angle (degrees) of a mesh :func:`heat_solver` solves on without the robust
#: intrinsic triangulation.
PLAIN_LAPLACIAN_MIN_ANGLE_DEG = 1.0


#: How far below zero (dimensionless) an interior edge's cotangent weight may fall and still count
#: as Delaunay in :func:`is_delaunay`.
DELAUNAY_TOLERANCE = 1e-6


def is_delaunay(vertices: np.ndarray, faces: np.ndarray, *, min_angle_deg: float = PLAIN_LAPLACIAN_MIN_ANGLE_DEG
                ) -> bool:
    """Whether a triangle mesh is already Delaunay, with no sliver.

    Every interior edge's two opposite corners sum to at most 180 degrees (its cotangent weight is
    not negative), and no corner is smaller than ``min_angle_deg``.  An intrinsic Delaunay
    triangulation of such a mesh flips no edge (boundary edges never flip), so it has the same
    cotangent Laplacian.  ``vertices`` ``(n, 3)`` m, ``faces`` ``(m, 3)`` int."""
    V = np.asarray(vertices, float)
    F = np.asarray(faces, np.int64)
    if len(F) == 0:
        return False
    P = V[F] - V.mean(axis=0)
    cot = np.empty(F.shape)
    for k in range(3):                    # corner k, opposite the edge (k+1, k+2)
        a, b = P[:, (k + 1) % 3] - P[:, k], P[:, (k + 2) % 3] - P[:, k]
        cross = np.linalg.norm(np.cross(a, b), axis=1)
        if not (cross > 0).all():
            return False                  # a degenerate face
        cot[:, k] = np.einsum("ij,ij->i", a, b) / cross
    if np.degrees(np.arctan(1.0 / np.abs(cot).max())) < min_angle_deg:
        return False
    edges = np.sort(np.stack([F[:, [1, 2]], F[:, [2, 0]], F[:, [0, 1]]], axis=1).reshape(-1, 2), axis=1)
    _, edge_of = np.unique(edges[:, 0] * len(V) + edges[:, 1], return_inverse=True)
    interior = np.bincount(edge_of) == 2
    # a grid's diagonals sum to exactly zero: the tolerance keeps rounding (a part far from the
    # origin) from deciding, as its 1e-6 overshoot of 180 degrees changes no distance
    return bool((np.bincount(edge_of, weights=cot.reshape(-1))[interior] >= -DELAUNAY_TOLERANCE).all())


def heat_solver(vertices: np.ndarray, faces: np.ndarray):
    """potpourri3d's heat-method distance solver, with the robust intrinsic triangulation only
    where the mesh needs it (:func:`is_delaunay`).

    The robust solver flips the mesh to an intrinsic Delaunay triangulation of a doubled
    ("tufted") cover before it factors the Laplacian.  On a mesh that is Delaunay already no edge
    flips, but its set-up and every solve cost more: on the blade's 89k-vertex working mesh
    0.95 s and 42 ms a solve, against 0.70 s and 28 ms, for distances that agree to 0.07 mm on
    average.  Elsewhere the robust solver stays: on bezier_dac_cad's working mesh (CAD slivers)
    the plain Laplacian's distances were twice as far from the exact geodesics, up to 18 mm."""
    import potpourri3d as pp3d

    V = np.asarray(vertices, float)
    V = np.ascontiguousarray(V - V.mean(axis=0))      # distances do not move with the part; rounding does
    F = np.ascontiguousarray(faces, np.int64)
    return pp3d.MeshHeatMethodDistanceSolver(V, F, 1.0, not is_delaunay(V, F))


class BandDistance:
    """Geodesic distance from a vertex set on a triangle mesh, only out to a stop distance.

    A first-order fast marching (Kimmel & Sethian's triangle update on the piecewise-flat
    surface) in one compiled loop: vertices are accepted in order of distance from the sources,
    each non-accepted corner of a face round the accepted vertex takes the smaller of the edge
    update (``d_u + |e|``) and, where the face's third corner is accepted too, the triangle update
    (the plane front through both accepted corners, kept only where it arrives from inside the
    face's angle at the corner).  The triangle update is taken even where it falls below the
    value of an accepted corner (through an obtuse angle): refusing it there, as a strictly causal
    march does, leaves the edge update, which on the long thin triangles of a halved CAD mesh
    overestimates by up to twice as much.  The march stops at the first vertex beyond ``stop``, so it
    visits the band ``d <= stop`` and its one-ring only: its cost grows with the band, not with the
    mesh.

    Set up once per mesh (the vertex-to-face table); every call is independent.

    Parameters
    ----------
    vertices : (n, 3) float
        Vertices, m.
    faces : (m, 3) int
        Triangles.

    Notes
    -----
    The distance is exact where it is planar across each face (from a straight source on a flat
    mesh it is exact to rounding); near a point source and round curved sources the plane-front
    update makes a first-order error.  Measured against analytic geodesics, in units of the
    median edge ``h`` (``tests/surface/test_band_distance.py``): a point on an irregular (Delaunay)
    plane, at most 0.73 h (mean 0.46 h); a point on a sphere, 1.35 h (0.45 h); a point on a
    cylinder, 1.01 h (0.36 h); a curve of vertices, 0.48 h (0.16 h).
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray):
        self.vertices = np.ascontiguousarray(vertices, float)
        self.faces = np.ascontiguousarray(faces, np.int64)
        n = len(self.vertices)
        corner = self.faces.ravel()
        order = np.argsort(corner, kind="stable")
        self.vertex_faces = np.ascontiguousarray(order // 3, np.int64)       # faces round each vertex
        self.start = np.concatenate([[0], np.cumsum(np.bincount(corner, minlength=n))]).astype(np.int64)

    def __call__(self, sources, source_distances=None, stop: float = np.inf) -> np.ndarray:
        """Distance ``(n,)`` (m) from ``sources`` ``(s,)`` (vertex indices; initial distances
        ``source_distances`` ``(s,)`` m, default 0) to every vertex within ``stop`` (m) of them;
        ``inf`` beyond it (and on pieces of the mesh no source reaches)."""
        sv = np.ascontiguousarray(np.asarray(sources, np.int64).ravel())
        sd = np.zeros(len(sv)) if source_distances is None else np.asarray(source_distances, float).ravel()
        if len(sv) == 0 or len(sd) != len(sv) or not np.isfinite(sd).all():
            raise InputError(f"a distance field needs sources with one finite distance each, got {len(sv)} "
                             f"and {len(sd)}")
        if sv.min() < 0 or sv.max() >= len(self.vertices):
            raise InputError(f"source vertices must lie in 0..{len(self.vertices) - 1}")
        stop = float(stop)
        if not stop >= 0:
            raise InputError(f"the stop distance must be >= 0 m (or inf), got {stop!r}")
        d = np.full(len(self.vertices), np.inf)
        _march(self.vertices, self.faces, self.start, self.vertex_faces, sv, np.ascontiguousarray(sd), stop, d)
        return d


def band_distance(vertices: np.ndarray, faces: np.ndarray, sources, source_distances=None,
                  stop: float = np.inf) -> np.ndarray:
    """:class:`BandDistance` set up and called once: the distance ``(n,)`` (m) from ``sources``
    ``(s,)`` out to ``stop`` (m), ``inf`` beyond."""
    return BandDistance(vertices, faces)(sources, source_distances, stop)


@jit()
def _triangle_update(V, c, a, b, da, db):   # pragma: no cover - compiled
    """The distance at corner ``c`` of the plane front through corners ``a`` and ``b`` at ``da`` and
    ``db`` (m), ``inf`` where that front does not reach ``c`` from inside the face's angle at ``c``."""
    e1x, e1y, e1z = V[a, 0] - V[c, 0], V[a, 1] - V[c, 1], V[a, 2] - V[c, 2]
    e2x, e2y, e2z = V[b, 0] - V[c, 0], V[b, 1] - V[c, 1], V[b, 2] - V[c, 2]
    q11 = e1x * e1x + e1y * e1y + e1z * e1z
    q22 = e2x * e2x + e2y * e2y + e2z * e2z
    q12 = e1x * e2x + e1y * e2y + e1z * e2z
    det = q11 * q22 - q12 * q12
    if det <= 1e-12 * q11 * q22:
        return np.inf
    # relative to da: the front at a is 0, at b is u (|u| <= |ab| for a front to exist)
    u = db - da
    # t solves |grad|^2 = 1 with grad = E Q^-1 (r - t), r = (0, u): A t^2 - 2 B t + C = 0 (scaled by det)
    A = q22 - 2.0 * q12 + q11
    B = -q12 * u + q11 * u
    C = q11 * u * u - det
    disc = B * B - A * C
    if disc < 0.0 or A <= 0.0:
        return np.inf
    t = (B + np.sqrt(disc)) / A
    # the back-characteristic from c must point into the face: Q^-1 (r - t) <= 0 componentwise
    r1, r2 = -t, u - t
    if q22 * r1 - q12 * r2 > 0.0 or q11 * r2 - q12 * r1 > 0.0:
        return np.inf
    return da + t


@jit()
def _march(V, F, start, vertex_faces, sources, source_d, stop, d):   # pragma: no cover - compiled
    """Fast marching from ``sources`` into ``d`` (``inf`` on entry), stopped past ``stop``."""
    n = len(d)
    state = np.zeros(n, np.int8)            # 0 far, 1 trial, 2 accepted
    heap = [(source_d[0], sources[0])]
    for i in range(len(sources)):
        s = sources[i]
        if source_d[i] < d[s]:
            d[s] = source_d[i]
            heapq.heappush(heap, (source_d[i], s))
    while len(heap) > 0:
        du, u = heapq.heappop(heap)
        if state[u] == 2 or du > d[u]:
            continue
        if du > stop:
            break
        state[u] = 2
        for k in range(start[u], start[u + 1]):
            f = vertex_faces[k]
            if F[f, 0] == F[f, 1] or F[f, 1] == F[f, 2] or F[f, 0] == F[f, 2]:
                continue                                          # a face with a repeated corner
            for j in range(3):
                c = F[f, j]
                if state[c] == 2:
                    continue
                o = F[f, 0] + F[f, 1] + F[f, 2] - u - c           # the face's third corner
                ex, ey, ez = V[c, 0] - V[u, 0], V[c, 1] - V[u, 1], V[c, 2] - V[u, 2]
                cand = du + np.sqrt(ex * ex + ey * ey + ez * ez)
                if state[o] == 2:
                    t = _triangle_update(V, c, u, o, du, d[o])
                    if t < cand:
                        cand = t
                if cand < d[c]:
                    d[c] = cand
                    state[c] = 1
                    heapq.heappush(heap, (cand, c))
    for v in range(n):
        if state[v] != 2:
            d[v] = np.inf
