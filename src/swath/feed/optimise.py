"""Feed (dwell) optimisation to a target depth map, as a linear programme solved by HiGHS.

Variables are the dwell times ``t_i`` (s) of the dwell nodes (:mod:`.kernel`); removal is ``K t``.
With ``Δs_i`` the node length the feed through node ``i`` is ``v_i = Δs_i / t_i``.

Constraints (all linear in ``t``)
---------------------------------
* feed ``v_min <= v_i <= cap_i``: the bounds ``Δs_i / cap_i <= t_i <= Δs_i / v_min``, with ``cap_i``
  the smallest of the feed limit and the centripetal ``sqrt(a_c / κ)`` and angular ``ω_max / ρ``
  caps along the node, computed on the timing grid exactly as :func:`swath.trajectory.time_path`
  does (:func:`node_speed_caps`);
* never over-grind: ``(K t)_j <= target_j + tolerance`` at every sample of the optimised region
  (touched samples at least ``boundary_margin`` from the open boundary);
* tangential acceleration ``|dv/dt| <= a_t``: with the pace ``p = 1/v = t/Δs``, ``dv/dt = −p'/p³``, so
  ``|p_{i+1} − p_i| <= a_t Δc p³`` between neighbouring nodes ``Δc`` apart.  ``p³`` is replaced by its
  tangent at a reference pace ``p0`` (below ``p³`` for every ``p > 0``), written at both nodes: a
  conservative linearisation.  Each row's ``p0`` is the faster of its two nodes' fastest paces
  (the timed fastest profile; :func:`~swath.feed.caps.row_reference_pace`), so the rows are exact
  where the programme runs fastest and hold it back little where it slows down.

Objectives
----------
* ``mode="match"``, ``objective="l1"``: minimise the area-weighted ``Σ a_j |(K t)_j − target_j|``;
  ``objective="minimax"``: minimise the largest under-removal ``max_j (target_j − (K t)_j)``.
* ``mode="max_removal"`` (Wang, hub grinding §2): maximise the removed volume ``Σ a_j (K t)_j``
  subject to the constraints above.

Depths are scaled to micrometres inside the solver so that HiGHS's absolute tolerances (1e-7) are
far below anything that matters.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np

from ..core import ToolPath
from ..errors import InputError
from ..trajectory.constraints import FeedLimit, FeedProfile, TangentialAccelLimit
from .caps import accel_feasible_pace, node_speed_caps, split_constraints
from .dwell_lp import _DEPTH_UNIT, solve_dwell
from .kernel import RemovalKernel, build_kernel, interior_mask, trajectory_node_dwell
from .timed import dwell_to_profile, simulated_on_kernel, timed_spread_removal, trim_over

log = logging.getLogger(__name__)

#: Touched samples outside the optimised region (near the open edges) are held under this many times
#: the given ``target + tolerance``, or what the fastest feed removes there where that is more:
#: the feed may not slow down beside an edge until it gouges it.  Without it, the default job's
#: deepest spot on bezier_dac_scan was 156 µm against a 4.7 µm median (84 µm there at the fastest
#: feed, by the kernel), on bezier_complex_shape 27 µm, on the hub 29 µm.  Held at 2 times, those are
#: 91, 13.4 and 14.3 µm; the interior CoVs move by 0.003 or less, but for the hub's (0.422 -> 0.439).
#: Held at 1 time (the region's own cap), the interiors paid for it: the plate 0.052 -> 0.068, the
#: hub 0.422 -> 0.509 (their bands need the passes slowed near the ends).
EDGE_CAP_RATIO = 2.0


@dataclass(frozen=True, eq=False)
class FeedResult:
    """An optimised feed and what it is predicted to do.

    Attributes
    ----------
    profile : FeedProfile
        One speed (m/s) per point of every pass; give it to :func:`swath.trajectory.time_path`.
    dwell : (n,) float
        Dwell per node, s.
    speed : (n,) float
        Feed through each node, m/s.
    kernel : RemovalKernel
    target : (S,) float
        Target depth on the kernel's samples, m.
    predicted : (S,) float
        Predicted removal ``K @ dwell``, m.
    region : (S,) bool
        Samples the optimisation was asked to match (touched, at least ``boundary_margin`` in).
    metrics : dict
        Figures with units in their keys: ``status``, ``solve_time_s``, ``kernel_time_s``,
        ``removal_cov``, ``removal_mean_m``, ``target_mean_m``, ``max_over_removal_m``,
        ``max_under_removal_m``, ``residual_rms_m``, ``contact_time_s``, ``fastest_contact_time_s``,
        what binds (:func:`_binding`): ``samples_at_cap``, ``nodes_at_fastest_fraction``,
        ``nodes_held_by_cap_fraction``, ``nodes_at_slowest_fraction``, and with ``simulate=``:
        ``simulated_rounds`` (per round ``kind`` ``"solve"`` or ``"trim"``, ``max_over_target_m``, ``samples_over``, ``held_back_ratio`` or
        ``nodes_sped_up``), ``simulated_max_over_target_m``, ``simulate_time_s`` (``solve_time_s``
        then includes the re-solves), ...
    """

    profile: FeedProfile
    dwell: np.ndarray
    speed: np.ndarray
    kernel: RemovalKernel
    target: np.ndarray
    predicted: np.ndarray
    region: np.ndarray
    metrics: dict = field(default_factory=dict)


# ----------------------------------------------------------------------------------------------
# The linear programme
# ----------------------------------------------------------------------------------------------
def _time_dwell(toolpath, nodes, dwell: np.ndarray, *, cons: list, v_min: float, v_max: float, heading_scale: float,
                lead_angle: float, rounds: int, ratio_tolerance: float):
    """The feed profile that makes :func:`swath.trajectory.time_path` spend ``dwell`` (s) in each node:
    the node feeds, corrected by the timed-to-planned dwell ratio for at most ``rounds`` rounds.
    Returns ``(profile, timed_ratio or None, last timed trajectory or None, command)`` with
    ``command`` ``(n,)`` the node feeds (m/s) the profile holds."""
    command = nodes.length / dwell
    profile = dwell_to_profile(toolpath, nodes, dwell)
    timed_ratio, traj = None, None
    for _ in range(max(0, int(rounds))):
        from ..trajectory import time_path

        traj = time_path(toolpath, cons + [profile], heading_scale=heading_scale, lead_angle=lead_angle)
        timed = trajectory_node_dwell(traj, nodes, toolpath)
        timed_ratio = np.where(dwell > 0, timed / dwell, 1.0)
        if np.abs(timed_ratio - 1).max() <= ratio_tolerance:
            break
        command = np.clip(command * timed_ratio, v_min, v_max)      # time_path applies the real caps itself
        profile = dwell_to_profile(toolpath, nodes, nodes.length / command)
        traj = None
    return profile, timed_ratio, traj, command


def _binding(kernel: RemovalKernel, dwell: np.ndarray, t_min: np.ndarray, predicted: np.ndarray, cap: np.ndarray,
             region: np.ndarray, tolerance: float, t_max: np.ndarray) -> dict:
    """What holds the feed up or down: region samples whose predicted removal (m, ``(S,)``) is at
    the programme's ``cap`` (m, ``(S,)``, within 0.1 % of ``tolerance``), the share of the ``n``
    nodes whose dwell (s, ``(n,)``) is the fastest the limits allow (``t_min``, s, within 0.1 %),
    the share that are at their fastest *and* reach a sample at the cap (slowing any of those
    would over-grind it, whatever the target elsewhere under the node), and the share at the
    slowest feed (``t_max``, s, within 0.1 %: the feed range, not the target, stops those from
    removing more).  (On the flat plate with
    a rotary pad the overlap of the overhanging outer pass and the next one's rim holds that whole
    next pass at the feed limit.)"""
    slack = 1e-3 * max(float(tolerance), 1e-3 * float(np.max(cap[region], initial=0.0)), 1e-15)
    at_cap = np.flatnonzero(region & (predicted >= cap - slack))
    fastest = dwell <= t_min * (1 + 1e-3)
    reached = np.zeros(len(dwell), bool)
    reached[np.unique(kernel.matrix.tocsr()[at_cap].indices)] = True
    n = max(len(dwell), 1)
    return {"samples_at_cap": int(len(at_cap)), "nodes_at_fastest_fraction": float(np.sum(fastest) / n),
            "nodes_held_by_cap_fraction": float(np.sum(fastest & reached) / n),
            "nodes_at_slowest_fraction": float(np.sum(dwell >= t_max * (1 - 1e-3)) / n)}


def resolve_target(target, samples) -> np.ndarray:
    """Target depth ``(S,)`` (m) on the kernel's samples from a number (uniform depth, m), an
    ``(S,)`` array, or an object with ``depth_on(surface)`` (:class:`swath.feed.targets.TargetMap`)."""
    S = len(samples.vertices)
    if hasattr(target, "depth_on"):
        out = np.asarray(target.depth_on(samples), float)
    elif np.ndim(target) == 0:
        out = np.full(S, float(target))
    else:
        out = np.asarray(target, float)
    if out.shape != (S,) or not np.isfinite(out).all() or (out < 0).any():
        raise InputError(f"the target depth must be one finite depth >= 0 m per sample ({S}), got shape "
                         f"{out.shape}; give a depth in m, a per-sample array or a TargetMap")
    return out


def removal_stats(depth: np.ndarray, target: np.ndarray, areas: np.ndarray, mask: np.ndarray) -> dict:
    """Removal figures over ``mask``: CoV, mean, residual and the worst over/under-removal (m)."""
    if not mask.any():
        nan = float("nan")
        return {"removal_cov": nan, "removal_mean_m": nan, "target_mean_m": nan, "max_over_removal_m": nan,
                "max_under_removal_m": nan, "residual_rms_m": nan, "region_area_m2": 0.0}
    a, d, t = areas[mask], depth[mask], target[mask]
    mean = float(np.average(d, weights=a))
    std = float(np.sqrt(np.average((d - mean) ** 2, weights=a)))
    r = d - t
    return {"removal_cov": std / mean if mean > 0 else float("nan"), "removal_mean_m": mean,
            "target_mean_m": float(np.average(t, weights=a)), "max_over_removal_m": float(r.max()),
            "max_under_removal_m": float(-r.min()), "residual_rms_m": float(np.sqrt(np.average(r**2, weights=a))),
            "region_area_m2": float(a.sum())}


def optimise_feed(toolpath: ToolPath, tool, constraints, *, target, tolerance: float, mode: str = "match",
                  objective: str = "l1", v_min: float | None = None, boundary_margin: float | None = None,
                  kernel: RemovalKernel | None = None, node_spacing: float | None = None,
                  sample_spacing: float | None = None, heading_scale: float = 5e-3, lead_angle: float = 0.0,
                  time_limit: float = 600.0,
                  region: np.ndarray | None = None, smoothing: float = 2e-2, time_weight: float = 1e-3,
                  cap_margin: float = 0.5, model_error: float = 0.10, round_slack: float = 0.1,
                  max_rows: int = 5000, timing_rounds: int = 5, ratio_tolerance: float = 0.01, trajectory=None,
                  edge_cap_ratio: float = EDGE_CAP_RATIO,
                  simulate=None, simulate_rounds: int = 6, simulate_margin: float = 0.02,
                  trim_rounds: int = 8, spread_check: bool = True, target_floor: str = "none",
                  progress=None) -> FeedResult:
    """Optimise the feed along every pass of ``toolpath`` so its removal matches ``target``.

    Parameters
    ----------
    toolpath : ToolPath
        Passes from any planner.
    tool : Tool
    constraints : sequence
        The trajectory constraints: a :class:`FeedLimit` (the largest feed, m/s) and optionally
        :class:`CentripetalLimit`, :class:`AngularSpeedLimit`, :class:`TangentialAccelLimit`.
    target : float, (S,) float or TargetMap
        Target depth, m: a uniform depth, one per kernel sample, or a
        :class:`swath.feed.targets.TargetMap`.
    tolerance : float
        Largest allowed removal above the target, m (a hard constraint at every optimised sample).
    mode : {"match", "max_removal"}
        Match the target (``objective`` ``"l1"`` or ``"minimax"``) or Wang's maximal removal without
        over-grinding.
    v_min : float, optional
        Slowest feed, m/s (default a tenth of the feed limit).
    boundary_margin : float, optional
        Samples closer than this (m) to the open boundary are not optimised (default the pad radius;
        the pad hangs over the edge there).
    kernel : RemovalKernel, optional
        A kernel already built for ``toolpath`` (else built here with ``node_spacing`` and
        ``sample_spacing``, m).
    heading_scale : float
        As in :func:`swath.trajectory.time_path`, m (for the angular-speed caps).
    lead_angle : float
        As in :func:`swath.trajectory.time_path`, rad: the tilt every timing here uses.  When it is
        not 0 the kernel is built on the poses of ``toolpath`` timed with it (the tilted pad presses
        elsewhere than the untilted one), unless ``kernel`` or ``trajectory`` is given; a given
        ``trajectory`` must carry the same lead angle.
    region : (S,) bool, optional
        Kernel samples to match (instead of every touched sample ``boundary_margin`` in).
    edge_cap_ratio : float
        The touched samples outside the region are held under this many times ``target +
        tolerance`` (the target as given, before ``target_floor`` raises it), or under what the
        fastest feed removes there where that is more
        (:data:`EDGE_CAP_RATIO`; ``inf``: not held).
    cap_margin : float
        Fraction of ``tolerance`` held back for the difference between the kernel and the timed
        trajectory (the simulator's pose discretisation moves single samples by a few %): the
        programme caps the kernel removal at ``target + tolerance − holdback`` with ``holdback`` the
        larger of ``cap_margin·tolerance`` and ``model_error`` times the region's mean target.
    round_slack : float
        Fraction of what the programme's cap holds back under ``target + tolerance`` (at each
        sample, as first set) by which a thinned-out sample may exceed the cap before the
        programme is solved again with it as a cap row (:func:`.dwell_lp.solve_dwell`'s ``slack``;
        default 0.1).  The accepted excess stays within the tolerance.  0 chases every excess above
        a thousandth of the tolerance: on crs_part_5 at a 12 µm target that took three more
        interior-point solves of 7-9 s each for excesses of 0.11 µm and less.
    model_error : float
        Fraction of the target depth by which an independent removal simulation of the timed
        trajectory may differ from the kernel on single samples (pose discretisation on both
        sides).  Measured on the plate at the default steps against a 0.25 mm-pose reference: the
        kernel −5..+3 %, :func:`swath.simulate.simulate_removal` (poses one sample spacing apart)
        ±5.5 %; the simulator above the kernel by up to 8.7 % of the target on the benchmark plate.  When it exceeds the tolerance, the programme's cap falls below
        the target (the target is lowered by the difference): never over-grinding as the simulator
        measures it then costs a little depth.  Measured by ``bench_feed.py`` on an optimised
        (varying) feed: the kernel is within 0.01-0.26 µm of the trajectory integrated at every
        sample.  :func:`swath.simulate.simulate_removal` used to lump 6-17 mm of a fast stretch
        (a fixed count of samples), then 0.6 s of a slow one (a fixed travel), into one pose, and
        moved single samples by up to +27 % of the target; it now bounds both.  ``simulate=``
        corrects for what remains.
    trajectory : Trajectory, optional
        ``toolpath`` timed at any feed: the kernel then uses its contact poses (see
        :func:`build_kernel`); recommended on scans.
    timing_rounds : int
        Rounds of timing correction (default 3): the profile is timed with
        :func:`swath.trajectory.time_path` under ``constraints``, each node's commanded feed is scaled
        by its timed-to-planned dwell ratio (within the feed range) and the profile rebuilt, until
        every ratio is within ``ratio_tolerance`` of 1.  The timing's acceleration sweep rounds the
        speed steps between nodes and otherwise adds up to 10 % of dwell where the feed changes
        (measured: 1, 2, 3 rounds leave at most 11 %, 7 %, 5.5 %).  0 skips it (no timing inside;
        then the passes' start and end at rest are not known to the programme either).
    max_rows : int
        Largest number of sample rows in the programme's objective (more region samples are thinned
        to one per grid cell, area-weighted; see :func:`.dwell_lp.thin_rows`), and as many cap rows at the
        cells' peaks.  The HiGHS interior-point time grows faster than linearly with it; measured on
        the panel (47k region samples, 651 nodes): 20000 rows 12.2 s CPU, 8000 6.9 s, 4000 3.6 s,
        with the same CoV (0.136) and over-removal.
    smoothing : float
        Weight of the cost on pace changes between neighbouring nodes, relative to the objective
        (ties between dwell distributions with the same removal go to the smoother one).
    time_weight : float
        Cost of a second of dwell, as a fraction of what a second of a typical node is worth to the
        objective (:func:`.dwell_lp.solve_dwell`): ties go to the shorter cycle, and nodes over no
        optimised sample (near the boundary, over holes) run at the fastest feed.  0 leaves them
        wherever the solver puts them.
    time_limit : float
        HiGHS time limit, s.
    simulate : callable, optional
        ``simulate(trajectory)`` → an object with ``surface.vertices`` ``(S', 3)`` (m) and ``depth``
        ``(S',)`` (m), e.g. ``lambda traj: swath.simulate.simulate_removal(traj, surface, tool)``
        (the feed stage may not import the simulator).  When given, the timed trajectory is
        simulated and, while a region sample is simulated over ``target + tolerance``, the
        programme's cap at the kernel samples under it is tightened by the measured ratio
        (kernel / simulated removal there, less ``simulate_margin`` of the target) and the
        programme solved and timed again, at most ``simulate_rounds`` times (logged; figures in
        ``metrics["simulated_rounds"]``).  Caps are only ever tightened, never below what the
        fastest feed removes.  When samples are still over after those rounds, or no cap changes,
        the trim rounds (``trim_rounds``) speed up the nodes over them; what is still over after
        those is logged as a warning (the target is below what the fastest feed the limits allow
        removes there).
    simulate_rounds : int
        Most simulate / re-solve rounds (default 6; a round runs only while a sample is over).  On
        bezier_dac_scan (raster with ``edge_margin=inf``) the simulator reads up to 28 % more than
        the kernel at single samples of the scan, and the samples over fell 35 -> 14 -> 5 -> 1 -> 0
        in rounds 1-5 (3.5 µm over the target with the tolerance 2.55 µm after the third).
    simulate_margin : float
        Extra fraction of the target taken off a tightened cap (the simulator's pose grouping moves
        with the feed, so the measured ratio shifts a little from round to round).
    trim_rounds : int
        With ``simulate=``: when samples are still simulated over ``target + tolerance`` after the
        re-solve rounds (or their caps cannot be tightened), at most this many rounds that only ever
        raise the commanded feed of the nodes over those samples, by the ratio they are over, and
        simulate again (:func:`trim_over`; default 8).  A faster command never slows the timed
        trajectory anywhere, so no sample removes more than before: the over-removal falls until it
        is within the tolerance or the nodes run as fast as the limits allow (then a warning).
        Re-solving instead moves the feed steps, and with them the simulator's excess.
    spread_check : bool
        With ``simulate=``: after the re-solve rounds, also read each sample's depth from the kernel
        with every node's dwell spread as the timed trajectory spreads it
        (:func:`timed_spread_removal`), and trim where the larger of that and the simulated depth
        is over (default True; one kernel build per check).  ``metrics["simulated_rounds"]`` then
        holds ``spread_max_over_target_m`` and ``spread_samples_over`` in the last solve round.
    target_floor : {"none", "fastest"}
        ``"fastest"``: raise the target at every sample to what the passes remove there at the
        fastest feed the limits allow (wherever the passes run they remove at least that), instead
        of refusing such a target: for a target map that tapers to zero, e.g. the excess of a
        rework scan.  ``metrics["target_raised_max_m"]`` says by how much at most.
    progress : callable, optional
        ``progress(stage, done, total)`` with ``stage`` in ``"kernel"`` (batches of poses),
        ``"solve"`` (before each HiGHS solve: ``done`` the solves before it, ``total`` 0 since their
        number is not known in advance), ``"simulate"`` (each simulated round) and ``"trim"`` (each
        trim round).

    Returns
    -------
    FeedResult

    Raises
    ------
    InfeasibleError
        When even the largest allowed feed removes more than ``target + tolerance`` somewhere (the
        message names the sample, both depths and the least feasible target).
    """
    cons = split_constraints(constraints)
    v_max = cons[FeedLimit].speed
    v_min = 0.1 * v_max if v_min is None else float(v_min)
    if not (np.isfinite(v_min) and 0 < v_min <= v_max):
        raise InputError(f"v_min must lie in (0, feed limit {v_max:g}] m/s, got {v_min!r}")
    if not (np.isfinite(tolerance) and tolerance >= 0):
        raise InputError(f"tolerance must be a depth >= 0 m, got {tolerance!r}")
    if not (0 <= cap_margin < 1):
        raise InputError(f"cap_margin must lie in [0, 1), got {cap_margin!r}")
    if not (0 <= model_error < 1):
        raise InputError(f"model_error must be a fraction of the target depth in [0, 1), got {model_error!r}")
    if not (0 <= round_slack < 1):
        raise InputError(f"round_slack must lie in [0, 1), got {round_slack!r}")
    margin = tool.pad_radius if boundary_margin is None else float(boundary_margin)
    from ..trajectory.timing import check_lead_angle

    lead_angle = check_lead_angle(lead_angle)
    if trajectory is not None and float(trajectory.metadata.get("lead_angle_rad", 0.0)) != lead_angle:
        raise InputError(f"the trajectory given for the kernel was timed with a lead angle of "
                         f"{trajectory.metadata.get('lead_angle_rad', 0.0)!r} rad, not the {lead_angle!r} rad asked for; "
                         "time it with the same lead_angle")
    t0 = time.perf_counter()
    if kernel is None and trajectory is None and lead_angle != 0.0:
        from ..trajectory import time_path

        # the kernel must see the tilted pad: its poses from the plan timed with the lead
        trajectory = time_path(toolpath, list(cons.values()), heading_scale=heading_scale, lead_angle=lead_angle)
    if kernel is None:
        cb = None if progress is None else (lambda done, total: progress("kernel", done, total))
        kernel = build_kernel(toolpath, tool, node_spacing=node_spacing, sample_spacing=sample_spacing,
                              trajectory=trajectory, progress=cb)
    t_kernel = time.perf_counter() - t0
    nodes = kernel.nodes
    target_s = resolve_target(target, kernel.samples)
    caps = np.clip(node_speed_caps(toolpath, nodes, list(cons.values()), heading_scale=heading_scale), v_min, v_max)
    if timing_rounds > 0:
        # the timing's own floor: a pass starts and ends at rest, so its first and last nodes take
        # longer than Δs / cap at any command; the programme must know (else those nodes over-grind)
        from ..trajectory import time_path

        fastest_traj = time_path(toolpath, list(cons.values()), heading_scale=heading_scale, lead_angle=lead_angle)
        floor = trajectory_node_dwell(fastest_traj, nodes, toolpath)
        caps = np.clip(np.minimum(caps, nodes.length / np.maximum(floor, 1e-12)), v_min, v_max)
    t_min, t_max = nodes.length / caps, nodes.length / v_min
    tl = cons.get(TangentialAccelLimit)
    # the acceleration rows are linearised at the fastest pace each node can run at (the timing's
    # own floor where it was timed): tangents of p³ there, exact at the fastest profile
    accel_ref = np.maximum(1.0 / caps, 1.0 / v_max)
    if tl is not None:
        # the fastest profile that meets the linearised acceleration rows (else a sharp cap next to
        # a free node leaves the programme infeasible)
        pace = np.minimum(accel_feasible_pace(1.0 / caps, nodes, tl.a_t, accel_ref), 1.0 / v_min)
        t_min = nodes.length * pace
        caps = 1.0 / pace
    touched = np.diff(kernel.matrix.tocsr().indptr) > 0
    if region is None:
        region = touched & interior_mask(kernel.samples, margin)
    else:
        region = np.asarray(region, bool)
        if region.shape != touched.shape:
            raise InputError(f"region must be one bool per kernel sample ({len(touched)}), got shape {region.shape}")
        region = region & touched
    solves = 0

    def on_solve():
        nonlocal solves
        if progress is not None:
            progress("solve", solves, 0)
        solves += 1

    if target_floor not in ("none", "fastest"):
        raise InputError(f"target_floor must be 'none' or 'fastest', got {target_floor!r}")
    raised = 0.0
    given_target = target_s              # before the floor: the edge cap reads it (below)
    if target_floor == "fastest":
        at_fastest = kernel.removal(t_min)
        raised = float(np.max(np.maximum(at_fastest - target_s, 0.0)[region], initial=0.0))
        target_s = np.maximum(target_s, at_fastest)
    t1 = time.perf_counter()
    mean_target = float(np.average(target_s[region], weights=kernel.samples.vertex_areas[region])) if region.any() else 0.0
    lp_tolerance = tolerance - max(cap_margin * tolerance, model_error * mean_target)
    # the programme's cap: the held-back one, but never below what the fastest feed removes (where
    # that lies between, those nodes simply run at the fastest feed); a target above the cap is lowered
    fastest = kernel.removal(t_min)
    cap = np.maximum(target_s + lp_tolerance, np.minimum(fastest, target_s + tolerance))
    # the touched samples outside the region (near the open edges): the objective does not read
    # them, but the feed must not slow down to gouge them either; they stay under EDGE_CAP_RATIO
    # times the region's cap, or under what the fastest feed removes there where that is more (a
    # convex fold at the edge of bezier_dac_scan: 156 um with the feed slowed beside it).  The given
    # target, not the one raised to the fastest feed's removal: twice the raised one let the feed slow
    # down over that fold again (124 um by the kernel where the fastest feed removes 84 um)
    edge = touched & ~region if np.isfinite(edge_cap_ratio) else np.zeros_like(region)
    cap[edge] = np.maximum(edge_cap_ratio * (given_target + tolerance), fastest)[edge]
    lp_target = np.minimum(target_s, cap)
    # from the first caps: the simulated rounds only tighten them, so it stays within the tolerance
    slack = round_slack * np.maximum(target_s + tolerance - cap, 0.0)
    solve_kw = dict(t_min=t_min, t_max=t_max, region=region, mode=mode, objective=objective,
                    a_t=None if tl is None else tl.a_t, v_max=v_max, accel_ref=accel_ref, time_limit=time_limit,
                    smoothing=smoothing, max_rows=max_rows, time_weight=time_weight, slack=slack, on_solve=on_solve,
                    capped=region | edge)
    held: dict = {}                 # the samples the programme held at its cap, for the re-solves
    dwell, status = solve_dwell(kernel, lp_target, tolerance=cap - lp_target, found=held, **solve_kw)
    t_solve = time.perf_counter() - t1
    timing = dict(cons=list(cons.values()), v_min=v_min, v_max=v_max, heading_scale=heading_scale, lead_angle=lead_angle,
                  rounds=timing_rounds, ratio_tolerance=ratio_tolerance)
    profile, timed_ratio, traj, command = _time_dwell(toolpath, nodes, dwell, **timing)
    sim_rounds: list[dict] = []
    t_simulate = 0.0
    bad = np.zeros(0, np.int64)
    if simulate is not None:
        limit = target_s + tolerance
        excess = 0.0
        for rnd in range(max(0, int(simulate_rounds)) + 1):
            if traj is None:
                from ..trajectory import time_path

                traj = time_path(toolpath, timing["cons"] + [profile], heading_scale=heading_scale, lead_angle=lead_angle)
            if progress is not None:
                progress("simulate", rnd, simulate_rounds + 1)
            t3 = time.perf_counter()
            worst = simulated_on_kernel(simulate(traj), kernel.samples)
            t_simulate += time.perf_counter() - t3
            over = worst - limit
            timed_pred = kernel.removal(trajectory_node_dwell(traj, nodes, toolpath))
            bad = np.flatnonzero(region & (over > 0))
            sim_rounds.append({"kind": "solve",
                               "max_over_target_m": float(np.max(worst[region] - target_s[region], initial=0.0)),
                               "samples_over": int(len(bad))})
            log.info("feed optimisation, simulated round %d: largest simulated removal over the target %.3g um "
                     "(tolerance %.3g um), %d samples over", rnd, sim_rounds[-1]["max_over_target_m"] / _DEPTH_UNIT,
                     tolerance / _DEPTH_UNIT, len(bad))
            if len(bad) == 0:
                break
            if rnd == simulate_rounds:
                log.info("feed optimisation: after %d simulated rounds %d samples are still simulated over the "
                         "target + tolerance by up to %.3g um; speeding up the nodes over them",
                         simulate_rounds, len(bad), float(over[bad].max()) / _DEPTH_UNIT)
                break
            # The simulator removes worst / timed_pred of what the kernel predicts.  Where it measured
            # over the limit, cap the kernel at limit · (kernel / simulated) less a margin; everywhere,
            # hold back the largest excess ratio seen where the kernel removes at least half the
            # target (the simulator's pose grouping moves with the feed, so the excess moves too).
            # Never below the fastest feed's removal.
            ratio = worst / np.maximum(timed_pred, 1e-300)
            counted = region & (timed_pred >= 0.5 * target_s)
            excess = max(float(np.max(ratio[counted], initial=1.0)) - 1.0, excess)
            tightened = limit / (1.0 + excess) - simulate_margin * target_s
            tightened[bad] = np.minimum(tightened[bad], limit[bad] / ratio[bad] - simulate_margin * target_s[bad])
            new_cap = np.maximum(np.minimum(cap, tightened), np.minimum(fastest, cap))
            sim_rounds[-1]["held_back_ratio"] = excess
            if np.array_equal(new_cap, cap):
                # nothing left to tighten (the samples over are at the fastest feed already): another
                # round would solve, time and simulate the same programme again
                log.info("feed optimisation: %d samples are simulated over the target + tolerance by up to "
                         "%.3g um and the programme's caps cannot be tightened; speeding up the nodes over them",
                         len(bad), float(over[bad].max()) / _DEPTH_UNIT)
                break
            cap = new_cap
            lp_target = np.minimum(target_s, cap)
            t2 = time.perf_counter()
            dwell, status = solve_dwell(kernel, lp_target, tolerance=cap - lp_target,
                                        cap_rows=held.get("cap_rows"), found=held, **solve_kw)
            t_solve += time.perf_counter() - t2
            profile, timed_ratio, traj, command = _time_dwell(toolpath, nodes, dwell, **timing)
        if spread_check:
            t3 = time.perf_counter()
            worst = np.maximum(worst, timed_spread_removal(kernel, traj))
            t_simulate += time.perf_counter() - t3
            bad = np.flatnonzero(region & (worst > limit))
            sim_rounds[-1]["spread_max_over_target_m"] = float(np.max(worst[region] - target_s[region], initial=0.0))
            sim_rounds[-1]["spread_samples_over"] = int(len(bad))
        if len(bad):
            trimmed_profile, trimmed_traj, trimmed_command, trimmed = trim_over(
                kernel, toolpath, traj, command, caps, bad, worst, limit, target_s, region, simulate,
                sim_rounds, rounds=trim_rounds, margin=simulate_margin, timing=timing, progress=progress,
                spread_check=spread_check)
            t_simulate += sum(r.get("simulate_time_s", 0.0) for r in sim_rounds if r.get("kind") == "trim")
            if trimmed:
                # the planned dwell shrinks by the factor the command rose (the timing correction's
                # command / dwell relation is kept)
                dwell = dwell * (command / trimmed_command)
                profile, traj, command = trimmed_profile, trimmed_traj, trimmed_command
    speed = nodes.length / dwell
    predicted = kernel.removal(dwell)
    metrics = {"status": status, "mode": mode, "objective": objective, "kernel_time_s": t_kernel,
               "solve_time_s": t_solve, "n_nodes": len(nodes), "n_region_samples": int(region.sum()),
               "kernel_nonzeros": int(kernel.matrix.nnz), "tolerance_m": float(tolerance),
               "programme_cap_over_target_m": float(lp_tolerance), "target_raised_max_m": raised,
               "v_min_m_per_s": v_min, "v_max_m_per_s": v_max, "contact_time_s": float(dwell.sum()),
               "fastest_contact_time_s": float(t_min.sum()), "speed_mean_m_per_s": float(np.mean(speed)),
               "speed_min_m_per_s": float(speed.min()), "speed_max_m_per_s": float(speed.max())}
    metrics.update(removal_stats(predicted, target_s, kernel.samples.vertex_areas, region))
    metrics.update(_binding(kernel, dwell, t_min, predicted, cap, region, tolerance, t_max))
    log.info("feed optimisation (%s/%s): %d nodes, %d samples, CoV %.3f, solve %.1f s", mode, objective, len(nodes),
             region.sum(), metrics["removal_cov"], t_solve)
    if sim_rounds:
        metrics["simulated_rounds"] = sim_rounds
        metrics["simulated_max_over_target_m"] = sim_rounds[-1]["max_over_target_m"]
        metrics["simulate_time_s"] = t_simulate
    if timed_ratio is not None:
        metrics["timed_dwell_ratio_p5_p50_p95"] = [float(x) for x in np.percentile(timed_ratio, [5, 50, 95])]
    return FeedResult(profile, dwell, speed, kernel, target_s, predicted, region, metrics)
