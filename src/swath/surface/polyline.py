"""Polylines: arc length, resampling at equal arc-length steps, and densifying — the one
implementation every stage uses.  Pure functions on ``(k, 3)`` point arrays, m."""

from __future__ import annotations

import numpy as np


def arc_length(points: np.ndarray) -> np.ndarray:
    """Cumulative arc length ``(k,)`` (m) of a polyline ``(k, 3)``, starting at 0."""
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(seg)])


def resample_uniform(points: np.ndarray, step: float, *columns: np.ndarray):
    """Resample a polyline at equal arc-length steps.

    Parameters
    ----------
    points : (k, 3) float
        Polyline, m.
    step : float
        Largest allowed spacing, m; the actual spacing is ``L / ceil(L / step)``.
    *columns : (k, ...) float
        Per-point data interpolated linearly in arc length alongside (normals are re-normalised by
        the caller).

    Returns
    -------
    s : (n,) float
        Arc length of the new samples, m (``s[0] = 0``, ``s[-1] = L``).
    points : (n, 3) float
        The resampled points (on the polyline's chords).
    *columns : (n, ...) float
        The interpolated columns.
    """
    s_old = arc_length(points)
    length = s_old[-1]
    n = max(int(np.ceil(length / step - 1e-9)), 1) + 1
    s = np.linspace(0.0, length, n)
    keep = np.concatenate([[True], np.diff(s_old) > 0])     # drop repeated points
    s_old = s_old[keep]
    out = [s, _interp_rows(s, s_old, points[keep])]
    out += [_interp_rows(s, s_old, np.asarray(c, float)[keep]) for c in columns]
    return tuple(out)


def _interp_rows(x: np.ndarray, xp: np.ndarray, fp: np.ndarray) -> np.ndarray:
    """``np.interp`` of every column of ``fp`` ``(k, ...)``."""
    if len(xp) == 1:
        return np.repeat(fp[:1], len(x), axis=0)
    flat = fp.reshape(len(fp), -1)
    out = np.stack([np.interp(x, xp, flat[:, j]) for j in range(flat.shape[1])], axis=1)
    return out.reshape((len(x),) + fp.shape[1:])


def densify(points: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
    """Insert points so that no segment of the polyline ``(k, 3)`` is longer than ``step`` (m);
    the original points are kept.

    Returns
    -------
    points : (n, 3) float
    source_index : (n,) float
        Fractional index of each point in the original polyline (integers at the originals).
    """
    points = np.asarray(points, float)
    if len(points) < 2:
        return points.copy(), np.arange(len(points), dtype=float)
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    n_sub = np.maximum(np.ceil(seg / step).astype(int), 1)
    frac = np.concatenate([np.arange(k) / k for k in n_sub])
    seg_id = np.repeat(np.arange(len(seg)), n_sub)
    out = points[seg_id] + frac[:, None] * (points[seg_id + 1] - points[seg_id])
    return np.vstack([out, points[-1:]]), np.concatenate([seg_id + frac, [len(points) - 1.0]])
