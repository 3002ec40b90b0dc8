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
   smoothing lengths along u and v chosen by generalised cross-validation unless given.  Third
   derivatives leave constant curvature unpenalised, so curved parts and edges are not flattened.
   With "rows" the thesis's *skinning* comes first: each row is smoothed into a curve (all rows
   share one knot vector), then the curves' control points are smoothed across the rows — at
   that level a row's positioning error is one noisy sample, so cross-validation sets the
   across-row smoothing right; the final fit of all points keeps that smoothing across the rows.
4. **Correct the parameters**: project the points on the fitted patch and refit.

Refusals (with the reason and the fix in the message): too few points, points that do not form
one patch (separate pieces, a closed mesh), and a parameterisation that folds over.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import InfeasibleError, InputError
from .bspline import BSplinePatch, _span_samples, basis_derivatives, clamped_knots
from .geometry import normalize

log = logging.getLogger(__name__)

PARAMETERIZATIONS = ("auto", "projection", "lscm", "rows")

#: Exponent of the knot-spacing weights of the smoothness penalty (see :func:`_gram`): the local
#: smoothing length scales as ``(h / h̄)^(γ/6)`` with the knot span ``h``.
PENALTY_GAMMA = 6.0

#: Total turning (rad) of a direction below which curvature hardly moves the knots.
TURN_SIGNIFICANT = 0.2

#: Knot spans are at most this many times shorter than even spacing.
KNOT_CONCENTRATION = 4.0


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

    def to_dict(self) -> dict:
        """A JSON-ready copy (SI units)."""
        return {"rms_m": self.rms, "max_error_m": self.max_error, "n_points": self.n_points,
                "n_dropped": self.n_dropped, "n_ctrl": list(self.n_ctrl), "degree": list(self.degree),
                "knots_u": self.knots_u.tolist(), "knots_v": self.knots_v.tolist(),
                "parameterization": self.parameterization, "smoothing_m": list(self.smoothing),
                "time_s": self.time}


# ----------------------------------------------------------------------------------------------
# Public entry point
# ----------------------------------------------------------------------------------------------
def fit_patch(points, *, normals=None, mesh_faces=None, rows=None, parameterization: str = "auto",
              degree=3, n_ctrl=None, smoothing="gcv", knot_curvature_weight: float = 0.5,
              max_turn: float = 0.1, max_ctrl_spacing: float | None = None, knot_rounds: int = 2,
              reparam_rounds: int = 1) -> tuple[BSplinePatch, FitReport]:
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
        :func:`swath.surface.scansim.simulate_laser_scan`).  Enables ``"rows"`` (skinning).
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

    _check_spread(X)
    # One patch: no separate pieces (stray specks of < 1 % are dropped with a warning).
    n_dropped = 0
    if F is not None:
        _check_mesh_patch(len(X), F)
    else:
        keep = _main_piece(X)
        if not keep.all():
            n_dropped = int((~keep).sum())
            log.warning("fit_patch: dropping %d stray points that lie apart from the patch", n_dropped)
            X = X[keep]
            N_in = None if N_in is None else N_in[keep]
            R_ids = None if R_ids is None else R_ids[keep]
    opts = dict(p=p, q=q, n_ctrl=n_ctrl_req, smoothing=smoothing, qk=float(knot_curvature_weight),
                max_turn=float(max_turn), h_max=max_ctrl_spacing, knot_rounds=int(knot_rounds),
                reparam_rounds=int(reparam_rounds))

    method = parameterization
    if method == "auto" and R_ids is not None:
        method = "rows"
    if method in ("auto", "projection"):
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
    _, _, dist = patch.project(X, initial=(u, v))
    report = FitReport(rms=float(np.sqrt(np.mean(dist**2))), max_error=float(dist.max()), n_points=len(X),
                       n_dropped=n_dropped, n_ctrl=patch.shape, degree=patch.degree,
                       knots_u=np.array(patch.knots_u), knots_v=np.array(patch.knots_v),
                       parameterization=method, smoothing=lengths, time=time.perf_counter() - t_start)
    log.info("fit_patch: %s, %d points, control net %dx%d, rms %.3g m, max %.3g m, %.2f s", method, len(X),
             *patch.shape, report.rms, report.max_error, report.time)
    return patch, report


# ----------------------------------------------------------------------------------------------
# Input checks
# ----------------------------------------------------------------------------------------------
def _pair(value, name: str) -> tuple[int, int]:
    arr = np.broadcast_to(np.asarray(value), (2,)) if np.ndim(value) <= 1 else None
    if arr is None or arr.shape != (2,):
        raise InputError(f"{name} must be an int or a pair of ints, got {value!r}")
    try:
        a, b = (int(x) for x in arr)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be an int or a pair of ints, got {value!r}") from None
    if a != arr[0] or b != arr[1]:
        raise InputError(f"{name} must be integers, got {value!r}")
    return a, b


def _optional_array(a, shape, name, dtype):
    if a is None:
        return None
    arr = np.asarray(a)
    if arr.ndim != len(shape) or any(s is not None and s != d for s, d in zip(shape, arr.shape)):
        want = "(" + ", ".join("k" if s is None else str(s) for s in shape) + ")"
        raise InputError(f"expected {name} of shape {want}, got {arr.shape}")
    if dtype is int:
        if not np.issubdtype(arr.dtype, np.integer):
            if not (np.isfinite(arr).all() and np.all(np.mod(arr, 1) == 0)):
                raise InputError(f"{name} must be integers")
        return arr.astype(np.int64)
    arr = arr.astype(float)
    if not np.isfinite(arr).all():
        raise InputError(f"{name} contain NaN or infinite values")
    return arr


def _check_spread(X: np.ndarray) -> None:
    c = X.mean(axis=0)
    ev = np.linalg.eigvalsh(np.cov((X - c).T))
    if not ev[2] > 0:
        raise InputError("all points coincide; a surface cannot be fitted")
    if ev[1] <= 1e-8 * ev[2]:
        raise InputError("the points are (nearly) collinear; a surface patch needs points spread in two directions")


def _nn_scale(X: np.ndarray, tree=None, k: int = 8, sample: int = 5000, nearest_pct: float = 50.0):
    """A percentile (default the median) of the nearest-neighbour distance and the 95th
    percentile of the k-th neighbour distance, m (estimated on a sample of the points)."""
    from scipy.spatial import cKDTree

    tree = tree if tree is not None else cKDTree(X)
    rng = np.random.default_rng(0)
    idx = rng.choice(len(X), size=min(sample, len(X)), replace=False)
    d, _ = tree.query(X[idx], k=min(k + 1, len(X)))
    return float(np.percentile(d[:, 1], nearest_pct)), float(np.percentile(d[:, -1], 95))


def _main_piece(X: np.ndarray) -> np.ndarray:
    """Mask of the points in the largest connected piece; refuses several sizeable pieces.

    Connectivity: points are voxelised at three times the 95th-percentile 8th-neighbour distance
    and voxels touching (26-neighbourhood) are joined.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    _, d8 = _nn_scale(X)
    cell = 3.0 * max(d8, 1e-12)
    ijk = np.floor((X - X.min(axis=0)) / cell).astype(np.int64)
    dims = ijk.max(axis=0) + 3
    keys = ((ijk[:, 0] + 1) * dims[1] + (ijk[:, 1] + 1)) * dims[2] + (ijk[:, 2] + 1)
    vox, inv = np.unique(keys, return_inverse=True)
    inv = inv.ravel()
    src, dst = [], []
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            for dz in (-1, 0, 1):
                if (dx, dy, dz) <= (0, 0, 0):
                    continue
                nb = vox + (dx * dims[1] + dy) * dims[2] + dz
                pos = np.clip(np.searchsorted(vox, nb), 0, len(vox) - 1)
                hit = vox[pos] == nb
                src.append(np.nonzero(hit)[0])
                dst.append(pos[hit])
    src, dst = np.concatenate(src), np.concatenate(dst)
    graph = coo_matrix((np.ones(len(src)), (src, dst)), shape=(len(vox), len(vox)))
    n_comp, label = connected_components(graph, directed=False)
    if n_comp == 1:
        return np.ones(len(X), dtype=bool)
    sizes = np.bincount(label[inv], minlength=n_comp)
    order = np.argsort(-sizes)
    big = sizes >= max(0.01 * len(X), 10)
    if big.sum() > 1:
        shown = ", ".join(str(s) for s in sizes[order][:5])
        raise InfeasibleError(f"the points form {int(big.sum())} separate pieces (sizes {shown} points; gaps wider "
                              f"than {cell * 1e3:.3g} mm), not one patch; fit each piece separately")
    return label[inv] == order[0]


def _check_mesh_patch(n_vertices: int, F: np.ndarray) -> None:
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    from .topology import boundary_edges

    used = np.unique(F)
    if len(used) < n_vertices:
        raise InputError(f"{n_vertices - len(used)} points are not used by any face; pass only the mesh's "
                         "vertices with mesh_faces (or fit the points without faces)")
    e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    graph = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n_vertices, n_vertices))
    n_comp, label = connected_components(graph, directed=False)
    if n_comp > 1:
        sizes = np.sort(np.bincount(label))[::-1]
        raise InfeasibleError(f"the mesh has {n_comp} separate pieces (sizes {', '.join(map(str, sizes[:5]))} "
                              "vertices), not one patch; fit each piece separately")
    if len(boundary_edges(F)) == 0:
        raise InfeasibleError("the mesh is closed (no boundary), so one patch cannot cover it; cut it into "
                              "open patches first")


# ----------------------------------------------------------------------------------------------
# Parameterisations
# ----------------------------------------------------------------------------------------------
def _signed_areas(uv: np.ndarray, F: np.ndarray) -> np.ndarray:
    a, b, c = uv[F[:, 0]], uv[F[:, 1]], uv[F[:, 2]]
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))


def _flipped_triangles(uv: np.ndarray, F: np.ndarray) -> tuple[int, int]:
    """Count of triangles with negative and positive signed area in the parameter plane (area
    below 1e-9 of the mean is ignored)."""
    area = _signed_areas(uv, F)
    eps = 1e-9 * np.abs(area).mean()
    return int((area < -eps).sum()), int((area > eps).sum())


def _projection_parameters(X: np.ndarray, F):
    """Coordinates ``(n, 2)`` in the best-fit plane, and whether (and why) the projection folds."""
    from scipy.spatial import cKDTree

    c = X.mean(axis=0)
    _, vecs = np.linalg.eigh(np.cov((X - c).T))
    e1, e2 = vecs[:, 2], vecs[:, 1]
    uv = np.stack([(X - c) @ e1, (X - c) @ e2], axis=1)
    if F is not None:
        neg, pos = _flipped_triangles(uv, F)
        if pos < neg:                       # winding says the normal side is -e3: mirror v
            e2 = -e2
            uv[:, 1] *= -1
            neg, pos = pos, neg
        if neg > 0:
            return uv, True, f"{neg} of {len(F)} triangles flip over in the plane"
        return uv, False, ""
    # Without faces: points that are neighbours in the plane but far apart in space lie on
    # different layers of a fold.
    h, _ = _nn_scale(X)
    k = min(9, len(X))
    d2, idx = cKDTree(uv).query(uv, k=k)
    d3 = np.linalg.norm(X[idx] - X[:, None, :], axis=2)
    layered = np.any(d3 > 3.0 * d2 + 10.0 * h, axis=1)
    frac = layered.mean()
    if frac > 0.005:
        return uv, True, f"{100 * frac:.1f} % of the points lie over other points"
    return uv, False, ""


def _lscm_parameters(X: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Least-squares conformal map of the mesh, rotated to its principal axes and scaled so the
    parameter area equals the surface area (parameters in metres, roughly arc length)."""
    try:
        import igl
    except ImportError:  # pragma: no cover - libigl is a dependency
        raise InputError("the 'lscm' parameterisation needs libigl (pip install libigl)") from None
    from .geometry import face_normals_and_areas

    Fi = np.ascontiguousarray(F, dtype=np.int64)
    bnd = np.asarray(igl.boundary_loop(Fi), dtype=np.int64)
    a = bnd[np.argmax(np.linalg.norm(X[bnd] - X[bnd[0]], axis=1))]
    b = bnd[np.argmax(np.linalg.norm(X[bnd] - X[a], axis=1))]
    d = float(np.linalg.norm(X[a] - X[b]))
    res = igl.lscm(np.ascontiguousarray(X), Fi, np.array([a, b], dtype=np.int64),
                   np.array([[0.0, 0.0], [d, 0.0]]))
    uv = np.asarray(res[0] if isinstance(res, tuple) else res, dtype=float)
    if not np.isfinite(uv).all():
        raise InfeasibleError("the LSCM parameterisation failed (non-finite result); check the mesh for "
                              "degenerate or non-manifold triangles")
    uv = uv - uv.mean(axis=0)
    _, vecs = np.linalg.eigh(np.cov(uv.T))
    uv = uv @ vecs[:, ::-1]
    neg, pos = _flipped_triangles(uv, F)
    if pos < neg:
        uv[:, 1] *= -1
        neg, pos = pos, neg
    if neg > 0:
        raise InfeasibleError(f"the LSCM parameterisation folds over: {neg} of {len(F)} triangles are flipped in "
                              "the parameter plane; repair the mesh (fold-overs, spikes) or cut it into simpler "
                              "patches")
    _, area3 = face_normals_and_areas(X, F)
    area2 = np.abs(_signed_areas(uv, F)).sum()
    return uv * np.sqrt(area3.sum() / area2)


# ----------------------------------------------------------------------------------------------
# Penalised least squares
# ----------------------------------------------------------------------------------------------
def _gram(knots: np.ndarray, degree: int, order: int) -> np.ndarray:
    """Weighted Gram matrix ``∫ w(t) N_i^(order)(t) N_j^(order)(t) dt`` ``(n, n)`` of a B-spline basis.

    Exact (Gauss–Legendre, three points per knot span).  The weight is constant on each span,
    ``w = (h / h̄)^γ`` with ``h`` the span, ``h̄`` the mean span and γ = :data:`PENALTY_GAMMA`: where
    :func:`curvature_knots` packed the knots densely (high curvature) the penalty relaxes, so the
    fit follows tight bends such as a leading edge while staying smooth elsewhere.
    """
    t = np.asarray(knots, float)
    n = len(t) - degree - 1
    if order > degree:
        return np.zeros((n, n))
    breaks = np.unique(t[degree:n + 1])
    h = np.diff(breaks)
    hbar = (breaks[-1] - breaks[0]) / (n - degree)
    w = (h / hbar) ** PENALTY_GAMMA
    gx, gw = np.polynomial.legendre.leggauss(3)
    x = (0.5 * (breaks[:-1, None] + breaks[1:, None]) + 0.5 * h[:, None] * gx[None, :]).ravel()
    weight = (0.5 * h[:, None] * gw[None, :] * w[:, None]).ravel()
    span, N = basis_derivatives(t, degree, x, order)
    cols = span[:, None] - degree + np.arange(degree + 1)
    vals = N[order]
    idx = cols[:, :, None] * n + cols[:, None, :]
    G = np.bincount(idx.ravel(), weights=(weight[:, None, None] * vals[:, :, None] * vals[:, None, :]).ravel(),
                    minlength=n * n)
    return G.reshape(n, n)


def _spd_solve(A: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve ``A x = rhs`` for a symmetric positive-definite ``A`` ``(n, n)`` (Cholesky)."""
    from scipy.linalg import cho_factor, cho_solve

    return cho_solve(cho_factor(A), rhs)


def _lambda_grid(h_min: float, L: float) -> np.ndarray:
    """Candidate smoothing lengths, m, log-spaced over a generous range."""
    return np.geomspace(max(h_min, 1e-9) / 20.0, max(L, h_min) * 20.0, 90)


def _smooth_columns(G: np.ndarray, rhs: np.ndarray, yty: np.ndarray, P: np.ndarray, n_obs: int, smoothing,
                    ell_grid: np.ndarray, *, pool: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Minimise ``|B c − y|² + ℓ⁶ cᵀ P c`` for every column of ``y`` (skinning, stage 2).

    ``G = BᵀB`` ``(n, n)``, ``rhs = Bᵀy`` ``(n, m)``, ``yty = Σ y²`` per column ``(m,)``; the columns
    come in threes (a control point's x, y, z).  With ``smoothing == "gcv"`` the length ``ℓ`` of
    every such group minimises the generalised cross-validation score
    ``n_obs · RSS / (n_obs − edf)²`` over ``ell_grid``, the RSS pooled over the ``pool`` groups on
    either side; one simultaneous diagonalisation of ``G`` and ``P`` serves every length.
    Returns ``(c (n, m), ℓ (m,))``.
    """
    from scipy.linalg import eigh, solve_triangular
    from scipy.ndimage import uniform_filter1d

    n, m = rhs.shape
    ridge = 1e-11 * max(np.trace(G), np.trace(P), 1e-300) / n * np.eye(n)
    if not isinstance(smoothing, str):
        ell = float(smoothing)
        return _spd_solve(G + ell**6 * P + ridge, rhs), np.full(m, ell)
    # X^T (G + P) X = I, X^T G X = diag(mu), X^T P X = diag(1 - mu).
    Lc = np.linalg.cholesky(G + P + ridge)
    M = solve_triangular(Lc, solve_triangular(Lc, G, lower=True).T, lower=True)
    mu, Q = eigh(0.5 * (M + M.T))
    mu = np.clip(mu, 0.0, 1.0)
    Xm = solve_triangular(Lc.T, Q, lower=False)
    z = Xm.T @ rhs                                                    # (n, m)
    d = 1.0 / (mu[None, :] + ell_grid[:, None] ** 6 * (1.0 - mu[None, :]) + 1e-300)     # (g, n)
    edf = (mu[None, :] * d).sum(axis=1)                               # (g,)
    rss = yty[None, :] - (2 * d - mu[None, :] * d * d) @ (z * z)      # (g, m)
    rss = rss.reshape(len(ell_grid), m // 3, 3).sum(axis=2)
    pooled = uniform_filter1d(rss, size=2 * pool + 1, axis=1, mode="nearest")
    gcv = n_obs * np.maximum(pooled, 0.0) / np.maximum(n_obs - edf, 1e-9)[:, None] ** 2
    gcv[edf >= n_obs - 1] = np.inf
    ell = np.repeat(ell_grid[np.argmin(gcv, axis=0)], 3)
    dcol = 1.0 / (mu[:, None] + ell[None, :] ** 6 * (1.0 - mu[:, None]) + 1e-300)   # (n, m)
    return Xm @ (dcol * z), ell


def _design_2d(u, v, ku, kv, p, q, nu, nv):
    """Sparse design matrix ``(k, nu·nv)`` of the tensor-product basis (flat index ``i·nv + j``)."""
    from scipy.sparse import csr_matrix

    su, Nu = basis_derivatives(ku, p, u, 0)
    sv, Nv = basis_derivatives(kv, q, v, 0)
    iu = su[:, None] - p + np.arange(p + 1)
    iv = sv[:, None] - q + np.arange(q + 1)
    cols = (iu[:, :, None] * nv + iv[:, None, :]).reshape(len(u), -1)
    vals = (Nu[0][:, :, None] * Nv[0][:, None, :]).reshape(len(u), -1)
    k = cols.shape[1]
    return csr_matrix((vals.ravel(), cols.ravel(), np.arange(0, len(u) * k + 1, k)), shape=(len(u), nu * nv))


def _design_1d(x, knots, p, n) -> np.ndarray:
    """Dense design matrix ``(k, n)`` of a B-spline basis."""
    span, Nb = basis_derivatives(knots, p, x, 0)
    B = np.zeros((len(x), n))
    np.put_along_axis(B, span[:, None] - p + np.arange(p + 1), Nb[0], axis=1)
    return B


def _penalty_2d(ku: np.ndarray, kv: np.ndarray, p: int, q: int, density: float) -> list[np.ndarray]:
    """Third-order thin-plate energy ``∫∫ w (|S_uuu|² + 3|S_uuv|² + 3|S_uvv|² + |S_vvv|²) du dv`` as
    quadratic forms in the control points, one per term: ``[T_0, T_1, T_2, T_3]`` with ``T_k`` the
    term with ``k`` derivatives in u, each ``(nu·nv, nu·nv)``.

    With smoothing lengths ``ℓ_u, ℓ_v`` the penalty is ``Σ_k ℓ_u^(2k) ℓ_v^(2(3−k)) T_k`` (for one
    length ``ℓ⁶ Σ T_k``), scaled so that features shorter than about ``ℓ`` metres are damped
    (``density`` = points per m² of parameter domain).  Third derivatives leave quadratic shapes
    (constant curvature) unpenalised, so the penalty neither flattens curved regions nor pulls
    the patch's edges toward zero curvature.  The weight ``w`` relaxes it where knots are dense
    (see :func:`_gram`).  Degrees are at least 3."""
    Gu = [_gram(ku, p, k) for k in range(4)]
    Gv = [_gram(kv, q, k) for k in range(4)]
    scale = density / (2 * np.pi) ** 6
    return [math.comb(3, k) * scale * np.kron(Gu[k], Gv[3 - k]) for k in range(4)]


def _combine(parts: list[np.ndarray], ell_u: float, ell_v: float) -> np.ndarray:
    return sum(ell_u ** (2 * k) * ell_v ** (2 * (3 - k)) * T for k, T in enumerate(parts))


def _penalty_1d(knots: np.ndarray, p: int, density: float) -> np.ndarray:
    """Third-derivative energy of a curve, weighted as in :func:`_gram` (``density`` = points
    per m), scaled like :func:`_penalty_2d`."""
    return _gram(knots, p, 3) * density / (2 * np.pi) ** 6


# ----------------------------------------------------------------------------------------------
# Knots
# ----------------------------------------------------------------------------------------------
def curvature_knots(s: np.ndarray, kappa2: np.ndarray, n_spans: int, *, q: float = 0.5,
                    min_span: float = 0.0, kappa_abs: np.ndarray | None = None,
                    max_turn: float | None = None) -> np.ndarray:
    """Interior knots placed by the curvature-based distribution ``R(s) = q·b(s)/B + (1−q)·s/L``.

    ``b(s) = ∫₀ˢ κ²``, ``B = b(L)``; the knots are ``R⁻¹(i / n_spans)``.  ``R'(s)`` is the knot
    density; two optional bounds keep it practical: it is capped where it would space knots
    closer than ``min_span``, and raised where a span would turn by more than ``max_turn``
    (``|κ| / (n·max_turn)``); the difference is taken from (or given to) the rest in proportion, so
    ``R`` keeps the thesis's shape wherever no bound is active.

    Parameters
    ----------
    s : (m,) float
        Increasing positions along the curve (arc length, or a parameter proportional to it), m.
    kappa2 : (m,) float
        Squared curvature at ``s``, 1/m².
    n_spans : int
        Number of knot spans wanted.
    q : float
        Weight of curvature (0 = even spacing).
    min_span : float
        Smallest span wanted, m.
    kappa_abs : (m,) float, optional
        ``|κ|`` at ``s`` (1/m), with ``max_turn`` (rad): the largest turning wanted per span.

    Returns
    -------
    (n_spans − 1,) float
        Interior knots.
    """
    s = np.asarray(s, float)
    kappa2 = np.asarray(kappa2, float)
    if s.ndim != 1 or len(s) < 2 or kappa2.shape != s.shape:
        raise InputError(f"expected s and kappa2 of the same shape (m >= 2,), got {s.shape} and {kappa2.shape}")
    if not (np.all(np.diff(s) > 0) and np.isfinite(kappa2).all() and (kappa2 >= 0).all()):
        raise InputError("s must increase strictly and kappa2 be finite and non-negative")
    n_spans = int(n_spans)
    if n_spans < 1:
        raise InputError(f"n_spans must be at least 1, got {n_spans}")
    L = s[-1] - s[0]
    ds = np.diff(s)
    B = _trapz(kappa2, ds)
    dens = (q * kappa2 / B if B > 0 else 0.0) + (1 - q) / L
    cap = 1.0 / (n_spans * min_span) if min_span > 0 else np.inf
    if cap * L < 1.0:
        cap = 1.0 / L
    floor = np.zeros_like(s)
    if kappa_abs is not None and max_turn:
        floor = np.minimum(np.asarray(kappa_abs, float) / (n_spans * max_turn), cap)
    for _ in range(200):
        d = np.clip(dens, floor, cap)
        mass = _trapz(d, ds)
        free = (dens > floor) & (dens < cap)
        if abs(mass - 1.0) < 1e-9 or not free.any():
            break
        fixed = _trapz(np.where(free, 0.0, d), ds)
        loose = _trapz(np.where(free, d, 0.0), ds)
        if loose <= 0 or fixed >= 1.0:
            break
        dens = np.where(free, d * (1.0 - fixed) / loose, d)
    dens = np.clip(dens, floor, cap)
    R = np.concatenate([[0.0], np.cumsum(0.5 * (dens[1:] + dens[:-1]) * ds)])
    R /= R[-1]
    return np.interp(np.arange(1, n_spans) / n_spans, R, s)


def _trapz(f, ds):
    return float(np.sum(0.5 * (f[1:] + f[:-1]) * ds))


def _profile(patch: BSplinePatch, direction: int, n_other: int = 12):
    """Along ``direction`` (0 = u, 1 = v): parameters ``(m,)``, mean speed ``|S_d|``, mean squared
    and mean absolute normal curvature of the iso-curves (averaged over the other direction)."""
    ta = _span_samples(patch.knots_u if direction == 0 else patch.knots_v, patch.degree[direction], 8, cap=3000)
    (u0, u1), (v0, v1) = patch.domain
    other = np.linspace(*((v0, v1) if direction == 0 else (u0, u1)), n_other + 2)[1:-1]
    A, O = np.meshgrid(ta, other, indexing="ij")
    u, v = (A, O) if direction == 0 else (O, A)
    D = patch.derivatives(u.ravel(), v.ravel(), 2)
    Sd = D[:, 1, 0] if direction == 0 else D[:, 0, 1]
    Sdd = D[:, 2, 0] if direction == 0 else D[:, 0, 2]
    n = normalize(np.cross(D[:, 1, 0], D[:, 0, 1]))
    speed2 = np.einsum("ij,ij->i", Sd, Sd)
    kappa = np.einsum("ij,ij->i", n, Sdd) / np.maximum(speed2, 1e-300)
    shape = A.shape
    k2 = (kappa**2).reshape(shape).mean(1)
    kabs = np.abs(kappa).reshape(shape).mean(1)
    # The first and last knot spans of a fit are the least certain (data on one side only): hold
    # the curvature there at its value one span inside, so edge noise does not attract knots.
    knots = patch.knots_u if direction == 0 else patch.knots_v
    breaks = np.unique(knots)
    if len(breaks) >= 4:
        lo, hi = breaks[1], breaks[-2]
        for arr in (k2, kabs):
            arr[ta < lo] = np.interp(lo, ta, arr)
            arr[ta > hi] = np.interp(hi, ta, arr)
    return ta, np.sqrt(speed2).reshape(shape).mean(1), k2, kabs


def _spans_for(L: float, turning: float, max_turn: float, h_max: float, cap: int) -> int:
    return int(np.clip(math.ceil(L / h_max) + math.ceil(turning / max_turn), 1, max(cap, 1)))


def _knots_from_patch(patch: BSplinePatch, direction: int, n_spans_req, degree: int, opts, cap: int,
                      min_span: float, domain) -> np.ndarray:
    """Knot vector along ``direction`` from the curvature of ``patch`` (a pilot fit)."""
    t, speed, k2, kabs = _profile(patch, direction)
    s = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(t))])
    L = s[-1]
    turning = _trapz(kabs, np.diff(s))
    if n_spans_req is None:
        h_max = opts["h_max"] if opts["h_max"] is not None else min(0.05, L / 4)
        n_spans = _spans_for(L, turning, opts["max_turn"], h_max, cap)
        n_spans = max(1, min(n_spans, int(L / max(min_span, 1e-12))))
    else:
        n_spans = n_spans_req
    # Knot spans at least min_span and at most KNOT_CONCENTRATION times denser than even spacing.
    # A direction that hardly turns (total turning well below TURN_SIGNIFICANT) keeps nearly even
    # knots, so noise in a flat direction does not attract knots.
    min_span = max(min_span, L / (KNOT_CONCENTRATION * n_spans))
    q_eff = opts["qk"] * turning**2 / (turning**2 + TURN_SIGNIFICANT**2)
    interior_s = curvature_knots(s, k2, n_spans, q=q_eff, min_span=min_span, kappa_abs=kabs,
                                 max_turn=opts["max_turn"])
    interior = np.interp(interior_s, s, t)
    return clamped_knots(interior, degree, domain)


def _uniform_knots(n_spans: int, degree: int, domain) -> np.ndarray:
    return clamped_knots(np.linspace(domain[0], domain[1], n_spans + 1)[1:-1], degree, domain)


# ----------------------------------------------------------------------------------------------
# Global fit (projection / LSCM parameters)
# ----------------------------------------------------------------------------------------------
def _fit_global(X, uv, *, p, q, n_ctrl, smoothing, qk, max_turn, h_max, knot_rounds, reparam_rounds):
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
    for r in range(max(knot_rounds, 0) + 1):
        if r > 0:
            ku = _knots_from_patch(patch, 0, req_u, p, opts, cap_u, min_span, dom_u)
            kv = _knots_from_patch(patch, 1, req_v, q, opts, cap_v, min_span, dom_v)
        if r == max(knot_rounds, 0):
            break
        span_u, span_v = Lu / (len(ku) - 2 * p - 1), Lv / (len(kv) - 2 * q - 1)
        patch, _ = _aniso_step(X, u, v, ku, kv, p, q, "fixed", grid_u, grid_v, span_u, span_v)
    # Final fit: smoothing along u and v by GCV (or as given), then parameter correction.
    ells = (None, None)
    for r in range(max(reparam_rounds, 0) + 1):
        if r > 0:
            u, v, _ = patch.project(X, initial=(u, v), tol=1e-9)
        patch, ells = _aniso_step(X, u, v, ku, kv, p, q, smoothing, grid_u, grid_v, *ells)
    return patch, ells, u, v


# ----------------------------------------------------------------------------------------------
# Skinning along scan rows
# ----------------------------------------------------------------------------------------------
def _row_structure(X: np.ndarray, rows: np.ndarray, p: int, q: int):
    """Group points by row (rows sorted by id, points in input order), orient every row like the
    first, and parameterise: normalised smoothed arc length along each row (scaled to the mean row
    length) and cumulative distance between rows across."""
    from scipy.ndimage import uniform_filter1d

    order = np.argsort(rows, kind="stable")
    ids, starts, counts = np.unique(rows[order], return_index=True, return_counts=True)
    if len(ids) < q + 3:
        raise InputError(f"skinning needs at least {q + 3} scan rows, got {len(ids)}")
    if counts.min() < p + 3:
        raise InputError(f"scan row {ids[np.argmin(counts)]} has only {counts.min()} points; every row needs at "
                         f"least {p + 3} (drop short rows)")
    order = order.copy()
    # Scan order: consecutive points of a row are neighbours (a jump of 20 typical steps is not).
    step = np.linalg.norm(np.diff(X[order], axis=0), axis=1)
    same_row = np.diff(rows[order]) == 0
    typical = float(np.median(step[same_row])) if same_row.any() else 0.0
    t = np.empty(len(X))
    lengths = np.empty(len(ids))
    prev_first = prev_last = None
    for r, (a, n) in enumerate(zip(starts, counts)):
        idx = order[a:a + n].copy()
        P = X[idx]
        if prev_first is not None:
            # Bidirectional scans: run every row the same way as the previous one.
            same = np.linalg.norm(P[0] - prev_first) + np.linalg.norm(P[-1] - prev_last)
            swap = np.linalg.norm(P[-1] - prev_first) + np.linalg.norm(P[0] - prev_last)
            if swap < same:
                idx = idx[::-1].copy()
                order[a:a + n] = idx
                P = X[idx]
        prev_first, prev_last = P[0], P[-1]
        raw = np.linalg.norm(np.diff(P, axis=0), axis=1)
        if raw.max() > 20 * max(typical, 1e-12):
            raise InputError(f"scan row {ids[r]} jumps by {raw.max() * 1e3:.3g} mm between consecutive points "
                             f"(typical step {typical * 1e3:.3g} mm); rows must hold their points in scan "
                             "order without gaps")
        Ps = uniform_filter1d(P, size=min(5, n), axis=0, mode="nearest")
        seg = np.linalg.norm(np.diff(Ps, axis=0), axis=1)
        s = np.concatenate([[0.0], np.cumsum(seg)])
        lengths[r] = s[-1]
        t[idx] = s / max(s[-1], 1e-300)
    Lbar = float(lengths.mean())
    row_of = np.empty(len(X), dtype=np.int64)
    for r, (a, n) in enumerate(zip(starts, counts)):
        row_of[order[a:a + n]] = r
    # Across: every row resampled at common normalised positions; the rows' positioning errors
    # are smoothed out of this stack (a wide moving average over rows) before measuring the
    # distances between consecutive rows, so they do not accumulate into v.
    grid = np.linspace(0, 1, 64)
    Q = np.empty((len(ids), 64, 3))
    for r, (a, n) in enumerate(zip(starts, counts)):
        idx = order[a:a + n]
        for c in range(3):
            Q[r, :, c] = np.interp(grid, t[idx], X[idx, c])
    width = int(min(len(ids), max(9, len(ids) // 8)))
    Qs = uniform_filter1d(Q, size=width, axis=0, mode="nearest")
    # Near the ends the one-sided average lags: extrapolate from the inner rows linearly.
    half = width // 2
    if len(ids) > 2 * half + 2 and half > 0:
        lo_slope = (Qs[half + 1] - Qs[half])
        hi_slope = (Qs[-half - 1] - Qs[-half - 2])
        Qs[:half] = Qs[half] - lo_slope * np.arange(half, 0, -1)[:, None, None]
        Qs[-half:] = Qs[-half - 1] + hi_slope * np.arange(1, half + 1)[:, None, None]
    gaps = np.linalg.norm(np.diff(Qs, axis=0), axis=2).mean(axis=1)
    v_rows = np.concatenate([[0.0], np.cumsum(gaps)])
    return t * Lbar, row_of, v_rows, Lbar, order


def _row_fit(u, row_of, X, n_rows, ku, p, ell, density):
    """Stage 1 of skinning: every row smoothed into a curve on the common knot vector ``ku`` with
    smoothing length ``ell`` (m).  Returns the control points ``(R, n, 3)``."""
    n = len(ku) - p - 1
    span, Nb = basis_derivatives(ku, p, u, 0)
    cols = span[:, None] - p + np.arange(p + 1)
    vals = Nb[0]
    ii = (row_of[:, None, None] * n + cols[:, :, None]) * n + cols[:, None, :]
    G = np.bincount(ii.ravel(), weights=(vals[:, :, None] * vals[:, None, :]).ravel(),
                    minlength=n_rows * n * n).reshape(n_rows, n, n)
    jj = (row_of[:, None] * n + cols).ravel()
    rhs = np.stack([np.bincount(jj, weights=(vals * X[:, c, None]).ravel(), minlength=n_rows * n)
                    for c in range(3)], axis=-1).reshape(n_rows, n, 3)
    P = _penalty_1d(ku, p, density)
    scale = np.trace(G, axis1=1, axis2=2).mean() / n
    A = G + ell**6 * P + 1e-9 * max(scale, 1e-300) * np.eye(n)
    try:
        return np.linalg.solve(A, rhs)
    except np.linalg.LinAlgError:
        raise InfeasibleError("a scan row has too few points for the knot vector; give fewer control "
                              "points or more smoothing") from None


def _fit_rows(X, rows, *, p, q, n_ctrl, smoothing, qk, max_turn, h_max, knot_rounds, reparam_rounds):
    """Skinning (Jaeger §3.2.2): rows smoothed into curves on one knot vector, their control points
    smoothed across the rows; then one penalised fit of all points with the across-row smoothing
    found at row level.  Returns ``(patch, (ℓ_u, ℓ_v), u, v)``."""
    u, row_of, v_rows, Lbar, _ = _row_structure(X, rows, p, q)
    R = len(v_rows)
    Lv = float(v_rows[-1])
    dom_u, dom_v = (0.0, Lbar), (0.0, Lv)
    pts_per_row = len(X) / R
    h_along = Lbar / pts_per_row
    h_across = Lv / max(R - 1, 1)
    cap_u = max(1, min(150, int(pts_per_row / 3)))
    cap_v = max(1, min(150, (R - 1) // 3))
    opts = dict(qk=qk, max_turn=max_turn, h_max=h_max)
    req_u = None if n_ctrl is None else n_ctrl[0] - p
    req_v = None if n_ctrl is None else n_ctrl[1] - q
    hmu = h_max if h_max is not None else min(0.05, Lbar / 4)
    hmv = h_max if h_max is not None else min(0.05, Lv / 4)
    nsu = req_u if req_u is not None else min(cap_u, math.ceil(Lbar / hmu) + 4)
    nsv = req_v if req_v is not None else min(cap_v, math.ceil(Lv / hmv) + 4)
    ku, kv = _uniform_knots(nsu, p, dom_u), _uniform_knots(nsv, q, dom_v)
    v = v_rows[row_of]
    grid_u = _lambda_grid(h_along, Lbar)
    grid_v = _lambda_grid(h_across, Lv)
    fixed = not isinstance(smoothing, str)

    def skin(u, ku, kv):
        # Stage 1: each row on its own, smoothed at the scale of the knot spans (or as asked).
        ell_u = float(smoothing) if fixed else (ku[-1] - ku[0]) / (len(ku) - 2 * p - 1)
        coef = _row_fit(u, row_of, X, R, ku, p, ell_u, pts_per_row / Lbar)
        # Stage 2: the rows' control points smoothed across the rows, the smoothing chosen by GCV
        # per control column (row-to-row positioning errors are the noise at this level).
        nv = len(kv) - q - 1
        nu = coef.shape[1]
        Bv = _design_1d(v_rows, kv, q, nv)
        Y = coef.reshape(R, nu * 3)
        P = _penalty_1d(kv, q, R / Lv)
        net, ell_v = _smooth_columns(Bv.T @ Bv, Bv.T @ Y, (Y * Y).sum(axis=0), P, R, smoothing, grid_v)
        net = net.reshape(nv, nu, 3).transpose(1, 0, 2)
        return BSplinePatch(net, ku, kv, (p, q)), (ell_u, float(np.median(ell_v)))

    patch, ells = skin(u, ku, kv)
    for _ in range(max(knot_rounds, 0)):
        ku = _knots_from_patch(patch, 0, req_u, p, opts, cap_u, 2 * h_along, dom_u)
        kv = _knots_from_patch(patch, 1, req_v, q, opts, cap_v, 2.5 * h_across, dom_v)
        patch, ells = skin(u, ku, kv)
    # Final fit of all points at once (every knot span then holds points of many rows, which keeps
    # tight, densely knotted bends well conditioned): across the rows the smoothing found by
    # skinning, along the rows by GCV; parameters along the rows from projection on the current
    # patch (consistent from row to row).
    ells = (None, ells[1])
    for _ in range(max(reparam_rounds, 0) + 1):
        u = patch.project(X, initial=(u, v), tol=1e-9)[0]
        patch, ells = _aniso_step(X, u, v, ku, kv, p, q, smoothing, grid_u, grid_v, *ells)
    return patch, ells, u, v


def _aniso_step(X, u, v, ku, kv, p, q, smoothing, grid_u, grid_v, ell_u=None, ell_v=None):
    """Penalised fit with separate smoothing lengths along u and v.

    Lengths given as None are chosen by GCV (golden-section search on a log scale); a numeric
    ``smoothing`` fixes both; ``"fixed"`` uses the given ones.  Returns ``(patch, (ell_u, ell_v))``.
    """
    from scipy.linalg import LinAlgError, cho_factor, cho_solve

    nu, nv = len(ku) - p - 1, len(kv) - q - 1
    B = _design_2d(u, v, ku, kv, p, q, nu, nv)
    G = (B.T @ B).toarray()
    rhs = B.T @ X
    yty = float((X * X).sum())
    Lu, Lv = ku[-1] - ku[0], kv[-1] - kv[0]
    parts = _penalty_2d(ku, kv, p, q, len(X) / (Lu * Lv))
    ridge = 1e-11 * max(np.trace(G), 1e-300) / len(G) * np.eye(len(G))
    N = len(X)
    # Fixed Rademacher probes for a Hutchinson estimate of the effective degrees of freedom: GCV
    # depends on them only through (1 − edf/N)², so a rough estimate is plenty.
    probes = np.random.default_rng(0).choice([-1.0, 1.0], size=(len(G), 8))
    Gz = G @ probes

    def solve(lu, lv, score):
        A = G + _combine(parts, lu, lv) + ridge
        try:
            cho = cho_factor(A)
        except LinAlgError:
            raise InfeasibleError("the fit is under-determined (too few points spread over the patch for the "
                                  "control net); give fewer control points (n_ctrl) or some smoothing") from None
        c = cho_solve(cho, rhs)
        if not score:
            return c
        rss = max(yty - 2 * float((c * rhs).sum()) + float((c * (G @ c)).sum()), 0.0)
        edf = float((probes * cho_solve(cho, Gz)).sum() / probes.shape[1])
        return N * rss / max(N - edf, 1e-9) ** 2

    def golden(f, lo, hi, iters=14):
        a, b = math.log(lo), math.log(hi)
        g = (math.sqrt(5) - 1) / 2
        c1, c2 = b - g * (b - a), a + g * (b - a)
        f1, f2 = f(math.exp(c1)), f(math.exp(c2))
        for _ in range(iters):
            if f1 <= f2:
                b, c2, f2 = c2, c1, f1
                c1 = b - g * (b - a)
                f1 = f(math.exp(c1))
            else:
                a, c1, f1 = c1, c2, f2
                c2 = a + g * (b - a)
                f2 = f(math.exp(c2))
        return math.exp(c1 if f1 <= f2 else c2)

    if smoothing == "fixed":
        pass
    elif not isinstance(smoothing, str):
        ell_u = ell_v = float(smoothing)
    elif ell_u is None and ell_v is None:
        # One length for both first, then each direction within a factor 30 of it.
        lo, hi = min(grid_u[0], grid_v[0]), max(grid_u[-1], grid_v[-1])
        ell = golden(lambda e: solve(e, e, True), lo, hi, 12)
        ell_u = golden(lambda e: solve(e, ell, True), max(lo, ell / 30), min(hi, ell * 30), 8)
        ell_v = golden(lambda e: solve(ell_u, e, True), max(lo, ell / 30), min(hi, ell * 30), 8)
    elif ell_u is None:
        ell_u = golden(lambda e: solve(e, ell_v, True), grid_u[0], grid_u[-1], 12)
    elif ell_v is None:
        ell_v = golden(lambda e: solve(ell_u, e, True), grid_v[0], grid_v[-1], 12)
    c = solve(ell_u, ell_v, False)
    return BSplinePatch(c.reshape(nu, nv, 3), ku, kv, (p, q)), (float(ell_u), float(ell_v))


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
        from .geometry import face_normals_and_areas, vertex_normals

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
