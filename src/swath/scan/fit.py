"""Least-squares B-spline fits of noisy scans (Jaeger ch. 3: skinning, curvature-based knots).

:func:`fit_patch` turns a point cloud (or the vertices of a mesh patch) into a smooth
:class:`~swath.surface.bspline.BSplinePatch`:

1. **Parameterise** the points: by projection onto their best-fit plane for height-field-like
   patches; by a least-squares conformal map (``igl.lscm``) of the mesh when faces are given and
   the patch wraps (the blade round its leading edge); or by the scan rows ("rows": arc length
   along each row, distance between rows across).
2. **Place knots** densely where the surface bends, with the curvature-based distribution of the
   thesis, ``R(s) = q·b(s)/B + (1−q)·s/L``, ``b(s) = ∫₀ˢ κ²`` and ``B = b(L)``, read off a pilot fit;
   interior knots sit at ``R⁻¹(i/n)`` (:func:`curvature_knots`).
3. **Fit with a smoothness penalty**: a third-order thin-plate energy of the surface
   (``∫∫ |S_uuu|² + 3|S_uuv|² + 3|S_uvv|² + |S_vvv|²``), relaxed where the knots are dense, with
   smoothing lengths along u and v chosen by generalised cross-validation unless given (without
   scan rows, of the lengths whose score lies within one standard error of the minimum, the
   longest: errors correlated along unknown rows would otherwise pass for shape).  Third
   derivatives leave constant curvature unpenalised, so curved parts and edges are not flattened.
   With "rows" the thesis's *skinning* comes first: each row is smoothed into a curve (all rows
   share one knot vector), then the curves' control points are smoothed across the rows — at
   that level a row's positioning error is one noisy sample, so cross-validation sets the
   across-row smoothing right; the final fit of all points keeps that smoothing across the rows.
4. **Correct the parameters**: project the points on the fitted patch and refit.

The normal equations are banded and solved as such (:mod:`swath.scan.fit_solve`), so a fit of
~10⁵ points on a 130 × 100 control net takes seconds and a few hundred MB.  Points farther from the
patch than a tolerance (default 1 mm, the pad depression) make a warning; every stage reports
progress through an optional ``progress(stage, done, total)``.

Refusals (with the reason and the fix in the message): too few points, points that do not form
one patch (separate pieces, a closed mesh), and a parameterisation that folds over.
"""

from __future__ import annotations

import contextlib
import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import InfeasibleError, InputError
from ..surface.bspline import BSplinePatch
from .fit_input import (
    _check_mesh_patch,
    _check_spread,
    _lscm_parameters,
    _main_piece,
    _nn_scale,
    _optional_array,
    _pair,
    _projection_parameters,
)
from .fit_knots import _knots_from_patch, _uniform_knots
from .fit_rows import _fit_rows
from .fit_solve import _aniso_step, _gcv_progress, _lambda_grid

log = logging.getLogger(__name__)

PARAMETERIZATIONS = ("auto", "projection", "lscm", "rows")

#: Default fit tolerance, m: a point farther than this from the fitted patch makes a warning.  It
#: is the default pad depression (1 mm at the set force): where the patch is off by as much as the
#: pad is pressed in, the planned contact either loses the part or presses twice as hard, so the
#: removal predicted there means nothing.  Scan noise alone (0.1 mm on a good laser scanner) stays
#: well inside it.
FIT_TOLERANCE = 1e-3
#: A warning is given when more than this fraction of the points lie beyond the tolerance, or any
#: point lies beyond WARN_FACTOR times it (a few points just beyond it, such as the last points of
#: scan rows that skinning misses by a little over 1 mm, are not worth one).
WARN_FRACTION = 0.005
WARN_FACTOR = 5.0

@dataclass(frozen=True)
class FitReport:
    """How a fit went.

    Attributes
    ----------
    rms, max_error : float
        Root-mean-square and largest distance from the input points to the fitted patch, m.
    n_points : int
        Points used (after dropping stray specks, see ``n_dropped``).
    n_dropped : int
        Points left out because they formed tiny separate specks (< 1 % of the cloud).
    n_ctrl : (int, int)
        Control-net size ``(nu, nv)``.
    degree : (int, int)
        Degrees ``(p, q)``.
    knots_u, knots_v : ndarray
        The knot vectors (parameters in metres of arc length, roughly).
    parameterization : str
        ``"projection"``, ``"lscm"`` or ``"rows"``.
    smoothing : (float, float)
        Smoothing lengths (m) along u and along v: features shorter than about this are damped
        (locally shorter where knots are dense).
    time : float
        Wall-clock time of the fit, s.
    tolerance : float
        Distance from the patch beyond which a point makes a warning, m.
    warnings : tuple of str
        What went wrong enough to tell the user (points farther than ``tolerance``), each one line.
    """

    rms: float
    max_error: float
    n_points: int
    n_dropped: int
    n_ctrl: tuple[int, int]
    degree: tuple[int, int]
    knots_u: np.ndarray = field(repr=False)
    knots_v: np.ndarray = field(repr=False)
    parameterization: str
    smoothing: tuple[float, float]
    time: float
    tolerance: float = FIT_TOLERANCE
    warnings: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        """A JSON-ready copy (SI units)."""
        return {"rms_m": self.rms, "max_error_m": self.max_error, "n_points": self.n_points,
                "n_dropped": self.n_dropped, "n_ctrl": list(self.n_ctrl), "degree": list(self.degree),
                "knots_u": self.knots_u.tolist(), "knots_v": self.knots_v.tolist(),
                "parameterization": self.parameterization, "smoothing_m": list(self.smoothing),
                "time_s": self.time, "tolerance_m": self.tolerance, "warnings": list(self.warnings)}


# ----------------------------------------------------------------------------------------------
# Public entry point
# ----------------------------------------------------------------------------------------------
def fit_patch(points, *, normals=None, mesh_faces=None, rows=None, parameterization: str = "auto",
              degree=3, n_ctrl=None, smoothing="gcv", knot_curvature_weight: float = 0.5,
              max_turn: float = 0.1, max_ctrl_spacing: float | None = None, knot_rounds: int = 2,
              reparam_rounds: int = 1, tolerance: float = FIT_TOLERANCE,
              progress=None) -> tuple[BSplinePatch, FitReport]:
    """Fit a smooth B-spline patch to a noisy point cloud or mesh patch.

    Parameters
    ----------
    points : (n, 3) float
        Scan points or mesh vertices, m.
    normals : (n, 3) float, optional
        Normals at the points; only their side matters: the patch normal is turned to agree with
        them.  Without normals (or faces) the patch normal points to the convex side.
    mesh_faces : (m, 3) int, optional
        Triangles over ``points`` (a mesh patch).  Enables the ``"lscm"`` parameterisation; the
        winding sets the normal side.
    rows : (n,) int, optional
        Scan-row id of each point, points of a row in scan order (as from
        :func:`swath.examples.scansim.simulate_laser_scan`).  Enables ``"rows"`` (skinning).
    parameterization : {"auto", "projection", "lscm", "rows"}
        ``"auto"``: the scan rows when ``rows`` are given; otherwise projection onto the best-fit
        plane if that does not fold over, else LSCM (faces given), else refuse.
    degree : int or (int, int)
        Spline degree(s), 3 to 5, default cubic.
    n_ctrl : int or (int, int), optional
        Control points per direction.  Default: enough that the surface turns by at most
        ``max_turn`` per knot span plus one span per ``max_ctrl_spacing``, capped by the data.
    smoothing : "gcv" or float
        Smoothing length, m: features shorter than about this are damped (0 = plain least
        squares).  ``"gcv"`` chooses it by generalised cross-validation, separately along u and v
        (with ``"rows"``, across the rows at row level so that row-to-row offsets count as noise).
    knot_curvature_weight : float
        ``q`` in ``R(s)``: 0 spaces knots evenly, 1 purely by ``κ²``.
    max_turn : float
        Normal turning per knot span used for the default ``n_ctrl``, rad.
    max_ctrl_spacing : float, optional
        Largest knot span for the default ``n_ctrl``, m (default: min(50 mm, extent / 4)).
    knot_rounds : int
        Pilot-fit/knot-placement rounds (0 = uniform knots).
    reparam_rounds : int
        Parameter-correction rounds (project, refit).
    tolerance : float
        Largest acceptable distance of a point from the patch, m (default :data:`FIT_TOLERANCE`,
        the default pad depression): more than :data:`WARN_FRACTION` of the points beyond it, or
        any point beyond :data:`WARN_FACTOR` times it, make a warning (logged, and in
        ``report.warnings``).
    progress : callable, optional
        ``progress(stage, done, total)``, called at every stage of the fit (stage names start with
        ``"fit: "``) and at every smoothing length tried by cross-validation.

    Returns
    -------
    patch : BSplinePatch
    report : FitReport

    Raises
    ------
    InputError
        Malformed input: wrong shapes, too few points, collinear points, bad options.
    InfeasibleError
        The points do not form one patch (separate pieces, a closed mesh), or the chosen
        parameterisation folds over.
    """
    with _single_threaded_blas():
        return _fit_patch(points, normals=normals, mesh_faces=mesh_faces, rows=rows,
                          parameterization=parameterization, degree=degree, n_ctrl=n_ctrl, smoothing=smoothing,
                          knot_curvature_weight=knot_curvature_weight, max_turn=max_turn,
                          max_ctrl_spacing=max_ctrl_spacing, knot_rounds=knot_rounds, reparam_rounds=reparam_rounds,
                          tolerance=tolerance, progress=progress)


def _single_threaded_blas():
    """A context in which BLAS runs on one thread (when threadpoolctl is installed).

    The fit's factorisations are banded and small to medium; on a machine shared with other work,
    multi-threaded OpenBLAS spins its idle threads and runs them tens of times slower."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return contextlib.nullcontext()
    return threadpool_limits(limits=1, user_api="blas")


def _fit_patch(points, *, normals, mesh_faces, rows, parameterization, degree, n_ctrl, smoothing,
               knot_curvature_weight, max_turn, max_ctrl_spacing, knot_rounds, reparam_rounds, tolerance,
               progress):
    say = progress or (lambda stage, done, total: None)

    t_start = time.perf_counter()
    X = np.asarray(points, dtype=float)
    if X.ndim != 2 or X.shape[1] != 3:
        raise InputError(f"expected points of shape (n, 3), got {X.shape}")
    if not np.isfinite(X).all():
        raise InputError("points contain NaN or infinite coordinates; remove them before fitting")
    p, q = _pair(degree, "degree")
    if p < 3 or q < 3 or p > 5 or q > 5:
        raise InputError(f"fitted patches have degree 3 to 5 (the smoothness penalty acts on third "
                         f"derivatives), got {degree!r}")
    n_min = max(20, 2 * (p + 1) * (q + 1))
    if len(X) < n_min:
        raise InputError(f"too few points to fit a degree ({p}, {q}) patch: got {len(X)}, need at least {n_min}")
    if parameterization not in PARAMETERIZATIONS:
        raise InputError(f"parameterization must be one of {', '.join(PARAMETERIZATIONS)}, got {parameterization!r}")
    if not (0.0 <= knot_curvature_weight <= 1.0):
        raise InputError(f"knot_curvature_weight q must lie in [0, 1], got {knot_curvature_weight!r}")
    if not (isinstance(smoothing, str) and smoothing == "gcv"):
        try:
            smoothing = float(smoothing)
        except (TypeError, ValueError):
            raise InputError(f"smoothing must be 'gcv' or a length in metres, got {smoothing!r}") from None
        if not (np.isfinite(smoothing) and smoothing >= 0):
            raise InputError(f"smoothing must be a non-negative length in metres, got {smoothing!r}")
    if not (max_turn > 0):
        raise InputError(f"max_turn must be a positive angle in radians, got {max_turn!r}")
    if not (np.isfinite(tolerance) and tolerance > 0):
        raise InputError(f"tolerance must be a positive length in metres, got {tolerance!r}")
    N_in = _optional_array(normals, (len(X), 3), "normals", float)
    F = _optional_array(mesh_faces, (None, 3), "mesh_faces", int)
    if F is not None and (F.min() < 0 or F.max() >= len(X)):
        raise InputError(f"mesh_faces index vertices 0..{len(X) - 1}, got {F.min()}..{F.max()}")
    R_ids = _optional_array(rows, (len(X),), "rows", int)
    if parameterization == "lscm" and F is None:
        raise InputError("parameterization 'lscm' needs mesh_faces")
    if parameterization == "rows" and R_ids is None:
        raise InputError("parameterization 'rows' needs the scan-row id of every point (rows=...)")
    n_ctrl_req = None if n_ctrl is None else _pair(n_ctrl, "n_ctrl")
    if n_ctrl_req is not None and (n_ctrl_req[0] < p + 1 or n_ctrl_req[1] < q + 1):
        raise InputError(f"n_ctrl must be at least the degree + 1 = ({p + 1}, {q + 1}), got {n_ctrl!r}")

    say("fit: checking the points", 0, 1)
    _check_spread(X)
    # One patch: no separate pieces (stray specks of < 1 % are dropped with a warning).
    n_dropped = 0
    if F is not None:
        _check_mesh_patch(len(X), F)
    else:
        keep = _main_piece(X)
        if not keep.all():
            n_dropped = int((~keep).sum())
            log.warning("dropping %d stray points that lie apart from the patch", n_dropped)
            X = X[keep]
            N_in = None if N_in is None else N_in[keep]
            R_ids = None if R_ids is None else R_ids[keep]
    opts = dict(p=p, q=q, n_ctrl=n_ctrl_req, smoothing=smoothing, qk=float(knot_curvature_weight),
                max_turn=float(max_turn), h_max=max_ctrl_spacing, knot_rounds=int(knot_rounds),
                reparam_rounds=int(reparam_rounds), say=say)

    method = parameterization
    if method == "auto" and R_ids is not None:
        method = "rows"
    if method in ("auto", "projection"):
        say("fit: parameterising the points (projection on their best-fit plane)", 0, 1)
        uv, folds, why = _projection_parameters(X, F)
        if folds:
            if method == "projection":
                raise InfeasibleError(f"the projection parameterisation folds over: {why}. The patch is not a "
                                      "height field over its best-fit plane; use parameterization='lscm' with "
                                      "mesh_faces, or 'rows' with the scan-row ids")
            if F is None:
                raise InfeasibleError(f"the points fold over their best-fit plane ({why}), so they cannot be "
                                      "parameterised by projection; give mesh_faces (LSCM) or the scan-row ids "
                                      "(rows=...) for a patch that wraps")
            method = "lscm"
        else:
            method = "projection"
    if method == "lscm":
        say("fit: parameterising the mesh (least-squares conformal map)", 0, 1)
        uv = _lscm_parameters(X, F)

    if method == "rows":
        patch, lengths, u, v = _fit_rows(X, R_ids, **opts)
    else:
        patch, lengths, u, v = _fit_global(X, uv, **opts)

    # Normal side.
    patch, flipped = _orient(patch, X, u, v, N_in, F)
    patch = BSplinePatch(patch.control_points, patch.knots_u, patch.knots_v, patch.degree, name="fit")
    if flipped:
        u0, u1 = patch.domain[0]
        u = (u0 + u1) - u
    say("fit: measuring the distances of the points to the patch", 0, 1)
    _, _, dist = patch.project(X, initial=(u, v))
    warnings = _residual_warnings(dist, tolerance)
    for w in warnings:
        log.warning("%s", w)
    report = FitReport(rms=float(np.sqrt(np.mean(dist**2))), max_error=float(dist.max()), n_points=len(X),
                       n_dropped=n_dropped, n_ctrl=patch.shape, degree=patch.degree,
                       knots_u=np.array(patch.knots_u), knots_v=np.array(patch.knots_v),
                       parameterization=method, smoothing=lengths, time=time.perf_counter() - t_start,
                       tolerance=float(tolerance), warnings=tuple(warnings))
    log.info("fit_patch: %s, %d points, control net %dx%d, rms %.3g m, max %.3g m, %.2f s", method, len(X),
             *patch.shape, report.rms, report.max_error, report.time)
    say("fit: done", 1, 1)
    return patch, report


def _residual_warnings(dist: np.ndarray, tolerance: float) -> list[str]:
    """Warnings ``[str]`` when distances ``dist`` ``(n,)`` (m) of the points to the patch exceed
    ``tolerance`` (m) at more than :data:`WARN_FRACTION` of the points, or at any point by more
    than :data:`WARN_FACTOR` times: how many points, how far, and what to do."""
    far = dist > tolerance
    if not (far.mean() > WARN_FRACTION or dist.max() > WARN_FACTOR * tolerance):
        return []
    n_far = int(far.sum())
    return [f"{n_far} of {len(dist)} points ({100.0 * n_far / len(dist):.2g} %) lie more than "
            f"{tolerance * 1e3:.3g} mm (the fit tolerance) from the fitted patch, up to "
            f"{float(dist.max()) * 1e3:.3g} mm (rms {float(np.sqrt(np.mean(dist ** 2))) * 1e3:.3g} mm): the patch "
            "does not follow the scan there (stray points, a fold or a sharp feature the smooth patch "
            "cannot take); look at the residual map, clean the scan or fit the region on its own"]


# ----------------------------------------------------------------------------------------------
# Global fit (projection / LSCM parameters)
# ----------------------------------------------------------------------------------------------
def _fit_global(X, uv, *, p, q, n_ctrl, smoothing, qk, max_turn, h_max, knot_rounds, reparam_rounds, say):
    """One penalised fit of all points over their parameters ``uv`` (projection or LSCM).
    Returns ``(patch, (ℓ_u, ℓ_v), u, v)``."""
    u, v = uv[:, 0].copy(), uv[:, 1].copy()
    dom_u = (float(u.min()), float(u.max()))
    dom_v = (float(v.min()), float(v.max()))
    Lu, Lv = dom_u[1] - dom_u[0], dom_v[1] - dom_v[0]
    N = len(X)
    uv0 = np.stack([u, v, np.zeros_like(u)], axis=1)
    h_pts, _ = _nn_scale(uv0)
    # Smallest knot span: twice the spacing of the densest data (meshes refined at tight bends).
    min_span = 2.0 * _nn_scale(uv0, nearest_pct=5.0)[0]
    cap_total = max(N // 6, (p + 1) * (q + 1))
    cap_u = max(1, min(150, int(np.sqrt(cap_total * Lu / Lv))))
    cap_v = max(1, min(150, int(np.sqrt(cap_total * Lv / Lu))))
    opts = dict(qk=qk, max_turn=max_turn, h_max=h_max)
    req_u = None if n_ctrl is None else n_ctrl[0] - p
    req_v = None if n_ctrl is None else n_ctrl[1] - q
    hmu = h_max if h_max is not None else min(0.05, Lu / 4)
    hmv = h_max if h_max is not None else min(0.05, Lv / 4)
    # Pilot fits (uniform knots first), smoothed at the scale of their knot spans: they only
    # serve to read the curvature that places the knots.
    nsu = req_u if req_u is not None else min(cap_u, math.ceil(Lu / hmu) + 4)
    nsv = req_v if req_v is not None else min(cap_v, math.ceil(Lv / hmv) + 4)
    ku, kv = _uniform_knots(nsu, p, dom_u), _uniform_knots(nsv, q, dom_v)
    grid_u, grid_v = _lambda_grid(h_pts, Lu), _lambda_grid(h_pts, Lv)
    patch = None                      # the pilot fit of the previous round (set before it is read)
    for r in range(max(knot_rounds, 0) + 1):
        if r > 0:
            ku = _knots_from_patch(patch, 0, req_u, p, opts, cap_u, min_span, dom_u)
            kv = _knots_from_patch(patch, 1, req_v, q, opts, cap_v, min_span, dom_v)
        if r == max(knot_rounds, 0):
            break
        say("fit: pilot fits that place the knots by curvature", r, max(knot_rounds, 0))
        span_u, span_v = Lu / (len(ku) - 2 * p - 1), Lv / (len(kv) - 2 * q - 1)
        patch, _ = _aniso_step(X, u, v, ku, kv, p, q, "fixed", grid_u, grid_v, span_u, span_v)
    # Final fit: smoothing along u and v by GCV (or as given), then parameter correction.
    ells = (None, None)
    for r in range(max(reparam_rounds, 0) + 1):
        if r > 0:
            say("fit: correcting the parameters (projecting the points on the patch)", r - 1, max(reparam_rounds, 0))
            u, v, _ = patch.project(X, initial=(u, v), tol=1e-9)
        patch, ells = _aniso_step(X, u, v, ku, kv, p, q, smoothing, grid_u, grid_v, *ells,
                                  progress=_gcv_progress(say, r), one_se=True)
    return patch, ells, u, v


# ----------------------------------------------------------------------------------------------
# Orientation
# ----------------------------------------------------------------------------------------------
def _orient(patch: BSplinePatch, X, u, v, normals, F) -> tuple[BSplinePatch, bool]:
    """Turn the patch normal toward the given normals, the faces' winding, or the convex side."""
    sample = np.random.default_rng(0).choice(len(X), size=min(len(X), 4000), replace=False)
    n_patch = patch.normals(u[sample], v[sample])
    if normals is not None:
        flip = np.einsum("ij,ij->i", n_patch, normals[sample]).sum() < 0
    elif F is not None:
        from ..surface.geometry import face_normals_and_areas, vertex_normals

        fn, fa = face_normals_and_areas(X, F)
        vn = vertex_normals(len(X), F, fn, fa)
        flip = np.einsum("ij,ij->i", n_patch, vn[sample]).sum() < 0
    else:
        # Convex side: normals pointing away from the centroid of the points on average.
        rel = X[sample] - X.mean(axis=0)
        outward = float(np.einsum("ij,ij->i", n_patch, rel).mean())
        extent = float(np.ptp(X, axis=0).max())
        if abs(outward) > 1e-3 * extent:
            flip = outward < 0
        else:   # nearly flat: the normal's dominant world component positive
            mean_n = n_patch.mean(axis=0)
            flip = mean_n[np.argmax(np.abs(mean_n))] < 0
    return (patch.flipped(), True) if flip else (patch, False)
