"""The pad's removal integrated over the stretch of travel each simulation pose stands for.

The simulator (:func:`swath.simulate.simulate_removal`) sums the removal of poses about one
removal-sample spacing apart.  Evaluating the Preston rate only *at* each pose (a Riemann sum along
the pass) is exact where the pressure under a moving sample changes smoothly, but the pressure
jumps at the pad's rim: from ``k·e`` to zero for a pad pressed flat on a plane, and from about
``k·2R sin θ`` to zero at the trailing rim of a pad led by ``θ``.  A sample then collects one
pose more or less of that jump depending on where the poses fall, which is noise of about
``step · h_rim / ∫ h du`` in its depth: 4 % steps for the flat default pad on 3 mm poses, and a
removal that reads 6.0 % CoV where :func:`swath.feed.ripple.ripple_cov` (and a fine independent
integration of FORMATS.md's model) gives 3.7 % for passes 1.22 R apart led by 15°.

Here each pose carries the stretch of the pass it stands for, given by three poses along it
(start, middle and end, ``τ = −1/2, 0, 1/2``).  For every sample the height along tool z and the
squared distance from the tool axis are interpolated quadratically in ``τ`` through their values at
the three poses (exact for a straight pass on a plane; second order along curved ones); the sink
is the force balance at the pose itself (:func:`swath.contact.kernels`), held over the stretch.
The sample's mean rate over the stretch is then the exact integral of ``k·h(τ)⁺ · v_rel`` over the
part of ``[−1/2, 1/2]`` where it lies within ``R`` of the axis: piecewise over the roots of the
two quadratics, in closed form for an orbital pad (``h`` quadratic) and by three-point Gauss
quadrature on each piece for a rotary one (``ω·r``, ``r`` the root of a quadratic).  A pose whose
three poses coincide (a hold) is the point evaluation.

:func:`accumulate_swept_removal` is the compiled form (numba, the samples in a
:class:`~swath.surface.cells.SampleGrid`); :func:`swept_mean_height` the vectorised numpy form of
the same integral, for the numpy engine and for tests.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..errors import InputError
from .kernels import BALL, SampleGrid, _buffers, _gather, jit, run_over_accumulators
from .tool import Tool

#: Three-point Gauss-Legendre nodes on [0, 1] and their weights (sum 1).
_G3_NODES = np.array([0.5 - 0.5 * np.sqrt(0.6), 0.5, 0.5 + 0.5 * np.sqrt(0.6)])
_G3_WEIGHTS = np.array([5.0, 8.0, 5.0]) / 18.0


def quadratic_coefficients(fa, fm, fb):
    """``(c0, c1, c2)`` of the quadratic ``c0 + c1 τ + c2 τ²`` through ``fa, fm, fb`` at
    ``τ = −1/2, 0, 1/2`` (scalars or arrays of one shape)."""
    return fm, fb - fa, 2.0 * (fa + fb) - 4.0 * fm


def _roots_numpy(c0, c1, c2) -> np.ndarray:
    """(N, 2) roots of ``c0 + c1 τ + c2 τ²`` strictly inside ``(−1/2, 1/2)``, NaN where none."""
    out = np.full((len(c0), 2), np.nan)
    linear = np.abs(c2) <= 1e-9 * np.abs(c1)
    with np.errstate(divide="ignore", invalid="ignore"):
        lin = np.where(linear & (c1 != 0), -c0 / c1, np.nan)
        disc = c1 * c1 - 4.0 * c0 * c2
        sq = np.sqrt(np.where(disc >= 0, disc, np.nan))
        q = -0.5 * (c1 + np.where(c1 >= 0, sq, -sq))
        r1 = q / c2
        r2 = np.where(q != 0, c0 / q, np.nan)
    out[:, 0] = np.where(linear, lin, r1)
    out[:, 1] = np.where(linear, np.nan, r2)
    out[~((out > -0.5) & (out < 0.5))] = np.nan
    return out


def swept_mean_height(z, r2, sink, R: float, *, rotary: bool = False) -> np.ndarray:
    """Mean over ``τ ∈ [−1/2, 1/2]`` of ``h(τ)⁺ · [r(τ) <= R]`` (orbital) or of
    ``h(τ)⁺ · r(τ) · [r(τ) <= R]`` (rotary; m²), ``h = sink − z``.

    Parameters
    ----------
    z, r2 : (N, 3) float
        Height along tool z (m) and squared distance from the tool axis (m²) of each sample at the
        stretch's start, middle and end poses.
    sink : (N,) float
        Pad-face depth held over the stretch, m.
    R : float
        Pad radius, m.

    Returns
    -------
    (N,) float
        Mean height (m; m² for ``rotary``): times ``k · k_p · dwell`` (times ``ω`` for a rotary pad,
        ``ω · orbit radius`` for an orbital one) it is the depth removed.
    """
    z, r2 = np.asarray(z, float), np.asarray(r2, float)
    h0, h1, h2 = quadratic_coefficients(*(sink[:, None] - z).T)
    g0, g1, g2 = quadratic_coefficients(*(R * R - r2).T)
    q0, q1, q2 = quadratic_coefficients(*r2.T)
    cuts = np.concatenate([np.full((len(z), 1), -0.5), _roots_numpy(h0, h1, h2), _roots_numpy(g0, g1, g2),
                           np.full((len(z), 1), 0.5)], axis=1)
    cuts = np.sort(cuts, axis=1)                          # NaN last
    total = np.zeros(len(z))
    for k in range(cuts.shape[1] - 1):
        t0, t1 = cuts[:, k], cuts[:, k + 1]
        ok = np.isfinite(t0) & np.isfinite(t1) & (t1 > t0)
        tm = np.where(ok, 0.5 * (t0 + t1), 0.0)
        ok &= (h0 + tm * (h1 + tm * h2) > 0) & (g0 + tm * (g1 + tm * g2) >= 0)
        if not ok.any():
            continue
        a, b = t0[ok], t1[ok]
        if rotary:
            part = np.zeros(len(a))
            for node, weight in zip(_G3_NODES, _G3_WEIGHTS, strict=True):
                t = a + node * (b - a)
                hh = h0[ok] + t * (h1[ok] + t * h2[ok])
                rr = q0[ok] + t * (q1[ok] + t * q2[ok])
                part += weight * hh * np.sqrt(np.maximum(rr, 0.0))
            total[ok] += part * (b - a)
        else:
            def anti(t, c0=h0[ok], c1=h1[ok], c2=h2[ok]):
                return t * (c0 + t * (c1 / 2.0 + t * c2 / 3.0))
            total[ok] += anti(b) - anti(a)
    return total


# ----------------------------------------------------------------------------------------------
# Compiled form
# ----------------------------------------------------------------------------------------------
@jit()
def _roots(c0, c1, c2, out, n):
    """Append to ``out[n:]`` the roots of ``c0 + c1 τ + c2 τ²`` inside ``(−1/2, 1/2)``; new ``n``."""
    if abs(c2) <= 1e-9 * abs(c1):
        if c1 != 0.0:
            t = -c0 / c1
            if -0.5 < t < 0.5:
                out[n] = t
                n += 1
        return n
    disc = c1 * c1 - 4.0 * c0 * c2
    if disc < 0.0:
        return n
    sq = np.sqrt(disc)
    q = -0.5 * (c1 + sq) if c1 >= 0.0 else -0.5 * (c1 - sq)
    t = q / c2
    if -0.5 < t < 0.5:
        out[n] = t
        n += 1
    if q != 0.0:
        t = c0 / q
        if -0.5 < t < 0.5:
            out[n] = t
            n += 1
    return n


@jit()
def _swept_one(za, zm, zb, ra, rm, rb, s, R2, rotary, cuts):
    """:func:`swept_mean_height` of one sample (``cuts``: a scratch array of 6)."""
    h0 = s - zm
    h1 = -(zb - za)
    h2 = -(2.0 * (za + zb) - 4.0 * zm)
    g0 = R2 - rm
    g1 = -(rb - ra)
    g2 = -(2.0 * (ra + rb) - 4.0 * rm)
    cuts[0] = -0.5
    n = _roots(h0, h1, h2, cuts, 1)
    n = _roots(g0, g1, g2, cuts, n)
    cuts[n] = 0.5
    n += 1
    for i in range(1, n):                     # insertion sort of at most six cuts
        v = cuts[i]
        j = i - 1
        while j >= 0 and cuts[j] > v:
            cuts[j + 1] = cuts[j]
            j -= 1
        cuts[j + 1] = v
    q1 = rb - ra
    q2 = 2.0 * (ra + rb) - 4.0 * rm
    total = 0.0
    for k in range(n - 1):
        a = cuts[k]
        b = cuts[k + 1]
        if not b > a:
            continue
        t = 0.5 * (a + b)
        if not (h0 + t * (h1 + t * h2) > 0.0 and g0 + t * (g1 + t * g2) >= 0.0):
            continue
        if rotary:
            w = b - a
            c = 0.5 - 0.5 * np.sqrt(0.6)
            part = 0.0
            for j in range(3):
                if j == 0:
                    tt, wt = a + c * w, 5.0 / 18.0
                elif j == 1:
                    tt, wt = a + 0.5 * w, 8.0 / 18.0
                else:
                    tt, wt = b - c * w, 5.0 / 18.0
                rr = rm + tt * (q1 + tt * q2)
                part += wt * (h0 + tt * (h1 + tt * h2)) * np.sqrt(max(rr, 0.0))
            total += part * w
        else:
            total += (b * (h0 + b * (0.5 * h1 + b * h2 / 3.0))) - (a * (h0 + a * (0.5 * h1 + a * h2 / 3.0)))
    return total


@jit()
def _swept_removal(pts, nrm, areas, lo, cell, dims, start, positions, axes, stretch, reach, target, weight, k,
                   preston, rotary, speed, R, ball, out, sinks):
    """Add each pose's removal over its stretch (``stretch[p]``: start, middle, end position and
    axis, ``(3, 2, 3)``) to ``out`` ``(S,)``; the sinks to ``sinks``."""
    idx, zb, wb, r2b = _buffers()
    lim2 = R * R * (1.0 + 1e-6)
    cuts = np.empty(6)
    zs = np.empty(3)
    rs = np.empty(3)
    for p in range(positions.shape[0]):
        n, idx, zb, wb, r2b = _gather(pts, nrm, areas, lo, cell, dims, start, positions[p], axes[p], R + reach[p],
                                      ball + reach[p], idx, zb, wb, r2b)
        # the force balance of the pose itself: the gathered samples within R of its axis
        wsum = 0.0
        wz = 0.0
        for q in range(n):
            if r2b[q] <= lim2:
                wsum += wb[q]
                wz += wb[q] * zb[q]
        if not wsum > 0:
            sinks[p] = np.nan
            continue
        s = (target[p] + wz) / wsum
        for _ in range(100):
            f = 0.0
            area = 0.0
            for q in range(n):
                h = s - zb[q]
                if h > 0 and r2b[q] <= lim2:
                    f += wb[q] * h
                    area += wb[q]
            step = (f - target[p]) / area if area > 0 else 0.0
            s -= step
            if abs(step) <= 1e-15 + 1e-12 * abs(s):
                break
        sinks[p] = s
        if weight[p] == 0.0:
            continue
        scale = preston * k * speed * weight[p]
        for q in range(n):
            j = idx[q]
            for e in range(3):
                dx = pts[j, 0] - stretch[p, e, 0, 0]
                dy = pts[j, 1] - stretch[p, e, 0, 1]
                dz = pts[j, 2] - stretch[p, e, 0, 2]
                zz = dx * stretch[p, e, 1, 0] + dy * stretch[p, e, 1, 1] + dz * stretch[p, e, 1, 2]
                zs[e] = zz
                rs[e] = dx * dx + dy * dy + dz * dz - zz * zz
            m = _swept_one(zs[0], zs[1], zs[2], rs[0], rs[1], rs[2], s, R * R, rotary, cuts)
            if m > 0.0:
                out[j] += scale * m


def stretch_reach(positions: np.ndarray, stretch: np.ndarray) -> np.ndarray:
    """(P,) how far (m) the stretch's poses lie from the pose: the gather radius's margin."""
    return np.linalg.norm(stretch[:, :, 0, :] - positions[:, None, :], axis=2).max(axis=1)


def accumulate_swept_removal(grid: SampleGrid, positions: np.ndarray, axes: np.ndarray, stretch: np.ndarray,
                             weight: np.ndarray, tool: Tool, *, force=None, out: np.ndarray,
                             executor: ThreadPoolExecutor | None = None) -> np.ndarray:
    """Preston removal of a batch of poses, each integrated over its stretch (module notes),
    summed into the per-lane depth arrays ``out`` ``(T, S)`` (grid order, as
    :func:`swath.contact.kernels.accumulate_removal`).

    Parameters
    ----------
    grid : SampleGrid
    positions, axes : (P, 3) float
        The poses whose force balance sets the sink: TCP positions (m) and unit tool z-axes.
    stretch : (P, 3, 2, 3) float
        Per pose, the start, middle and end of the travel it stands for: position (m) and unit
        tool z-axis each.
    weight : (P,) float
        Dwell of each pose, s.
    tool : Tool
    force : (P,) float, optional
        Normal force per pose, N (default ``tool.force``).
    out : (T, S) float
        Depth accumulators, m.

    Returns
    -------
    (P,) float
        The sink of each pose, m (NaN where the pad touches nothing).
    """
    positions = np.ascontiguousarray(positions, dtype=np.float64)
    axes = np.ascontiguousarray(axes, dtype=np.float64)
    stretch = np.ascontiguousarray(stretch, dtype=np.float64)
    weight = np.ascontiguousarray(weight, dtype=np.float64)
    P = len(positions)
    if positions.shape != (P, 3) or axes.shape != (P, 3) or stretch.shape != (P, 3, 2, 3) or weight.shape != (P,):
        raise InputError(f"need (P, 3) positions and axes, (P, 3, 2, 3) stretches and (P,) dwells, got "
                         f"{positions.shape}, {axes.shape}, {stretch.shape}, {weight.shape}")
    target = np.full(P, tool.force / tool.k) if force is None else np.asarray(force, float) / tool.k
    sinks = np.full(P, np.nan)
    if P == 0 or len(grid) == 0:
        return sinks
    reach = stretch_reach(positions, stretch)
    rotary = tool.motion == "rotary"
    speed = float(tool.spindle_speed if rotary else tool.spindle_speed * tool.orbit_radius)
    R = float(tool.pad_radius)

    def run(t: int, lo: int, hi: int) -> None:
        _swept_removal(grid.points, grid.normals, grid.areas, grid.origin, grid.cell, grid.dims, grid.start,
                       positions[lo:hi], axes[lo:hi], stretch[lo:hi], reach[lo:hi], target[lo:hi],
                       weight[lo:hi], float(tool.k), float(tool.preston), rotary, speed, R, BALL * R, out[t],
                       sinks[lo:hi])

    run_over_accumulators(run, P, len(out), executor)
    return sinks


__all__ = ["accumulate_swept_removal", "quadratic_coefficients", "stretch_reach", "swept_mean_height"]
