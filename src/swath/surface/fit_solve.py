"""Penalised least squares of :func:`swath.surface.fit.fit_patch`: design matrices, the
third-order thin-plate penalty, and the smoothing lengths chosen by generalised cross-validation."""

from __future__ import annotations

import math

import numpy as np

from ..errors import InfeasibleError
from .bspline import BSplinePatch
from .bspline_basis import basis_derivatives


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

#: Exponent of the knot-spacing weights of the smoothness penalty (see :func:`_gram`): the local
#: smoothing length scales as ``(h / h̄)^(γ/6)`` with the knot span ``h``.
PENALTY_GAMMA = 6.0



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
