"""Rigid registration of a nominal CAD surface to a measured scan (Jaeger §3.3).

Two entry points, one engine:

* :func:`register_rigid` — general rigid registration (6 DOF): a coarse global search (84
  rotations — the principal-axes frame under its 24 axis swaps and sign flips, and the 60
  icosahedral rotations — each placed where it fits a distance field of the target best, then a
  few cheap ICP steps), trimmed point-to-plane ICP from the best few, and a final polish against
  the exact closest points on the target's triangles.
* :func:`register_on_table` — the thesis's constrained case: the part rests on a flat table, so
  only the rotation about the table normal and the translation in the table plane are unknown
  (3 DOF, optionally 4 with the height).  Points on the part's perimeter, which the scan measures
  most reliably, are matched to the target's perimeter and weighted more.

Each ICP step linearises the rotation (small angles ``ω``): for a source point ``p`` moved to
``p' = p + ω × (p - c) + δt`` and its correspondence ``q`` with unit direction ``u`` (the target
normal for point-to-plane, an in-plane perimeter normal for perimeter terms), the residual
``r = (p - q)·u`` becomes ``r + ((p - c) × u)·ω + u·δt``.  The weighted least-squares solution is
applied as an exact rotation, and the constrained case simply restricts ``(ω, δt)`` to a basis.
Trimming (keeping the ``trim`` fraction of closest correspondences each step, then dropping
residuals beyond three robust standard deviations) rejects outliers and the parts of either cloud
that the other does not cover.  Once a pose settles, the kept set is frozen and the steps become
Levenberg-Marquardt, so ICP converges even along motions the geometry barely constrains.

Not every part can be registered well from its surface alone: a part that is nearly symmetric
(an arch, a barrel-shaped panel) slides or turns on itself.  The result reports the one-sigma
uncertainty of the pose, the least-determined motion, and the next-best distinct pose, and logs a
warning when either says the answer is ambiguous.

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

#: Source points used by the fine ICP; larger inputs are subsampled at random (a surface's points
#: are weighted by their vertex areas).
MAX_POINTS = 20_000
#: Source points used to score coarse start poses.
COARSE_POINTS = 250
#: Target point spacing (fraction of the source size) used to score coarse start poses.
COARSE_SPACING = 0.02
#: Correspondence search radius (fraction of the source size) of the first coarse step.
COARSE_BOUND = 0.25
#: Coarse placement: source points scored, candidate-centre step (in target-thinning spacings),
#: distance clip (same unit), centres scored at once, placements kept for the coarse ICP, and
#: the largest distance-field grid (cells) and number of candidate centres.
PLACE_POINTS = 100
PLACE_STEP = 3.0
PLACE_CLIP = 3.0
PLACE_CHUNK = 512
PLACE_KEEP = 24
MAX_FIELD_CELLS = 4_000_000
MAX_CENTRES = 20_000
#: ICP steps run from every coarse start pose before they are scored.
COARSE_ITERATIONS = 10
#: Best distinct coarse poses refined to convergence (on a table, this many by the surface fit
#: and this many by the surface and perimeter fit).
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
#: A pose has settled (its trimmed set is frozen) when a step moves points by less than this
#: fraction of the source size, or after FREEZE_AFTER steps.
SETTLE_STEP = 1e-4
FREEZE_AFTER = 20
#: Correspondences whose point-to-plane residual exceeds this many robust standard deviations
#: (1.4826 × median absolute residual of the trimmed set), or GATE_FLOOR × the source size if
#: larger, are dropped too.
GATE_SIGMAS = 3.0
GATE_FLOOR = 1e-4
#: Correspondences are searched within this many times the last trimmed distance (+ the step).
SEARCH_FACTOR = 4.0
#: Residuals are reported for source points within this fraction of the source size of the target.
FAR_FRACTION = 0.1
#: With a surface target, the closest-vertex ICP stops at steps below this fraction of the
#: source size and the exact closest-point ICP takes over.
POLISH_FROM = 1e-5
#: Largest rotation (rad, about the weighted centroid) of one ICP step.
MAX_STEP_ANGLE = 0.3
#: A distinct pose whose score is within this factor of the best makes the answer ambiguous.
AMBIGUOUS_SCORE = 1.1
#: Relative eigenvalue of the normal equations below which a motion counts as unconstrained.
DEGENERATE_EIGENVALUE = 1e-10

NO_MATCH = "no correspondences"
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
        ICP steps taken by the fine stages (after the coarse search).
    converged : bool
        Whether the last step moved every source point by less than the tolerance.
    point_indices : (k,) int
        Indices into the source points of the points used (all of them unless subsampled).
    residuals : (k,) float
        Signed point-to-plane residual of each used point after registration, m (positive on the
        side the target normal points to); NaN where the target is farther than 10 % of the
        source size.
    inliers : (k,) bool
        Which used points are inliers (see ``inlier_distance`` of :func:`register_rigid`).
    dof : int
        Degrees of freedom solved for (6 general, 3 or 4 on a table).
    score : float
        How well the chosen pose fits, as an RMS distance (m), before the final polish: the
        ``trim`` fraction of closest source points' distances to the target, plus on a table the
        weighted in-plane distances of the perimeter points to the target's perimeter.  It
        ranked the refined candidate poses.
    runner_up_score : float or None
        The same for the best refined pose distinct from the chosen one; within a few percent of
        ``score`` means the part is (nearly) symmetric and the answer ambiguous.
    runner_up_angle, runner_up_shift : float or None
        Rotation (rad) and source-centroid distance (m) between the chosen pose and that one.
    source_centroid : (3,) float
        Weighted centroid of the used source points, source frame, m.
    sigma_rotation, sigma_translation : float
        One-sigma uncertainty of the rotation (rad) and of the translation at the source centroid
        (m), from the least-squares covariance; residuals are treated as independent, so a CAD
        that differs in shape from the scan is less certain than this says.
    weakest_motion : str
        The least-determined motion, in words (what a nearly symmetric part slides along).
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
    score: float = 0.0
    runner_up_score: float | None = None
    runner_up_angle: float | None = None
    runner_up_shift: float | None = None
    source_centroid: np.ndarray = field(default_factory=lambda: np.zeros(3), repr=False)
    sigma_rotation: float = 0.0
    sigma_translation: float = 0.0
    weakest_motion: str = ""

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
            "centroid_shift_m": (self.transform(self.source_centroid[None])[0] - self.source_centroid).tolist(),
            "sigma_rotation_deg": float(np.degrees(self.sigma_rotation)),
            "sigma_translation_m": float(self.sigma_translation),
            "weakest_motion": self.weakest_motion,
            "score_m": float(self.score),
            "runner_up_score_m": None if self.runner_up_score is None else float(self.runner_up_score),
            "runner_up_rotation_deg": (None if self.runner_up_angle is None
                                       else float(np.degrees(self.runner_up_angle))),
            "runner_up_shift_m": None if self.runner_up_shift is None else float(self.runner_up_shift),
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
        Search for the global alignment first: 84 rotations (the principal-axes frame under its
        24 axis swaps and sign flips, and the 60 icosahedral rotations), each placed where it fits
        a distance field of the target best; the 24 best placements get 10 cheap ICP steps and
        the 3 best distinct results are refined.  Off, ICP starts from ``initial`` alone.
    initial : (4, 4) float, optional
        A guess of the source-to-target transform (m); always among the start poses.
        Default identity.
    trim : float
        Fraction (0.2..1] of correspondences kept each step (the closest; of those, residuals
        beyond three robust standard deviations are dropped too); ``1 - trim`` should be at
        least the fraction of source points that are outliers or lie off the target.
    max_iterations : int
        ICP steps allowed in each fine stage (to the closest vertices' tangent planes, then, for
        a surface target, to the exact closest points on its triangles).
    tolerance : float
        Convergence: the last step moved every source point by less than this, m.
    inlier_distance : float, optional
        Distance (m) under which a source point counts as an inlier after registration (to the
        closest point of a surface target; to the tangent plane of the closest point of a point
        target).  Default: three robust standard deviations of the residuals, clipped to
        0.1 %..1 % of the source's size (its bounding-box diagonal in its principal frame).
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
        centres = _grid_centres(tgt, PLACE_STEP * COARSE_SPACING * src.size)
        starts += _place(src, tgt, _pca_starts(src, tgt) + _rotation_starts(src, tgt), centres, rng)
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
        normal (its tilt is kept), and the coarse search tries 24 turns about the table normal
        through the source centroid, each placed in the table plane (and in height with
        ``fit_height``) where it fits a distance field of the target best.

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
    src = _Source.build(source, source_normals, max_points, rng, boundary=source_boundary, perimeter=True)
    tgt = _Target.build(target, target_normals, table_normal=k)
    init = _check_matrix(initial)
    e1, e2 = _plane_axes(k)
    cols = [np.r_[k, 0, 0, 0], np.r_[0, 0, 0, e1], np.r_[0, 0, 0, e2]]
    if fit_height:
        cols.append(np.r_[0, 0, 0, k])
    basis = np.array(cols).T
    starts = [init]
    if coarse:
        c0 = init[:3, :3] @ src.centroid + init[:3, 3]
        centres = _grid_centres(tgt, PLACE_STEP * COARSE_SPACING * src.size, k=k,
                                height=None if fit_height else float(c0 @ k))
        starts += _place(src, tgt, _table_starts(src, tgt, init, k, fit_height), centres, rng)
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


class _DistanceField:
    """Distance (m) to the nearest target point on a voxel grid: a lookup that costs nothing next
    to a kd-tree query, for scoring thousands of placements during the coarse search."""

    def __init__(self, points, spacing, margin):
        from scipy.ndimage import distance_transform_edt

        self.h = float(spacing)
        self.origin = points.min(axis=0) - margin
        shape = np.ceil((points.max(axis=0) + margin - self.origin) / self.h).astype(int) + 1
        cells = int(np.prod(shape))
        if cells > MAX_FIELD_CELLS:             # very flat or very large targets: coarser grid
            self.h *= (cells / MAX_FIELD_CELLS) ** (1 / 3)
            shape = np.ceil((points.max(axis=0) + margin - self.origin) / self.h).astype(int) + 1
        occupied = np.zeros(shape, bool)
        occupied[tuple(np.round((points - self.origin) / self.h).astype(int).T)] = True
        self.grid = (distance_transform_edt(~occupied) * self.h).astype(np.float32)
        self.shape = np.array(shape)

    def index(self, points):
        """Integer grid coordinates ``(..., 3)`` of points ``(..., 3)``."""
        return np.round((points - self.origin) / self.h).astype(np.int64)

    def at(self, idx):
        """Distances ``(...)`` at integer grid coordinates ``(..., 3)`` (clamped to the grid)."""
        idx = np.clip(idx, 0, self.shape - 1)
        return self.grid[idx[..., 0], idx[..., 1], idx[..., 2]]


def _place(src, tgt, starts, centres, rng):
    """For each start pose, move the source centroid to the candidate centre ``(m, 3)`` where the
    start's rotation fits the target best: the mean clipped squared distance of a few source
    points in a distance field of the target.  This replaces centroid alignment, which fails when
    the target holds more than the part (a scan with its table and fixtures)."""
    spacing = COARSE_SPACING * src.size
    field = _DistanceField(tgt.points, spacing, 0.6 * src.size)
    n = min(PLACE_POINTS, len(src.points))
    local = src.points[rng.choice(len(src.points), size=n, replace=False)] - src.centroid
    clip = PLACE_CLIP * spacing
    # centres snapped to the grid, so each placement is an integer shift of the rotated points
    cidx = field.index(centres)
    out, losses = [], []
    for m in starts:
        q = np.round((local @ m[:3, :3].T) / field.h).astype(np.int64)
        best, best_loss = 0, np.inf
        for lo in range(0, len(cidx), PLACE_CHUNK):
            dist = np.minimum(field.at(q[None] + cidx[lo:lo + PLACE_CHUNK, None]), clip)
            loss = np.einsum("cn,cn->c", dist, dist)
            i = int(np.argmin(loss))
            if loss[i] < best_loss:
                best, best_loss = lo + i, loss[i]
        # the candidate itself, not its snapped grid cell: on a table its height must stay exact
        out.append(rigid_matrix(m[:3, :3], centres[best] - m[:3, :3] @ src.centroid))
        losses.append(best_loss)
    # only the best placements go on to the (costlier) coarse ICP
    return [out[i] for i in np.argsort(losses, kind="stable")[:PLACE_KEEP]]


def _grid_centres(tgt, step, k=None, height=None):
    """Candidate positions ``(m, 3)`` for the source centroid over the target's extent, ``step`` m
    apart; on a table (``k`` given) a grid in the table plane, at ``height`` along ``k`` when
    given, else at heights over the target's extent along ``k``."""
    pts = tgt.points
    if k is None:
        axes = np.eye(3)
    else:
        axes = np.vstack([_plane_axes(k), k])
    coords = pts @ axes.T
    lo, hi = coords.min(axis=0), coords.max(axis=0)
    if height is not None:
        lo[2] = hi[2] = height
    count = np.prod(np.floor((hi - lo) / step) + 1)
    if count > MAX_CENTRES:                     # a target much larger than the part: coarser grid
        dims = 2 if height is not None else 3
        step *= (count / MAX_CENTRES) ** (1 / dims)
    ticks = [np.arange(a, b + step, step) for a, b in zip(lo, hi)]
    if height is not None:
        ticks[2] = np.array([height])
    grid = np.stack(np.meshgrid(*ticks, indexing="ij"), axis=-1).reshape(-1, 3)
    centroid = tgt.centroid @ axes.T
    if height is not None:
        centroid[2] = height
    return np.vstack([grid, centroid]) @ axes


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
        sparse = tgt.thinned(COARSE_SPACING * src.size)
        mats, *_ = _icp(sub, sparse, starts, iterations=COARSE_ITERATIONS, tolerance=tolerance, exact=False,
                        check=False, bound=COARSE_BOUND * src.size, **opts)
        # the coarse poses have not converged, and a perimeter that is nearly symmetric can make a
        # turned pose look better than a true one that is still on its way: keep the best by the
        # surface alone and, on a table, the best with the perimeter too
        scores = _score(sub, sparse, mats, trim, cos_max, None, exact=False)
        chosen = list(_distinct(mats, np.argsort(scores), src, COARSE_KEEP))
        if boundary is not None:
            with_perimeter = _score(sub, sparse, mats, trim, cos_max, boundary, exact=False)
            for i in _distinct(mats, np.argsort(with_perimeter), src, COARSE_KEEP):
                if all(not _same_pose(mats[i], mats[j], src) for j in chosen):
                    chosen.append(int(i))
        log.info("registration: %d start poses; refining %d, coarse scores %s mm", len(starts), len(chosen),
                 np.round(1e3 * scores[chosen], 3).tolist())
        starts = mats[chosen]
    # --- fine: trimmed point-to-plane ICP to convergence from the best distinct poses (to a looser
    # tolerance when the exact polish follows)
    fine_tol = max(tolerance, POLISH_FROM * src.size) if tgt.surface is not None else tolerance
    mats, iters, conv, step, free = _icp(src, tgt, starts, iterations=max_iterations, tolerance=fine_tol,
                                         exact=False, check=True, **opts)
    if (free != "").all():
        raise InfeasibleError(_unconstrained_message(free[0]))
    fits = np.where(free != "", np.inf, _score(src, tgt, mats, trim, cos_max, boundary, exact=True))
    order = np.argsort(fits)
    best = int(order[0])
    score = float(fits[best])
    runner_up = next((j for j in order[1:] if np.isfinite(fits[j])
                      and not _same_pose(mats[best], mats[j], src)), None)
    runner_up = None if runner_up is None else (mats[runner_up], float(fits[runner_up]))
    matrix, iterations, converged, last_step = mats[best], int(iters[best]), bool(conv[best]), step[best]
    # --- polish against the exact closest points on the target's triangles
    if tgt.surface is not None:
        m2, it2, c2, s2, free = _icp(src, tgt, matrix[None], iterations=max_iterations, tolerance=tolerance,
                                     exact=True, check=True, **opts)
        if free[0]:
            raise InfeasibleError(_unconstrained_message(free[0]))
        matrix, iterations = m2[0], iterations + int(it2[0])
        converged, last_step = bool(c2[0]), s2[0]
    if not converged:
        msg = (f"ICP did not converge within {max_iterations} iterations (last step moved points by "
               f"{last_step:.3g} m, tolerance {tolerance:.3g} m); try a closer initial pose (initial=...), "
               "coarse=True, a smaller trim if the clouds overlap only partly, a larger max_iterations, "
               "or a looser tolerance")
        if require_convergence:
            raise InfeasibleError(msg)
        log.warning("registration: %s", msg)
    return _finish(src, tgt, matrix, iterations, converged, trim, inlier_distance, min_inlier_fraction,
                   cos_max, basis, boundary, score, runner_up)


def _subset(src, n, rng):
    """A random subset of about ``n`` source points plus up to ``n`` perimeter points."""
    if len(src.points) <= n:
        return src
    idx = np.sort(rng.choice(len(src.points), size=n, replace=False))
    keep = np.zeros(len(src.points), bool)
    keep[idx] = True
    bmask = np.zeros(len(src.points), bool)
    # keep the perimeter points too (up to n of them): the perimeter fixes a table registration
    perimeter = src.boundary
    if len(perimeter) > n:
        perimeter = rng.choice(perimeter, size=n, replace=False)
    bmask[perimeter] = True
    idx = np.flatnonzero(keep | bmask)
    return _Source(src.points[idx], None if src.normals is None else src.normals[idx], src.weights[idx],
                   src.indices[idx], np.flatnonzero(bmask[idx]))


def _apply(mats, points):
    """Points ``(n, 3)`` under transforms ``(h, 4, 4)`` → ``(h, n, 3)``."""
    return np.einsum("hij,nj->hni", mats[:, :3, :3], points) + mats[:, None, :3, 3]


def _trim_mask(dist, valid, trim):
    """Keep, per row, the ``trim`` fraction of valid correspondences with the smallest distance
    (infinite distances — nothing found within the search bound — are never kept)."""
    d = np.where(valid, dist, np.inf)
    n_valid = valid.sum(axis=1)
    kth = np.clip(np.ceil(trim * n_valid).astype(int) - 1, 0, d.shape[1] - 1)
    cut = np.take_along_axis(np.sort(d, axis=1), kth[:, None], axis=1)
    return valid & np.isfinite(dist) & (dist <= cut)


def _gate(r, kept, size):
    """Of the ``kept`` correspondences ``(a, n)``, drop those whose residual ``r`` ``(a, n)`` lies
    beyond GATE_SIGMAS robust standard deviations (1.4826 × median |r| of the kept ones; at least
    GATE_FLOOR × ``size``).  With outliers close to ``1 - trim`` of the points, the trimmed set
    would otherwise reach into the outliers nearest the surface; and perimeter points without a
    counterpart in the target (a scan that extends beyond the part) would pull the pose."""
    sigma = 1.4826 * _row_median(np.abs(r), kept)
    return kept & (np.abs(r) <= np.maximum(GATE_SIGMAS * sigma, GATE_FLOOR * size)[:, None])


def _row_median(values, mask):
    """Per-row (lower) median ``(a,)`` of ``values`` ``(a, n)`` where ``mask``; inf for empty rows."""
    v = np.sort(np.where(mask, values, np.inf), axis=1)
    m = mask.sum(axis=1)
    return np.where(m > 0, np.take_along_axis(v, np.maximum((m - 1) // 2, 0)[:, None], axis=1)[:, 0], np.inf)


def _icp(src, tgt, starts, *, basis, trim, cos_max, boundary, iterations, tolerance, exact, check,
         bound=None):
    """Trimmed point-to-plane ICP from several start poses at once.

    Each step solves the linearised least squares (Gauss-Newton).  Once a pose has settled its
    trimmed set is frozen (points flipping in and out of the set would otherwise keep it
    jittering) and the steps become Levenberg-Marquardt: a step that raises the objective is
    undone and retried with more damping, so the iteration converges even along motions the
    geometry barely constrains.

    Correspondences are searched within ``bound`` (m; default the source size) at first, then
    within a few times the trimmed distance plus the last step: far points are outliers, and
    bounded nearest-neighbour queries are many times faster.

    Returns the final transforms ``(h, 4, 4)``, the iterations taken ``(h,)``, whether each
    converged ``(h,)``, each last step size ``(h,)`` (m), and ``(h,)`` the motion each pose's
    correspondences left free ("" when constrained; only with ``check``, and such a pose stops)."""
    from scipy.spatial.transform import Rotation

    mats = np.array(starts, dtype=float)
    h, n = len(mats), len(src.points)
    nb = len(src.boundary) if boundary is not None else 0
    iters = np.zeros(h, int)
    conv = np.zeros(h, bool)
    last = np.full(h, np.inf)
    frozen = np.zeros(h, bool)
    keep_fixed = np.zeros((h, n), bool)
    kb_fixed = np.zeros((h, nb), bool)
    settle = SETTLE_STEP * src.size
    # the last accepted pose and its linear system, per start pose
    best = mats.copy()
    best_e = np.full(h, np.inf)
    dim = basis.shape[1]
    sys_a, sys_b = np.zeros((h, dim, dim)), np.zeros((h, dim))
    sys_c, sys_r, sys_ext = np.zeros((h, 3)), np.ones(h), np.zeros(h)
    mu = np.zeros(h)
    free = np.full(h, "", dtype=object)     # the motion a start pose's correspondences leave free
    bounds = np.full(h, src.size if bound is None else float(bound))
    for _ in range(iterations):
        act = np.flatnonzero(~conv)
        if len(act) == 0:
            break
        m = mats[act]
        A, b, e, c, radius, extent, keep, kb, cut, wsum = _system(src, tgt, m, basis, trim, cos_max, boundary,
                                                               exact, frozen[act], keep_fixed[act], kb_fixed[act],
                                                            bounds[act])
        if check:           # a start pose with no or degenerate correspondences is dropped
            bad = _free_motion(A, basis)
            empty = wsum <= 0
            if bad is not None or empty.any():
                drop = empty | (bad[0] if bad is not None else False)
                free[act[drop]] = np.where(empty[drop], NO_MATCH, "" if bad is None else bad[1])
                conv[act[drop]] = True
                keepers = ~drop
                act, m = act[keepers], m[keepers]
                A, b, e, c, radius, extent, keep, kb, cut = (
                    x[keepers] for x in (A, b, e, c, radius, extent, keep, kb, cut))
                if len(act) == 0:
                    break
        worse = frozen[act] & (e > best_e[act])
        good = act[~worse]
        best[good], best_e[good] = m[~worse], e[~worse]
        sys_a[good], sys_b[good], sys_c[good], sys_r[good], sys_ext[good] = (
            A[~worse], b[~worse], c[~worse], radius[~worse], extent[~worse])
        keep_fixed[good], kb_fixed[good] = keep[~worse], kb[~worse]
        mu[good] = np.where(mu[good] > 1e-9, mu[good] / 3.0, 0.0)
        mu[act[worse]] = np.maximum(mu[act[worse]] * 10.0, 1e-4)
        A, b, c, radius = sys_a[act], sys_b[act], sys_c[act], sys_r[act]
        damped = A + mu[act][:, None, None] * (np.eye(dim) * np.diagonal(A, axis1=1, axis2=2)[:, None, :])
        x = np.einsum("aij,aj->ai", np.linalg.pinv(damped, rcond=1e-12, hermitian=True), b)
        delta = np.einsum("ij,aj->ai", basis, x)
        # the linearisation holds for small steps: cap a step at MAX_STEP_ANGLE and one source size
        shrink = np.minimum(1.0, np.minimum(MAX_STEP_ANGLE * radius
                                            / np.maximum(np.linalg.norm(delta[:, :3], axis=1), 1e-300),
                                            src.size / np.maximum(np.linalg.norm(delta[:, 3:], axis=1), 1e-300)))
        delta *= shrink[:, None]
        omega = delta[:, :3] / radius[:, None]
        dt = delta[:, 3:]
        rot = Rotation.from_rotvec(omega).as_matrix()
        step = np.tile(np.eye(4), (len(act), 1, 1))
        step[:, :3, :3] = rot
        step[:, :3, 3] = c + dt - np.einsum("aij,aj->ai", rot, c)
        mats[act] = step @ best[act]
        size = np.linalg.norm(omega, axis=1) * sys_ext[act] + np.linalg.norm(dt, axis=1)
        iters[act] += 1
        last[act] = size
        conv[act] = size < tolerance
        bounds[act] = np.minimum(bounds[act], SEARCH_FACTOR * cut + size + 1e-3 * src.size)
        frozen[act] |= (size < settle) | (iters[act] >= FREEZE_AFTER)
    return mats, iters, conv, last, free


def _system(src, tgt, m, basis, trim, cos_max, boundary, exact, frozen, keep_fixed, kb_fixed, bounds):
    """Correspondences and the linearised least-squares system at poses ``m`` ``(a, 4, 4)``.

    Returns the normal matrices ``(a, d, d)``, right-hand sides ``(a, d)``, objectives ``(a,)``
    (weighted squared residuals, m²), rotation centres ``(a, 3)``, rms radii and largest
    distances from them ``(a,)`` (m), the kept correspondences ``(a, n)``, ``(a, b)``, the
    largest kept distance ``(a,)`` (m) and the total weight kept ``(a,)``."""
    n = len(src.points)
    p = _apply(m, src.points)                                                   # (a, n, 3)
    q, u, d = tgt.match(p.reshape(-1, 3), exact=exact, bound=float(bounds.max()))
    q, u, d = q.reshape(p.shape), u.reshape(p.shape), d.reshape(len(m), n)
    d = np.where(d <= bounds[:, None], d, np.inf)
    # a point with nothing within the bound stays "valid" (an infinitely far correspondence) so
    # that the trimmed fraction is a fraction of all points
    valid = np.ones_like(d, bool)
    if src.normals is not None:
        ns = np.einsum("aij,nj->ani", m[:, :3, :3], src.normals)
        valid &= (np.abs(np.einsum("anj,anj->an", ns, u)) >= cos_max) | ~np.isfinite(d)
    fz = frozen[:, None]
    r = np.einsum("anj,anj->an", p - q, u)
    keep = np.where(fz, keep_fixed & valid & np.isfinite(d), _gate(r, _trim_mask(d, valid, trim), src.size))
    cut = np.max(np.where(keep, d, 0.0), axis=1)
    rows_p, rows_u = [p], [u]
    rows_r = [r]
    rows_w = [np.where(keep, src.weights[None, :], 0.0)]
    kb = kb_fixed
    if boundary is not None and len(src.boundary):
        k, bw = boundary
        pb = p[:, src.boundary]
        if tgt.boundary_tree is not None:
            qb, ub, _ = tgt.match_perimeter(pb.reshape(-1, 3))
            qb, ub = qb.reshape(pb.shape), ub.reshape(pb.shape)
            # the perimeter residual lies in the table plane: trim on its in-plane length
            off = pb - qb
            dpl = np.linalg.norm(off - np.einsum("anj,j->an", off, k)[..., None] * k, axis=2)
            rb = np.einsum("anj,anj->an", off, ub)
            # gate on the in-plane distance, not the residual along the perimeter normal: a point
            # matched far along a straight edge has a small residual but no true counterpart
            kb = np.where(fz, kb_fixed, _gate(dpl, _trim_mask(dpl, np.ones_like(dpl, bool), trim), src.size))
        else:
            qb, ub = q[:, src.boundary], u[:, src.boundary]
            kb = keep[:, src.boundary]
        rows_p.append(pb)
        rows_u.append(ub)
        rows_r.append(np.einsum("anj,anj->an", pb - qb, ub))
        rows_w.append(np.where(kb, bw * src.weights[src.boundary][None, :], 0.0))
    P, U, R, W = (np.concatenate(x, axis=1) for x in (rows_p, rows_u, rows_r, rows_w))
    wsum = W.sum(axis=1)
    wpos = np.maximum(wsum, 1e-300)        # a start pose with nothing nearby stays put
    c = np.einsum("an,anj->aj", W, P) / wpos[:, None]
    off = P - c[:, None]
    dist2 = np.einsum("anj,anj->an", off, off)
    radius = np.maximum(np.sqrt(np.einsum("an,an->a", W, dist2) / wpos), 1e-12)
    extent = np.sqrt(np.max(np.where(W > 0, dist2, 0.0), axis=1))
    J = np.concatenate([np.cross(off, U) / radius[:, None, None], U], axis=2) @ basis      # (a, N, d)
    A = np.einsum("ani,an,anj->aij", J, W, J)
    b = -np.einsum("ani,an,an->ai", J, W, R)
    e = np.einsum("an,an->a", W, R * R)
    return A, b, e, c, radius, extent, keep, kb, cut, wsum


def _free_motion(A, basis):
    """Which normal matrices ``(a, d, d)`` leave a motion free (the geometry slides on itself),
    and the name of the first such motion; None when all are constrained."""
    ev, vec = np.linalg.eigh(A)
    bad = ev[:, 0] <= DEGENERATE_EIGENVALUE * np.maximum(ev[:, -1], 1e-300)
    if not bad.any():
        return None
    motion = basis @ vec[int(np.flatnonzero(bad)[0]), :, 0]
    return bad, _MOTION_NAMES[int(np.argmax(np.abs(motion)))]


def _unconstrained_message(free_motion: str) -> str:
    if free_motion == NO_MATCH:
        return ("no usable correspondences: no source point lies near the target (or every one's normal "
                "disagrees with the target's); check that both are in the same units and give an initial "
                "pose or coarse=True")
    return (f"the registration is unconstrained: the geometry does not fix the {free_motion} (a plane, "
            "sphere, cylinder or other surface that slides on itself); register a part with distinctive "
            "shape, or for a flat part on a table use register_on_table with its perimeter "
            "(boundary_weight > 0)")


def _score(src, tgt, mats, trim, cos_max, boundary, exact):
    """How well each pose ``(h, 4, 4)`` fits, as an RMS distance ``(h,)`` (m): the ``trim``
    fraction of closest source points' distances to the target (to its triangles with ``exact``,
    else to its closest points), plus, on a table, the weighted in-plane distances of the
    perimeter points to the target's perimeter (the trimmed, gated set ICP uses).

    Distances rather than point-to-plane residuals: a pose that hangs the part over the target's
    edge, or slides a flat part within a flat target, keeps small residuals but not small
    distances."""
    h, n = len(mats), len(src.points)
    p = _apply(mats, src.points)
    _, u, d = tgt.match(p.reshape(-1, 3), exact=exact, bound=0.5 * src.size)
    u, d = u.reshape(p.shape), d.reshape(h, n)
    valid = np.ones((h, n), bool)
    if src.normals is not None:
        ns = np.einsum("aij,nj->ani", mats[:, :3, :3], src.normals)
        valid &= (np.abs(np.einsum("anj,anj->an", ns, u)) >= cos_max) | ~np.isfinite(d)
    # the n_trim closest (an incompatible normal counts as far away)
    n_trim = max(int(np.ceil(trim * n)), 1)
    d = np.sort(np.where(valid, d, np.inf), axis=1)[:, :n_trim]
    num, den = np.sum(d * d, axis=1), np.full(h, float(n_trim))
    if boundary is not None and len(src.boundary) and tgt.boundary_tree is not None:
        k, bw = boundary
        pb = p[:, src.boundary]
        qb, _, _ = tgt.match_perimeter(pb.reshape(-1, 3))
        off = pb - qb.reshape(pb.shape)
        dpl = np.linalg.norm(off - np.einsum("anj,j->an", off, k)[..., None] * k, axis=2)
        kb = _gate(dpl, _trim_mask(dpl, np.ones_like(dpl, bool), trim), src.size)
        wb = np.where(kb, bw, 0.0)
        num, den = num + np.einsum("an,an->a", wb, np.where(kb, dpl, 0.0) ** 2), den + wb.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.sqrt(num / den)


def _centroid_shift(a, b, src):
    """Distance (m) between where poses ``a`` and ``b`` put the source centroid."""
    return float(np.linalg.norm((a[:3, :3] - b[:3, :3]) @ src.centroid + a[:3, 3] - b[:3, 3]))


def _same_pose(a, b, src):
    return (rotation_angle(a[:3, :3].T @ b[:3, :3]) < SAME_POSE_ANGLE
            and _centroid_shift(a, b, src) < SAME_POSE_SHIFT * src.size)


def _distinct(mats, order, src, keep):
    """Indices of the first ``keep`` poses in ``order`` that differ from each other."""
    chosen = []
    for i in order:
        if all(not _same_pose(mats[i], mats[j], src) for j in chosen):
            chosen.append(int(i))
        if len(chosen) == keep:
            break
    return np.array(chosen)


def _residuals(src, tgt, matrix, cos_max):
    """Signed point-to-plane residuals ``(n,)``, distances ``(n,)`` (m) to the exact closest target
    points, and which correspondences have compatible normals ``(n,)``.  Points with no target
    point within FAR_FRACTION of the source size get residual NaN and distance inf."""
    p = _apply(matrix[None], src.points)[0]
    q, u, d = tgt.match(p, exact=True, bound=FAR_FRACTION * src.size)
    r = np.where(np.isfinite(d), np.einsum("nj,nj->n", p - q, u), np.nan)
    valid = np.ones(len(p), bool)
    if src.normals is not None:
        valid &= np.abs(np.einsum("nj,nj->n", src.normals @ matrix[:3, :3].T, u)) >= cos_max
    return r, d, valid


def _inlier_rms(src, r, inl):
    return float(np.sqrt(np.average(r[inl] ** 2, weights=src.weights[inl]))) if inl.any() else float("inf")


def _uncertainty(src, tgt, matrix, basis, trim, cos_max, boundary):
    """One-sigma uncertainty of the rotation (rad) and of the translation at the source centroid
    (m), from the least-squares covariance ``σ² (JᵀWJ)⁻¹`` at the final pose (σ² the weighted
    mean squared residual), and the least-determined motion as a unit 6-vector
    ``(rotation axis × rms radius, translation)``.  Treats residuals as independent: where they are
    correlated (a CAD that differs in shape from the scan) the true uncertainty is larger."""
    A, _, e, _, radius, _, _, _, _, wsum = _system(
        src, tgt, matrix[None], basis, trim, cos_max, boundary, True, np.zeros(1, bool),
        np.zeros((1, len(src.points)), bool), np.zeros((1, len(src.boundary) if boundary else 0), bool),
        np.array([np.inf]))
    cov_b = (e[0] / max(wsum[0], 1e-300)) * np.linalg.pinv(A[0], rcond=1e-15, hermitian=True)
    cov = basis @ cov_b @ basis.T                                 # of (ω · radius, δt)
    rot = float(np.sqrt(np.linalg.eigvalsh(cov[:3, :3])[-1])) / radius[0]
    tra = float(np.sqrt(np.linalg.eigvalsh(cov[3:, 3:])[-1]))
    ev, vec = np.linalg.eigh(cov)
    return rot, tra, vec[:, -1] * np.sign(vec[np.argmax(np.abs(vec[:, -1])), -1])


def _describe_motion(motion, centroid):
    """Words for a unit 6-vector ``(rotation × radius, translation)``."""
    w, t = motion[:3], motion[3:]
    if np.linalg.norm(w) >= np.linalg.norm(t):
        return (f"rotation about axis {np.round(w / np.linalg.norm(w), 2).tolist()} through "
                f"{np.round(centroid, 3).tolist()} m")
    return f"translation along {np.round(t / np.linalg.norm(t), 2).tolist()}"


def _finish(src, tgt, matrix, iterations, converged, trim, inlier_distance, min_inlier_fraction, cos_max,
            basis, boundary, score, runner_up):
    r, d, valid = _residuals(src, tgt, matrix, cos_max)
    if inlier_distance is None:
        kept = _trim_mask(d[None], valid[None], trim)[0]
        sigma = 1.4826 * np.median(np.abs(r[kept])) if kept.any() else np.inf
        inlier_distance = float(np.clip(3 * sigma, 1e-3 * src.size, 1e-2 * src.size))
    # without triangles the closest vertex may be up to about a point spacing away sideways: a
    # point-cloud target judges inliers by the distance to the tangent plane
    reach = inlier_distance + (0.0 if tgt.surface is not None else 2.0 * tgt.spacing)
    inl = valid & (np.abs(np.nan_to_num(r, nan=np.inf)) <= inlier_distance) & (d <= reach)
    frac = float(inl.mean())
    rms = _inlier_rms(src, r, inl)
    if frac < min_inlier_fraction:
        raise InfeasibleError(
            f"only {100 * frac:.1f}% of the source points lie within {1e3 * inlier_distance:.3g} mm of the "
            f"target after registration (need {100 * min_inlier_fraction:.0f}%): the two do not overlap, or "
            "the global alignment failed; check that both are the same part in the same units, give an "
            "initial pose, or lower min_inlier_fraction for a partial scan")
    runner_score = runner_angle = runner_shift = None
    if runner_up is not None:
        other, runner_score = runner_up
        runner_angle = rotation_angle(matrix[:3, :3].T @ other[:3, :3])
        runner_shift = _centroid_shift(matrix, other, src)
    sig_rot, sig_tra, weakest = _uncertainty(src, tgt, matrix, basis, trim, cos_max, boundary)
    centroid = matrix[:3, :3] @ src.centroid + matrix[:3, 3]
    weak_text = _describe_motion(weakest, centroid)
    result = Registration(matrix=_ro(matrix.copy()), rms=rms, inlier_fraction=frac,
                          inlier_distance=float(inlier_distance), iterations=iterations, converged=converged,
                          point_indices=_ro(src.indices.copy()), residuals=_ro(r), inliers=_ro(inl),
                          dof=basis.shape[1], score=score, runner_up_score=runner_score,
                          runner_up_angle=runner_angle, runner_up_shift=runner_shift,
                          source_centroid=_ro(src.centroid.copy()), sigma_rotation=sig_rot,
                          sigma_translation=sig_tra, weakest_motion=weak_text)
    log.info("registration: rms %.4g mm over %.1f%% inliers, %d iterations, rotation %.3f deg; "
             "1-sigma %.3g mm / %.3g deg", 1e3 * rms, 100 * frac, iterations, np.degrees(result.angle),
             1e3 * sig_tra, np.degrees(sig_rot))
    if sig_tra + sig_rot * src.size / 2 > inlier_distance:
        log.warning("registration: the pose is poorly determined (1-sigma %.3g mm at the centroid, %.3g deg): "
                    "the surface nearly slides on itself by %s; use register_on_table with the perimeter, or "
                    "check the pose against features", 1e3 * sig_tra, np.degrees(sig_rot), weak_text)
    if runner_score is not None and runner_score < AMBIGUOUS_SCORE * score:
        log.warning("registration: another pose (turned %.1f deg, centroid %.3g mm away) fits almost as well "
                    "(score %.4g vs %.4g mm): the part is nearly symmetric; give initial= to pick one",
                    np.degrees(runner_angle), 1e3 * runner_shift, 1e3 * runner_score, 1e3 * score)
    return result


def _ro(a):
    a.setflags(write=False)
    return a
