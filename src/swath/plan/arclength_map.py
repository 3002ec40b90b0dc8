"""The arc-length parameterisation of a B-spline patch (Amersdorfer & Meurer): a map from (sigma, tau), lengths along the patch's parameter lines, to the surface, with exact derivatives."""

from __future__ import annotations

import logging

import numpy as np

from ..errors import InputError

log = logging.getLogger(__name__)


#: Gauss–Legendre nodes per tabulation interval.
GAUSS_NODES = 6


def _gauss(n: int):
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (x + 1.0), 0.5 * w


def _span_nodes(knots: np.ndarray, degree: int, per_span: int, cap: int):
    """Tabulation nodes: every distinct knot of the domain, each span cut into ``per_span`` equal
    intervals (fewer when there are many spans; at least 3 so each span has a cubic).

    Returns the nodes ``(k,)`` and, per span, the index of its first and last node (inclusive;
    neighbouring spans share the knot node)."""
    n = len(knots) - degree - 1
    brk = np.unique(knots[degree:n + 1])
    per = max(3, min(int(per_span), (cap - 1) // max(brk.size - 1, 1)))
    frac = np.arange(per) / per
    nodes = np.concatenate([(brk[:-1, None] + frac[None, :] * np.diff(brk)[:, None]).ravel(), brk[-1:]])
    first = np.arange(brk.size - 1) * per
    return nodes, np.stack([first, first + per], axis=1)


def _span_of(x: np.ndarray, breaks: np.ndarray) -> np.ndarray:
    """Index of the interval of ``breaks`` holding each ``x`` (clamped to the first/last)."""
    return np.clip(np.searchsorted(breaks, x, side="right") - 1, 0, len(breaks) - 2)


class ArcLengthMap:
    """Arc-length coordinates ``(σ, τ)`` on a B-spline patch and their inverse.

    Parameters
    ----------
    patch : BSplinePatch
    along : {"u", "v"}
        The parameter the passes run along (``a``); ``τ`` is measured along the other (``b``).
    per_span : (int, int)
        Tabulation intervals per knot span in ``a`` and in ``b``.

    Attributes
    ----------
    a_grid : (na,) float
        Tabulated ``a`` values (every knot among them).
    b_grid : (nb,) float
        Tabulated ``b`` values (every knot among them).
    tau_table : (na, nb) float
        ``τ(a_i, b_j)``, m, by Gauss–Legendre quadrature of ``|S_b|`` on every interval.
    sigma_grid : (na,) float
        ``σ(a_i)``, m.

    Notes
    -----
    The interpolants are piecewise over knot spans — one spline (1D) or tensor spline (2D) per
    span or pair of spans — because a patch is only as smooth as its knots allow (a rational arc
    joined to the next at a double knot has a jump in ``|S_b|``); a single spline across a knot
    would smear that kink.  The forward tables are quintic (about ``1e-10`` relative on smooth
    spans); the inverse ``b(a, τ)`` is a cubic inverse interpolation along each ``b`` iso-curve,
    bridged across ``a`` by a quintic tensor spline, then polished by :attr:`newton_steps`
    Newton steps against the forward table with the exact ``|S_b|``.
    """

    #: Newton steps that polish the inverse interpolation against the forward table.
    newton_steps = 2

    def __init__(self, patch, *, along: str = "u", per_span=(64, 64)):
        if along not in ("u", "v"):
            raise InputError(f"along must be 'u' or 'v', got {along!r}")
        from scipy.interpolate import CubicSpline, RectBivariateSpline, make_interp_spline

        self.patch = patch
        self.along = along
        ia = 0 if along == "u" else 1
        knots = (patch.knots_u, patch.knots_v)
        self.a_range = (float(patch.domain[ia][0]), float(patch.domain[ia][1]))
        self.b_range = (float(patch.domain[1 - ia][0]), float(patch.domain[1 - ia][1]))
        self.a_grid, self._a_spans = _span_nodes(knots[ia], patch.degree[ia], per_span[0], 600)
        self.b_grid, self._b_spans = _span_nodes(knots[1 - ia], patch.degree[1 - ia], per_span[1], 2000)
        self._a_breaks = self.a_grid[np.r_[self._a_spans[:, 0], self._a_spans[-1, 1]]]
        self._b_knot_idx = np.r_[self._b_spans[:, 0], self._b_spans[-1, 1]]
        self._b_breaks = self.b_grid[self._b_knot_idx]
        x, w = _gauss(GAUSS_NODES)

        # τ table: integrate |S_b| over each b interval at every tabulated a.
        db = np.diff(self.b_grid)
        bq = (self.b_grid[:-1, None] + x[None, :] * db[:, None]).ravel()
        A, B = np.meshgrid(self.a_grid, bq, indexing="ij")
        speed_b = np.linalg.norm(self._partials(A.ravel(), B.ravel())[1], axis=1).reshape(len(self.a_grid), -1, len(x))
        pieces = (speed_b * w).sum(axis=2) * db[None, :]
        if not np.all(pieces > 0):
            raise InputError("the patch has an iso-curve of zero length (a degenerate edge or pole); arc-length "
                             "coordinates need |S_b| > 0 — trim the patch or plan along the other direction")
        self.tau_table = np.concatenate([np.zeros((len(self.a_grid), 1)), np.cumsum(pieces, axis=1)], axis=1)
        # σ along the middle a iso-curve.
        b_mid = 0.5 * (self.b_range[0] + self.b_range[1])
        da = np.diff(self.a_grid)
        aq = (self.a_grid[:-1, None] + x[None, :] * da[:, None]).ravel()
        speed_a = np.linalg.norm(self._partials(aq, np.full(aq.shape, b_mid))[0], axis=1).reshape(-1, len(x))
        pa = (speed_a * w).sum(axis=1) * da
        if not np.all(pa > 0):
            raise InputError("the middle iso-curve of the patch has zero-length pieces; cannot build arc-length "
                             "coordinates")
        self.sigma_grid = np.concatenate([[0.0], np.cumsum(pa)])
        self._sigma_breaks = self.sigma_grid[np.r_[self._a_spans[:, 0], self._a_spans[-1, 1]]]

        # Piecewise interpolants: per a span (1D), per (a span, b span) (2D).
        self._sigma_of_a, self._a_of_sigma, self._knot_tau, self._tau_ab, self._b_ar = [], [], [], [], []
        r_nodes = [np.linspace(0.0, 1.0, j1 - j0 + 1) for j0, j1 in self._b_spans]
        for i0, i1 in self._a_spans:
            ai, si = self.a_grid[i0:i1 + 1], self.sigma_grid[i0:i1 + 1]
            self._sigma_of_a.append(make_interp_spline(ai, si, k=5))
            self._a_of_sigma.append(make_interp_spline(si, ai, k=5))
            self._knot_tau.append(make_interp_spline(ai, self.tau_table[i0:i1 + 1][:, self._b_knot_idx], k=5, axis=0))
            fwd, inv = [], []
            for (j0, j1), r in zip(self._b_spans, r_nodes):
                T = self.tau_table[i0:i1 + 1, j0:j1 + 1]
                bj = self.b_grid[j0:j1 + 1]
                fwd.append(RectBivariateSpline(ai, bj, T, kx=5, ky=5, s=0))
                Bt = np.empty((len(ai), len(r)))
                for row in range(len(ai)):         # inverse interpolation along each b iso-curve
                    Bt[row] = CubicSpline(T[row], bj)(T[row, 0] + r * (T[row, -1] - T[row, 0]))
                Bt[:, 0], Bt[:, -1] = bj[0], bj[-1]
                inv.append(RectBivariateSpline(ai, r, Bt, kx=5, ky=5, s=0))
            self._tau_ab.append(fwd)
            self._b_ar.append(inv)

    # --- parameter plumbing ------------------------------------------------------------------
    def uv(self, a, b) -> tuple[np.ndarray, np.ndarray]:
        """``(u, v)`` from ``(a, b)``."""
        return (a, b) if self.along == "u" else (b, a)

    def ab(self, u, v) -> tuple[np.ndarray, np.ndarray]:
        """``(a, b)`` from ``(u, v)``."""
        return (u, v) if self.along == "u" else (v, u)

    def _partials(self, a, b, order: int = 1):
        u, v = self.uv(np.asarray(a, float), np.asarray(b, float))
        D = self.patch.derivatives(u, v, order)
        Su, Sv = D[:, 1, 0], D[:, 0, 1]
        return (Su, Sv) if self.along == "u" else (Sv, Su)

    def _sigma(self, a):
        p = _span_of(a, self._a_breaks)
        out = np.empty(a.shape)
        for q in np.unique(p):
            m = p == q
            out[m] = self._sigma_of_a[q](a[m])
        return out

    def _knot_taus(self, a) -> np.ndarray:
        """``τ`` at every b knot for each ``a`` ``(k,)``: ``(k, n_knots)``."""
        p = _span_of(a, self._a_breaks)
        out = np.empty((a.size, len(self._b_breaks)))
        for q in np.unique(p):
            m = p == q
            out[m] = self._knot_tau[q](a[m])
        return out

    # --- maps ----------------------------------------------------------------------------------
    @property
    def sigma_length(self) -> float:
        """Length of the middle ``a`` iso-curve, m (``σ`` runs over ``[0, sigma_length]``)."""
        return float(self.sigma_grid[-1])

    def tau_length(self, a) -> np.ndarray:
        """Length ``(k,)`` of the ``b`` iso-curve through each ``a``, m."""
        a = np.clip(np.asarray(a, float).ravel(), *self.a_range)
        return self._knot_taus(a)[:, -1]

    def from_parameters(self, u, v) -> tuple[np.ndarray, np.ndarray]:
        """Arc-length coordinates ``σ, τ`` (m) of parameters ``u, v`` ``(k,)``."""
        a, b = self.ab(np.asarray(u, float).ravel(), np.asarray(v, float).ravel())
        a, b = np.clip(a, *self.a_range), np.clip(b, *self.b_range)
        p, k = _span_of(a, self._a_breaks), _span_of(b, self._b_breaks)
        tau = np.empty(a.shape)
        for key in np.unique(p * len(self._b_breaks) + k):
            q, r = divmod(int(key), len(self._b_breaks))
            m = (p == q) & (k == r)
            tau[m] = self._tau_ab[q][r](a[m], b[m], grid=False)
        return self._sigma(a), tau

    def tau_derivative_a(self, u, v) -> np.ndarray:
        """``∂τ/∂a`` (m per unit of ``a``) at ``u, v`` ``(k,)``."""
        a, b = self.ab(np.asarray(u, float).ravel(), np.asarray(v, float).ravel())
        a, b = np.clip(a, *self.a_range), np.clip(b, *self.b_range)
        p, k = _span_of(a, self._a_breaks), _span_of(b, self._b_breaks)
        out = np.empty(a.shape)
        for key in np.unique(p * len(self._b_breaks) + k):
            q, r = divmod(int(key), len(self._b_breaks))
            m = (p == q) & (k == r)
            out[m] = self._tau_ab[q][r](a[m], b[m], dx=1, grid=False)
        return out

    def a_of_sigma(self, sigma) -> np.ndarray:
        """The path parameter ``a`` ``(k,)`` at arc length ``σ`` (m) along the middle iso-curve."""
        s = np.clip(np.asarray(sigma, float).ravel(), 0.0, self.sigma_length)
        p = _span_of(s, self._sigma_breaks)
        a = np.empty(s.shape)
        for q in np.unique(p):
            m = p == q
            a[m] = self._a_of_sigma[q](s[m])
        return np.clip(a, *self.a_range)

    def top_crossing(self, sigma, tau, *, steps: int = 12) -> np.ndarray:
        """Refine ``σ`` ``(k,)`` near where the line ``τ = tau`` meets the far edge ``τ = L(a)``
        of the domain (the domain polygon is only a chain of chords there); secant steps."""
        s0 = np.asarray(sigma, float).ravel().copy()
        t = np.broadcast_to(np.asarray(tau, float).ravel(), s0.shape)
        s1 = s0 + 1e-6
        g0 = self.tau_length(self.a_of_sigma(s0)) - t
        for _ in range(steps):
            g1 = self.tau_length(self.a_of_sigma(s1)) - t
            den = g1 - g0
            ok = np.abs(den) > 1e-15
            s2 = np.where(ok, s1 - g1 * (s1 - s0) / np.where(ok, den, 1.0), s1)
            s0, g0, s1 = s1, g1, np.clip(s2, 0.0, self.sigma_length)
        return s1

    def to_parameters(self, sigma, tau) -> tuple[np.ndarray, np.ndarray]:
        """Parameters ``u, v`` ``(k,)`` of arc-length coordinates ``σ, τ`` (m), clamped to the domain."""
        s = np.clip(np.asarray(sigma, float).ravel(), 0.0, self.sigma_length)
        t = np.asarray(tau, float).ravel()
        p = _span_of(s, self._sigma_breaks)
        a = self.a_of_sigma(s)
        kt = self._knot_taus(a)
        t = np.clip(t, kt[:, 0], kt[:, -1])
        k = np.clip((t[:, None] >= kt[:, 1:-1]).sum(axis=1), 0, len(self._b_breaks) - 2)
        rows = np.arange(len(t))
        r = (t - kt[rows, k]) / (kt[rows, k + 1] - kt[rows, k])
        r = np.clip(r, 0.0, 1.0)
        b = np.empty(s.shape)
        for key in np.unique(p * len(self._b_breaks) + k):
            q, j = divmod(int(key), len(self._b_breaks))
            m = (p == q) & (k == j)
            b[m] = self._b_ar[q][j](a[m], r[m], grid=False)
        b = np.clip(b, *self.b_range)
        # Polish with Newton steps on the forward map (quintic, ~1e-10 relative), dτ/db = |S_b|.
        for _ in range(self.newton_steps):
            u, v = self.uv(a, b)
            err = self.from_parameters(u, v)[1] - t
            b = np.clip(b - err / np.linalg.norm(self._partials(a, b)[1], axis=1), *self.b_range)
        return self.uv(a, b)

    def tau_exact(self, u, v, *, intervals: int = 16) -> np.ndarray:
        """``τ`` at ``u, v`` by direct quadrature from the domain edge, m: Gauss–Legendre on
        ``intervals`` equal pieces of every knot span below ``b`` (no tables; for checking)."""
        a, b = self.ab(np.asarray(u, float).ravel(), np.asarray(v, float).ravel())
        x, w = _gauss(GAUSS_NODES)
        out = np.zeros(a.shape)
        for lo, hi in zip(self._b_breaks[:-1], self._b_breaks[1:]):
            top = np.clip(b, lo, hi)
            active = top > lo
            if not active.any():
                continue
            edges = lo + (top[active, None] - lo) * np.linspace(0, 1, intervals + 1)[None, :]
            h = np.diff(edges, axis=1)
            nodes = edges[:, :-1, None] + x[None, None, :] * h[:, :, None]
            aa = np.broadcast_to(a[active, None, None], nodes.shape)
            speed = np.linalg.norm(self._partials(aa.ravel(), nodes.ravel())[1], axis=1).reshape(nodes.shape)
            out[active] += ((speed * w).sum(axis=2) * h).sum(axis=1)
        return out

    def domain_polygon(self, *, samples: int = 3000) -> np.ndarray:
        """The patch's own boundary in ``(σ, τ)``, ``(k, 2)`` counter-clockwise (m)."""
        a = np.union1d(np.linspace(*self.a_range, samples), self.a_grid)
        sa = self._sigma(a)
        la = self.tau_length(a)
        b = np.union1d(np.linspace(*self.b_range, samples), self.b_grid)
        uv_r = self.uv(np.full(b.size, self.a_range[1]), b)
        uv_l = self.uv(np.full(b.size, self.a_range[0]), b)
        right = self.from_parameters(*uv_r)[1]
        left = self.from_parameters(*uv_l)[1]
        bottom = np.stack([sa, np.zeros(a.size)], 1)
        east = np.stack([np.full(b.size, sa[-1]), right], 1)
        top = np.stack([sa, la], 1)[::-1]
        west = np.stack([np.zeros(b.size), left], 1)[::-1]
        return np.vstack([bottom, east[1:], top[1:], west[1:-1]])
