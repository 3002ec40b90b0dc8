"""Rigid registration of a nominal CAD surface to a measured scan (Jaeger §3.3).

Two entry points, one engine:

* :func:`register_rigid` — general rigid registration (6 DOF): a coarse global search over many
  start poses (the principal-axes frames with their sign flips and axis swaps, plus an even set
  of rotations), each scored after a few cheap ICP steps; then trimmed point-to-plane ICP from the
  best few, and a final polish against the exact closest points on the target's triangles.
* :func:`register_on_table` — the thesis's constrained case: the part rests on a flat table, so
  only the rotation about the table normal and the translation in the table plane are unknown
  (3 DOF, optionally 4 with the height).  Points on the part's perimeter, which the scan measures
  most reliably, are matched to the target's perimeter and weighted more.

Each ICP step linearises the rotation (small angles ``ω``): for a source point ``p`` moved to
``p' = p + ω × (p - c) + δt`` and its correspondence ``q`` with unit direction ``u`` (the target
normal for point-to-plane, an in-plane perimeter normal for perimeter terms), the residual
``r = (p - q)·u`` becomes ``r + ((p - c) × u)·ω + u·δt``.  The weighted least-squares solution is
applied as an exact rotation, and the constrained case simply restricts ``(ω, δt)`` to a basis.
Trimming (keeping the ``trim`` fraction of closest correspondences each step) rejects outliers
and the parts of either cloud that the other does not cover.

Frames: the result's ``matrix`` maps source coordinates to target coordinates; registering a CAD
surface (source) onto a scan (target), it is ``cad2scan``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from ..errors import InfeasibleError, InputError
from .geometry import normalize
from .surface import Surface

log = logging.getLogger("swath.surface")

#: Source points used by the fine ICP; larger inputs are subsampled (area-weighted for surfaces).
MAX_POINTS = 20_000
#: Source points used to score coarse start poses.
COARSE_POINTS = 400
#: ICP steps run from every coarse start pose before they are scored.
COARSE_ITERATIONS = 12
#: Best distinct coarse poses refined to convergence.
COARSE_KEEP = 3
#: Fewest source points accepted.
MIN_POINTS = 10
#: Neighbours used to estimate normals of a target given as bare points.
NORMAL_NEIGHBOURS = 16
#: Target perimeter loops shorter than this (vertices) are scan holes, not the part's perimeter.
MIN_LOOP_VERTICES = 10
#: Two poses differing by less than this rotation (rad) and translation (fraction of the source
#: size) are the same pose.
SAME_POSE_ANGLE = np.radians(5.0)
SAME_POSE_SHIFT = 0.02
#: Largest rotation (rad, about the weighted centroid) of one ICP step.
MAX_STEP_ANGLE = 0.3
#: Relative eigenvalue of the normal equations below which a motion counts as unconstrained.
DEGENERATE_EIGENVALUE = 1e-10

_MOTION_NAMES = ("rotation about x", "rotation about y", "rotation about z",
                 "translation along x", "translation along y", "translation along z")


# --------------------------------------------------------------------------------------------
# result record
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Registration:
    """The result of a rigid registration.

    Attributes
    ----------
    matrix : (4, 4) float
        Homogeneous transform from the source frame to the target frame (``cad2scan`` when the
        CAD surface is the source and the scan the target); translation in metres.
    rms : float
        Root-mean-square point-to-plane residual over the inliers, m.
    inlier_fraction : float
        Fraction of the (subsampled) source points within ``inlier_distance`` of the target.
    inlier_distance : float
        Distance (m) under which a source point counts as an inlier.
    iterations : int
        ICP steps taken by the fine stage (after the coarse search).
    converged : bool
        Whether the last step moved every source point by less than the tolerance.
    point_indices : (k,) int
        Indices into the source points of the points used (all of them unless subsampled).
    residuals : (k,) float
        Signed point-to-plane residual of each used point after registration, m (positive on the
        side the target normal points to).
    inliers : (k,) bool
        Which used points are inliers.
    dof : int
        Degrees of freedom solved for (6 general, 3 or 4 on a table).
    runner_up_rms : float or None
        Residual RMS (m) of the best refined pose distinct from the chosen one; close to ``rms``
        means the part is (nearly) symmetric and the answer ambiguous.
    runner_up_angle : float or None
        Rotation (rad) between the chosen pose and that runner-up.
    """

    matrix: np.ndarray
    rms: float
    inlier_fraction: float
    inlier_distance: float
    iterations: int
    converged: bool
    point_indices: np.ndarray = field(repr=False)
    residuals: np.ndarray = field(repr=False)
    inliers: np.ndarray = field(repr=False)
    dof: int = 6
    runner_up_rms: float | None = None
    runner_up_angle: float | None = None

    @property
    def rotation(self) -> np.ndarray:
        """(3, 3) rotation part of :attr:`matrix`."""
        return self.matrix[:3, :3]

    @property
    def translation(self) -> np.ndarray:
        """(3,) translation part of :attr:`matrix`, m."""
        return self.matrix[:3, 3]

    @property
    def angle(self) -> float:
        """Total rotation angle of :attr:`matrix`, rad."""
        return rotation_angle(self.rotation)

    def transform(self, points) -> np.ndarray:
        """Source-frame points ``(n, 3)`` (m) expressed in the target frame ``(n, 3)``."""
        p = np.asarray(points, dtype=float)
        return p @ self.rotation.T + self.translation

    def to_dict(self) -> dict:
        """A JSON-ready summary (no per-point arrays): the transform and its quality."""
        r = np.abs(self.residuals[self.inliers]) if self.inliers.any() else np.zeros(1)
        return {
            "matrix": np.round(self.matrix, 12).tolist(),
            "frames": {"from": "source (cad)", "to": "target (scan)", "name": "cad2scan"},
            "rotation_deg": float(np.degrees(self.angle)),
            "translation_m": self.translation.tolist(),
            "rms_m": float(self.rms),
            "residual_p95_m": float(np.percentile(r, 95)),
            "residual_max_m": float(r.max()),
            "inlier_fraction": float(self.inlier_fraction),
            "inlier_distance_m": float(self.inlier_distance),
            "points_used": int(len(self.point_indices)),
            "iterations": int(self.iterations),
            "converged": bool(self.converged),
            "dof": int(self.dof),
            "runner_up_rms_m": None if self.runner_up_rms is None else float(self.runner_up_rms),
            "runner_up_rotation_deg": (None if self.runner_up_angle is None
                                       else float(np.degrees(self.runner_up_angle))),
        }


# --------------------------------------------------------------------------------------------
# public API
# --------------------------------------------------------------------------------------------
def register_rigid(source, target, *, source_normals=None, target_normals=None, coarse: bool = True,
                   initial=None, trim: float = 0.9, max_iterations: int = 100, tolerance: float = 1e-6,
                   inlier_distance: float | None = None, min_inlier_fraction: float = 0.3,
                   max_normal_angle: float = np.radians(60.0), max_points: int = MAX_POINTS,
                   require_convergence: bool = True, rng=None) -> Registration:
    """Rigidly register ``source`` onto ``target`` (6 DOF): coarse global search, then trimmed ICP.

    Parameters
    ----------
    source : (n, 3) float or Surface
        The points to move, m (e.g. the nominal CAD surface).  A :class:`Surface` contributes its
        vertices, smooth normals and vertex areas (as weights).
    target : Surface, (m, 3) float, or tuple ((m, 3) float, (m, 3) float)
        What to move onto, m (e.g. the scan): a surface (its kd-tree, normals and triangles are
        used), or points with optional normals (estimated from 16 neighbours when missing).
    source_normals : (n, 3) float, optional
        Unit normals of source points; used only to reject correspondences whose normals differ
        by more than ``max_normal_angle`` (either sign).
    target_normals : (m, 3) float, optional
        Unit normals of target points given as an array.
    coarse : bool
        Search for the global alignment first.  Off, ICP starts from ``initial`` alone.
    initial : (4, 4) float, optional
        A guess of the source-to-target transform (m); always among the start poses.
        Default identity.
    trim : float
        Fraction (0.2..1] of correspondences kept each step (the closest); ``1 - trim`` should
        exceed the outlier and non-overlap fraction of the source.
    max_iterations : int
        ICP steps allowed in the fine stage.
    tolerance : float
        Convergence: the last step moved every source point by less than this, m.
    inlier_distance : float, optional
        Distance (m) under which a source point counts as an inlier after registration.
        Default: three robust standard deviations of the residuals, clipped to 0.1 %..1 % of the
        source's bounding-box diagonal.
    min_inlier_fraction : float
        Refuse when fewer source points than this fraction are inliers (no overlap).
    max_normal_angle : float
        Correspondences whose normals differ by more (rad, either sign) are rejected, if both
        sides have normals.
    max_points : int
        Source points used; more are subsampled at random.
    require_convergence : bool
        Refuse (``InfeasibleError``) when ICP does not converge within ``max_iterations``;
        otherwise return with ``converged=False`` and a logged warning.
    rng : numpy.random.Generator or int, optional
        Randomness for subsampling (seed for repeatable results).

    Returns
    -------
    Registration
        ``matrix`` maps source to target coordinates (``cad2scan``).

    Raises
    ------
    InputError
        Wrong shapes, NaN coordinates, too few points, options out of range.
    InfeasibleError
        No overlap (inlier fraction below ``min_inlier_fraction``), unconstrained geometry
        (a plane, sphere or cylinder slides on itself), or no convergence.
    """
    _check_options(trim, max_iterations, tolerance, min_inlier_fraction, max_points, inlier_distance)
    rng = np.random.default_rng(rng)
    src = _Source.build(source, source_normals, max_points, rng)
    tgt = _Target.build(target, target_normals)
    init = _check_matrix(initial)
    basis = np.eye(6)
    starts = [init]
    if coarse:
        starts += _pca_starts(src, tgt) + _rotation_starts(src, tgt)
    return _register(src, tgt, np.array(starts), basis, trim=trim, max_iterations=max_iterations,
                     tolerance=tolerance, inlier_distance=inlier_distance,
                     min_inlier_fraction=min_inlier_fraction, max_normal_angle=max_normal_angle,
                     require_convergence=require_convergence, boundary=None, rng=rng)


def register_on_table(source, target, *, table_normal=(0.0, 0.0, 1.0), boundary_weight: float = 10.0,
                      source_boundary=None, fit_height: bool = False, source_normals=None,
                      target_normals=None, coarse: bool = True, initial=None, trim: float = 0.9,
                      max_iterations: int = 100, tolerance: float = 1e-6,
                      inlier_distance: float | None = None, min_inlier_fraction: float = 0.3,
                      max_normal_angle: float = np.radians(60.0), max_points: int = MAX_POINTS,
                      require_convergence: bool = True, rng=None) -> Registration:
    """Register a part resting on a flat table: rotation about the table normal, translation in
    the table plane (3 DOF; 4 with ``fit_height``), perimeter points weighted (Jaeger §3.3).

    Both clouds must already share the table: its normal is ``table_normal`` in both frames and,
    unless ``fit_height``, the table plane is at the same height.  Source perimeter points are
    matched to the target's perimeter (its boundary loops, when the target is a surface) in the
    table plane, each weighted ``boundary_weight`` times an interior point; all source points are
    also matched point-to-plane to the target surface.

    Parameters
    ----------
    source : (n, 3) float or Surface
        The part to move (e.g. the CAD), m.  A surface's boundary loops are its perimeter.
    target : Surface, (m, 3) float, or tuple ((m, 3) float, (m, 3) float)
        What to move onto (e.g. the scan), m.  Only a surface has a perimeter to match; for bare
        points the perimeter points are matched to the surface like the others, still weighted.
    table_normal : (3,) float
        The table's normal (any length), in both frames.
    boundary_weight : float
        Weight of each perimeter point relative to an interior point (>= 0; 0 ignores the
        perimeter).
    source_boundary : (b,) int, optional
        Indices of the source's perimeter points; default the boundary loops of a surface
        source (none for bare points).
    fit_height : bool
        Also solve for the translation along the table normal (4 DOF).
    source_normals, target_normals, coarse, initial, trim, max_iterations, tolerance,
    inlier_distance, min_inlier_fraction, max_normal_angle, max_points, require_convergence, rng
        As for :func:`register_rigid`; ``initial`` must already be a rotation about the table
        normal (its tilt is kept), and the coarse search tries 24 turns about the table normal.

    Returns
    -------
    Registration
        ``matrix`` maps source to target coordinates; ``dof`` is 3 (or 4).

    Raises
    ------
    InputError
        As :func:`register_rigid`, plus a zero or NaN ``table_normal``, a negative
        ``boundary_weight`` or out-of-range ``source_boundary`` indices.
    InfeasibleError
        As :func:`register_rigid`; a flat part without perimeter weight is unconstrained.
    """
    _check_options(trim, max_iterations, tolerance, min_inlier_fraction, max_points, inlier_distance)
    k = np.asarray(table_normal, dtype=float).reshape(-1)
    if k.shape != (3,) or not np.isfinite(k).all() or np.linalg.norm(k) == 0:
        raise InputError(f"table_normal must be a non-zero 3-vector, got {table_normal!r}")
    k = k / np.linalg.norm(k)
    if not (np.isfinite(boundary_weight) and boundary_weight >= 0):
        raise InputError(f"boundary_weight must be >= 0, got {boundary_weight!r}")
    rng = np.random.default_rng(rng)
    src = _Source.build(source, source_normals, max_points, rng, boundary=source_boundary)
    tgt = _Target.build(target, target_normals, table_normal=k)
    init = _check_matrix(initial)
    e1, e2 = _plane_axes(k)
    cols = [np.r_[k, 0, 0, 0], np.r_[0, 0, 0, e1], np.r_[0, 0, 0, e2]]
    if fit_height:
        cols.append(np.r_[0, 0, 0, k])
    basis = np.array(cols).T
    starts = [init]
    if coarse:
        starts += _table_starts(src, tgt, init, k, fit_height)
    boundary = (k, float(boundary_weight)) if boundary_weight > 0 and len(src.boundary) else None
    return _register(src, tgt, np.array(starts), basis, trim=trim, max_iterations=max_iterations,
                     tolerance=tolerance, inlier_distance=inlier_distance,
                     min_inlier_fraction=min_inlier_fraction, max_normal_angle=max_normal_angle,
                     require_convergence=require_convergence, boundary=boundary, rng=rng)


def rotation_angle(rotation) -> float:
    """Angle (rad) of a rotation matrix ``(3, 3)``."""
    c = (np.trace(np.asarray(rotation)) - 1.0) / 2.0
    return float(np.arccos(np.clip(c, -1.0, 1.0)))


def rigid_matrix(rotation, translation) -> np.ndarray:
    """A homogeneous transform ``(4, 4)`` from a rotation ``(3, 3)`` and a translation ``(3,)`` (m)."""
    m = np.eye(4)
    m[:3, :3] = rotation
    m[:3, 3] = translation
    return m


# --------------------------------------------------------------------------------------------
# inputs
# --------------------------------------------------------------------------------------------
def _check_options(trim, max_iterations, tolerance, min_inlier_fraction, max_points, inlier_distance):
    if not (0.2 <= trim <= 1.0):
        raise InputError(f"trim must lie in 0.2..1 (the fraction of correspondences kept), got {trim!r}")
    if int(max_iterations) < 1:
        raise InputError(f"max_iterations must be >= 1, got {max_iterations!r}")
    if not (np.isfinite(tolerance) and tolerance > 0):
        raise InputError(f"tolerance must be a positive distance in m, got {tolerance!r}")
    if not (0.0 <= min_inlier_fraction <= 1.0):
        raise InputError(f"min_inlier_fraction must lie in 0..1, got {min_inlier_fraction!r}")
    if int(max_points) < MIN_POINTS:
        raise InputError(f"max_points must be >= {MIN_POINTS}, got {max_points!r}")
    if inlier_distance is not None and not (np.isfinite(inlier_distance) and inlier_distance > 0):
        raise InputError(f"inlier_distance must be a positive distance in m, got {inlier_distance!r}")


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


def _check_matrix(initial) -> np.ndarray:
    if initial is None:
        return np.eye(4)
    m = np.asarray(initial, dtype=float)
    if m.shape != (4, 4) or not np.isfinite(m).all():
        raise InputError(f"initial must be a finite (4, 4) transform, got shape {m.shape}")
    r = m[:3, :3]
    if not np.allclose(r.T @ r, np.eye(3), atol=1e-6) or np.linalg.det(r) < 0:
        raise InputError("initial's upper-left 3x3 block is not a rotation (orthonormal, det +1)")
    return m


class _Source:
    """Source points (subsampled), optional normals and weights, perimeter indices."""

    def __init__(self, points, normals, weights, indices, boundary):
        self.points = points
        self.normals = normals
        self.weights = weights
        self.indices = indices          # into the caller's points
        self.boundary = boundary        # into self.points
        self.centroid = np.average(points, axis=0, weights=weights)
        self.size = float(np.linalg.norm(np.ptp(points, axis=0)))

    @classmethod
    def build(cls, source, normals, max_points, rng, boundary=None):
        if isinstance(source, Surface):
            pts = source.vertices
            nrm = source.normals if normals is None else _check_normals(normals, len(pts), "source_normals")
            w = source.vertex_areas / source.vertex_areas.mean()
            if boundary is None:
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
        self.boundary_points = None     # (b, 3) perimeter vertices
        self.boundary_normals = None    # (b, 3) in-plane unit normals of the perimeter
        self.boundary_tree = None

    @classmethod
    def build(cls, target, normals=None, table_normal=None):
        from scipy.spatial import cKDTree

        if isinstance(target, Surface):
            if normals is not None:
                raise InputError("target_normals is only for a target given as points; a Surface has its own")
            tgt = cls(target.vertices, target.normals, target.kdtree, surface=target)
        else:
            if isinstance(target, tuple) and len(target) == 2:
                target, normals = target
            pts = _check_points(target, "target")
            nrm = _check_normals(normals, len(pts), "target_normals")
            tree = cKDTree(pts)
            if nrm is None:
                nrm = _pca_normals(pts, tree, NORMAL_NEIGHBOURS)
            tgt = cls(pts, nrm, tree)
        if table_normal is not None and tgt.surface is not None:
            tgt._set_perimeter(table_normal)
        return tgt

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
            self.boundary_tree = cKDTree(self.boundary_points)

    def match(self, points, exact=False):
        """Closest target points ``(k, 3)``, their unit normals ``(k, 3)`` and distances ``(k,)``."""
        if exact and self.surface is not None:
            return self._closest_on_faces(points)
        d, i = self.tree.query(points)
        return self.points[i], self.normals[i], d

    def match_perimeter(self, points):
        d, i = self.boundary_tree.query(points)
        return self.boundary_points[i], self.boundary_normals[i], d

    def _closest_on_faces(self, points, neighbours=3):
        """Closest points on the faces around the ``neighbours`` nearest vertices (exact for any
        reasonably shaped mesh; much faster than a global triangle search)."""
        s = self.surface
        if self._rings is None:
            self._rings = _vertex_faces(s.faces, len(s.vertices))
        _, vi = self.tree.query(points, k=min(neighbours, len(s.vertices)))
        vi = vi.reshape(len(points), -1)
        cand = self._rings[vi].reshape(len(points), -1)                  # (k, c) faces, -1 = none
        valid = cand >= 0
        f = np.where(valid, cand, 0)
        tri = s.vertices[s.faces[f]]                                     # (k, c, 3, 3)
        p = np.broadcast_to(points[:, None, :], f.shape + (3,))
        c = _closest_on_triangles(p, tri[..., 0, :], tri[..., 1, :], tri[..., 2, :])
        d2 = np.where(valid, np.einsum("kcj,kcj->kc", c - p, c - p), np.inf)
        best = np.argmin(d2, axis=1)
        rows = np.arange(len(points))
        face = f[rows, best]
        closest = c[rows, best]
        return closest, s.face_normals[face], np.sqrt(d2[rows, best])


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


# --------------------------------------------------------------------------------------------
# start poses
# --------------------------------------------------------------------------------------------
def _right_handed_axes(points, weights):
    from .geometry import principal_axes

    c, axes = principal_axes(points, weights)
    if np.linalg.det(axes) < 0:
        axes = axes.copy()
        axes[2] *= -1
    return c, axes


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


# --------------------------------------------------------------------------------------------
# the engine
# --------------------------------------------------------------------------------------------
def _register(src, tgt, starts, basis, *, trim, max_iterations, tolerance, inlier_distance,
              min_inlier_fraction, max_normal_angle, require_convergence, boundary, rng):
    cos_max = float(np.cos(max_normal_angle))
    opts = dict(basis=basis, trim=trim, cos_max=cos_max, boundary=boundary)
    # --- coarse: a few cheap steps from every start pose on a small subsample, then score
    if len(starts) > 1:
        sub = _subset(src, COARSE_POINTS, rng)
        mats, *_ = _icp(sub, tgt, starts, iterations=COARSE_ITERATIONS, tolerance=tolerance, exact=False,
                        check=False, **opts)
        scores = _score(sub, tgt, mats, trim)
        order = np.argsort(scores)
        chosen = _distinct(mats, order, src.size, COARSE_KEEP)
        log.info("registration: %d start poses; best coarse scores %s mm", len(starts),
                 np.round(1e3 * scores[chosen], 3).tolist())
        starts = mats[chosen]
    # --- fine: trimmed point-to-plane ICP to convergence from the best distinct poses
    mats, iters, conv, step = _icp(src, tgt, starts, iterations=max_iterations, tolerance=tolerance,
                                   exact=False, check=True, **opts)
    scores = _score(src, tgt, mats, trim)
    order = np.argsort(scores)
    best = int(order[0])
    runner_up = next((mats[j] for j in order[1:] if not _same_pose(mats[best], mats[j], src.size)), None)
    matrix, iterations, converged, last_step = mats[best], int(iters[best]), bool(conv[best]), step[best]
    # --- polish against the exact closest points on the target's triangles
    if tgt.surface is not None:
        m2, it2, c2, s2 = _icp(src, tgt, matrix[None], iterations=max_iterations, tolerance=tolerance,
                               exact=True, check=True, **opts)
        matrix, iterations = m2[0], iterations + int(it2[0])
        converged, last_step = converged and bool(c2[0]), s2[0]
    if not converged:
        msg = (f"ICP did not converge within {max_iterations} iterations (last step moved points by "
               f"{last_step:.3g} m, tolerance {tolerance:.3g} m); try a closer initial pose (initial=...), "
               "coarse=True, a smaller trim if the clouds overlap only partly, a larger max_iterations, "
               "or a looser tolerance")
        if require_convergence:
            raise InfeasibleError(msg)
        log.warning("registration: %s", msg)
    return _finish(src, tgt, matrix, iterations, converged, trim, inlier_distance, min_inlier_fraction,
                   cos_max, basis.shape[1], runner_up)


def _subset(src, n, rng):
    if len(src.points) <= n:
        return src
    idx = np.sort(rng.choice(len(src.points), size=n, replace=False))
    keep = np.zeros(len(src.points), bool)
    keep[idx] = True
    bmask = np.zeros(len(src.points), bool)
    bmask[src.boundary] = True
    # keep every perimeter point: the perimeter is what fixes a table registration
    idx = np.flatnonzero(keep | bmask)
    return _Source(src.points[idx], None if src.normals is None else src.normals[idx], src.weights[idx],
                   src.indices[idx], np.flatnonzero(bmask[idx]))


def _apply(mats, points):
    """Points ``(n, 3)`` under transforms ``(h, 4, 4)`` → ``(h, n, 3)``."""
    return np.einsum("hij,nj->hni", mats[:, :3, :3], points) + mats[:, None, :3, 3]


def _trim_mask(dist, valid, trim):
    """Keep, per row, the ``trim`` fraction of valid correspondences with the smallest distance."""
    d = np.where(valid, dist, np.nan)
    with np.errstate(all="ignore"):
        cut = np.nanquantile(d, trim, axis=1) if np.isfinite(d).any() else np.full(len(d), np.nan)
    return valid & (dist <= cut[:, None])


def _icp(src, tgt, starts, *, basis, trim, cos_max, boundary, iterations, tolerance, exact, check):
    """Trimmed point-to-plane ICP from several start poses at once.

    Returns the final transforms ``(h, 4, 4)``, the iterations taken ``(h,)``, whether each
    converged ``(h,)`` and each last step size ``(h,)`` (m)."""
    from scipy.spatial.transform import Rotation

    mats = np.array(starts, dtype=float)
    h, n = len(mats), len(src.points)
    iters = np.zeros(h, int)
    conv = np.zeros(h, bool)
    last = np.full(h, np.inf)
    use_perimeter = boundary is not None and tgt.boundary_tree is not None
    for _ in range(iterations):
        act = np.flatnonzero(~conv)
        if len(act) == 0:
            break
        m = mats[act]
        p = _apply(m, src.points)                                               # (a, n, 3)
        q, u, d = tgt.match(p.reshape(-1, 3), exact=exact)
        q, u, d = q.reshape(p.shape), u.reshape(p.shape), d.reshape(len(act), n)
        valid = np.ones_like(d, bool)
        if src.normals is not None:
            ns = np.einsum("aij,nj->ani", m[:, :3, :3], src.normals)
            valid &= np.abs(np.einsum("anj,anj->an", ns, u)) >= cos_max
        keep = _trim_mask(d, valid, trim)
        w = np.where(keep, src.weights[None, :], 0.0)
        rows_p, rows_u, rows_r, rows_w = [p], [u], [np.einsum("anj,anj->an", p - q, u)], [w]
        if boundary is not None and len(src.boundary):
            k, bw = boundary
            pb = p[:, src.boundary]
            if use_perimeter:
                qb, ub, db = tgt.match_perimeter(pb.reshape(-1, 3))
                qb, ub, db = qb.reshape(pb.shape), ub.reshape(pb.shape), db.reshape(pb.shape[:2])
                # the perimeter residual lies in the table plane
                dpl = np.linalg.norm((pb - qb) - np.einsum("anj,j->an", pb - qb, k)[..., None] * k, axis=2)
                kb = _trim_mask(dpl, np.ones_like(dpl, bool), trim)
            else:
                qb, ub = q[:, src.boundary], u[:, src.boundary]
                kb = keep[:, src.boundary]
            rows_p.append(pb)
            rows_u.append(ub)
            rows_r.append(np.einsum("anj,anj->an", pb - qb, ub))
            rows_w.append(np.where(kb, bw * src.weights[src.boundary][None, :], 0.0))
        P, U, R, W = (np.concatenate(x, axis=1) for x in (rows_p, rows_u, rows_r, rows_w))
        wsum = W.sum(axis=1)
        if (wsum <= 0).any():
            raise InfeasibleError("no usable correspondences (every source point's normal disagrees with "
                                  "the target's, or nothing overlaps); check the inputs' units and poses")
        c = np.einsum("an,anj->aj", W, P) / wsum[:, None]
        radius = np.sqrt(np.einsum("an,an->a", W, np.einsum("anj,anj->an", P - c[:, None], P - c[:, None]))
                         / wsum)
        radius = np.maximum(radius, 1e-12)
        J6 = np.concatenate([np.cross(P - c[:, None], U) / radius[:, None, None], U], axis=2)
        J = J6 @ basis                                                          # (a, N, d)
        A = np.einsum("ani,an,anj->aij", J, W, J)
        b = -np.einsum("ani,an,an->ai", J, W, R)
        if check:
            _check_constrained(A, basis)
        x = np.einsum("aij,aj->ai", np.linalg.pinv(A, rcond=1e-12, hermitian=True), b)
        delta = np.einsum("ij,aj->ai", basis, x)
        # linearisation holds for small steps: cap a step at MAX_STEP_ANGLE and one source size
        shrink = np.minimum(1.0, np.minimum(MAX_STEP_ANGLE / np.maximum(np.linalg.norm(delta[:, :3], axis=1), 1e-300),
                                            src.size / np.maximum(np.linalg.norm(delta[:, 3:], axis=1), 1e-300)))
        delta *= shrink[:, None]
        omega = delta[:, :3] / radius[:, None]
        dt = delta[:, 3:]
        rot = Rotation.from_rotvec(omega).as_matrix()
        step = np.tile(np.eye(4), (len(act), 1, 1))
        step[:, :3, :3] = rot
        step[:, :3, 3] = c + dt - np.einsum("aij,aj->ai", rot, c)
        mats[act] = step @ m
        size = np.linalg.norm(omega, axis=1) * np.max(np.linalg.norm(P - c[:, None], axis=2), axis=1) \
            + np.linalg.norm(dt, axis=1)
        iters[act] += 1
        last[act] = size
        conv[act] = size < tolerance
    return mats, iters, conv, last


def _check_constrained(A, basis):
    """Refuse when the normal equations leave a motion free (sliding symmetric geometry)."""
    ev, vec = np.linalg.eigh(A)
    top = ev[:, -1:]
    bad = ev[:, 0] <= DEGENERATE_EIGENVALUE * np.maximum(top[:, 0], 1e-300)
    if bad.any():
        a = int(np.flatnonzero(bad)[0])
        motion = basis @ vec[a, :, 0]
        name = _MOTION_NAMES[int(np.argmax(np.abs(motion)))]
        raise InfeasibleError(
            f"the registration is unconstrained: the geometry does not fix the {name} (a plane, sphere, "
            "cylinder or other surface that slides on itself); register a part with distinctive shape, "
            "or for a flat part on a table use register_on_table with its perimeter (boundary_weight > 0)")


def _score(src, tgt, mats, trim):
    """Trimmed RMS distance (m) from the source points to the nearest target points, per pose."""
    p = _apply(mats, src.points)
    _, _, d = tgt.match(p.reshape(-1, 3))
    d = np.sort(d.reshape(len(mats), -1), axis=1)
    n = max(int(round(trim * d.shape[1])), 1)
    return np.sqrt(np.mean(d[:, :n] ** 2, axis=1))


def _same_pose(a, b, size):
    ang = rotation_angle(a[:3, :3].T @ b[:3, :3])
    return ang < SAME_POSE_ANGLE and np.linalg.norm(a[:3, 3] - b[:3, 3]) < SAME_POSE_SHIFT * size


def _distinct(mats, order, size, keep):
    chosen = []
    for i in order:
        if all(not _same_pose(mats[i], mats[j], size) for j in chosen):
            chosen.append(int(i))
        if len(chosen) == keep:
            break
    return np.array(chosen)


def _residuals(src, tgt, matrix, cos_max):
    """Signed point-to-plane residuals ``(n,)``, distances ``(n,)`` (m) to the exact closest target
    points, and which correspondences have compatible normals ``(n,)``."""
    p = _apply(matrix[None], src.points)[0]
    q, u, d = tgt.match(p, exact=True)
    r = np.einsum("nj,nj->n", p - q, u)
    valid = np.ones(len(p), bool)
    if src.normals is not None:
        valid &= np.abs(np.einsum("nj,nj->n", src.normals @ matrix[:3, :3].T, u)) >= cos_max
    return r, d, valid


def _inlier_rms(src, r, inl):
    return float(np.sqrt(np.average(r[inl] ** 2, weights=src.weights[inl]))) if inl.any() else float("inf")


def _finish(src, tgt, matrix, iterations, converged, trim, inlier_distance, min_inlier_fraction, cos_max,
            dof, runner_up):
    r, d, valid = _residuals(src, tgt, matrix, cos_max)
    if inlier_distance is None:
        kept = _trim_mask(d[None], valid[None], trim)[0]
        dev = np.abs(r[kept]) if kept.any() else np.abs(r)
        sigma = 1.4826 * np.median(dev)
        inlier_distance = float(np.clip(3 * sigma, 1e-3 * src.size, 1e-2 * src.size))
    inl = valid & (d <= inlier_distance)
    frac = float(inl.mean())
    rms = _inlier_rms(src, r, inl)
    if frac < min_inlier_fraction:
        raise InfeasibleError(
            f"only {100 * frac:.1f}% of the source points lie within {1e3 * inlier_distance:.3g} mm of the "
            f"target after registration (need {100 * min_inlier_fraction:.0f}%): the two do not overlap, or "
            "the global alignment failed; check that both are the same part in the same units, give an "
            "initial pose, or lower min_inlier_fraction for a partial scan")
    runner_rms = runner_angle = None
    if runner_up is not None:
        r2, d2, v2 = _residuals(src, tgt, runner_up, cos_max)
        runner_rms = _inlier_rms(src, r2, v2 & (d2 <= inlier_distance))
        runner_angle = rotation_angle(matrix[:3, :3].T @ runner_up[:3, :3])
    result = Registration(matrix=_ro(matrix.copy()), rms=rms, inlier_fraction=frac,
                          inlier_distance=float(inlier_distance), iterations=iterations, converged=converged,
                          point_indices=_ro(src.indices.copy()), residuals=_ro(r), inliers=_ro(inl), dof=dof,
                          runner_up_rms=runner_rms, runner_up_angle=runner_angle)
    log.info("registration: rms %.4g mm over %.1f%% inliers, %d iterations, rotation %.3f deg",
             1e3 * rms, 100 * frac, iterations, np.degrees(result.angle))
    return result


def _ro(a):
    a.setflags(write=False)
    return a
