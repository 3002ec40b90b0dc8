"""B-spline basis functions (Cox–de Boor with derivatives), knot spans and clamped knot vectors."""

from __future__ import annotations

import numpy as np

from ..errors import InputError


# ----------------------------------------------------------------------------------------------
# Basis functions
# ----------------------------------------------------------------------------------------------
def find_span(knots: np.ndarray, degree: int, x: np.ndarray) -> np.ndarray:
    """Index ``i`` of the knot span ``[t_i, t_i+1)`` holding each ``x`` ``(k,)``, ``degree <= i < n``.

    The right end of the domain belongs to the last non-empty span.
    """
    n = len(knots) - degree - 1
    span = np.searchsorted(knots, x, side="right") - 1
    span = np.clip(span, degree, n - 1)
    # Inside the domain, a span that ends on the domain's right end may still be empty when the
    # last knot is repeated; step back over empty spans (only happens at x == t_n).
    empty = knots[span + 1] <= knots[span]
    while np.any(empty):
        span = np.where(empty, span - 1, span)
        empty = knots[span + 1] <= knots[span]
    return span


def basis_derivatives(knots: np.ndarray, degree: int, x: np.ndarray, order: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The ``degree + 1`` non-zero B-spline basis functions at ``x`` and their derivatives.

    Cox–de Boor recursion with its derivative (the triangular table of lower-degree basis
    functions is built once per point and differentiated with the knot-difference formula),
    vectorised over the points.

    Parameters
    ----------
    knots : (n + degree + 1,) float
        Non-decreasing knot vector.
    degree : int
        Polynomial degree ``p``.
    x : (k,) float
        Parameter values inside ``[t_p, t_n]``.
    order : int
        Highest derivative wanted (derivatives above ``degree`` are zero).

    Returns
    -------
    span : (k,) int
        Knot span of each point; the non-zero functions are ``N_{span-p} .. N_{span}``.
    ders : (order + 1, k, degree + 1) float
        ``ders[d, i, a]`` is the ``d``-th derivative of ``N_{span_i - p + a}`` at ``x_i``.
    """
    t = np.asarray(knots, float)
    p = int(degree)
    x = np.asarray(x, float).ravel()
    span = find_span(t, p, x)
    k = x.size
    ndu = np.empty((p + 1, p + 1, k))
    left = np.empty((p + 1, k))
    right = np.empty((p + 1, k))
    ndu[0, 0] = 1.0
    for j in range(1, p + 1):
        left[j] = x - t[span + 1 - j]
        right[j] = t[span + j] - x
        saved = np.zeros(k)
        for r in range(j):
            ndu[j, r] = right[r + 1] + left[j - r]          # knot differences (lower triangle)
            temp = ndu[r, j - 1] / ndu[j, r]
            ndu[r, j] = saved + right[r + 1] * temp          # basis functions (upper triangle)
            saved = left[j - r] * temp
        ndu[j, j] = saved
    ders = np.zeros((order + 1, k, p + 1))
    ders[0] = ndu[:, p].T
    top = min(order, p)
    if top >= 1:
        a = np.zeros((2, p + 1, k))
        for r in range(p + 1):
            s1, s2 = 0, 1
            a[0, 0] = 1.0
            for d in range(1, top + 1):
                acc = np.zeros(k)
                rk, pk = r - d, p - d
                if r >= d:
                    a[s2, 0] = a[s1, 0] / ndu[pk + 1, rk]
                    acc += a[s2, 0] * ndu[rk, pk]
                j1 = 1 if rk >= -1 else -rk
                j2 = d - 1 if r - 1 <= pk else p - r
                for j in range(j1, j2 + 1):
                    a[s2, j] = (a[s1, j] - a[s1, j - 1]) / ndu[pk + 1, rk + j]
                    acc += a[s2, j] * ndu[rk + j, pk]
                if r <= pk:
                    a[s2, d] = -a[s1, d - 1] / ndu[pk + 1, r]
                    acc += a[s2, d] * ndu[r, pk]
                ders[d, :, r] = acc
                s1, s2 = s2, s1
        factor = float(p)
        for d in range(1, top + 1):
            ders[d] *= factor
            factor *= p - d
    return span, ders


def clamped_knots(interior, degree: int, domain: tuple[float, float]) -> np.ndarray:
    """A clamped (open) knot vector: ``degree + 1`` copies of each domain end around ``interior``."""
    a, b = float(domain[0]), float(domain[1])
    return np.concatenate([np.full(degree + 1, a), np.asarray(interior, float), np.full(degree + 1, b)])


def _check_knots(knots, n: int, degree: int, which: str) -> np.ndarray:
    t = np.array(knots, dtype=float).ravel()
    if t.size != n + degree + 1:
        raise InputError(f"knot vector {which} must have {n + degree + 1} entries for {n} control points "
                         f"of degree {degree}, got {t.size}")
    if not np.isfinite(t).all():
        raise InputError(f"knot vector {which} contains NaN or infinite values")
    if np.any(np.diff(t) < 0):
        raise InputError(f"knot vector {which} must be non-decreasing")
    if not t[n] > t[degree]:
        raise InputError(f"knot vector {which} gives an empty parameter domain")
    inner = t[degree + 1:n]
    if inner.size:
        _, counts = np.unique(inner, return_counts=True)
        if counts.max() > degree:
            raise InputError(f"an interior knot in {which} is repeated {counts.max()} times; at most {degree} "
                             "(the degree) keeps the patch continuous")
    return t


def span_samples(knots: np.ndarray, degree: int, per_span: int, cap: int) -> np.ndarray:
    """Parameter samples with ``per_span`` steps in every non-empty knot span (at most ``cap``)."""
    n = len(knots) - degree - 1
    breaks = np.unique(knots[degree:n + 1])
    per = max(1, min(per_span, cap // max(breaks.size - 1, 1)))
    if (breaks.size - 1) * per + 1 > cap:   # too many spans: uniform in the parameter instead
        return np.linspace(breaks[0], breaks[-1], cap)
    frac = np.arange(per) / per
    out = (breaks[:-1, None] + frac[None, :] * np.diff(breaks)[:, None]).ravel()
    return np.concatenate([out, breaks[-1:]])
