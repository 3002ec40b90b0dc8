"""Curvature-based resampling of scan rows (Jaeger §3.2.3), before skinning.

A point laser measures a row at equal steps, so a tight bend (a blade's leading edge) gets as few
points as a flat stretch of the same length, and the least-squares fit, which weighs every point
alike, spends its accuracy where the surface is easy.  Jaeger spaces the samples with the
distribution function

    R(s) = q b(s) / B + (1 - q) s / L,    b(s) = ∫₀ˢ κ²(t) dt,   B = b(L)        (3.24-3.26)

over a row's arc length ``s`` (``L`` its length, ``κ`` its curvature, ``q`` how strongly the
curvature counts) and samples at ``R⁻¹`` of equal steps: more samples where the row bends.  Here
each row is smoothed by local quadratic regression against its arc length (Jaeger's local
regression: :func:`local_quadratic`, ``window`` measured points, tricube weights), its curvature is
read off that regression at the measured points, and the resampled points are the regression's
values at the new arc lengths.

Measured, it does not improve a fit of a point-laser scan and is therefore not applied unless
called (``benchmarks/bench_scan_resample.py``; the figures are in the scan guide): such a scan is
already sampled at the density the fit uses, and the fit's knots follow the same distribution
function, so moving samples from flat stretches into bends takes points where they helped and puts
smoothed ones (the regression's bias at a tight bend) where they add nothing.  It is meant for rows
measured far denser than the fit needs (a line laser), to choose where to keep the points.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError

#: Default curvature weight ``q`` of the distribution function.
RESAMPLE_Q = 0.5


def row_distribution(s: np.ndarray, kappa: np.ndarray, q: float) -> np.ndarray:
    """Jaeger's distribution function ``R(s)`` ``(k,)`` at increasing arc lengths ``s`` ``(k,)``
    (m) from the curvature ``kappa`` ``(k,)`` (1/m) there: ``q b(s)/B + (1 - q) s/L``, from 0 to 1
    (the trapezoid rule for ``b``; a straight row, ``B = 0``, gives ``s/L``)."""
    L = float(s[-1] - s[0])
    k2 = np.asarray(kappa, float) ** 2
    b = np.concatenate([[0.0], np.cumsum(0.5 * (k2[1:] + k2[:-1]) * np.diff(s))])
    B = float(b[-1])
    lin = (s - s[0]) / L
    return lin if B <= 0 else q * b / B + (1 - q) * lin


def local_quadratic(s: np.ndarray, P: np.ndarray, at: np.ndarray, k: int):
    """Local quadratic regression of a row: at each arc length of ``at`` ``(m,)`` a weighted
    least-squares quadratic in ``s`` through the ``k`` measured points nearest in arc length
    (tricube weights), for each coordinate of ``P`` ``(n, 3)`` at ``s`` ``(n,)`` (m).

    Returns the positions ``(m, 3)`` (m), first ``(m, 3)`` and second ``(m, 3)`` derivatives with
    respect to ``s`` there."""
    n = len(s)
    k = min(k, n)
    lo = np.clip(np.searchsorted(s, at) - k // 2, 0, n - k)
    idx = lo[:, None] + np.arange(k)                                     # (m, k)
    ds = s[idx] - at[:, None]
    h = np.max(np.abs(ds), axis=1, keepdims=True) * 1.0001 + 1e-12
    w = (1 - (np.abs(ds) / h) ** 3) ** 3
    V = np.stack([np.ones_like(ds), ds, ds * ds], axis=2)                 # (m, k, 3)
    A = np.einsum("mki,mk,mkj->mij", V, w, V)
    b = np.einsum("mki,mk,mkc->mic", V, w, P[idx])                       # (m, 3 coeffs, 3 coords)
    c = np.linalg.solve(A + 1e-18 * np.eye(3), b)
    return c[:, 0], c[:, 1], 2.0 * c[:, 2]


def resample_rows(points, rows, *, q: float = RESAMPLE_Q, factor: float = 1.0, window: int = 11):
    """Resample every scan row by Jaeger's curvature distribution.

    Parameters
    ----------
    points : (n, 3) float
        Scan points, m, each row's points in scan order.
    rows : (n,) int
        Row id of each point.
    q : float
        Curvature weight in [0, 1) of :func:`row_distribution` (0: equal arc-length steps).
    factor : float
        Samples per row relative to its measured points (> 0).
    window : int
        Measured points in each local regression (>= 5).

    Returns
    -------
    points : (m, 3) float
        The resampled points, m, row by row, each row in its scan order.
    rows : (m,) int
        Their row ids.
    """
    from scipy.ndimage import uniform_filter1d

    X = np.asarray(points, float)
    R = np.asarray(rows).reshape(-1)
    if X.ndim != 2 or X.shape[1] != 3 or len(R) != len(X):
        raise InputError(f"resample_rows needs (n, 3) points and (n,) row ids, got {X.shape} and {R.shape}")
    if not (0.0 <= q < 1.0 and factor > 0 and int(window) >= 5):
        raise InputError(f"resample_rows needs q in [0, 1), factor > 0 and window >= 5, got q={q!r}, "
                         f"factor={factor!r}, window={window!r}")
    order = np.argsort(R, kind="stable")
    ids, starts, counts = np.unique(R[order], return_index=True, return_counts=True)
    out_p, out_r = [], []
    for rid, a, n in zip(ids, starts, counts):
        P = X[order[a:a + n]]
        if n < 2 * window:               # too short to resample: kept as measured
            out_p.append(P)
            out_r.append(np.full(n, rid))
            continue
        # arc length of the lightly smoothed row (noise would lengthen it), strictly increasing
        Ps = uniform_filter1d(P, size=5, axis=0, mode="nearest")
        seg = np.maximum(np.linalg.norm(np.diff(Ps, axis=0), axis=1), 1e-12)
        s = np.concatenate([[0.0], np.cumsum(seg)])
        _, d1, d2 = local_quadratic(s, P, s, int(window))
        speed = np.maximum(np.linalg.norm(d1, axis=1), 1e-12)
        kappa = np.linalg.norm(np.cross(d1, d2), axis=1) / speed**3
        dist = row_distribution(s, kappa, q)
        m = max(int(round(factor * n)), 2 * window)
        s_new = np.interp(np.linspace(0.0, 1.0, m), dist, s)
        out_p.append(local_quadratic(s, P, s_new, int(window))[0])
        out_r.append(np.full(m, rid))
    return np.concatenate(out_p), np.concatenate(out_r)
