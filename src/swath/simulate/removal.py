"""Preston material removal over the surface, and the metrics of a finishing plan.

Removal rate at a surface point under the pad is Preston's ``k_p · p · v_rel`` (FORMATS.md): ``p``
from the pad contact model at each in-contact pose, ``v_rel`` the abrasive's sliding speed
(uniform for an orbital pad, ``ω·r`` for a rotary one).  Depth is integrated over the
trajectory's in-contact samples at removal samples that cover the part at a set spacing in both
directions (:mod:`swath.simulate.samples`; or, with ``sampling="mesh"``, the vertices of a
subdivided copy of the part).

The integration runs in the compiled kernels of :mod:`swath.contact.kernels` (numba: each pose's
force balance solved and its removal added straight into the depth array, memory just the
samples), or, with ``engine="numpy"`` or without numba, on the vectorised pose-sample pair lists of
:func:`swath.contact.mesh_contact` (the earlier path, kept as the reference).

Each integration pose stands for a stretch of travel (about two sample spacings), and the removal
of a sample is integrated exactly over that stretch (:mod:`swath.contact.swept`), not read at the
pose alone: the pressure jumps at the pad's rim, and a Riemann sum over poses aliased that jump
into the depth (4 % steps for the flat default pad, and a led pad's ripple read 6.0 % CoV where
FORMATS.md's model gives 3.7 %).
"""

from __future__ import annotations

import logging
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial import cKDTree

from ..contact import Tool, mesh_contact
from ..contact.tool import sample_spacing_for
from ..contact.widths import coverage_lower_bound, lower_bound_density, pad_scale_samples, surface_memo  # noqa: F401
from ..core.cpus import usable_cpus
from ..errors import InputError
from .samples import RemovalSamples, lattice_columns, lattice_count, removal_samples

if TYPE_CHECKING:
    from ..surface import Surface

log = logging.getLogger(__name__)

#: Pad travel between integration poses, as a fraction of the removal-sample spacing, when each
#: pose's removal is integrated over the stretch it stands for (``swept=True``, the default): the
#: integral is exact along a straight pass on a plane, so the poses need not be denser than the
#: pad's path curves.  Against poses every 0.25 spacings the interior CoV of a raster on the blade
#: and the panel (flat pad and 11° lead) moves by at most 0.002, as at 1 spacing.
INTEGRATION_STEP = 2.0
#: The same for poses evaluated at their own position only (``swept=False``): the depth of a sample
#: is summed from poses about one sample spacing apart.  Against every trajectory sample (about
#: 1 mm apart) the removal mean is unchanged and the CoV moves from 0.0864 to 0.0865 on a 22 m
#: raster of the panel, at 2.4 times less cost (flat pad; a led pad aliases, see ``swept``).
POINT_INTEGRATION_STEP = 1.0


@dataclass(frozen=True, eq=False)
class RemovalMap:
    """Predicted removal depth on a sampled copy of the part surface.

    Attributes
    ----------
    surface : RemovalSamples or Surface
        The samples the removal is computed at (:class:`~swath.simulate.samples.RemovalSamples`:
        ``vertices``, ``normals``, ``vertex_areas`` and display ``faces``; or a subdivided
        :class:`~swath.surface.Surface`), fine enough that the pad spans many samples.
    depth : (n,) float
        Removal depth at each sample (``surface.vertices``), m.
    metrics : dict
        Figures derived from the removal and the trajectory; every key carries its unit
        (see :func:`plan_metrics`).
    """

    surface: RemovalSamples | Surface
    depth: np.ndarray
    metrics: dict = field(default_factory=dict)

    @property
    def covered(self) -> np.ndarray:
        """(n,) bool: samples the pressed pad touched at least once."""
        return self.depth > 0


#: The removal engines of :func:`simulate_removal`.
ENGINES = ("auto", "compiled", "numpy")

#: The removal samplings of :func:`simulate_removal`.
SAMPLINGS = ("lattice", "mesh")

#: The removal samples are kept below this count: on a larger part the sample spacing grows (and
#: the metrics say so), so the simulation's memory stays bounded whatever the part's size.
MAX_REMOVAL_SAMPLES = 2_500_000


#: Vertices per ``area / (0.433 spacing²)`` that :meth:`swath.surface.Surface.subdivided` gives at
#: most on the meshes measured (1.2 on regular grids, 1.7-1.8 on the CAD part crs_part_5; an edge
#: just over the spacing is cut into two, so up to about 2 on a mesh of edges slightly too long).
#: Meshes of slivers narrower than the spacing can need more (their short edges are never split):
#: :func:`simulate_removal` counts the real samples and widens the spacing again if they exceed the cap.
SUBDIVISION_DENSITY = 2.0


def samples_for_area(area: float, spacing: float) -> int:
    """An upper estimate of how many vertices a surface of ``area`` (m²) subdivided to edges of
    ``spacing`` (m) has (:data:`SUBDIVISION_DENSITY` times the ``area / (0.433 spacing²)`` of an
    even mesh; not for meshes of slivers narrower than ``spacing``)."""
    return int(SUBDIVISION_DENSITY * area / (0.433 * spacing**2)) + 1


def spacing_for_samples(area: float, samples: int) -> float:
    """The sample spacing (m) at which :func:`samples_for_area` of ``area`` (m²) is ``samples``."""
    return float(np.sqrt(SUBDIVISION_DENSITY * area / (0.433 * samples)))


def contact_dwell(trajectory) -> np.ndarray:
    """(n,) time (s) each trajectory sample stands for in contact: half of each adjacent step whose
    two ends are both in contact."""
    c = trajectory.contact
    dt = np.diff(trajectory.t)
    both = c[1:] & c[:-1]
    half = np.where(both, 0.5 * dt, 0.0)
    dwell = np.zeros(len(c))
    dwell[:-1] += half
    dwell[1:] += half
    return dwell


def simulate_removal(trajectory, surface, tool: Tool, *, sample_spacing: float | None = None,
                     chunk: int = 1500, progress=None, force=None, engine: str = "auto",
                     sampling: str = "mesh", rate_scale=None, holds: dict | None = None,
                     swept: bool = True) -> RemovalMap:
    """Integrate Preston removal of ``trajectory`` over ``surface``.

    Parameters
    ----------
    trajectory : Trajectory
        Timed poses; only in-contact samples remove material.
    surface : Surface
        The part surface (part frame, normals toward the tool).
    tool : Tool
    sample_spacing : float, optional
        Distance between removal samples, m (default :func:`sample_spacing_for`); widened, with a
        warning and ``metrics["removal_sample_spacing_m"]`` saying so, where the part would need
        more than :data:`MAX_REMOVAL_SAMPLES`.
    chunk : int
        Poses per batch (numpy engine: memory ~ chunk × samples under the pad); ``progress`` is
        called after each.
    progress : callable, optional
        Called as ``progress(done, total)`` after each batch.
    force : (n,) float, optional
        Normal force per trajectory sample, N (e.g. ``ForceTrace.force`` from
        :func:`swath.simulate.simulate_force`): each integration pose solves the force balance for
        the dwell-weighted mean force of the samples it stands for, instead of ``tool.force``.
    engine : {"auto", "compiled", "numpy"}
        ``"compiled"``: the numba kernel of :mod:`swath.contact.kernels` (float64, no pair lists:
        memory is the samples); ``"numpy"``: the vectorised pair lists of
        :func:`swath.contact.mesh_contact` in float32 (the earlier path, 10-20 times slower);
        ``"auto"``: compiled when numba is installed.  Both evaluate the same model; their depths
        differ by the numpy path's float32 rounding (about 1e-5 relative).
    rate_scale : (n,) float, optional
        Factor on the removal rate per trajectory sample, e.g. the pad wear ``exp(−λ a)`` of
        :func:`swath.process.media.media_schedule` (default 1 everywhere).
    holds : dict, optional
        Poses where the tool stands still in contact (the landings and lifts of
        :attr:`swath.simulate.force.ForceTrace.holds`: ``position``, ``axis``, ``dwell``,
        ``force``), added to the trajectory's integration poses.
    sampling : {"lattice", "mesh"}
        ``"lattice"``: :func:`swath.simulate.samples.removal_samples`, samples at most
        ``sample_spacing`` apart along and across every triangle (a sliver gets one row), normals
        interpolated from the part's; ``"mesh"``: the vertices of
        ``surface.subdivided(sample_spacing)`` (every edge split to at most the spacing; the
        sampling before, several times the samples on meshes of slivers, and slower to build).
        The default stays ``"mesh"`` while :func:`swath.feed.build_kernel` samples the part by
        subdivision (its kernel is checked sample by sample against this simulation).
    swept : bool
        True (default): each integration pose's removal is integrated exactly over the stretch of
        travel it stands for (:mod:`swath.contact.swept`), so the jump of the pressure at the pad's
        rim does not alias against the poses; False: the rate evaluated at the pose only (a
        Riemann sum along the pass, the earlier integration; its depth steps by one pose of the rim
        pressure, 4 % for the flat default pad on 3 mm poses and over 10 % for a led pad).

    Returns
    -------
    RemovalMap
        Depth per sample (``surface``: the :class:`~swath.simulate.samples.RemovalSamples`, or the
        subdivided :class:`~swath.surface.Surface` with ``sampling="mesh"``); ``metrics`` filled
        by :func:`plan_metrics`.
    """
    spacing = sample_spacing_for(tool) if sample_spacing is None else float(sample_spacing)
    if not (np.isfinite(spacing) and spacing > 0):
        raise InputError(f"sample spacing must be positive, got {sample_spacing!r} m")
    if sampling not in SAMPLINGS:
        raise InputError(f"removal sampling must be one of {', '.join(SAMPLINGS)}, got {sampling!r}")
    # imported here: numba takes about half a second to import, needed only when simulating
    from ..contact import kernels

    if engine not in ENGINES:
        raise InputError(f"removal engine must be one of {', '.join(ENGINES)}, got {engine!r}")
    if engine == "compiled" and not kernels.AVAILABLE:
        raise InputError("the compiled removal engine needs numba; install it (pip install numba) or use "
                         "engine='numpy'")
    if sampling == "lattice":
        samples, spacing = _lattice_samples(surface, spacing)
    else:
        samples, spacing = _mesh_samples(surface, spacing)
    # Coordinates relative to the part's centre: a part far from the origin keeps its micrometre heights.
    origin = 0.5 * (samples.vertices.min(axis=0) + samples.vertices.max(axis=0))
    local = samples.vertices - origin
    positions = trajectory.position - origin
    step = INTEGRATION_STEP if swept else POINT_INTEGRATION_STEP
    idx, dwell, live, group = _integration_groups(trajectory, step * spacing)
    if rate_scale is not None:
        # removal is linear in the rate: a factor on the rate is the same factor on the dwell
        dwell = dwell * np.asarray(rate_scale, float)[idx]
    pose_force = None
    if force is not None:
        pose_force = _pose_force(trajectory, force, idx)
    axes = trajectory.tool_z()
    pose_pos, pose_axes = positions[idx], axes[idx]
    stretch = None
    if swept:
        stretch = _stretches(trajectory, live, group, idx)
        stretch[:, :, 0, :] -= origin
        # the force balance at the middle of each stretch: the sink held over it is then centred
        # (at a pass end, where the sink changes fast as the pad runs off the edge, a pose at one
        # end of its stretch would tilt the result toward the direction of travel)
        pose_pos, pose_axes = stretch[:, 1, 0, :].copy(), stretch[:, 1, 1, :].copy()
    if holds is not None and len(holds["dwell"]):
        hold_pos, hold_axes = np.asarray(holds["position"], float) - origin, np.asarray(holds["axis"], float)
        pose_pos = np.concatenate([pose_pos, hold_pos])
        pose_axes = np.concatenate([pose_axes, hold_axes])
        if stretch is not None:       # a hold stands still: its stretch is the pose itself
            still = np.stack([hold_pos, hold_axes], axis=1)[:, None, :, :].repeat(3, axis=1)
            stretch = np.concatenate([stretch, still])
        dwell = np.concatenate([dwell, np.asarray(holds["dwell"], float)])
        own = np.full(len(idx), tool.force) if pose_force is None else pose_force
        pose_force = np.concatenate([own, np.asarray(holds["force"], float)])
    run = _depth_numpy if engine == "numpy" or not kernels.AVAILABLE else _depth_compiled
    depth = run(local, samples.normals, samples.vertex_areas, pose_pos, pose_axes, dwell, tool,
                pose_force=pose_force, chunk=chunk, progress=progress, stretch=stretch)
    removal = RemovalMap(samples, depth)
    metrics = plan_metrics(trajectory, surface, tool, removal)
    metrics["removal_sample_spacing_m"] = spacing
    return RemovalMap(samples, depth, metrics)


def _lattice_samples(surface, spacing: float):
    """(RemovalSamples, spacing used, m): the lattice of :func:`removal_samples` at ``spacing``,
    widened until it has at most :data:`MAX_REMOVAL_SAMPLES` samples (counted before any is made)."""
    memo = getattr(surface, "memo", None)
    if memo is not None:
        # kept with the part through the job (its KD-tree and interior masks with them): a default
        # job simulates the same part at the same spacing five to ten times (crs_part_5: seven,
        # 0.3 s each to sample, index and mask)
        return memo(("removal lattice samples", float(spacing)), lambda: _make_lattice_samples(surface, spacing),
                    lasting=True)
    return _make_lattice_samples(surface, spacing)


def _make_lattice_samples(surface, spacing: float):
    """:func:`_lattice_samples` without the keeping."""
    cols = lattice_columns(surface, spacing)
    while (count := lattice_count(cols)) > MAX_REMOVAL_SAMPLES:
        wider = spacing * 1.02 * float(np.sqrt(count / MAX_REMOVAL_SAMPLES))
        log.warning("removal sampled at %.2f mm instead of %.2f mm: %d samples exceed the %d cap",
                    wider * 1e3, spacing * 1e3, count, MAX_REMOVAL_SAMPLES)
        spacing = wider
        cols = lattice_columns(surface, spacing)
    return removal_samples(surface, spacing, columns=cols), spacing


def _mesh_samples(surface, spacing: float):
    """(Surface, spacing used, m): ``surface.subdivided(spacing)``, the spacing widened first by
    the area estimate and then by the real count until at most :data:`MAX_REMOVAL_SAMPLES`.

    Kept per surface and spacing (:func:`swath.contact.widths.surface_memo`, with the smooth
    normals and areas the samples compute): the feed optimisation simulates the same part several
    times, and on crs_part_5 making the samples took 2.6 s and their normals 1.6 s of each
    simulation.  Read-only, so sharing them is safe."""
    def make():
        samples, used = _make_mesh_samples(surface, spacing)
        # the surface itself is not kept: a memo value holding its own key would never be freed
        return (None if samples is surface else samples), used

    samples, used = surface_memo(surface, ("removal mesh samples", float(spacing)), make)
    return (surface if samples is None else samples), used


def _make_mesh_samples(surface, spacing: float):
    """:func:`_mesh_samples` without the keeping."""
    if samples_for_area(surface.area, spacing) > MAX_REMOVAL_SAMPLES:
        wider = spacing_for_samples(surface.area, MAX_REMOVAL_SAMPLES)
        log.warning("removal sampled at %.2f mm instead of %.2f mm to stay within %d samples (%.2f m² part)",
                    wider * 1e3, spacing * 1e3, MAX_REMOVAL_SAMPLES, surface.area)
        spacing = wider
    samples = surface.subdivided(spacing)
    while len(samples.vertices) > MAX_REMOVAL_SAMPLES and samples is not surface:
        # more than estimated (slivers): widen by the excess and subdivide again
        wider = spacing * 1.05 * float(np.sqrt(len(samples.vertices) / MAX_REMOVAL_SAMPLES))
        log.warning("removal sampled at %.2f mm instead of %.2f mm: %d samples exceed the %d cap",
                    wider * 1e3, spacing * 1e3, len(samples.vertices), MAX_REMOVAL_SAMPLES)
        spacing = wider
        samples = surface.subdivided(spacing)
    return samples, spacing


def _depth_compiled(points, normals, areas, positions, axes, dwell, tool: Tool, *, pose_force=None,
                    chunk: int = 1500, progress=None, stretch=None) -> np.ndarray:
    """Removal depth (m) per sample ``(S,)`` from the compiled kernel (float64; no pair lists).

    ``points, normals (S, 3)``, ``areas (S,)`` (m, m²) are the samples, ``positions, axes (P, 3)``
    the integration poses (m), ``dwell (P,)`` their times (s), ``pose_force (P,)`` their forces (N),
    ``stretch (P, 3, 2, 3)`` the travel each stands for (None: evaluated at the pose only)."""
    from ..contact import kernels
    from ..contact.swept import accumulate_swept_removal

    grid = kernels.sample_grid(points, normals, areas, cell=kernels.default_cell(tool))
    out = np.zeros((kernels.LANES, len(grid)))           # fixed lanes: the same sum on any CPU count
    step = max(int(chunk), 1)
    with ThreadPoolExecutor(max_workers=min(len(out), kernels.default_threads())) as pool:
        for lo in range(0, len(positions), step):
            hi = min(lo + step, len(positions))
            f = None if pose_force is None else pose_force[lo:hi]
            if stretch is None:
                kernels.accumulate_removal(grid, positions[lo:hi], axes[lo:hi], dwell[lo:hi], tool, out=out, force=f,
                                           executor=pool)
            else:
                accumulate_swept_removal(grid, positions[lo:hi], axes[lo:hi], stretch[lo:hi], dwell[lo:hi], tool,
                                         out=out, force=f, executor=pool)
            if progress is not None:
                progress(hi, len(positions))
    return kernels.depth_in_input_order(grid, out)


def _depth_numpy(points, normals, areas, positions, axes, dwell, tool: Tool, *, pose_force=None,
                 chunk: int = 1500, progress=None, stretch=None) -> np.ndarray:
    """Removal depth (m) per sample ``(S,)`` from :func:`swath.contact.mesh_contact` pair lists in
    float32 (the path before the compiled kernel; arguments as :func:`_depth_compiled`)."""
    # float32 for the pad queries (see mesh_contact): half the memory traffic; areas and depths float64.
    pts, nrm = points.astype(np.float32), normals.astype(np.float32)
    tree = cKDTree(points)
    depth = np.zeros(len(pts))

    def batch(lo: int) -> np.ndarray:
        sl = slice(lo, lo + chunk)
        f = None if pose_force is None else pose_force[sl]
        if stretch is not None:
            return _swept_batch(points, nrm, areas, tree, positions[sl], axes[sl], stretch[sl], dwell[sl], tool, f)
        mc = mesh_contact(pts, nrm, areas, tree, positions[sl], axes[sl], tool, force=f)
        rate = tool.preston * mc.pressure * tool.relative_speed(mc.radius)
        return np.bincount(mc.sample, weights=rate * dwell[sl][mc.pose], minlength=len(pts))

    # numpy and the KD-tree release the GIL in their inner loops, so batches overlap on two threads.
    starts = list(range(0, len(positions), chunk))
    with ThreadPoolExecutor(max_workers=max(1, min(2, usable_cpus()))) as pool:
        for k, part in enumerate(pool.map(batch, starts), start=1):
            depth += part
            if progress is not None:
                progress(min(k * chunk, len(positions)), len(positions))
    return depth


def _swept_batch(points, normals, areas, tree, positions, axes, stretch, dwell, tool: Tool, force) -> np.ndarray:
    """Depth (m, ``(S,)``) of a batch of poses each integrated over its stretch, with pose-sample
    pairs from the KD-tree (the numpy form of :func:`swath.contact.swept.accumulate_swept_removal`:
    the force balance of each pose over the samples within ``R`` of its axis, in float64)."""
    from ..contact.kernels import BALL
    from ..contact.model import solve_sink
    from ..contact.swept import stretch_reach, swept_mean_height

    R = tool.pad_radius
    reach = stretch_reach(positions, stretch)
    coo = cKDTree(positions).sparse_distance_matrix(tree, BALL * R + float(reach.max(initial=0.0)),
                                                     output_type="coo_matrix")
    if coo.nnz == 0:
        return np.zeros(len(points))
    pose, sample = coo.row, coo.col
    rel = points[sample] - positions[pose]
    a = axes[pose]
    z = np.einsum("ij,ij->i", rel, a)
    d2 = np.einsum("ij,ij->i", rel, rel)
    r2 = d2 - z * z
    keep = ((np.einsum("ij,ij->i", normals[sample].astype(float), a) < 0.0) & (r2 <= (R + reach[pose]) ** 2 * (1 + 1e-6))
            & (d2 <= (BALL * R + reach[pose]) ** 2))
    pose, sample, z, r2 = pose[keep], sample[keep], z[keep], r2[keep]
    inside = r2 <= R * R * (1 + 1e-6)
    target = np.full(len(positions), tool.force / tool.k) if force is None else np.asarray(force, float) / tool.k
    sink = solve_sink(z[inside], areas[sample[inside]], pose[inside], target)
    ok = np.isfinite(sink[pose])
    pose, sample = pose[ok], sample[ok]
    zs = np.empty((len(pose), 3))
    rs = np.empty((len(pose), 3))
    for e in range(3):
        rel = points[sample] - stretch[pose, e, 0, :]
        zs[:, e] = np.einsum("ij,ij->i", rel, stretch[pose, e, 1, :])
        rs[:, e] = np.einsum("ij,ij->i", rel, rel) - zs[:, e] ** 2
    rotary = tool.motion == "rotary"
    mean = swept_mean_height(zs, rs, sink[pose], R, rotary=rotary)
    speed = tool.spindle_speed if rotary else tool.spindle_speed * tool.orbit_radius
    return np.bincount(sample, weights=tool.preston * tool.k * speed * mean * dwell[pose], minlength=len(points))


def _integration_poses(trajectory, max_travel: float) -> tuple[np.ndarray, np.ndarray]:
    """In-contact poses to integrate at, and the dwell (s) each stands for.

    Consecutive in-contact samples are grouped by their progress along the contact run: each step
    advances it by the larger of the distance travelled and the distance the trajectory's fast feed
    (:func:`_reference_speed`) would cover in the step's time.  A group spans about ``max_travel``
    metres of progress (a whole number of the median progress step; a single longer step is a group
    of its own), and the middle sample of each group carries the group's whole dwell.

    Grouping by travel, not by a fixed sample count, matters where the feed is fast: the trajectory
    is sampled in time (≤ 20 ms), so a fixed count would lump 10-30 mm of a fast stretch into one
    pose.  Bounding the time as well matters where it is slow: a 3 mm group at a tenth of the feed
    holds ten times the dwell of one at the feed, and a removal sample on the edge of the contact
    patch, touched by part of such a group only, got the whole group's dwell or none of it
    (bezier_dac_scan, an optimised feed: 12.2 µm where its samples remove 5.3 µm).  At a constant
    feed the grouping is the distance grouping.  The trajectory is sampled finer than the removal
    samples need, so this loses nothing measurable and saves most of the work.
    """
    rep, sums, _, _ = _integration_groups(trajectory, max_travel)
    return rep, sums


def _integration_groups(trajectory, max_travel: float):
    """:func:`_integration_poses` and the groups behind them: ``(rep, dwell, live, group)`` with
    ``live`` the in-contact samples (indices, ascending) and ``group`` the group of each."""
    dwell = contact_dwell(trajectory)
    live = trajectory.contact & (dwell > 0)
    idx = np.flatnonzero(live)
    if len(idx) == 0:
        return idx, dwell[idx], idx, idx
    step = np.linalg.norm(np.diff(trajectory.position[idx], axis=0), axis=1)
    run_start = np.concatenate([[True], (np.diff(idx) > 1)])
    inner = ~run_start[1:]                                   # steps within a contact run
    step_time = np.diff(trajectory.t[idx])
    v_ref = _reference_speed(step[inner], step_time[inner])
    # progress of each step, m: its travel, or its time at the reference speed where that is longer
    advance = np.maximum(step, v_ref * step_time)
    # progress along each contact run from its start, m
    travel = np.concatenate([[0.0], np.cumsum(np.where(run_start[1:], 0.0, advance))])
    run_id = np.cumsum(run_start) - 1
    travel -= travel[np.flatnonzero(run_start)][run_id]
    # Bucket width: a whole number of the typical step, and a half-step offset, so that at a constant
    # feed every group holds the same number of samples (uneven groups alias against the samples).
    typical = float(np.median(advance[inner])) if inner.any() else max_travel
    width = max(1, int(max_travel / max(typical, 1e-12) + 1e-9)) * typical     # 3 mm / 1 mm is 3, not 2.999
    bucket = np.floor((travel + 0.5 * typical) / width).astype(np.int64)
    group = np.cumsum(np.concatenate([[True], (run_id[1:] != run_id[:-1]) | (bucket[1:] != bucket[:-1])])) - 1
    sums = np.bincount(group, weights=dwell[idx])
    counts = np.bincount(group)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    rep = idx[starts + counts // 2]
    return rep, sums, idx, group


def _stretches(trajectory, live: np.ndarray, group: np.ndarray, rep: np.ndarray) -> np.ndarray:
    """(G, 3, 2, 3): for each integration group, the start, middle and end of the travel it
    stands for (position, m, and unit tool z-axis each; :mod:`swath.contact.swept`).

    A sample stands for half of each in-contact step next to it (:func:`contact_dwell`), so a group
    runs from halfway before its first sample to halfway after its last (the sample itself at the
    ends of a contact run); its middle is halfway along that arc.  Positions and axes between
    samples are interpolated linearly in arc length (axes normalised)."""
    G = len(rep)
    out = np.empty((G, 3, 2, 3))
    if G == 0:
        return out
    pos = trajectory.position[live]
    axes = trajectory.tool_z()[live]
    run_start = np.concatenate([[True], np.diff(live) > 1])
    step = np.concatenate([[0.0], np.linalg.norm(np.diff(pos, axis=0), axis=1)])
    step[run_start] = 1.0                       # a gap between runs: the arc never joins them
    arc = np.cumsum(step)
    before = np.where(run_start, arc, arc - 0.5 * step)
    run_end = np.concatenate([run_start[1:], [True]])
    after = np.where(run_end, arc, arc + 0.5 * np.concatenate([step[1:], [0.0]]))
    first = np.concatenate([[0], np.flatnonzero(np.diff(group)) + 1])
    last = np.concatenate([first[1:] - 1, [len(group) - 1]])
    ends = np.stack([before[first], 0.5 * (before[first] + after[last]), after[last]], axis=1)   # (G, 3)
    for d in range(3):
        out[:, :, 0, d] = np.interp(ends, arc, pos[:, d])
        out[:, :, 1, d] = np.interp(ends, arc, axes[:, d])
    out[:, :, 1, :] /= np.linalg.norm(out[:, :, 1, :], axis=2, keepdims=True)
    return out


def _reference_speed(step: np.ndarray, step_time: np.ndarray) -> float:
    """The trajectory's fast in-contact feed (m/s): the speed exceeded on only a tenth of the
    contact path, from the steps ``step (k,)`` (m) and their times ``step_time (k,)`` (s).  The
    feed limit of a timed trajectory at a constant feed; a spike on a few steps does not move it."""
    moving = (step > 0) & (step_time > 0)
    if not moving.any():
        return 0.0
    speed = step[moving] / step_time[moving]
    order = np.argsort(speed)
    along = np.cumsum(step[moving][order])
    return float(speed[order][min(np.searchsorted(along, 0.9 * along[-1]), len(order) - 1)])


def _pose_force(trajectory, force, idx: np.ndarray) -> np.ndarray:
    """Force (N) at each integration pose ``idx``: the dwell-weighted mean of ``force`` over the
    in-contact samples nearest to it along the trajectory (the samples it stands for)."""
    force = np.asarray(force, float)
    if force.shape != (len(trajectory),) or not np.all(np.isfinite(force)) or np.any(force < 0):
        raise InputError(f"force must be ({len(trajectory)},) finite non-negative newtons, one per trajectory "
                         f"sample, got shape {force.shape}")
    if len(idx) == 0:
        return np.zeros(0)
    dwell = contact_dwell(trajectory)
    live = np.flatnonzero(trajectory.contact & (dwell > 0))
    # each live sample belongs to the nearest representative at or after its group start
    owner = np.clip(np.searchsorted(idx, live, side="left"), 0, len(idx) - 1)
    prev = np.clip(owner - 1, 0, len(idx) - 1)
    closer_prev = np.abs(live - idx[prev]) < np.abs(idx[owner] - live)
    owner = np.where(closer_prev, prev, owner)
    w = dwell[live]
    num = np.bincount(owner, weights=w * force[live], minlength=len(idx))
    den = np.bincount(owner, weights=w, minlength=len(idx))
    return np.where(den > 0, num / np.maximum(den, 1e-300), force[idx])


def _weighted_mean_std(values: np.ndarray, weights: np.ndarray) -> tuple[float, float]:
    """Weighted mean and standard deviation of ``values`` ``(k,)`` (``weights`` ``(k,)``, not all 0)."""
    mean = float(np.average(values, weights=weights))
    return mean, float(np.sqrt(np.average((values - mean) ** 2, weights=weights)))


def plan_metrics(trajectory, surface, tool: Tool, removal: RemovalMap) -> dict:
    """Every figure of a plan, keys with units.

    ``coverage_fraction`` is the area fraction the pressed pad touched (``effective_coverage_fraction``:
    the fraction that received at least 10 % of the median depth); ``removal_cov`` the
    area-weighted coefficient of variation of depth over the touched area; ``efficiency`` is ``L*`` of
    the touched area (``covered_lower_bound_m``) over ``L_contact``, at most 1 for any plan up to the
    sampling (``coverage_lower_bound_m`` is ``L*`` of the whole part).  ``interior_removal_cov`` is
    the coefficient of variation over the samples more than a pad radius from the open boundary,
    untouched ones included (``interior_area_m2``; the whole part when it is closed): the band at
    the edge, where the pad hangs over, is left out, as issue 12's figure and the feed
    optimisation's region leave it out.
    """
    a = removal.surface.vertex_areas
    d = removal.depth
    cov = d > 0
    covered_area = float(a[cov].sum())
    total = float(a.sum())
    if cov.any():
        w = a[cov]
        mean, std = _weighted_mean_std(d[cov], w)
        order = np.argsort(d[cov])
        cdf = np.cumsum(w[order]) / w.sum()
        pct = lambda q: float(d[cov][order][min(int(np.searchsorted(cdf, q)), len(order) - 1)])
        median = pct(0.5)
        effective = float(a[d >= 0.1 * median].sum()) / total if median > 0 else 0.0
        p5, p95 = pct(0.05), pct(0.95)
    else:
        # The trajectory never touched the part: no depth statistics (NaN), zero coverage.
        mean = std = median = effective = p5 = p95 = float("nan")
    inner = removal.surface.farther_from_boundary(tool.pad_radius)
    cov_interior = float("nan")
    if inner.any() and len(d):
        mean_i, std_i = _weighted_mean_std(d[inner], a[inner])
        if mean_i > 0:
            cov_interior = std_i / mean_i
    L_contact = trajectory.contact_length
    # L* over the whole part, and over the part the plan touched: efficiency compares the path run
    # with the shortest that could have covered what it covered, so it cannot pass 1 by leaving
    # area untouched.
    pad = pad_scale_samples(surface, tool)
    memo = getattr(surface, "memo", None)
    # the same for every simulation of the part with this pad (0.27 s each on crs_part_5)
    density = (lower_bound_density(pad, tool) if memo is None else
               memo(("lower bound density", tool), lambda: lower_bound_density(pad, tool), lasting=True))
    L_star = float(density.sum())
    touched = d[removal.surface.kdtree.query(pad.points)[1]] > 0 if len(d) else np.zeros(len(density), bool)
    L_star_touched = float(density[touched].sum())
    return {
        "surface_area_m2": total,
        "covered_area_m2": covered_area,
        "coverage_fraction": covered_area / total if total > 0 else 0.0,
        "effective_coverage_fraction": effective,
        "removal_mean_m": mean,
        "removal_std_m": std,
        "removal_cov": std / mean if mean and mean > 0 else float("nan"),
        "interior_removal_cov": cov_interior,
        "interior_area_m2": float(a[inner].sum()),
        "removal_p5_m": p5,
        "removal_median_m": median,
        "removal_p95_m": p95,
        "removal_max_m": float(d.max()) if len(d) else float("nan"),
        "contact_length_m": L_contact,
        "air_length_m": trajectory.air_length,
        "cycle_time_s": trajectory.duration,
        "contact_time_s": float(contact_dwell(trajectory).sum()),
        "coverage_lower_bound_m": L_star,
        "covered_lower_bound_m": L_star_touched,
        "efficiency": L_star_touched / L_contact if L_contact > 0 else float("nan"),
        "n_passes": int(trajectory.pass_index.max() + 1) if len(trajectory) else 0,
        "n_samples": int(len(trajectory)),
        "n_removal_samples": int(len(d)),
    }
