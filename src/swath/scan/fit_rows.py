"""Skinning along scan rows (Jaeger §3.2.2) for :func:`swath.scan.fit.fit_patch`."""

from __future__ import annotations

import math

import numpy as np

from ..errors import InfeasibleError, InputError
from ..surface.bspline import BSplinePatch
from ..surface.bspline_basis import basis_derivatives
from .fit_knots import _knots_from_patch, _uniform_knots
from .fit_solve import (
    _aniso_step,
    _design_1d,
    _gcv_progress,
    _lambda_grid,
    _penalty_1d,
    _smooth_columns,
)


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


def _fit_rows(X, rows, *, p, q, n_ctrl, smoothing, qk, max_turn, h_max, knot_rounds, reparam_rounds, say):
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

    say("fit: skinning the scan rows (pilot fits that place the knots)", 0, max(knot_rounds, 0) + 1)
    patch, ells = skin(u, ku, kv)
    for r in range(max(knot_rounds, 0)):
        ku = _knots_from_patch(patch, 0, req_u, p, opts, cap_u, 2 * h_along, dom_u)
        kv = _knots_from_patch(patch, 1, req_v, q, opts, cap_v, 2.5 * h_across, dom_v)
        patch, ells = skin(u, ku, kv)
        say("fit: skinning the scan rows (pilot fits that place the knots)", r + 1, max(knot_rounds, 0) + 1)
    # Final fit of all points at once (every knot span then holds points of many rows, which keeps
    # tight, densely knotted bends well conditioned): across the rows the smoothing found by
    # skinning, along the rows by GCV; parameters along the rows from projection on the current
    # patch (consistent from row to row).
    ells = (None, ells[1])
    for r in range(max(reparam_rounds, 0) + 1):
        say("fit: projecting the points on the patch (parameters along the rows)", r, max(reparam_rounds, 0) + 1)
        u = patch.project(X, initial=(u, v), tol=1e-9)[0]
        patch, ells = _aniso_step(X, u, v, ku, kv, p, q, smoothing, grid_u, grid_v, *ells,
                                  progress=_gcv_progress(say, r))
    return patch, ells, u, v
