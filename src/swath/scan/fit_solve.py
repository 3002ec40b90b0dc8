"""Penalised least squares of :func:`swath.scan.fit.fit_patch`: design matrices, the
third-order thin-plate penalty, and the smoothing lengths chosen by generalised cross-validation."""

from __future__ import annotations

import math

import numpy as np

from ..errors import InfeasibleError
from ..surface.bspline import BSplinePatch
from ..surface.bspline_basis import basis_derivatives

#: Exponent of the knot-spacing weights of the smoothness penalty (see :func:`_gram`): the local
#: smoothing length scales as ``(h / h̄)^(γ/6)`` with the knot span ``h``.
PENALTY_GAMMA = 6.0

#: Bisection steps of the one-standard-error rule that lengthens a GCV smoothing length
#: (see ``smoothest`` in :func:`_aniso_step`).
ONE_SE_STEPS = 8



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
        fixed = float(smoothing)
        return _spd_solve(G + fixed**6 * P + ridge, rhs), np.full(m, fixed)
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
    term with ``k`` derivatives in u, each a sparse ``(nu·nv, nu·nv)`` matrix.

    With smoothing lengths ``ℓ_u, ℓ_v`` the penalty is ``Σ_k ℓ_u^(2k) ℓ_v^(2(3−k)) T_k`` (for one
    length ``ℓ⁶ Σ T_k``), scaled so that features shorter than about ``ℓ`` metres are damped
    (``density`` = points per m² of parameter domain).  Third derivatives leave quadratic shapes
    (constant curvature) unpenalised, so the penalty neither flattens curved regions nor pulls
    the patch's edges toward zero curvature.  The weight ``w`` relaxes it where knots are dense
    (see :func:`_gram`).  Degrees are at least 3."""
    Gu = [_gram(ku, p, k) for k in range(4)]
    Gv = [_gram(kv, q, k) for k in range(4)]
    scale = density / (2 * np.pi) ** 6
    from scipy.sparse import csr_matrix, kron

    return [(math.comb(3, k) * scale * kron(csr_matrix(Gu[k]), csr_matrix(Gv[3 - k]))).tocsr() for k in range(4)]


def _penalty_1d(knots: np.ndarray, p: int, density: float) -> np.ndarray:
    """Third-derivative energy of a curve, weighted as in :func:`_gram` (``density`` = points
    per m), scaled like :func:`_penalty_2d`."""
    return _gram(knots, p, 3) * density / (2 * np.pi) ** 6


def _gcv_progress(say, round_: int):
    """``progress(done, total)`` of one penalised fit, as a fit stage."""
    stage = ("fit: choosing the smoothing by cross-validation" if round_ == 0 else
             f"fit: refitting after parameter correction {round_}")
    return lambda done, total: say(stage, done, total)


def _aniso_step(X, u, v, ku, kv, p, q, smoothing, grid_u, grid_v, ell_u=None, ell_v=None, *, progress=None,
                one_se: bool = False):
    """Penalised fit with separate smoothing lengths along u and v.

    Lengths given as None are chosen by GCV (golden-section search on a log scale); a numeric
    ``smoothing`` fixes both; ``"fixed"`` uses the given ones.  Returns ``(patch, (ell_u, ell_v))``.
    ``progress(done, total)`` is called after every solve (each smoothing length tried, and the last).
    With ``one_se`` every length chosen by GCV is then lengthened by the one-standard-error rule
    (``smoothest`` below): for fits whose points carry errors correlated along scan rows that the
    fit does not know about (projection or LSCM parameters); along known rows the errors are
    independent and GCV's own minimum is kept.

    The normal equations are banded: control point ``(i, j)`` couples only to ``|Δi| ≤ p,
    |Δj| ≤ q`` (in the data term and in every penalty term), so with the unknowns ordered along
    the shorter direction first the half-bandwidth is ``degree · (shorter side) + degree`` and one
    banded Cholesky factorisation costs ``O(n b²)`` time and ``O(n b)`` memory (``n = nu·nv``),
    not the ``O(n³)`` and ``O(n²)`` of a dense one.
    """
    nu, nv = len(ku) - p - 1, len(kv) - q - 1
    B = _design_2d(u, v, ku, kv, p, q, nu, nv)
    G = (B.T @ B).tocsr()
    rhs = np.asarray(B.T @ X)
    yty = float((X * X).sum())
    Lu, Lv = ku[-1] - ku[0], kv[-1] - kv[0]
    parts = _penalty_2d(ku, kv, p, q, len(X) / (Lu * Lv))
    system = _BandedSystem(G, parts, nu, nv, p, q)
    N = len(X)
    # Fixed Rademacher probes for a Hutchinson estimate of the effective degrees of freedom: GCV
    # depends on them only through (1 − edf/N)², so a rough estimate is plenty.
    probes = np.random.default_rng(0).choice([-1.0, 1.0], size=(nu * nv, 8))
    Gz = G @ probes
    both = np.concatenate([rhs, Gz], axis=1)

    if smoothing == "fixed" or not isinstance(smoothing, str) or (ell_u is not None and ell_v is not None):
        total = 1
    elif ell_u is None and ell_v is None:
        total = (12 + 2) + 2 * (8 + 2 + one_se * (ONE_SE_STEPS + 1)) + 1
    else:
        total = 12 + 2 + one_se * (ONE_SE_STEPS + 1) + 1
    done = [0]
    say = progress or (lambda done, total: None)
    say(0, total)

    def solve(lu, lv, score):
        done[0] += 1
        say(min(done[0], total), total)
        if not score:
            return system.solve(lu, lv, rhs)
        sol = system.solve(lu, lv, both)
        c, w = sol[:, :3], sol[:, 3:]
        rss = max(yty - 2 * float((c * rhs).sum()) + float((c * (G @ c)).sum()), 0.0)
        edf = float((probes * w).sum() / probes.shape[1])
        edfs[(lu, lv)] = edf
        return N * rss / max(N - edf, 1e-9) ** 2

    edfs: dict = {}

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

    def smoothest(f, key, best, hi):
        """The one-standard-error rule (Hastie, Tibshirani & Friedman, *Elements of Statistical
        Learning* §7.10) on the GCV score: the longest smoothing length in ``[best, hi]`` whose
        score exceeds the minimum by at most its relative standard error ``√(2 / (N − edf))`` (a
        residual sum of squares is χ² with that many degrees of freedom).  The GCV curve of a
        scan is flat near its minimum, and scan errors that are correlated along the rows (a
        row's positioning offset) pull the minimum toward fitting them; of the lengths the data
        cannot tell apart, this takes the smoothest.  (Counting only the independent errors,
        from the correlation of neighbouring residuals, would widen the band further, but on a
        real scan the misfit of features correlates the residuals too, and that doubled the rms
        of the bezier_dac_scan fit.)"""
        if not one_se:
            return best
        f_best = f(best)
        target = f_best * (1.0 + math.sqrt(2.0 / max(N - edfs[key(best)], 1.0)))
        a, b = math.log(best), math.log(hi)
        if f(hi) <= target:
            return hi
        for _ in range(ONE_SE_STEPS - 1):
            mid = 0.5 * (a + b)
            if f(math.exp(mid)) <= target:
                a = mid
            else:
                b = mid
        return math.exp(a)

    if smoothing == "fixed":
        pass
    elif not isinstance(smoothing, str):
        ell_u = ell_v = float(smoothing)
    elif ell_u is None and ell_v is None:
        # One length for both first, then each direction within a factor 30 of it.
        lo, hi = min(grid_u[0], grid_v[0]), max(grid_u[-1], grid_v[-1])
        ell = golden(lambda e: solve(e, e, True), lo, hi, 12)
        f_u = lambda e: solve(e, ell, True)                                          # noqa: E731
        ell_u = smoothest(f_u, lambda e: (e, ell), golden(f_u, max(lo, ell / 30), min(hi, ell * 30), 8),
                          min(hi, ell * 30))
        f_v = lambda e: solve(ell_u, e, True)                                        # noqa: E731
        ell_v = smoothest(f_v, lambda e: (ell_u, e), golden(f_v, max(lo, ell / 30), min(hi, ell * 30), 8),
                          min(hi, ell * 30))
    elif ell_u is None:
        f_u = lambda e: solve(e, ell_v, True)                                        # noqa: E731
        ell_u = smoothest(f_u, lambda e: (e, ell_v), golden(f_u, grid_u[0], grid_u[-1], 12), grid_u[-1])
    elif ell_v is None:
        f_v = lambda e: solve(ell_u, e, True)                                        # noqa: E731
        ell_v = smoothest(f_v, lambda e: (ell_u, e), golden(f_v, grid_v[0], grid_v[-1], 12), grid_v[-1])
    c = solve(ell_u, ell_v, False)
    return BSplinePatch(c.reshape(nu, nv, 3), ku, kv, (p, q)), (float(ell_u), float(ell_v))


class _BandedSystem:
    """``(G + Σ_k ℓ_u^(2k) ℓ_v^(2(3−k)) T_k + ridge) c = rhs`` in LAPACK's banded storage.

    ``G`` and the penalty terms ``T_k`` are sparse ``(nu·nv, nu·nv)`` over the flat index
    ``i·nv + j``; they are permuted to the order with the shorter direction running fastest and
    stored as upper bands ``(b + 1, n)`` once, so each smoothing length costs one weighted sum of
    bands and one banded Cholesky factorisation.
    """

    def __init__(self, G, parts, nu: int, nv: int, p: int, q: int):
        idx = np.arange(nu * nv).reshape(nu, nv)
        if nu < nv:        # u runs fastest: flat index j·nu + i
            self.perm = idx.T.ravel()
            self.bw = q * nu + p
        else:
            self.perm = idx.ravel()
            self.bw = p * nv + q
        self.n = nu * nv
        self.G = self._band(G)
        self.T = [self._band(T) for T in parts]
        self.ridge = 1e-11 * max(float(G.diagonal().sum()), 1e-300) / self.n

    def _band(self, A) -> np.ndarray:
        A = A.tocsr()[self.perm][:, self.perm].tocoo()
        up = (A.row <= A.col) & (A.col - A.row <= self.bw)
        ab = np.zeros((self.bw + 1, self.n))
        np.add.at(ab, (self.bw + A.row[up] - A.col[up], A.col[up]), A.data[up])
        return ab

    def solve(self, ell_u: float, ell_v: float, rhs: np.ndarray) -> np.ndarray:
        from scipy.linalg import LinAlgError, cho_solve_banded, cholesky_banded

        ab = self.G.copy()
        for k, T in enumerate(self.T):
            ab += (ell_u ** (2 * k) * ell_v ** (2 * (3 - k))) * T
        ab[-1] += self.ridge
        try:
            cb = cholesky_banded(ab, overwrite_ab=True, lower=False, check_finite=False)
        except LinAlgError:
            raise InfeasibleError("the fit is under-determined (too few points spread over the patch for the "
                                  "control net); give fewer control points (n_ctrl) or some smoothing") from None
        out = np.empty_like(rhs)
        out[self.perm] = cho_solve_banded((cb, False), rhs[self.perm], check_finite=False)
        return out
