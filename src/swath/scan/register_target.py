"""Registration data: the sampled source points and the target (points, normals, KD-tree,
perimeter, exact closest points on triangles) of :mod:`swath.scan.register`."""

from __future__ import annotations

import logging

import numpy as np

from ..errors import InputError
from ..surface.geometry import normalize
from ..surface.surface import Surface
from .register_settings import MIN_LOOP_VERTICES, MIN_POINTS, NORMAL_NEIGHBOURS

log = logging.getLogger("swath.scan")
class _Source:
    """Source points (subsampled), optional normals and weights, perimeter indices."""

    def __init__(self, points, normals, weights, indices, boundary):
        self.points = points
        self.normals = normals
        self.weights = weights
        self.indices = indices          # into the caller's points
        self.boundary = boundary        # into self.points
        self.centroid, axes = _right_handed_axes(points, weights)
        # bounding-box diagonal in the principal frame: the same for any pose of the source
        self.size = float(np.linalg.norm(np.ptp((points - self.centroid) @ axes.T, axis=0)))

    @classmethod
    def build(cls, source, normals, max_points, rng, boundary=None, perimeter=False):
        if isinstance(source, Surface):
            pts = source.vertices
            nrm = source.normals if normals is None else _check_normals(normals, len(pts), "source_normals")
            w = source.vertex_areas / source.vertex_areas.mean()
            if boundary is None and perimeter:
                loops = source.boundary_loops
                boundary = np.concatenate(loops) if loops else np.zeros(0, int)
            if len(pts) < MIN_POINTS:
                raise InputError(f"the source surface has {len(pts)} vertices; registration needs at "
                                 f"least {MIN_POINTS}")
        else:
            pts = _check_points(source, "source")
            nrm = _check_normals(normals, len(pts), "source_normals")
            w = np.ones(len(pts))
        bnd_mask = np.zeros(len(pts), bool)
        if boundary is not None:
            b = np.asarray(boundary).reshape(-1)
            if len(b) and (not np.issubdtype(b.dtype, np.integer) or b.min() < 0 or b.max() >= len(pts)):
                raise InputError(f"source_boundary must hold point indices in 0..{len(pts) - 1}")
            bnd_mask[b.astype(int)] = True
        if not np.ptp(pts, axis=0).any():
            raise InputError("all source points coincide; nothing to register")
        idx = np.arange(len(pts))
        if len(pts) > max_points:
            idx = np.sort(rng.choice(len(pts), size=int(max_points), replace=False))
            log.info("registration: subsampled the source from %d to %d points", len(pts), len(idx))
        return cls(pts[idx], None if nrm is None else nrm[idx], w[idx], idx, np.flatnonzero(bnd_mask[idx]))


class _Target:
    """Target points with normals and a kd-tree; triangles for exact closest points; perimeter."""

    def __init__(self, points, normals, tree, surface=None):
        self.points = points
        self.normals = normals
        self.tree = tree
        self.surface = surface
        self.centroid = points.mean(axis=0)
        self._rings = None
        self._longest_edge = None
        self._vertex_ids = None         # surface vertex index of each point, when they differ
        self.boundary_points = None     # (b, 3) perimeter vertices
        self.boundary_normals = None    # (b, 3) in-plane unit normals of the perimeter
        self.boundary_tree = None
        self.plane_axes = None          # (2, 3) axes of the table plane
        self.spacing = 0.0              # median point spacing of a point-cloud target, m

    @classmethod
    def build(cls, target, normals=None, table_normal=None):
        from scipy.spatial import cKDTree

        if isinstance(target, Surface):
            if normals is not None:
                raise InputError("target_normals is only for a target given as points; a Surface has its own")
            used = np.zeros(len(target.vertices), bool)
            used[target.faces.ravel()] = True
            if used.all():
                tgt = cls(target.vertices, target.normals, target.kdtree, surface=target)
            else:       # vertices without faces have no normal and no triangle to project onto
                idx = np.flatnonzero(used)
                tgt = cls(target.vertices[idx], target.normals[idx], cKDTree(target.vertices[idx]),
                          surface=target)
                tgt._vertex_ids = idx
        else:
            if isinstance(target, tuple) and len(target) == 2:
                target, normals = target
            pts = _check_points(target, "target")
            nrm = _check_normals(normals, len(pts), "target_normals")
            tree = cKDTree(pts)
            if nrm is None:
                nrm = _pca_normals(pts, tree, NORMAL_NEIGHBOURS)
            tgt = cls(pts, nrm, tree)
            sample = pts[:: max(len(pts) // 2000, 1)]
            tgt.spacing = float(np.median(tree.query(sample, k=2)[0][:, 1]))
        if table_normal is not None and tgt.surface is not None:
            tgt._set_perimeter(table_normal)
        return tgt

    def thinned(self, spacing):
        """A point target with one point (and its normal) per cube of ``spacing`` m: for scoring
        coarse start poses, where far nearest-neighbour queries on dense scans are slow."""
        from scipy.spatial import cKDTree

        key = np.floor((self.points - self.points.min(axis=0)) / spacing).astype(np.int64)
        _, first = np.unique(key, axis=0, return_index=True)
        if len(first) > 0.7 * len(self.points):
            return self
        pts, nrm = self.points[first], self.normals[first]
        out = _Target(pts, nrm, cKDTree(pts))
        out.boundary_points, out.boundary_normals = self.boundary_points, self.boundary_normals
        out.boundary_tree, out.plane_axes = self.boundary_tree, self.plane_axes
        return out

    def _set_perimeter(self, k):
        from scipy.spatial import cKDTree

        pts, nrm = [], []
        v = self.surface.vertices
        for loop in self.surface.boundary_loops:
            if len(loop) < MIN_LOOP_VERTICES:
                continue
            p = v[loop]
            tangent = np.roll(p, -1, axis=0) - np.roll(p, 1, axis=0)
            m = np.cross(tangent, k)
            ok = np.linalg.norm(m, axis=1) > 1e-12
            pts.append(p[ok])
            nrm.append(normalize(m[ok]))
        if pts and sum(len(p) for p in pts) >= 3:
            self.boundary_points = np.concatenate(pts)
            self.boundary_normals = np.concatenate(nrm)
            # perimeters are matched in the table plane (seen from above, as in the thesis): a
            # scan's wall foot lies below the CAD's edge but at the same place on the table
            self.plane_axes = np.array(_plane_axes(k))
            self.boundary_tree = cKDTree(self.boundary_points @ self.plane_axes.T)

    def match(self, points, exact=False, bound=np.inf):
        """Closest target points ``(k, 3)``, their unit normals ``(k, 3)`` and distances ``(k,)``
        (m); points with no target point within ``bound`` (m) get distance ``inf``.

        ``exact`` projects onto the triangles of a surface target; otherwise the closest vertex
        and its normal stand for the tangent plane."""
        points = np.asarray(points, dtype=float)
        if exact and self.surface is not None:
            return self._closest_on_faces(points, bound)
        d, i = self.tree.query(points, distance_upper_bound=bound)
        found = np.isfinite(d)
        i = np.where(found, i, 0)
        return (np.where(found[:, None], self.points[i], points),
                np.where(found[:, None], self.normals[i], 0.0), d)

    def match_perimeter(self, points):
        """Nearest perimeter points in the table plane ``(k, 3)``, their in-plane unit normals
        ``(k, 3)`` and in-plane distances ``(k,)`` (m)."""
        d, i = self.boundary_tree.query(points @ self.plane_axes.T)
        return self.boundary_points[i], self.boundary_normals[i], d

    def _closest_on_faces(self, points, bound, neighbours=2):
        """Closest points on the faces around the ``neighbours`` nearest vertices: exact for any
        reasonably shaped mesh, and far faster than a search over all triangles."""
        s = self.surface
        if self._rings is None:
            self._rings = _vertex_faces(s.faces, len(s.vertices))
        k = min(neighbours, len(self.points))
        if self._longest_edge is None:
            self._longest_edge = float(s.edge_lengths.max())
        # a point within ``bound`` of a triangle is within bound + its longest edge of a vertex
        dv, vi = self.tree.query(points, k=k, distance_upper_bound=bound + self._longest_edge)
        dv, vi = dv.reshape(len(points), k), vi.reshape(len(points), k)
        found = np.isfinite(dv)
        vi = np.where(found, vi, 0)
        if self._vertex_ids is not None:
            vi = self._vertex_ids[vi]
        cand = np.where(found[:, :, None], self._rings[vi], -1).reshape(len(points), -1)
        pi, slot = np.nonzero(cand >= 0)
        face = cand[pi, slot]
        tri = s.vertices[s.faces[face]]
        c = _closest_on_triangles(points[pi], tri[:, 0], tri[:, 1], tri[:, 2])
        d2 = np.einsum("kj,kj->k", c - points[pi], c - points[pi])
        dense = np.full(cand.shape, np.inf)
        dense[pi, slot] = d2
        best = np.argmin(dense, axis=1)
        hit = np.isfinite(dense[np.arange(len(points)), best])
        pair = np.full(cand.shape, -1, dtype=np.int64)
        pair[pi, slot] = np.arange(len(pi))
        first = pair[np.flatnonzero(hit), best[hit]]
        closest, normals = points.copy(), np.zeros_like(points)
        dist = np.full(len(points), np.inf)
        closest[hit], normals[hit], dist[hit] = c[first], s.face_normals[face[first]], np.sqrt(d2[first])
        far = dist > bound
        closest[far], normals[far], dist[far] = points[far], 0.0, np.inf
        return closest, normals, dist


def _vertex_faces(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """Faces around each vertex, ``(n, max_valence)`` padded with -1."""
    vert = faces.ravel()
    face = np.repeat(np.arange(len(faces)), 3)
    order = np.argsort(vert, kind="stable")
    vert, face = vert[order], face[order]
    counts = np.bincount(vert, minlength=n_vertices)
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    slot = np.arange(len(vert)) - start[vert]
    out = np.full((n_vertices, max(int(counts.max()), 1)), -1, dtype=np.int64)
    out[vert, slot] = face
    return out


def _closest_on_triangles(p, a, b, c):
    """Closest points on triangles ``(a, b, c)`` to points ``p`` (all ``(..., 3)``), by the
    Voronoi regions of vertices, edges and face (Ericson, Real-Time Collision Detection §5.1.5)."""
    def dot(x, y):
        return np.einsum("...j,...j->...", x, y)

    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = dot(ab, ap), dot(ac, ap)
    bp = p - b
    d3, d4 = dot(ab, bp), dot(ac, bp)
    cp = p - c
    d5, d6 = dot(ab, cp), dot(ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        v = np.where(denom != 0, vb / denom, 0.0)
        w = np.where(denom != 0, vc / denom, 0.0)
        out = a + ab * v[..., None] + ac * w[..., None]                               # inside
        t = np.clip(np.nan_to_num((d4 - d3) / ((d4 - d3) + (d5 - d6))), 0, 1)
        m = (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0)
        out = np.where(m[..., None], b + (c - b) * t[..., None], out)                   # edge BC
        t = np.clip(np.nan_to_num(d2 / (d2 - d6)), 0, 1)
        m = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
        out = np.where(m[..., None], a + ac * t[..., None], out)                        # edge AC
        m = (d6 >= 0) & (d5 <= d6)
        out = np.where(m[..., None], c, out)                                            # vertex C
        t = np.clip(np.nan_to_num(d1 / (d1 - d3)), 0, 1)
        m = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
        out = np.where(m[..., None], a + ab * t[..., None], out)                        # edge AB
        m = (d3 >= 0) & (d4 <= d3)
        out = np.where(m[..., None], b, out)                                            # vertex B
        m = (d1 <= 0) & (d2 <= 0)
        out = np.where(m[..., None], a, out)                                            # vertex A
    return out


def _pca_normals(points, tree, k):
    """Unit normals ``(n, 3)`` by the smallest principal direction of ``k`` neighbours."""
    _, idx = tree.query(points, k=min(k, len(points)))
    nb = points[idx]
    d = nb - nb.mean(axis=1, keepdims=True)
    cov = np.einsum("nki,nkj->nij", d, d)
    _, vec = np.linalg.eigh(cov)
    return vec[:, :, 0]


def _plane_axes(k):
    helper = np.array([1.0, 0, 0]) if abs(k[0]) < 0.9 else np.array([0, 1.0, 0])
    e1 = normalize(np.cross(helper, k))
    return e1, np.cross(k, e1)


def _check_points(points, what: str) -> np.ndarray:
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3:
        raise InputError(f"{what} must be an (n, 3) array of points in m, got shape {p.shape}")
    if len(p) < MIN_POINTS:
        raise InputError(f"{what} has {len(p)} points; registration needs at least {MIN_POINTS} "
                         "(pass the whole surface or scan, not a few picked points)")
    bad = ~np.isfinite(p).all(axis=1)
    if bad.any():
        raise InputError(f"{what}: {int(bad.sum())} of {len(p)} points have NaN or infinite "
                         "coordinates; remove them first")
    return p


def _check_normals(normals, n: int, what: str) -> np.ndarray | None:
    if normals is None:
        return None
    nr = np.asarray(normals, dtype=float)
    if nr.shape != (n, 3):
        raise InputError(f"{what} must have shape ({n}, 3) like the points, got {nr.shape}")
    if not np.isfinite(nr).all():
        raise InputError(f"{what} contain NaN or infinite values")
    return normalize(nr)


def _right_handed_axes(points, weights):
    from ..surface.geometry import principal_axes

    c, axes = principal_axes(points, weights)
    if np.linalg.det(axes) < 0:
        axes = axes.copy()
        axes[2] *= -1
    return c, axes
