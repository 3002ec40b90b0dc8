"""Knot placement of :func:`swath.scan.fit.fit_patch`: the curvature-based distribution of
Jaeger's thesis, read off a pilot fit."""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError
from ..surface.bspline import BSplinePatch
from ..surface.bspline_basis import clamped_knots, span_samples
from ..surface.geometry import normalize

#: Total turning (rad) of a direction below which curvature hardly moves the knots.
TURN_SIGNIFICANT = 0.2

#: Knot spans are at most this many times shorter than even spacing.
KNOT_CONCENTRATION = 4.0



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
    ta = span_samples(patch.knots_u if direction == 0 else patch.knots_v, patch.degree[direction], 8, cap=3000)
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
