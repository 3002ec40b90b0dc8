"""Many slice polylines resampled at once: :func:`swath.plan.slicing.resample` for every fragment of
a plan in one compiled walk, the same points bit for bit.

A raster plan cuts hundreds of fragments (four candidate directions, 84 passes each on
noether_raw_mesh); resampling them one by one costs more in per-call overhead than in arithmetic.
Here the fragments are laid end to end and one kernel walks them, doing each fragment's arithmetic
in the order :func:`~swath.plan.slicing.resample` does it: the segment lengths as
``np.linalg.norm`` takes them (``sqrt((dx² + dy²) + dz²)``), their running sum as ``np.cumsum``
(left to right), the sample positions as ``np.linspace`` places them (``k · step``, the last one
the length itself), the segment each falls on as ``np.searchsorted(..., side="right") - 1``, and
the same interpolation, clipped the same way.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..surface import cells
from ..surface.cells import jit
from .slicing import SlicePolyline, SurfaceSamples, resample


def resample_all(polylines: list[SlicePolyline], spacing: float) -> list[SurfaceSamples]:
    """``[resample(pl, spacing) for pl in polylines]``, the same samples bit for bit, in one compiled
    walk (without numba: that list).

    Parameters
    ----------
    polylines : list of SlicePolyline
        Each with at least two points; all with per-vertex values or all without.
    spacing : float
        Largest arc-length step, m.

    Returns
    -------
    list of SurfaceSamples
    """
    if not (np.isfinite(spacing) and spacing > 0):
        raise InputError(f"resampling spacing must be positive and finite, got {spacing!r} m")
    with_values = {pl.values is not None for pl in polylines}
    if not polylines or not cells.AVAILABLE or len(with_values) != 1:
        return [resample(pl, spacing) for pl in polylines]
    counts = np.array([len(pl.points) for pl in polylines], np.int64)
    start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    points = np.ascontiguousarray(np.concatenate([pl.points for pl in polylines]), float)
    has_values = with_values == {True}
    values = (np.ascontiguousarray(np.concatenate([np.asarray(pl.values) for pl in polylines]), float)
              if has_values else np.zeros((len(points), 0)))
    # each point's step to the next as np.linalg.norm measures it (the steps across two fragments
    # are never read)
    step = np.zeros(len(points))
    if len(points) > 1:
        step[:-1] = np.linalg.norm(np.diff(points, axis=0), axis=1)
    pts, vals, seg, out_start = _resample_kernel(points, values, step, start, float(spacing))
    out = []
    for k, pl in enumerate(polylines):
        a, b = out_start[k], out_start[k + 1]
        out.append(SurfaceSamples(pts[a:b], pl.faces[seg[a:b]], vals[a:b] if has_values else None))
    return out


@jit()
def _resample_kernel(points, values, step, start, spacing):  # pragma: no cover - compiled
    # One loop, written out, compiles in a fraction of the time of several small kernels.
    m = len(start) - 1
    longest = 1
    for k in range(m):
        longest = max(longest, start[k + 1] - start[k])
    cum = np.empty(longest)
    out_start = np.zeros(m + 1, np.int64)
    for sweep in range(2):                   # the sample counts, then the samples
        if sweep == 1:
            total = out_start[m]
            pts = np.empty((total, 3))
            vals = np.empty((total, values.shape[1]))
            seg_of = np.empty(total, np.int64)
        for k in range(m):
            a, b = start[k], start[k + 1]
            n_seg = b - a - 1
            # np.concatenate([[0.0], np.cumsum(seg)]): left to right
            cum[0] = 0.0
            if n_seg >= 1:
                cum[1] = step[a]
            for j in range(2, n_seg + 1):
                cum[j] = cum[j - 1] + step[a + j - 1]
            length = cum[n_seg]
            if sweep == 0:
                out_start[k + 1] = out_start[k] + max(int(np.ceil(length / spacing)), 1) + 1
                continue
            o = out_start[k]
            n = out_start[k + 1] - o
            div = n - 1
            dstep = length / div
            j = 0
            for t in range(n):
                # np.linspace(0.0, length, n)
                if dstep == 0.0:
                    s = (t / div) * length + 0.0
                else:
                    s = t * dstep + 0.0
                if t == n - 1:
                    s = length
                # np.searchsorted(cum, s, side="right") - 1, clipped to the segments
                while j + 1 <= n_seg and cum[j + 1] <= s:
                    j += 1
                i = min(max(j, 0), n_seg - 1)
                seg = step[a + i]
                u = (s - cum[i]) / seg if seg > 0 else 0.0
                u = min(max(u, 0.0), 1.0)
                for c in range(3):
                    pts[o + t, c] = points[a + i, c] + u * (points[a + i + 1, c] - points[a + i, c])
                for c in range(values.shape[1]):
                    vals[o + t, c] = values[a + i, c] + u * (values[a + i + 1, c] - values[a + i, c])
                seg_of[o + t] = i
            for c in range(3):
                pts[o, c] = points[a, c]
                pts[o + n - 1, c] = points[b - 1, c]
            for c in range(values.shape[1]):
                vals[o, c] = values[a, c]
                vals[o + n - 1, c] = values[b - 1, c]
    return pts, vals, seg_of, out_start
