"""The removal kernel: depth removed per second of dwell, per dwell node, at every surface sample.

Each pass of a :class:`~swath.plan.ToolPath` is cut into *dwell nodes*: consecutive arc-length
intervals of about ``node_spacing`` (default a few mm).  When the pad crosses node ``i`` at a constant
speed, every surface sample ``j`` it touches there loses depth at the mean Preston rate

    K[j, i] = mean over poses in the node of  k_p · p_j · v_rel(r_j)          (m/s)

with ``p_j`` from the force-balanced contact patch (the compiled contact kernels of
:mod:`swath.contact.kernels` in float64, as :func:`swath.simulate.simulate_removal` uses them, or
without numba :func:`swath.contact.mesh_contact` in float32: the same model) and ``v_rel`` the
abrasive's sliding speed (uniform for an orbital pad, ``ω·r`` for a rotary one).  The removal of a
plan that spends ``t_i`` seconds in node ``i`` is ``K @ t``.

The matrix is built in chunks of poses, so memory stays bounded by the number of non-zeros (about
``samples under the pad × nodes``) plus one chunk's pair list.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..contact import Tool, mesh_contact
from ..contact.tool import sample_spacing_for
from ..errors import InputError
from ..surface import Surface
from ..trajectory.geometry import arc_length

log = logging.getLogger(__name__)


def default_node_spacing(tool: Tool) -> float:
    """Default dwell-node length along a pass, m: a sixth of the pad radius, at most 6 mm."""
    return min(6e-3, tool.pad_radius / 6)


@dataclass(frozen=True, eq=False)
class DwellNodes:
    """Dwell nodes along the passes of a tool path.

    Attributes
    ----------
    pass_index : (n,) int
        Pass each node belongs to.
    s_start, s_end : (n,) float
        Arc-length interval of the node along its pass, m.
    position : (n, 3) float
        Pass point at the middle of the node, m, part frame.
    pass_start : (p + 1,) int
        Nodes of pass ``k`` are ``pass_start[k]:pass_start[k + 1]``.
    """

    pass_index: np.ndarray
    s_start: np.ndarray
    s_end: np.ndarray
    position: np.ndarray
    pass_start: np.ndarray

    def __len__(self) -> int:
        return len(self.pass_index)

    @property
    def length(self) -> np.ndarray:
        """(n,) node length along the pass, m."""
        return self.s_end - self.s_start

    @property
    def s_mid(self) -> np.ndarray:
        """(n,) arc length of the node middles, m."""
        return 0.5 * (self.s_start + self.s_end)


@dataclass(frozen=True, eq=False)
class RemovalKernel:
    """Removal rate of every dwell node at every surface sample.

    Attributes
    ----------
    matrix : scipy.sparse.csc_matrix, (S, n) float
        Depth removal rate ``K[j, i]`` at sample ``j`` while the pad dwells in node ``i``, m/s.
    samples : Surface
        The sampled part (``surface.subdivided(sample_spacing)``; the simulator's samples).
    nodes : DwellNodes
    toolpath : ToolPath
    tool : Tool
    pose_step : float
        Spacing of the contact poses within a node, m (see :func:`build_kernel`).
    spread : str
        How a node's dwell is shared among its poses: ``"even"`` or ``"timed"`` (see :func:`build_kernel`).
    """

    matrix: sp.csc_matrix
    samples: Surface
    nodes: DwellNodes
    toolpath: object
    tool: Tool
    pose_step: float = 0.0
    spread: str = "even"

    def respread(self, trajectory, *, progress=None) -> RemovalKernel:
        """This kernel (same nodes, samples and poses) with each node's dwell shared among its poses
        as ``trajectory`` shares it: ``trajectory`` is this tool path timed with the feed being
        planned (see ``spread="timed"`` in :func:`build_kernel`)."""
        return build_kernel(self.toolpath, self.tool, nodes=self.nodes, samples=self.samples,
                            pose_step=self.pose_step, trajectory=trajectory, spread="timed", progress=progress)

    def removal(self, dwell: np.ndarray) -> np.ndarray:
        """Depth ``(S,)`` (m) removed by dwell times ``(n,)`` (s)."""
        return self.matrix @ np.asarray(dwell, float)

    def dwell_at_speed(self, speed) -> np.ndarray:
        """Dwell ``(n,)`` (s) of crossing every node at ``speed`` (m/s, scalar or ``(n,)``)."""
        return self.nodes.length / np.asarray(speed, float)


def dwell_nodes(toolpath, *, node_spacing: float) -> DwellNodes:
    """Cut every pass of ``toolpath`` into nodes of equal length, at most ``node_spacing`` (m)."""
    if not (np.isfinite(node_spacing) and node_spacing > 0):
        raise InputError(f"node spacing must be a positive length in m, got {node_spacing!r}")
    pidx, s0, s1, pos, starts = [], [], [], [], [0]
    for k, p in enumerate(toolpath.passes):
        s = arc_length(p.points)
        length = s[-1]
        m = max(int(np.ceil(length / node_spacing - 1e-9)), 1)
        edges = np.linspace(0.0, length, m + 1)
        mid = 0.5 * (edges[:-1] + edges[1:])
        pidx.append(np.full(m, k))
        s0.append(edges[:-1])
        s1.append(edges[1:])
        pos.append(_interp_polyline(s, p.points, mid))
        starts.append(starts[-1] + m)
    return DwellNodes(np.concatenate(pidx), np.concatenate(s0), np.concatenate(s1), np.vstack(pos),
                      np.asarray(starts))


def _interp_polyline(s: np.ndarray, values: np.ndarray, at: np.ndarray) -> np.ndarray:
    keep = np.concatenate([[True], np.diff(s) > 0])
    s, values = s[keep], values[keep]
    return np.stack([np.interp(at, s, values[:, c]) for c in range(values.shape[1])], axis=1)


def _pass_geometry(toolpath, trajectory):
    """Per pass: arc length ``(k,)`` (m, on the pass polyline's scale), positions ``(k, 3)``, tool
    z-axes ``(k, 3)`` and times ``(k,)`` (s, or None) to interpolate poses from: the pass polyline
    and minus its normals (no times), or the timed trajectory's in-contact samples of that pass
    (travelled distance scaled to the pass length, as :func:`trajectory_node_dwell` reads it)."""
    out = []
    tz = None if trajectory is None else trajectory.tool_z()
    for k, p in enumerate(toolpath.passes):
        if trajectory is not None:
            sel = np.flatnonzero((trajectory.pass_index == k) & trajectory.contact)
            if len(sel) >= 2:
                s = arc_length(trajectory.position[sel])
                s = s * (p.length / s[-1]) if s[-1] > 0 else s
                out.append((s, trajectory.position[sel], tz[sel], trajectory.t[sel]))
                continue
        out.append((arc_length(p.points), p.points, -p.normals, None))
    return out


#: Largest turn of the tool axis between two poses of a node, rad (1 degree).  Where a scan's noisy
#: normals swing the axis fast (tens of degrees per mm, so the angular-speed limit crawls there), the
#: pressure at the patch rim changes from one millimetre to the next by a factor of several: poses
#: only a distance step apart there missed 12 % of a rim sample's removal on bezier_dac_scan.
MAX_POSE_TURN = np.radians(1.0)


def _turn_along(s: np.ndarray, zaxes: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Cumulative turn (rad) of the unit axes ``zaxes (k, 3)`` along ``s (k,)``, read at ``at``."""
    z = zaxes / np.maximum(np.linalg.norm(zaxes, axis=1, keepdims=True), 1e-300)
    cos = np.clip(np.einsum("ij,ij->i", z[:-1], z[1:]), -1.0, 1.0)
    turn = np.concatenate([[0.0], np.cumsum(np.arccos(cos))])
    keep = np.concatenate([[True], np.diff(s) > 0])
    return np.interp(at, s[keep], turn[keep])


def _sub_poses(toolpath, nodes: DwellNodes, step: float, trajectory=None, *, timed: bool = False):
    """Poses spread evenly through every node: about ``step`` apart, and closer where the tool axis
    turns more than :data:`MAX_POSE_TURN` in a step.  Returns positions, tool z-axes, the node of
    each pose and its weight: its share of the node's dwell, 1 / poses in the node (the dwell spread
    evenly along it), or with ``timed`` the share of the node's time ``trajectory`` spends in the
    pose's stretch of the node (evenly in a node where it spends no time)."""
    pos, axes, node, weight = [], [], [], []
    for k, (s, points, zaxes, times) in enumerate(_pass_geometry(toolpath, trajectory)):
        a, b = nodes.pass_start[k], nodes.pass_start[k + 1]
        length = nodes.length[a:b]
        turn = np.diff(_turn_along(s, zaxes, np.append(nodes.s_start[a:b], nodes.s_end[b - 1])))
        m = np.maximum(np.ceil(np.maximum(length / step, turn / MAX_POSE_TURN) - 1e-9).astype(int), 1)
        nid = np.repeat(np.arange(a, b), m)
        local = np.arange(len(nid)) - np.repeat(np.cumsum(m) - m, m)
        at = nodes.s_start[nid] + (local + 0.5) / m[nid - a] * nodes.length[nid]
        pos.append(_interp_polyline(s, points, at))
        z = _interp_polyline(s, zaxes, at)
        axes.append(z / np.maximum(np.linalg.norm(z, axis=1, keepdims=True), 1e-300))
        node.append(nid)
        share = 1.0 / m[nid - a]
        if timed and times is not None:
            keep = np.concatenate([[True], np.diff(s) > 0])
            lo = nodes.s_start[nid] + local / m[nid - a] * nodes.length[nid]
            dt = np.diff(np.interp(np.stack([lo, lo + share * nodes.length[nid]]), s[keep], times[keep]), axis=0)[0]
            total = np.bincount(nid - a, weights=dt, minlength=b - a)[nid - a]
            share = np.where(total > 0, dt / np.where(total > 0, total, 1.0), share)
        weight.append(share)
    return np.vstack(pos), np.vstack(axes), np.concatenate(node), np.concatenate(weight)


#: Most surface samples a kernel uses by default: a larger part is sampled more coarsely (the cost
#: grows with samples × poses, about the cube of 1 / spacing).
MAX_KERNEL_SAMPLES = 400_000
#: Most dwell nodes by default: on longer paths the nodes grow (the programme's size follows them).
MAX_KERNEL_NODES = 6000


def kernel_sample_spacing(surface, tool: Tool, *, max_samples: int = MAX_KERNEL_SAMPLES) -> float:
    """Default kernel sample spacing, m: the simulator's (:func:`sample_spacing_for`), widened so
    the part holds at most about ``max_samples`` samples (a subdivided mesh holds about
    ``area / (0.2 spacing²)`` vertices)."""
    spacing = sample_spacing_for(tool)
    return max(spacing, float(np.sqrt(surface.area / (0.2 * max_samples))))


def build_kernel(toolpath, tool: Tool, *, node_spacing: float | None = None, sample_spacing: float | None = None,
                 pose_step: float | None = None, samples=None, trajectory=None, spread: str = "even",
                 nodes: DwellNodes | None = None, chunk: int = 2000, engine: str = "auto",
                 progress=None) -> RemovalKernel:
    """Build the removal kernel of ``toolpath`` on its surface.

    Parameters
    ----------
    toolpath : ToolPath
        Passes on ``toolpath.surface`` (part frame, normals toward the tool).
    tool : Tool
        The pad (radius, force, stiffness, Preston coefficient, orbital or rotary).
    node_spacing : float, optional
        Dwell-node length along the passes, m (default :func:`default_node_spacing`, longer on paths
        that would need more than :data:`MAX_KERNEL_NODES` nodes).
    sample_spacing : float, optional
        Largest edge of the sampled surface, m (default :func:`kernel_sample_spacing`: the
        simulator's, coarser on parts that would need more than :data:`MAX_KERNEL_SAMPLES`).
    pose_step : float, optional
        Spacing of the contact poses averaged within a node, m (default: half the sample spacing,
        which halves the ripple a pose grid leaves on single samples); closer where the tool axis
        turns more than :data:`MAX_POSE_TURN` in a step.
    samples : Surface, optional
        The sampled surface to use (``toolpath.surface.subdivided(sample_spacing)``), when the
        caller already has it (saves the subdivision and its KD-tree when many kernels are built).
    trajectory : Trajectory, optional
        ``toolpath`` already timed (any feed): the contact poses are then read from its in-contact
        samples (the positions and tool axes the robot will use, after the timing stage's projection
        and normal smoothing) instead of the pass polylines.  On noisy scans this keeps the kernel
        and :func:`swath.simulate.simulate_removal` of the final trajectory on the same poses.
    spread : {"even", "timed"}
        How a node's dwell is shared among its poses.  ``"even"``: evenly along the node (a
        constant feed through it).  ``"timed"``: as ``trajectory`` (required) spends its time in the
        node; give the tool path timed with the feed being planned.  Where the feed steps between
        nodes (5 to 50 mm/s on a scan's crawl zones), the timing changes speed within the last
        millimetre of a node, and a sample at the patch rim can lose 25 % more than the even spread
        predicts; :meth:`RemovalKernel.respread` rebuilds a kernel this way.
    nodes : DwellNodes, optional
        Use these nodes (of this tool path) instead of cutting new ones (``node_spacing`` is then
        ignored).
    chunk : int
        Poses per vectorised batch (memory about ``chunk ×`` samples under the pad pairs).
    engine : {"auto", "compiled", "numpy"}
        The contact model's evaluation: ``"compiled"`` the numba kernels
        (:func:`swath.contact.kernels.contact_pairs` on one cell grid of the samples, float64),
        ``"numpy"`` :func:`swath.contact.mesh_contact` (KD-tree pairs, float32, three to ten times
        slower), ``"auto"`` compiled when numba is installed.  The same pairs; the rates differ by
        the float32 rounding (about 1e-6 relative).
    progress : callable, optional
        ``progress(done, total)`` after each batch.

    Returns
    -------
    RemovalKernel
    """
    from ..contact import kernels

    if engine not in ("auto", "compiled", "numpy"):
        raise InputError(f"kernel engine must be 'auto', 'compiled' or 'numpy', got {engine!r}")
    if engine == "compiled" and not kernels.AVAILABLE:
        raise InputError("the compiled kernel engine needs numba; install it (pip install numba) or use engine='numpy'")
    compiled = engine == "compiled" or (engine == "auto" and kernels.AVAILABLE)
    if not toolpath.passes:
        raise InputError("the tool path has no passes; plan passes before building a removal kernel")
    if sample_spacing is not None:
        spacing = float(sample_spacing)
    elif samples is not None:
        spacing = sample_spacing_for(tool)
    else:
        spacing = kernel_sample_spacing(toolpath.surface, tool)
    if not (np.isfinite(spacing) and spacing > 0):
        raise InputError(f"sample spacing must be a positive length in m, got {sample_spacing!r}")
    if spread not in ("even", "timed"):
        raise InputError(f"spread must be 'even' or 'timed', got {spread!r}")
    if spread == "timed" and trajectory is None:
        raise InputError("spread='timed' shares each node's dwell as a timed trajectory does; give trajectory=")
    if nodes is None:
        if node_spacing is None:
            node_spacing = max(default_node_spacing(tool), toolpath.contact_length / MAX_KERNEL_NODES)
        nodes = dwell_nodes(toolpath, node_spacing=node_spacing)
    step = 0.5 * spacing if pose_step is None else float(pose_step)
    if samples is None:
        samples = toolpath.surface.subdivided(spacing)
    if compiled:
        grid = kernels.sample_grid(samples.vertices, samples.normals, samples.vertex_areas,
                                   cell=kernels.default_cell(tool))
    else:
        pts, nrm = samples.vertices.astype(np.float32), samples.normals.astype(np.float32)
        area, tree = samples.vertex_areas, samples.kdtree
    position, axes, node, weight = _sub_poses(toolpath, nodes, step, trajectory, timed=spread == "timed")
    S, n = len(samples.vertices), len(nodes)
    blocks = []
    if progress is not None:
        progress(0, len(position))
    for lo in range(0, len(position), chunk):
        hi = min(lo + chunk, len(position))
        if compiled:
            pose, sample, pressure, radius, _ = kernels.contact_pairs(grid, position[lo:hi], axes[lo:hi], tool)
        else:
            mc = mesh_contact(pts, nrm, area, tree, position[lo:hi], axes[lo:hi], tool)
            pose, sample, pressure, radius = mc.pose, mc.sample, mc.pressure, mc.radius
        rate = tool.preston * pressure * tool.relative_speed(radius) * weight[lo:hi][pose]
        blocks.append(sp.csc_matrix((rate, (sample, node[lo:hi][pose])), shape=(S, n)))
        if len(blocks) > 8:                                  # keep the pending list short
            blocks = [sum(blocks[1:], blocks[0]).tocsc()]
        if progress is not None:
            progress(hi, len(position))
    matrix = sum(blocks[1:], blocks[0]).tocsc() if blocks else sp.csc_matrix((S, n))
    matrix.sum_duplicates()
    log.info("removal kernel: %d samples x %d nodes, %d non-zeros (%d poses)", S, n, matrix.nnz, len(position))
    return RemovalKernel(matrix, samples, nodes, toolpath, tool, step, spread)


def trajectory_node_dwell(trajectory, nodes: DwellNodes, toolpath) -> np.ndarray:
    """Dwell ``(n,)`` (s) a timed trajectory spends in each node.

    Along each pass the trajectory's in-contact samples give time against travelled distance
    (scaled to the pass's polyline length); a node's dwell is the time between reaching its start
    and its end, read by linear interpolation (exact for the piecewise-constant-speed steps; no
    rounding to whole samples).
    """
    out = np.zeros(len(nodes))
    for k, p in enumerate(toolpath.passes):
        sel = np.flatnonzero((trajectory.pass_index == k) & trajectory.contact)
        if len(sel) < 2:
            continue
        s = arc_length(trajectory.position[sel])
        total = s[-1]
        s = s * (p.length / total) if total > 0 else s
        t = trajectory.t[sel]
        keep = np.concatenate([[True], np.diff(s) > 0])
        a, b = nodes.pass_start[k], nodes.pass_start[k + 1]
        t_at = lambda x: np.interp(x, s[keep], t[keep])
        out[a:b] = t_at(nodes.s_end[a:b]) - t_at(nodes.s_start[a:b])
    return out


def interior_mask(samples, margin: float) -> np.ndarray:
    """(S,) bool: samples farther than ``margin`` (m) from the surface's open boundary (all True
    on a closed surface); :meth:`Surface.farther_from_boundary`."""
    return samples.farther_from_boundary(margin)
