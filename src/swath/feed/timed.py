"""The optimised dwell as the timing runs it (:func:`swath.feed.optimise.optimise_feed`'s checks).

* :func:`dwell_to_profile` — one dwell per node as a feed profile the timing takes;
* :func:`simulated_on_kernel` — a removal simulation read on the kernel's samples;
* :func:`timed_spread_removal` — the kernel's removal with each node's dwell spread as the timed
  trajectory spreads it;
* :func:`trim_over` — the nodes over simulated over-removal sped up until it is within the limit.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from ..core import ToolPath
from ..errors import InputError
from ..trajectory.constraints import FeedProfile
from ..trajectory.geometry import arc_length
from .dwell_lp import _DEPTH_UNIT
from .kernel import RemovalKernel, trajectory_node_dwell

log = logging.getLogger("swath.feed.optimise")


def dwell_to_profile(toolpath: ToolPath, nodes, dwell: np.ndarray) -> FeedProfile:
    """A :class:`FeedProfile` (one speed per pass point, m/s): every point takes the feed of the
    node it lies in, so each node is crossed in its dwell (the speed changes within one point step,
    about 1 mm, at node boundaries; the timing's acceleration limit rounds those steps).  Linear
    interpolation of the pace between node middles instead moved up to 40 % of the tolerance of
    over-removal between nodes on the plate benchmark."""
    speed = nodes.length / dwell
    speeds = []
    for k, p in enumerate(toolpath.passes):
        a, b = nodes.pass_start[k], nodes.pass_start[k + 1]
        s = arc_length(p.points)
        j = np.clip(np.searchsorted(nodes.s_end[a:b], s, side="left"), 0, b - a - 1)
        speeds.append(speed[a:b][j])
    return FeedProfile(tuple(speeds))



def trim_over(kernel: RemovalKernel, toolpath, traj, command: np.ndarray, fastest: np.ndarray, bad: np.ndarray,
               worst: np.ndarray,
               limit: np.ndarray, target: np.ndarray, region: np.ndarray, simulate, sim_rounds: list, *,
               rounds: int, margin: float, timing: dict, progress=None, spread_check: bool = False):
    """Speed up the nodes over simulated over-removal until it is within the limit.

    ``bad`` ``(b,)`` are region samples whose simulated depth ``worst`` ``(S,)`` (m), of the timed
    trajectory ``traj``, is over ``limit`` ``(S,)`` (m).  Each must lose the fraction
    ``1 − (limit − margin·target) / worst`` of its removal; the nodes already at their ``fastest``
    feed ``(n,)`` (m/s: the caps the limits set) cannot give any, so the others' share (the kernel
    on the timed dwell) must shrink by more.  Every node that reaches a bad sample has its commanded
    feed ``command`` ``(n,)`` (m/s) divided by the smallest such ratio among the bad samples it
    reaches, up to ``fastest``; the profile is timed and simulated again, at most ``rounds``
    times.  Commands only rise, and the timing's speed is the least of the caps and the commands
    after its acceleration sweeps, so it rises or stays everywhere: no sample gets more dwell.  Each
    round is appended to ``sim_rounds`` (``kind="trim"``).  ``spread_check``: a sample's depth is
    the larger of the simulated one and :func:`timed_spread_removal`'s.

    Returns ``(profile, trajectory, command, trimmed)``; ``trimmed`` is False (and the profile
    None) when no command could rise.
    """
    from ..trajectory import time_path

    nodes = kernel.nodes
    csr = kernel.matrix.tocsr()
    profile, trimmed = None, False
    for k in range(max(0, int(rounds))):
        keep = np.clip((limit[bad] - margin * target[bad]) / np.maximum(worst[bad], 1e-300), 0.0, 1.0)
        sub = csr[bad]
        timed = trajectory_node_dwell(traj, nodes, toolpath)
        free = command < fastest * (1 - 1e-9)
        whole = sub @ timed
        movable = sub @ np.where(free, timed, 0.0)
        # the movable share r_m of the removal r must become r·keep − (r − r_m)
        ratio = np.clip((keep * whole - (whole - movable)) / np.maximum(movable, 1e-300), 1e-3, 1.0)
        factor = np.ones(len(command))
        rows = np.repeat(np.arange(len(bad)), np.diff(sub.indptr))
        np.minimum.at(factor, sub.indices, ratio[rows])
        new = np.minimum(command / factor, np.maximum(fastest, command))
        rose = new > command * (1 + 1e-9)
        if not rose.any():
            log.warning("feed optimisation: %d samples are simulated over the target + tolerance by up to %.3g um "
                        "and every node over them runs as fast as the limits allow; raise the target, the "
                        "tolerance or the feed limit", len(bad), float((worst[bad] - limit[bad]).max()) / _DEPTH_UNIT)
            break
        command, trimmed = new, True
        profile = dwell_to_profile(toolpath, nodes, nodes.length / command)
        traj = time_path(toolpath, timing["cons"] + [profile], heading_scale=timing["heading_scale"],
                         lead_angle=timing["lead_angle"])
        if progress is not None:
            progress("trim", k, rounds)
        t0 = time.perf_counter()
        worst = simulated_on_kernel(simulate(traj), kernel.samples)
        if spread_check:
            worst = np.maximum(worst, timed_spread_removal(kernel, traj))
        bad = np.flatnonzero(region & (worst > limit))
        sim_rounds.append({"kind": "trim", "max_over_target_m": float(np.max(worst[region] - target[region],
                                                                               initial=0.0)),
                           "samples_over": int(len(bad)), "nodes_sped_up": int(np.sum(rose)),
                           "simulate_time_s": time.perf_counter() - t0})
        log.info("feed optimisation, trim round %d: %d nodes sped up; largest simulated removal over the target "
                 "%.3g um, %d samples over", k, sim_rounds[-1]["nodes_sped_up"],
                 sim_rounds[-1]["max_over_target_m"] / _DEPTH_UNIT, len(bad))
        if len(bad) == 0:
            break
    else:
        if len(bad) and rounds > 0:
            log.warning("feed optimisation: after %d trim rounds %d samples are still simulated over the target + "
                        "tolerance by up to %.3g um; raise trim_rounds, the tolerance or the target", rounds, len(bad),
                        float((worst[bad] - limit[bad]).max()) / _DEPTH_UNIT)
    return profile, traj, command, trimmed


def timed_spread_removal(kernel: RemovalKernel, traj) -> np.ndarray:
    """Depth ``(S,)`` (m) the kernel predicts for the timed trajectory ``traj`` with each node's
    dwell shared among its poses as ``traj`` shares it (:meth:`RemovalKernel.respread`).  Where the
    feed steps between nodes the timing changes speed inside a node, which the even spread does not
    see and the removal simulation's pose grouping can blur; measured on bezier_dac_scan this reads
    within 0.2 µm of the trajectory integrated at every sample, where the simulation read up to
    0.65 µm less."""
    timed = trajectory_node_dwell(traj, kernel.nodes, kernel.toolpath)
    return kernel.respread(traj).removal(timed)


def simulated_on_kernel(removal, samples) -> np.ndarray:
    """The largest simulated depth (m) at the simulator's samples nearest to each kernel sample,
    ``(S,)``: the removal's own values when both sample the part alike (the usual case)."""
    sim_points = np.asarray(removal.surface.vertices, float)
    depth = np.asarray(removal.depth, float)
    if depth.shape != (len(sim_points),):
        raise InputError(f"simulate must return one depth per sample ({len(sim_points)}), got shape {depth.shape}")
    if sim_points.shape == samples.vertices.shape and np.allclose(sim_points, samples.vertices, atol=1e-9):
        return depth
    _, nearest = samples.kdtree.query(sim_points)
    out = np.zeros(len(samples.vertices))
    np.maximum.at(out, nearest, depth)
    return out
