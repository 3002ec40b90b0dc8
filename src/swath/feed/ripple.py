"""The pad's cross-profile and the ripple of parallel passes: the spacing that sums flattest.

A pad pressed flat on a plane (pressure ``p = F / (π R²)`` over the disc) and swept at speed ``v``
along a straight line removes, at lateral offset ``y`` from the line,

    depth(y) = k_p · p / v · ∫_{−c}^{c} v_rel(√(x² + y²)) dx,        c = √(R² − y²)

— for an orbital pad (``v_rel`` constant) ``2 c k_p p v_rel / v``, a semicircle; for a rotary pad
(``v_rel = ω r``) ``k_p p ω / v · (c R + y² asinh(c / |y|))``.  Feed along a pass cannot change
this profile, so parallel passes a spacing ``d`` apart leave a periodic ripple across the passes
whatever the feed.  :func:`ripple_cov` measures it (the coefficient of variation of the summed
profiles over one period) and :func:`ripple_spacing` chooses the spacing with the least ripple
among those whose contact length stays within a given multiple of the coverage lower bound
(``L / L* = 2R / d`` on a plane).

On a flat orbital pad the ripple is 28 % at ``d = 2R``, least near ``d = 1.7 R`` (9 %; the first
Fourier harmonic of the semicircle, ``2 J₁(2πR/d) / (2πR/d)``, vanishes at ``d = 1.64 R``) and
below 5 % only for ``d <= 0.9 R`` (``L >= 2.2 L*``).

Why no feed can remove the ripple (straight passes on a plane, ``d`` apart, pass ``j`` with any
dwell per unit length ``g_j(x) >= 0`` along it).  The removal is
``r(x, y) = Σ_j ∫ g_j(s) P(x − s, y − j d) ds`` with ``P`` the pad's footprint rate, so its mean
along the passes is ``r̄(y) = Σ_j ḡ_j p(y − j d)``, ``p`` the cross profile and ``ḡ_j`` the pass's
mean dwell.  (a) By the law of total variance ``Var r >= Var r̄``: variation along the passes
only adds.  (b) Over ``N`` passes (period ``N d``) the Fourier coefficients of ``r̄`` at the
harmonics ``m / d`` of the spacing are ``p̂(m/d) · mean(ḡ) / d`` — the weights enter only through
their mean, exactly as with equal feeds — and the mean of ``r̄`` is ``p̂(0) · mean(ḡ) / d``; the
other harmonics (``m / (N d)``, ``m`` not a multiple of ``N``) only add variance (Parseval).  So
``CoV(r) >= ripple_cov(d)`` whatever the feed, and the least CoV of equally spaced passes within
``L <= 1.5 L*`` (``d >= 4R/3``) is ``ripple_spacing``'s: 9.2 % at ``d = 1.68 R`` (orbital), 7.5 % at
``d = 1.88 R`` (rotary, ``Tool(motion="rotary")``).  Two crossed layers within ``1.5 L*`` need
``d >= 8R/3`` per layer, and the cells where both layers' gaps cross (1/16 of the area) stay
untouched (CoV > 25 %).  A tilted pad changes ``p`` itself and is not covered by this argument:
led by ``Tool.half_pad_lead`` (the leading edge lifted until half the pad presses, pressure falling
linearly to zero under the TCP) an orbital pad's profile is the parabola ``∝ R² − y²``, whose
least ripple within 1.5 L* is 5.3 % at ``d = 1.40 R`` (``cross_profile(..., lead_angle=...)``;
a rotary pad 5.8 % at 1.56 R).

Unequal spacing is outside (b): :func:`lattice_cov` measures any periodic pattern of offsets and
dwell weights.  A numerical search (2-8 passes per period, offsets and weights free, mean spacing
``>= 4R/3``) found at best 8.2 % for the orbital pad (passes ``5/3 R`` apart with every fourth
split into two half-weight passes 0.31 R apart): better than 9.2 %, still far from 5 %.
A sideways weave along each pass (:func:`weave_ripple_cov`) got to 5.4 % at exactly ``1.5 L*``, with
a wavelength of about ``R`` that turns the tool far faster than the angular-speed limit allows.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from ..contact import Tool
from ..errors import InputError

_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(48)
#: Gauss-Legendre on the half chord [0, 1] (the integrand is even in x and has a kink at x = 0 when y = 0)
_CHORD_NODES, _CHORD_WEIGHTS = 0.5 * (_NODES + 1.0), _WEIGHTS


def cross_profile(tool: Tool, offsets, *, speed: float = 1.0, lead_angle: float = 0.0) -> np.ndarray:
    """Depth (m) removed at lateral ``offsets`` (m, ``(k,)``) from a straight pass on a plane
    crossed at ``speed`` (m/s): the chord integral of the Preston rate under the flat pad.

    ``lead_angle`` (rad) tilts the pad about the axis across the feed, as
    :func:`swath.trajectory.time_path` does (:func:`_tilted_profile`); 0 is the pad pressed flat."""
    y = np.abs(np.asarray(offsets, float))
    if not (np.isfinite(speed) and speed > 0):
        raise InputError(f"speed must be a positive speed in m/s, got {speed!r}")
    if lead_angle != 0.0:
        return _tilted_profile(tool, y, speed, float(lead_angle))
    R = tool.pad_radius
    pressure = tool.force / (np.pi * R * R)
    c = np.sqrt(np.clip(R * R - y * y, 0.0, None))
    x = c[:, None] * _CHORD_NODES[None, :]                          # points on the half chord
    rate = tool.relative_speed(np.sqrt(x * x + y[:, None] ** 2))
    return tool.preston * pressure / speed * (c * (rate * _CHORD_WEIGHTS[None, :]).sum(axis=1))


def tilted_sink(tool: Tool, lead_angle: float) -> float:
    """The sink ``s`` (m) of a pad tilted by ``lead_angle`` (rad) on a plane: the root of the force
    balance ``F = (k / cos θ) ∫∫_disc (s − x tan θ)⁺ dx dy`` (the disc in the pad's own
    coordinates; ``x = u cos θ`` for a plane point ``u`` ahead of the TCP).  0 at
    ``Tool.half_pad_lead``; the depression on flat at 0.

    With ``c = s / tan θ`` the contact is the disc's part ``x < c``, and the integral is
    ``tan θ · (c A(c) + (2/3)(R² − c²)^{3/2})``, ``A(c) = c √(R² − c²) + R² (asin(c/R) + π/2)``
    the area of that part; once ``c >= R`` the whole pad touches and it is ``π R² s``."""
    from scipy.optimize import brentq

    R, t = tool.pad_radius, abs(math.tan(lead_angle))
    need = tool.force * math.cos(lead_angle) / tool.k
    whole = need / (math.pi * R * R)
    if whole >= R * t:                        # the whole pad touches (no tilt, or a small one)
        return whole

    def excess(c):
        root = math.sqrt(max(R * R - c * c, 0.0))
        area = c * root + R * R * (math.asin(max(-1.0, min(1.0, c / R))) + 0.5 * math.pi)
        return t * (c * area + (2.0 / 3.0) * root**3) - need

    return t * float(brentq(excess, -R, R, xtol=1e-15 * R, rtol=1e-15))


def _tilted_profile(tool: Tool, y: np.ndarray, speed: float, lead: float) -> np.ndarray:
    """:func:`cross_profile` of a pad tilted by ``lead`` (rad) about the axis across the feed: at
    ``x`` along the feed (pad coordinates) the pressure is ``k (s − x tan θ)⁺``, ``s`` from
    :func:`tilted_sink`, and a pass over the plane point at ``u = x / cos θ`` lasts ``du / v``.
    Integrated up to the contact's straight edge ``x = s / tan θ`` (Gauss-Legendre on the chord's
    touching part): exact for an orbital pad, whose integrand is linear there; a rotary pad's
    ``ω r`` has a kink at the pad centre, which costs up to 1e-4 of the profile near ``y = 0`` when
    the centre lies inside the contact (a lead below the half-pad angle; measured at 3°)."""
    R, t = tool.pad_radius, math.tan(abs(lead))
    s = tilted_sink(tool, lead)
    w = np.sqrt(np.clip(R * R - y * y, 0.0, None))                 # half chord at offset y
    edge = s / t                                                     # contact where x < edge
    lo, hi = -w, np.minimum(w, edge)
    span = np.clip(hi - lo, 0.0, None)
    x = lo[:, None] + span[:, None] * _CHORD_NODES[None, :]
    h = np.clip(s - x * t, 0.0, None)
    rate = tool.relative_speed(np.sqrt(x * x + y[:, None] ** 2))
    integral = span * (h * rate * _CHORD_WEIGHTS[None, :]).sum(axis=1)
    # _CHORD_WEIGHTS sum to 2 over [0, 1]: half of that is the unit interval's measure
    return tool.preston * tool.k / (speed * math.cos(lead)) * 0.5 * integral


def ripple_cov(tool: Tool, spacing: float, *, n: int = 512, lead_angle: float = 0.0) -> float:
    """Coefficient of variation of the summed cross-profiles of infinitely many parallel passes
    ``spacing`` (m) apart, all at the same feed (over one period, ``n`` points), the pad tilted by
    ``lead_angle`` (rad, :func:`cross_profile`)."""
    d = float(spacing)
    if not (np.isfinite(d) and d > 0):
        raise InputError(f"spacing must be a positive length in m, got {spacing!r}")
    return lattice_cov(tool, [0.0], [1.0], d, n=n, lead_angle=lead_angle)


def lattice_cov(tool: Tool, offsets, weights, period: float, *, n: int = 1024, lead_angle: float = 0.0) -> float:
    """Coefficient of variation of the summed cross-profiles of passes at ``offsets`` (m, ``(N,)``)
    across the feed, each with relative dwell ``weights`` (``(N,)``, >= 0: the pass's mean dwell per
    unit length), the pattern repeated every ``period`` (m) — over one period, ``n`` points.

    :func:`ripple_cov` is ``lattice_cov(tool, [0], [1], d)``.  With ``N`` equally spaced passes
    and any weights the CoV is never below ``ripple_cov(tool, period / N)`` (module docstring).
    """
    y0 = np.asarray(offsets, float).reshape(-1)
    w = np.asarray(weights, float).reshape(-1)
    P = float(period)
    if not (np.isfinite(P) and P > 0):
        raise InputError(f"period must be a positive length in m, got {period!r}")
    if y0.size == 0 or y0.shape != w.shape or not np.all(np.isfinite(y0)):
        raise InputError(f"need one finite offset (m) per weight, got {y0.size} offsets and {w.size} weights")
    if not (np.all(np.isfinite(w)) and np.all(w >= 0) and w.sum() > 0):
        raise InputError(f"weights must be finite, >= 0 and not all 0, got {w.tolist()!r}")
    R = tool.pad_radius
    y = (np.arange(n) + 0.5) / n * P
    images = np.arange(-int(np.ceil(R / P)) - 1, int(np.ceil(R / P)) + 2) * P
    rel = (y[:, None, None] - y0[None, :, None] - images[None, None, :]).ravel()
    total = (cross_profile(tool, rel, lead_angle=lead_angle).reshape(n, y0.size, -1).sum(axis=2) * w[None, :]).sum(axis=1)
    return float(total.std() / total.mean())


@functools.cache
def _radial_rule() -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes and weights (256) on [-1, 1], made on first use: the eigenvalue solve
    behind them costs up to 0.4 s of CPU where a threaded BLAS shares a busy machine, and only the
    weave model needs them."""
    return np.polynomial.legendre.leggauss(256)


def _footprint_transform(tool: Tool, k) -> np.ndarray:
    """The pad's footprint rate on a plane, Fourier-transformed at wavenumbers ``k`` (rad/m) and
    divided by its value at 0 (the footprint is round, so the transform is radial: a Hankel
    transform of ``relative_speed(r)`` over the disc)."""
    from scipy.special import j0

    R = tool.pad_radius
    nodes, weights = _radial_rule()
    r = 0.5 * R * (nodes + 1.0)
    w = 0.5 * R * weights * r * tool.relative_speed(r)
    kk = np.asarray(k, float)
    return (j0(kk.reshape(-1, 1) * r[None, :]) @ w).reshape(kk.shape) / w.sum()


def weave_length_factor(amplitude: float, wavelength: float) -> float:
    """Path length per unit advance of a sinusoidal weave ``y = amplitude · sin(2π x / wavelength)``
    (both m): the factor a weave puts on the contact length."""
    t = (np.arange(2048) + 0.5) / 2048
    slope = 2 * np.pi * amplitude / wavelength * np.cos(2 * np.pi * t)
    return float(np.mean(np.sqrt(1.0 + slope**2)))


def weave_ripple_cov(tool: Tool, spacing: float, *, amplitude: float, wavelength: float, phase: float = 0.0,
                     harmonics: int = 40) -> float:
    """Coefficient of variation over the plane of the removal of parallel passes ``spacing`` (m)
    apart, each weaving sideways as ``amplitude · sin(2π x / wavelength)`` (m, m), pass ``j`` shifted
    along by ``j · phase`` wavelengths, all at the same dwell per unit advance.

    The passes form a lattice; the removal's Fourier coefficient at
    ``(n / wavelength, (m + n · phase) / spacing)`` is the footprint's transform there (relative to 0)
    times ``J_n(2π (m + n · phase) amplitude / spacing)``, and the CoV is the root sum of their
    squares (``|m|, |n| <= harmonics``).  ``amplitude = 0`` gives :func:`ripple_cov`.

    A weave spreads each harmonic ``m / spacing`` of the straight passes into side bands
    ``Σ_n J_n² = 1`` at higher wavenumbers, where the footprint transmits less, but only where the
    wavelength is short against the pad (about ``R``); its length factor
    (:func:`weave_length_factor`) multiplies ``L / L*``.  The best a search found for the orbital pad
    within ``L <= 1.5 L*`` (sixty Nelder-Mead starts over spacing, amplitude, wavelength and phase)
    is 5.4 %, at ``d = 1.65 R``, ``amplitude = 0.17 R``, ``wavelength = 1.02 R`` — and there the
    travel direction swings ±47° every half ``R``: at 50 mm/s with a 38 mm pad the tool turns about
    its axis at up to 8.5 rad/s, far above a 1 rad/s limit.
    """
    from scipy.special import jv

    d, A, lam = float(spacing), float(amplitude), float(wavelength)
    if not (np.isfinite(d) and d > 0 and np.isfinite(lam) and lam > 0 and np.isfinite(A) and A >= 0):
        raise InputError(f"need a positive spacing and wavelength and an amplitude >= 0 (m), got spacing={spacing!r}, "
                         f"wavelength={wavelength!r}, amplitude={amplitude!r}")
    m = np.arange(-harmonics, harmonics + 1)[:, None]
    n = np.arange(-harmonics, harmonics + 1)[None, :]
    ky = 2 * np.pi * (m + n * float(phase)) / d
    kx = 2 * np.pi * n / lam + 0.0 * ky
    coef = _footprint_transform(tool, np.hypot(kx, ky)) * jv(n, ky * A)
    coef[harmonics, harmonics] = 0.0                              # the mean
    return float(np.sqrt(np.sum(coef**2)))


def ripple_spacing(tool: Tool, *, max_length_ratio: float = 1.5, min_length_ratio: float = 1.0,
                   steps: int = 61, lead_angle: float = 0.0) -> tuple[float, float]:
    """The pass spacing (m) with the least ripple whose contact length ``2R / d`` lies within
    ``[min_length_ratio, max_length_ratio]`` times the coverage lower bound; returns
    ``(spacing, ripple CoV)``.

    A scan of ``steps`` spacings, then a golden-section refinement around the best (the CoV is
    smooth in the spacing).  ``lead_angle`` (rad): the pad tilted as in :func:`cross_profile`
    (at ``Tool.half_pad_lead`` the least ripple within 1.5 L* is 5.3 % at ``d = 1.40 R``).
    """
    if not (np.isfinite(max_length_ratio) and max_length_ratio >= min_length_ratio > 0):
        raise InputError(f"need 0 < min_length_ratio <= max_length_ratio, got {min_length_ratio!r}, "
                         f"{max_length_ratio!r}")
    R = tool.pad_radius
    lo, hi = 2 * R / max_length_ratio, 2 * R / min_length_ratio
    grid = np.linspace(lo, hi, steps)
    def ripple(d):
        return ripple_cov(tool, d, lead_angle=lead_angle)

    cov = np.array([ripple(d) for d in grid])
    k = int(np.argmin(cov))
    a, b = grid[max(k - 1, 0)], grid[min(k + 1, steps - 1)]
    g = (np.sqrt(5) - 1) / 2
    for _ in range(30):
        c1, c2 = b - g * (b - a), a + g * (b - a)
        if ripple(c1) <= ripple(c2):
            b = c2
        else:
            a = c1
    d = 0.5 * (a + b)
    best = (d, ripple(d))
    return best if best[1] <= cov[k] else (float(grid[k]), float(cov[k]))


def ripple_overlap(tool: Tool, *, max_length_ratio: float = 1.5, lead_angle: float = 0.0) -> float:
    """The swath overlap (fraction of the swath width) that puts neighbouring passes at the
    least-ripple spacing: ``1 − d* / (2R)``, ``d*`` from :func:`ripple_spacing`.

    For planners that space passes by overlap of the local swath width (the uniform planner's
    ``overlap``): on a plane the width is ``2R`` and the spacing is ``d*``; where curvature narrows
    the swath the spacing shrinks with it, keeping the ratio ``d / w`` the ripple analysis chose.
    Orbital pad: about 0.16; rotary pad: about 0.06 (``max_length_ratio`` 1.5).
    """
    d, _ = ripple_spacing(tool, max_length_ratio=max_length_ratio, lead_angle=lead_angle)
    return float(1.0 - d / (2.0 * tool.pad_radius))


__all__ = ["cross_profile", "lattice_cov", "ripple_cov", "ripple_overlap", "ripple_spacing", "weave_length_factor",
           "weave_ripple_cov"]
