"""Compiled (numba) evaluation of the pad contact model of :mod:`swath.contact.model`.

The same model as :func:`swath.contact.mesh_contact` and :func:`swath.contact.solve_sink`: the pad
face is a plane at sink ``s`` below the TCP along tool z; a sample within ``R`` of the tool axis,
inside the ``hypot(R, R/2)`` ball about the TCP and with its normal facing the tool, carries
pressure ``k·max(s − z, 0)``; ``s`` solves ``F = k Σ area·max(s − z, 0)`` exactly (Newton on the
convex piecewise-linear balance, started where every candidate touches).

Instead of pose-sample pair lists this module keeps the samples in a uniform grid of cells
(:class:`SampleGrid`, samples sorted by cell so each cell is one contiguous run) and, for each pose,
gathers the samples of the cells the ball reaches, solves the force balance and adds Preston's
``k_p · p · v_rel(r) · dwell`` to the depth of every touched sample directly
(:func:`accumulate_removal`); :func:`contact_pairs` lists the touching pose-sample pairs and
:func:`touched_samples` marks the touched samples under a capped pad-face depth (the uniform
planner's coverage test).  Memory is the samples plus one depth array per thread, whatever the
path length.  Poses are split over threads, each summing into its own depth array.

Everything runs in float64.  The kernels are compiled on first use and cached on disk
(``cache=True``); where no cache directory is writable numba compiles them in memory at every
process start instead (a few seconds).  :data:`AVAILABLE` is False when numba is not installed;
callers then use the numpy path (:func:`swath.contact.mesh_contact`).  The threads are plain
Python threads around GIL-free kernels, so no numba threading layer (OpenMP, TBB) is involved and
the kernels are safe to call from several threads or forked workers at once.
"""

from __future__ import annotations

import logging
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..core.cpus import usable_cpus
from ..errors import InputError
from ..surface.cells import AVAILABLE, SampleGrid, jit, sample_grid  # noqa: F401  (re-exported)
from .tool import Tool

log = logging.getLogger(__name__)

#: Radius of the ball (in pad radii) that holds every point of the pad cylinder with |z| <= R/2 —
#: the candidate region of :func:`swath.contact.mesh_contact`.
BALL = float(np.hypot(1.0, 0.5))


#: Depth accumulators (lanes) of a simulation: a fixed number, whatever the threads, so the summed
#: depth does not depend on how many CPUs the process may use (a batch job on one CPU gives the same
#: figures to the last digit as the same job run with two).
LANES = 4


def default_threads() -> int:
    """Threads the removal kernel splits poses over: the usable CPUs (:func:`swath.core.cpus.usable_cpus`), at most 8."""
    return max(1, min(8, usable_cpus()))


# ----------------------------------------------------------------------------------------------
# Kernels
# ----------------------------------------------------------------------------------------------
@jit()
def _gather(pts, nrm, areas, lo, cell, dims, start, c, a, R, ball, idx, zb, wb, r2b):
    """Samples under the pad at TCP ``c`` with axis ``a``: fills ``idx, z, w, r2`` (grown when
    full) and returns them with the count."""
    ball2 = ball * ball
    lim2 = R * R * (1.0 + 1e-6)
    i0 = max(int(np.floor((c[0] - ball - lo[0]) / cell)), 0)
    i1 = min(int(np.floor((c[0] + ball - lo[0]) / cell)), dims[0] - 1)
    j0 = max(int(np.floor((c[1] - ball - lo[1]) / cell)), 0)
    j1 = min(int(np.floor((c[1] + ball - lo[1]) / cell)), dims[1] - 1)
    k0 = max(int(np.floor((c[2] - ball - lo[2]) / cell)), 0)
    k1 = min(int(np.floor((c[2] + ball - lo[2]) / cell)), dims[2] - 1)
    margin = 1e-9 * cell
    n = 0
    for i in range(i0, i1 + 1):
        bx0 = lo[0] + i * cell
        dx = max(bx0 - c[0], c[0] - (bx0 + cell), 0.0) - margin
        dx2 = dx * dx if dx > 0 else 0.0
        for j in range(j0, j1 + 1):
            by0 = lo[1] + j * cell
            dy = max(by0 - c[1], c[1] - (by0 + cell), 0.0) - margin
            dxy2 = dx2 + (dy * dy if dy > 0 else 0.0)
            if dxy2 > ball2:
                continue
            for k in range(k0, k1 + 1):
                bz0 = lo[2] + k * cell
                dz = max(bz0 - c[2], c[2] - (bz0 + cell), 0.0) - margin
                if dxy2 + (dz * dz if dz > 0 else 0.0) > ball2:
                    continue
                cid = (i * dims[1] + j) * dims[2] + k
                s0 = start[cid]
                s1 = start[cid + 1]
                if n + (s1 - s0) > len(idx):
                    grow = max(2 * len(idx), n + (s1 - s0))
                    idx2 = np.empty(grow, np.int64)
                    z2 = np.empty(grow)
                    w2 = np.empty(grow)
                    r22 = np.empty(grow)
                    idx2[:n] = idx[:n]
                    z2[:n] = zb[:n]
                    w2[:n] = wb[:n]
                    r22[:n] = r2b[:n]
                    idx, zb, wb, r2b = idx2, z2, w2, r22
                for q in range(s0, s1):
                    rx = pts[q, 0] - c[0]
                    ry = pts[q, 1] - c[1]
                    rz = pts[q, 2] - c[2]
                    d2 = rx * rx + ry * ry + rz * rz
                    if d2 > ball2:
                        continue
                    if nrm[q, 0] * a[0] + nrm[q, 1] * a[1] + nrm[q, 2] * a[2] >= 0.0:
                        continue
                    z = rx * a[0] + ry * a[1] + rz * a[2]
                    r2 = d2 - z * z
                    if r2 > lim2:
                        continue
                    idx[n] = q
                    zb[n] = z
                    wb[n] = areas[q]
                    r2b[n] = r2
                    n += 1
    return n, idx, zb, wb, r2b


@jit()
def _sink(zb, wb, n, target):
    """Exact ``s`` with ``Σ w·max(s − z, 0) = target`` over the first ``n`` samples (NaN if none);
    the iteration of :func:`swath.contact.solve_sink` for one group."""
    wsum = 0.0
    wz = 0.0
    for q in range(n):
        wsum += wb[q]
        wz += wb[q] * zb[q]
    if not wsum > 0:
        return np.nan
    s = (target + wz) / wsum
    for _ in range(100):
        f = 0.0
        area = 0.0
        for q in range(n):
            h = s - zb[q]
            if h > 0:
                f += wb[q] * h
                area += wb[q]
        step = (f - target) / area if area > 0 else 0.0
        s -= step
        if abs(step) <= 1e-15 + 1e-12 * abs(s):
            break
    return s


@jit()
def _buffers():
    """Empty gather buffers ``(idx, z, w, r2)`` for :func:`_gather` (it grows them when full)."""
    return np.empty(4096, np.int64), np.empty(4096), np.empty(4096), np.empty(4096)


@jit()
def _removal(pts, nrm, areas, lo, cell, dims, start, positions, axes, target, weight, k, preston,
             rotary, speed, R, ball, out, sinks):
    """Add ``weight · k_p · k·h · v_rel(r)`` of every pose to ``out`` ``(S,)``; the sinks to ``sinks``."""
    idx, zb, wb, r2b = _buffers()
    for p in range(positions.shape[0]):
        n, idx, zb, wb, r2b = _gather(pts, nrm, areas, lo, cell, dims, start, positions[p], axes[p], R, ball,
                                      idx, zb, wb, r2b)
        s = _sink(zb, wb, n, target[p])
        sinks[p] = s
        if not (s == s) or weight[p] == 0.0:
            continue
        for q in range(n):
            h = s - zb[q]
            if h > 0:
                v = speed * np.sqrt(max(r2b[q], 0.0)) if rotary else speed
                out[idx[q]] += preston * (k * h) * v * weight[p]


@jit()
def _count_pairs(pts, nrm, areas, lo, cell, dims, start, positions, axes, target, R, ball, sinks, counts):
    """Sink per pose and the number of touching samples per pose."""
    idx, zb, wb, r2b = _buffers()
    for p in range(positions.shape[0]):
        n, idx, zb, wb, r2b = _gather(pts, nrm, areas, lo, cell, dims, start, positions[p], axes[p], R, ball,
                                      idx, zb, wb, r2b)
        s = _sink(zb, wb, n, target[p])
        sinks[p] = s
        m = 0
        for q in range(n):
            if s - zb[q] > 0:
                m += 1
        counts[p] = m


@jit()
def _fill_pairs(pts, nrm, areas, lo, cell, dims, start, positions, axes, R, ball, sinks, offsets, k,
                pose, sample, pressure, radius):
    """Write the touching pairs of every pose at ``offsets[p]`` (after :func:`_count_pairs`)."""
    idx, zb, wb, r2b = _buffers()
    for p in range(positions.shape[0]):
        s = sinks[p]
        if not (s == s):
            continue
        n, idx, zb, wb, r2b = _gather(pts, nrm, areas, lo, cell, dims, start, positions[p], axes[p], R, ball,
                                      idx, zb, wb, r2b)
        o = offsets[p]
        for q in range(n):
            h = s - zb[q]
            if h > 0:
                pose[o] = p
                sample[o] = idx[q]
                pressure[o] = k * h
                radius[o] = np.sqrt(max(r2b[q], 0.0))
                o += 1


@jit()
def _touched(pts, nrm, areas, lo, cell, dims, start, positions, axes, target, cap, R, ball, out):
    """Mark in ``out`` ``(S,)`` (cell order) every sample whose height along tool z lies below both
    the pose's sink and ``cap[p]`` (poses with a NaN sink or cap mark nothing)."""
    idx, zb, wb, r2b = _buffers()
    for p in range(positions.shape[0]):
        if not (cap[p] == cap[p]):
            continue
        n, idx, zb, wb, r2b = _gather(pts, nrm, areas, lo, cell, dims, start, positions[p], axes[p], R, ball,
                                      idx, zb, wb, r2b)
        s = _sink(zb, wb, n, target[p])
        if not (s == s):
            continue
        limit = s if s < cap[p] else cap[p]
        for q in range(n):
            if zb[q] < limit:
                out[idx[q]] = True


# ----------------------------------------------------------------------------------------------
# Python entry points
# ----------------------------------------------------------------------------------------------
def default_cell(tool: Tool) -> float:
    """Grid cell edge (m) for queries with ``tool``: half the query-ball radius."""
    return 0.5 * BALL * tool.pad_radius


def _pose_arrays(grid: SampleGrid, positions, axes, tool: Tool, force):
    positions = np.ascontiguousarray(positions, dtype=np.float64)
    axes = np.ascontiguousarray(axes, dtype=np.float64)
    P = len(positions)
    if positions.shape != (P, 3) or axes.shape != (P, 3):
        raise InputError(f"positions and axes must both be (P, 3), got {positions.shape} and {axes.shape}")
    if force is None:
        target = np.full(P, tool.force / tool.k)
    else:
        force = np.asarray(force, dtype=np.float64)
        if force.shape != (P,):
            raise InputError(f"force must be one value (N) per pose, shape ({P},), got {force.shape}")
        target = force / tool.k
    return positions, axes, np.ascontiguousarray(target)


def accumulate_removal(grid: SampleGrid, positions: np.ndarray, axes: np.ndarray, weight: np.ndarray,
                       tool: Tool, *, force=None, out: np.ndarray | None = None, threads: int | None = None,
                       executor: ThreadPoolExecutor | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Preston removal of a batch of poses, summed into per-thread depth arrays.

    Parameters
    ----------
    grid : SampleGrid
        The surface samples (in the frame of ``positions``).
    positions : (P, 3) float
        TCP positions, m.
    axes : (P, 3) float
        Unit tool z-axes (pointing into the part).
    weight : (P,) float
        Time each pose stands for (dwell), s.
    tool : Tool
    force : (P,) float, optional
        Normal force per pose, N (default ``tool.force``).
    out : (T, S) float, optional
        Depth accumulators (m) to add to, one row per thread, in the grid's sample order; created
        (zeros) when None.
    threads : int, optional
        Threads (rows of ``out``) when ``out`` is created (default :func:`default_threads`).  The
        kernel releases the GIL; each thread takes a contiguous block of poses and its own row.
    executor : ThreadPoolExecutor, optional
        Worker threads to reuse over many calls (any number: rows are queued on them); a pool of
        up to :func:`default_threads` workers is made for this call when None.

    Returns
    -------
    out : (T, S) float
        The accumulators; ``out.sum(axis=0)[inverse of grid.order]`` is the depth per original sample
        (see :func:`depth_in_input_order`).  Rows are independent: with
        ``threads=1`` the sum is in pose order.
    sink : (P,) float
        Pad-face depth per pose, m (NaN where the pad touches nothing).
    """
    positions, axes, target = _pose_arrays(grid, positions, axes, tool, force)
    weight = np.ascontiguousarray(weight, dtype=np.float64)
    if weight.shape != (len(positions),):
        raise InputError(f"weight must be one dwell (s) per pose, shape ({len(positions)},), got {weight.shape}")
    if out is None:
        out = np.zeros((max(1, int(default_threads() if threads is None else threads)), len(grid)))
    elif out.ndim != 2 or out.shape[1] != len(grid) or out.dtype != np.float64:
        raise InputError(f"out must be (T, {len(grid)}) float64 depth accumulators, got {out.shape} {out.dtype}")
    P = len(positions)
    sinks = np.full(P, np.nan)
    if P == 0 or len(grid) == 0:
        return out, sinks
    rotary = tool.motion == "rotary"
    speed = float(tool.spindle_speed if rotary else tool.spindle_speed * tool.orbit_radius)
    R = float(tool.pad_radius)

    def run(t: int, lo: int, hi: int) -> None:
        _removal(grid.points, grid.normals, grid.areas, grid.origin, grid.cell, grid.dims, grid.start,
                 positions[lo:hi], axes[lo:hi], target[lo:hi], weight[lo:hi], float(tool.k),
                 float(tool.preston), rotary, speed, R, BALL * R, out[t], sinks[lo:hi])

    run_over_accumulators(run, P, len(out), executor)
    return out, sinks


def run_over_accumulators(run, n_poses: int, n_accumulators: int, executor=None) -> None:
    """Call ``run(t, lo, hi)`` for each accumulator ``t`` with its share ``lo:hi`` of the poses, on
    threads (``executor``, or a pool of :func:`default_threads`) when there are enough poses.

    Each accumulator is written by one call only, so the threads never share an array."""
    def one(t: int) -> None:
        lo, hi = t * n_poses // n_accumulators, (t + 1) * n_poses // n_accumulators
        if hi > lo:
            run(t, lo, hi)

    if n_accumulators == 1 or n_poses < 2 * n_accumulators:
        for t in range(n_accumulators):
            one(t)
    elif executor is not None:
        list(executor.map(one, range(n_accumulators)))
    else:
        with ThreadPoolExecutor(max_workers=min(n_accumulators, default_threads())) as pool:
            list(pool.map(one, range(n_accumulators)))


def depth_in_input_order(grid: SampleGrid, out: np.ndarray) -> np.ndarray:
    """(S,) float: the per-thread accumulators of :func:`accumulate_removal` summed, in the order
    the samples were given to :func:`sample_grid`."""
    depth = np.empty(len(grid))
    depth[grid.order] = out.sum(axis=0)
    return depth


def contact_pairs(grid: SampleGrid, positions: np.ndarray, axes: np.ndarray, tool: Tool, *, force=None):
    """Touching pose-sample pairs, as :func:`swath.contact.mesh_contact` returns them.

    Returns
    -------
    pose, sample : (N,) int
        Pose index and original sample index of each pair (poses ascending).
    pressure, radius : (N,) float
        Contact pressure (Pa) and distance from the tool axis (m).
    sink : (P,) float
        Pad-face depth per pose, m (NaN where the pad touches nothing).
    """
    positions, axes, target = _pose_arrays(grid, positions, axes, tool, force)
    P = len(positions)
    sinks = np.full(P, np.nan)
    counts = np.zeros(P, np.int64)
    R = float(tool.pad_radius)
    args = (grid.points, grid.normals, grid.areas, grid.origin, grid.cell, grid.dims, grid.start, positions, axes)
    if P and len(grid):
        _count_pairs(*args, target, R, BALL * R, sinks, counts)
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    N = int(offsets[-1])
    pose = np.empty(N, np.int64)
    sample = np.empty(N, np.int64)
    pressure = np.empty(N)
    radius = np.empty(N)
    if N:
        _fill_pairs(*args, R, BALL * R, sinks, offsets, float(tool.k), pose, sample, pressure, radius)
    return pose, grid.order[sample], pressure, radius, sinks


def touched_samples(grid: SampleGrid, positions: np.ndarray, axes: np.ndarray, tool: Tool, *,
                    max_sink: np.ndarray, force=None) -> np.ndarray:
    """Samples the pressed pad touches, with the pad-face depth capped per pose.

    The model of :func:`contact_pairs` (the same sink per pose); a sample counts when it lies above
    the pad face at depth ``min(sink, max_sink)`` along tool z, i.e. its height ``z`` below both.
    ``max_sink = inf`` gives exactly the samples :func:`contact_pairs` returns.

    Parameters
    ----------
    grid : SampleGrid
        The surface samples (in the frame of ``positions``).
    positions : (P, 3) float
        TCP positions, m.
    axes : (P, 3) float
        Unit tool z-axes (pointing into the part).
    tool : Tool
    max_sink : (P,) float
        Largest pad-face depth counted per pose, m (NaN: the pose touches nothing).
    force : (P,) float, optional
        Normal force per pose, N (default ``tool.force``).

    Returns
    -------
    (S,) bool
        Touched samples, in the order they were given to :func:`sample_grid`.
    """
    positions, axes, target = _pose_arrays(grid, positions, axes, tool, force)
    cap = np.ascontiguousarray(max_sink, dtype=np.float64)
    if cap.shape != (len(positions),):
        raise InputError(f"max_sink must be one depth (m) per pose, shape ({len(positions)},), got {cap.shape}")
    hit = np.zeros(len(grid), bool)
    if len(positions) and len(grid):
        R = float(tool.pad_radius)
        _touched(grid.points, grid.normals, grid.areas, grid.origin, grid.cell, grid.dims, grid.start, positions,
                 axes, target, cap, R, BALL * R, hit)
    out = np.zeros(len(grid), bool)
    out[grid.order] = hit
    return out
