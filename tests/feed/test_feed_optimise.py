"""Feed optimisation against analytic answers on a flat plate (uniform pad pressure F / (π R²))."""

import math

import numpy as np
import pytest

from swath.contact import Tool
from swath.core import Pass, ToolPath
from swath.errors import InfeasibleError, InputError
from swath.examples import flat_plate
from swath.feed import build_kernel, optimise_feed, trajectory_node_dwell
from swath.simulate.removal import simulate_removal
from swath.trajectory import FeedLimit, TangentialAccelLimit, time_path

TOOL = Tool(pad_radius=0.02, force=20.0)
R = TOOL.pad_radius
V_MAX = 0.05


def _line(x0, x1, y, step=1e-3):
    n = int(round(abs(x1 - x0) / step)) + 1
    pts = np.stack([np.linspace(x0, x1, n), np.full(n, y), np.zeros(n)], axis=1)
    return Pass(pts, np.tile([0.0, 0.0, 1.0], (n, 1)))


def _centre_rate():
    """Removal rate (m/s) under a pressed flat pad: k_p · F/(πR²) · v_rel."""
    return TOOL.preston * TOOL.force / (math.pi * R**2) * TOOL.relative_speed(0.0)


@pytest.fixture(scope="module")
def plate():
    return flat_plate(size_x=0.24, size_y=0.2, spacing=2.5e-3)


@pytest.mark.parametrize("from_trajectory", [False, True])
def test_kernel_reproduces_simulator(plate, from_trajectory):
    tp = ToolPath(plate, [_line(0.04, 0.2, 0.08), _line(0.2, 0.04, 0.11)], "test")
    traj = time_path(tp, [FeedLimit(0.03), TangentialAccelLimit(0.5)])
    k = build_kernel(tp, TOOL, trajectory=traj if from_trajectory else None)
    sim = simulate_removal(traj, plate, TOOL)
    pred = k.removal(trajectory_node_dwell(traj, k.nodes, tp))
    on = sim.depth > 0.2 * sim.depth.max()
    rel = np.abs(pred[on] - sim.depth[on]) / sim.depth[on]
    assert rel.mean() < 0.04
    # total removed volume agrees closely
    a = k.samples.vertex_areas
    assert abs(a @ pred / (a @ sim.depth) - 1) < 0.01


def test_straight_pass_uniform_target_needs_constant_feed(plate):
    """The target is what one constant feed v* removes (uniform along the pass, the pad's own
    profile across it): the optimum is that constant feed, and its centre line depth is rate·2R/v*."""
    tp = ToolPath(plate, [_line(0.02, 0.22, 0.1)], "test")
    k = build_kernel(tp, TOOL)
    v_star = 0.02
    target = k.removal(k.dwell_at_speed(v_star))
    res = optimise_feed(tp, TOOL, [FeedLimit(V_MAX)], target=target, tolerance=0.05 * target.max(), model_error=0.0,
                        kernel=k, boundary_margin=0.0)
    mid = np.abs(k.nodes.s_mid - 0.1) < 0.06                         # away from the pass ends
    np.testing.assert_allclose(res.speed[mid], v_star, rtol=0.02)
    np.testing.assert_allclose(res.profile.speeds[0][40:160], v_star, rtol=0.02)
    centre = (np.abs(k.samples.vertices[:, 1] - 0.1) < 1e-6) & (np.abs(k.samples.vertices[:, 0] - 0.12) < 0.05)
    # pose discretisation (poses one sample spacing apart) leaves a +-5 % ripple on single samples
    np.testing.assert_allclose(target[centre], _centre_rate() * 2 * R / v_star, rtol=0.06)
    assert np.mean(target[centre]) == pytest.approx(_centre_rate() * 2 * R / v_star, rel=0.04)


def test_nodes_at_the_slowest_feed_are_counted_where_the_target_asks_for_more(plate):
    """A target twice as deep as the slowest feed removes holds every node at the slowest feed
    (the feed range binds, not the target); the target one constant feed removes holds none."""
    tp = ToolPath(plate, [_line(0.02, 0.22, 0.1)], "test")
    k = build_kernel(tp, TOOL)
    v_min = 0.005
    deep = 2.0 * k.removal(k.dwell_at_speed(v_min))
    res = optimise_feed(tp, TOOL, [FeedLimit(V_MAX)], target=deep, tolerance=0.05 * deep.max(), model_error=0.0,
                        kernel=k, boundary_margin=0.0, v_min=v_min)
    assert res.metrics["nodes_at_slowest_fraction"] == 1.0
    np.testing.assert_allclose(res.speed, v_min, rtol=1e-3)
    even = k.removal(k.dwell_at_speed(0.02))
    res = optimise_feed(tp, TOOL, [FeedLimit(V_MAX)], target=even, tolerance=0.05 * even.max(), model_error=0.0,
                        kernel=k, boundary_margin=0.0, v_min=v_min)
    assert res.metrics["nodes_at_slowest_fraction"] == 0.0


def test_two_overlapping_passes_change_feed_where_they_overlap(plate):
    """Pass A (x 0.02..0.22) and pass B (x 0.12..0.22) d = R/2 apart; the target is a uniform depth D
    on both centre lines (one pad radius in from the pass ends).  A centre line gets rate·2R per unit pace from its own pass and
    rate·2·sqrt(R² − d²) from the neighbour (the pad chord at lateral offset d).  So where A runs alone
    its feed is v = rate·2R / D; where the two overlap both run at v = rate·(2R + 2 sqrt(R² − d²)) / D:
    the optimum changes speed exactly over the overlap (it speeds up there: each line is also ground
    by the other pass)."""
    d = R / 2
    y0 = 0.1 - d / 2
    tp = ToolPath(plate, [_line(0.02, 0.22, y0), _line(0.12, 0.22, y0 + d)], "test")
    k = build_kernel(tp, TOOL)
    x, y = k.samples.vertices[:, 0], k.samples.vertices[:, 1]
    # the centre lines, one pad radius in from each pass's ends
    on_lines = (((np.abs(y - y0) < 1e-6) & (x >= 0.02 + R) & (x <= 0.22 - R))
                | ((np.abs(y - y0 - d) < 1e-6) & (x >= 0.12 + R) & (x <= 0.22 - R)))
    D = 8e-6
    res = optimise_feed(tp, TOOL, [FeedLimit(V_MAX)], target=D, tolerance=0.05 * D, kernel=k, region=on_lines,
                        model_error=0.0)
    rate = _centre_rate()
    v_alone = rate * 2 * R / D
    v_overlap = rate * (2 * R + 2 * math.sqrt(R**2 - d**2)) / D
    assert v_overlap < V_MAX
    nodes, s = k.nodes, k.nodes.s_mid
    a, b = nodes.pass_index == 0, nodes.pass_index == 1
    alone = a & (s > 0.03) & (s < 0.07)                        # x 0.05..0.09: B's pad is > R away
    overlap_a = a & (s > 0.135) & (s < 0.165)                   # x 0.155..0.185
    overlap_b = b & (s > 0.035) & (s < 0.065)                   # x 0.155..0.185 (B starts at x = 0.12)
    assert np.mean(res.speed[alone]) == pytest.approx(v_alone, rel=0.04)
    assert np.mean(res.speed[overlap_a]) == pytest.approx(v_overlap, rel=0.05)
    assert np.mean(res.speed[overlap_b]) == pytest.approx(v_overlap, rel=0.05)
    assert res.metrics["max_over_removal_m"] <= 0.05 * D * (1 + 1e-9)


@pytest.mark.parametrize("mode, objective, max_rows", [("match", "l1", 20000), ("match", "minimax", 20000),
                                                       ("max_removal", "l1", 20000), ("match", "l1", 300)])
def test_over_removal_never_exceeds_tolerance(plate, mode, objective, max_rows):
    """Also with the programme's samples thinned to 300: the left-out samples that the solution
    over-grinds are added back as caps until none is over."""
    tp = ToolPath(plate, [_line(0.02, 0.22, y) for y in (0.06, 0.085, 0.11, 0.135)], "test")
    k = build_kernel(tp, TOOL)
    cons = [FeedLimit(V_MAX), TangentialAccelLimit(0.2)]
    # the fastest the timing allows: the passes start and end at rest
    fastest = k.removal(trajectory_node_dwell(time_path(tp, cons), k.nodes, tp))
    D = 1.1 * fastest.max()
    tol = 0.05 * D
    res = optimise_feed(tp, TOOL, cons, target=D, tolerance=tol,
                        mode=mode, objective=objective, kernel=k, boundary_margin=0.0, max_rows=max_rows)
    over = res.predicted[res.region] - D
    assert over.max() <= tol * (1 + 1e-6)
    # and with the dwell the timed trajectory really spends in each node (pass ends included)
    timed = trajectory_node_dwell(time_path(tp, cons + [res.profile]), k.nodes, tp)
    assert (k.removal(timed)[res.region] - D).max() <= tol * (1 + 1e-6)
    assert (res.speed <= V_MAX * (1 + 1e-9)).all() and (res.speed >= 0.1 * V_MAX * (1 - 1e-9)).all()
    # linearised acceleration limit: |dv/dt| = |dp/ds| / p^3 <= a_t between neighbouring nodes
    pace = 1 / res.speed
    same = k.nodes.pass_index[1:] == k.nodes.pass_index[:-1]
    dpds = np.abs(np.diff(pace)) / np.diff(k.nodes.s_mid)
    assert (dpds[same] / np.minimum(pace[1:], pace[:-1])[same] ** 3 <= 0.2 * (1 + 1e-6)).all()


def test_infeasible_target_names_the_numbers(plate):
    tp = ToolPath(plate, [_line(0.02, 0.22, 0.1)], "test")
    single = _centre_rate() * 2 * R / V_MAX                          # removed at the fastest feed
    with pytest.raises(InfeasibleError, match=r"already removes .* um .* target 0\.1 um"):
        optimise_feed(tp, TOOL, [FeedLimit(V_MAX)], target=0.1e-6, tolerance=0.0, boundary_margin=0.0)
    assert single > 0.1e-6


def test_accel_sweep_makes_a_sharp_cap_feasible():
    """One node capped at a tenth of the feed between free nodes: the sweep slows its neighbours so
    the linearised acceleration rows hold everywhere, and nodes far away stay at full speed."""
    from swath.feed.caps import accel_feasible_pace
    from swath.feed.kernel import dwell_nodes

    plate = flat_plate(size_x=0.3, size_y=0.05, spacing=1e-2)
    nodes = dwell_nodes(ToolPath(plate, [_line(0.0, 0.3, 0.025)], "t"), node_spacing=3e-3)
    p_ref = 1 / V_MAX
    p_min = np.full(len(nodes), p_ref)
    p_min[50] = 10 * p_ref
    a_t = 0.05
    p = accel_feasible_pace(p_min, nodes, a_t, p_ref)
    c = a_t * np.diff(nodes.s_mid) * p_ref**2
    dp = np.abs(np.diff(p))
    assert (dp <= c * (3 * p[:-1] - 2 * p_ref) * (1 + 1e-9)).all()
    assert (dp <= c * (3 * p[1:] - 2 * p_ref) * (1 + 1e-9)).all()
    assert (p >= p_min).all() and p[0] == p_ref and p[-1] == p_ref
    assert p[49] > p_ref and p[51] > p_ref


def test_acceleration_rows_linearised_at_the_fastest_profile_let_it_run_as_the_timing_does():
    """A pass accelerating from rest at 0.05 m/s² under a 0.4 m/s feed limit: v² = v0² + 2 a s.
    The rows linearised at 1 / v_max (p³'s tangent there) lie far below p³ at the paces of the
    ramp, and the sweep held it under 50 mm/s; linearised at the ramp's own paces they let it
    reach 90 % of its speed, and they still never allow a faster change than p³ does."""
    from types import SimpleNamespace

    from swath.feed.caps import accel_feasible_pace, row_reference_pace

    a_t, v_max, step = 0.05, 0.4, 5e-3
    s = np.arange(0.0, 0.2, step) + 0.5 * step
    ramp = np.sqrt(0.02**2 + 2 * a_t * s)                             # 20 mm/s at the start, 141 mm/s at 0.2 m
    nodes = SimpleNamespace(pass_index=np.zeros(len(s), int), s_mid=s)
    at_limit = 1 / accel_feasible_pace(1 / ramp, nodes, a_t, 1 / v_max)
    at_ramp = 1 / accel_feasible_pace(1 / ramp, nodes, a_t, 1 / ramp)
    assert at_limit.max() < 0.05
    assert at_ramp.min() >= 0.9 * ramp.min() and (at_ramp >= 0.9 * ramp).mean() > 0.5
    assert (at_ramp <= ramp * (1 + 1e-12)).all()                     # never faster than the caps
    # a row holds at both nodes; at the faster one (pace p_f >= its reference p0) it allows
    # a_t Δs p0² (3 p_f - 2 p0), the tangent, at most a_t Δs p_f³: never more than p³ there allows
    p = 1 / at_ramp
    p0 = row_reference_pace(1 / ramp, len(s))
    assert (np.abs(np.diff(p)) <= a_t * step * np.minimum(p[:-1], p[1:]) ** 3 * (1 + 1e-9)).all()
    assert p0 == pytest.approx(np.minimum(1 / ramp[:-1], 1 / ramp[1:]))
    with pytest.raises(InputError, match="one pace or one per node"):
        row_reference_pace(np.ones(3), len(s))


def test_thin_rows_keeps_each_cells_peak_when_scored(plate):
    """With a score, the row kept in each grid cell is the cell's highest-scoring sample; the
    weights (cell areas) add up to the region's area either way."""
    from swath.feed.dwell_lp import thin_rows

    region = np.ones(len(plate.vertices), bool)
    score = np.random.default_rng(3).random(len(plate.vertices))
    rows, w = thin_rows(plate, region, 500)
    peaks, wp = thin_rows(plate, region, 500, score=score)
    assert len(peaks) == len(rows) and len(rows) <= 1.3 * 500
    np.testing.assert_allclose(w, wp)
    assert w.sum() == pytest.approx(plate.vertex_areas.sum(), rel=1e-12)
    cell = float(np.sqrt(plate.vertex_areas.sum() / 500))
    key = np.floor(plate.vertices / cell).astype(np.int64)
    for r in peaks[:50]:
        same = np.flatnonzero((key == key[r]).all(axis=1))
        assert score[r] == score[same].max()


def test_a_sample_at_its_cap_holds_every_pass_over_it_at_the_feed_limit(plate):
    """Pass A and pass B 1.25 R apart (B's centre line out of A's reach).  On a line between them
    (0.875 R from A, 0.375 R from B) the target leaves no room above what both passes remove at the
    feed limit; B's own centre line asks for twice what B removes there.  Slowing B anywhere would
    over-grind the line between, so B stays at the feed limit and its centre line gets half its
    target (the flat plate's rotary benchmark: the overhanging outer pass and the next pass's rim),
    and the metrics say so.  Without the line in the region B runs at half the limit."""
    y_a, y_b, y_line = 0.07, 0.095, 0.0875
    tp = ToolPath(plate, [_line(0.02, 0.22, y_a), _line(0.22, 0.02, y_b)], "test")
    k = build_kernel(tp, TOOL)
    x, y = k.samples.vertices[:, 0], k.samples.vertices[:, 1]
    inside = (x >= 0.02 + R) & (x <= 0.22 - R)
    line, b_row = inside & (np.abs(y - y_line) < 1e-6), inside & (np.abs(y - y_b) < 1e-6)
    fastest = k.removal(k.dwell_at_speed(V_MAX))
    f = float(np.mean(fastest[b_row]))
    tol = 0.05 * f
    target = np.where(line, fastest - tol, 2 * f)
    kw = dict(target=target, tolerance=tol, kernel=k, model_error=0.0, cap_margin=0.0, timing_rounds=0)
    held = optimise_feed(tp, TOOL, [FeedLimit(V_MAX)], region=line | b_row, **kw)
    free = optimise_feed(tp, TOOL, [FeedLimit(V_MAX)], region=b_row, **kw)
    mid_b = (k.nodes.pass_index == 1) & (np.abs(k.nodes.s_mid - 0.1) < 0.06)
    np.testing.assert_allclose(held.speed[mid_b], V_MAX, rtol=1e-3)
    assert np.mean(held.predicted[b_row]) / (2 * f) == pytest.approx(0.5, abs=0.01)
    assert held.metrics["samples_at_cap"] >= line.sum() * 0.95
    assert held.metrics["nodes_held_by_cap_fraction"] > 0.8
    # (node by node the feed may alternate: only sums over the pad's length reach a sample)
    assert 1 / np.mean(1 / free.speed[mid_b]) == pytest.approx(V_MAX / 2, rel=0.02)
    assert np.mean(free.predicted[b_row]) / (2 * f) == pytest.approx(1.0, abs=0.01)
    assert free.metrics["nodes_held_by_cap_fraction"] == 0.0


@pytest.mark.parametrize("mode, objective", [("match", "l1"), ("match", "minimax"), ("max_removal", "l1")])
def test_nodes_over_no_optimised_sample_run_at_the_fastest_feed(plate, mode, objective):
    """One pass x 0.02..0.22 m; only its centre line at x 0.04..0.10 m is optimised.  The nodes more
    than a pad radius past x = 0.10 m touch no optimised sample: they run at the feed limit (the
    cost on dwell breaks the tie), while the matched stretch keeps the feed the target asks for."""
    tp = ToolPath(plate, [_line(0.02, 0.22, 0.1)], "test")
    k = build_kernel(tp, TOOL)
    x, y = k.samples.vertices[:, 0], k.samples.vertices[:, 1]
    region = (np.abs(y - 0.1) < 1e-6) & (x >= 0.04) & (x <= 0.10)
    D = 8e-6
    kw = dict(target=D, tolerance=0.05 * D, kernel=k, region=region, model_error=0.0, mode=mode, objective=objective)
    res = optimise_feed(tp, TOOL, [FeedLimit(V_MAX)], **kw)
    untied = optimise_feed(tp, TOOL, [FeedLimit(V_MAX)], time_weight=0.0, **kw)
    s = k.nodes.s_mid                                          # from x = 0.02
    free = s > 0.10 + R - 0.02 + 5e-3
    matched = (s > 0.03) & (s < 0.07)
    np.testing.assert_allclose(res.speed[free], V_MAX, rtol=1e-6)
    np.testing.assert_allclose(np.median(res.speed[matched]), np.median(untied.speed[matched]), rtol=0.01)
    assert res.metrics["removal_cov"] == pytest.approx(untied.metrics["removal_cov"], abs=1e-3)
    assert res.metrics["contact_time_s"] < untied.metrics["contact_time_s"] - 1.0


def test_kernel_poses_follow_a_fast_turning_tool_axis(plate, monkeypatch):
    """Where the tool axis swings fast (a scan's noisy normals), the pressure under the pad's rim
    changes within a millimetre; the kernel's poses are then closer than the distance step, so the
    kernel matches a reference integrated every 10 um."""
    import swath.feed.kernel as kernel

    x = np.arange(0.04, 0.2 + 1e-9, 0.1e-3)
    tilt = np.radians(8.0) * np.sin(2 * np.pi * x / 3e-3)      # +-8 degrees every 3 mm: 17 degrees/mm
    points = np.stack([x, np.full_like(x, 0.1), np.zeros_like(x)], axis=1)
    normals = np.stack([np.zeros_like(x), np.sin(tilt), np.cos(tilt)], axis=1)
    tp = ToolPath(plate, [Pass(points, normals)], "wobble")
    ref = build_kernel(tp, TOOL, pose_step=1e-5)
    dwell = ref.nodes.length / 0.02

    def worst_error():
        k = build_kernel(tp, TOOL, samples=ref.samples)       # default pose step: 1.25 mm here
        want, got = ref.removal(dwell), k.removal(dwell)
        on = want > 0.2 * want.max()
        return float(np.max(np.abs(got[on] - want[on]) / want[on]))

    assert worst_error() < 0.02
    monkeypatch.setattr(kernel, "MAX_POSE_TURN", np.inf)        # poses by distance only
    assert worst_error() > 0.2


def test_timed_spread_reproduces_the_simulator_where_the_feed_steps(plate, monkeypatch):
    """Node feeds alternating 5 and 50 mm/s: the timing changes speed inside the nodes, so spreading
    each node's dwell evenly along it misses single samples by over 15 %; shared as the trajectory
    spends it (``respread``), the kernel matches the simulator integrated every 0.1 mm."""
    import swath.simulate.removal as removal
    from swath.feed.timed import dwell_to_profile

    tp = ToolPath(plate, [_line(0.04, 0.2, 0.1)], "steps")
    nodes = build_kernel(tp, TOOL).nodes
    speed = np.where(np.arange(len(nodes)) % 2 == 0, 0.005, 0.05)
    cons = [FeedLimit(0.05), TangentialAccelLimit(0.5)]
    traj = time_path(tp, cons + [dwell_to_profile(tp, nodes, nodes.length / speed)])
    monkeypatch.setattr(removal, "INTEGRATION_STEP", 0.04)
    sim = simulate_removal(traj, plate, TOOL).depth
    even = build_kernel(tp, TOOL, trajectory=traj, pose_step=2e-5)     # poses fine enough to leave the spread
    timed = even.respread(traj)
    assert timed.spread == "timed" and timed.nodes is even.nodes and timed.matrix.shape == even.matrix.shape
    dwell = trajectory_node_dwell(traj, nodes, tp)
    on = sim > 0.2 * sim.max()

    def worst(k):
        return float(np.max(np.abs(k.removal(dwell)[on] - sim[on]) / sim[on]))

    assert worst(timed) < 0.04
    assert worst(even) > 0.15
    with pytest.raises(InputError, match="give trajectory="):
        build_kernel(tp, TOOL, spread="timed")


def _four_passes_just_above_the_fastest(plate):
    """Four parallel passes on the plate and a uniform target 10 % above the most their fastest
    feed removes: ``(kernel, t_min (n,) s, region (S,) bool, D m, target (S,) m)``."""
    tp = ToolPath(plate, [_line(0.02, 0.22, y) for y in (0.06, 0.085, 0.11, 0.135)], "test")
    k = build_kernel(tp, TOOL)
    t_min = k.nodes.length / V_MAX
    region = np.diff(k.matrix.tocsr().indptr) > 0
    D = 1.1 * k.removal(t_min)[region].max()
    return k, t_min, region, D, np.full(k.matrix.shape[0], D)


def test_rows_held_at_the_cap_carry_over_to_a_later_solve(plate, monkeypatch):
    """With the programme thinned to 300 samples, the first solve finds over-ground samples round by
    round; given them back, a second solve of the same kernel with the same caps needs one round,
    and every sample still keeps within the cap."""
    import swath.feed.dwell_lp as lp

    k, t_min, region, D, target = _four_passes_just_above_the_fastest(plate)
    solves = []
    real = lp._solve
    monkeypatch.setattr(lp, "_solve", lambda *a, **kw: solves.append(len(kw["cap_rows"])) or real(*a, **kw))
    kw = dict(tolerance=0.05 * D, t_min=t_min, t_max=10 * t_min, region=region, max_rows=300)
    found: dict = {}
    first, _ = lp.solve_dwell(k, target, found=found, **kw)
    rounds_first = len(solves)
    assert rounds_first >= 2 and len(found["cap_rows"]) > 0
    assert region[found["cap_rows"]].all()
    solves.clear()
    second, _ = lp.solve_dwell(k, target, cap_rows=found["cap_rows"], **kw)
    assert len(solves) == 1 and solves[0] >= len(found["cap_rows"])
    assert (k.removal(second)[region] - D).max() <= 0.05 * D * (1 + 1e-6)


def test_slack_stops_the_rounds_early_on_the_same_path(plate, monkeypatch):
    """With a slack the rounds add the same cap rows as without, and stop at the first solve whose
    largest excess over the cap is within the slack; that excess is the accepted one."""
    import swath.feed.dwell_lp as lp

    k, t_min, region, D, target = _four_passes_just_above_the_fastest(plate)
    tol = 0.05 * D
    solves, excess = [], []
    real = lp._solve

    def counted(*a, **kw):
        dwell, status = real(*a, **kw)
        solves.append(len(kw["cap_rows"]))
        excess.append(float((k.removal(dwell)[region] - (D + tol)).max()))
        return dwell, status

    monkeypatch.setattr(lp, "_solve", counted)
    kw = dict(tolerance=tol, t_min=t_min, t_max=10 * t_min, region=region, max_rows=300)
    exact, _ = lp.solve_dwell(k, target, **kw)
    full_solves, full_excess = list(solves), list(excess)
    assert len(full_solves) >= 3 and full_excess[-1] <= 1e-3 * tol
    # a slack just above the second solve's excess: the rounds stop after it
    slack = 1.01 * full_excess[1]
    assert full_excess[0] > slack > 1e-3 * tol
    solves.clear(), excess.clear()
    early, _ = lp.solve_dwell(k, target, slack=slack, **kw)
    assert solves == full_solves[:2]
    assert (k.removal(early)[region] - (D + tol)).max() == pytest.approx(full_excess[1], rel=1e-9)
    # as one value per sample: none on the samples the excess sits on -> no early stop
    per_sample = np.full(len(target), slack)
    per_sample[np.argmax(np.where(region, k.removal(early) - (D + tol), -np.inf))] = 0.0
    solves.clear(), excess.clear()
    lp.solve_dwell(k, target, slack=per_sample, **kw)
    assert len(solves) > 2


@pytest.mark.parametrize("bad", [dict(round_slack=1.0), dict(round_slack=-0.1), dict(cap_margin=1.0),
                                 dict(model_error=-0.5)])
def test_fractions_out_of_range_are_refused_by_name_before_the_kernel(plate, bad, monkeypatch):
    import swath.feed.optimise as opt

    def no_kernel(*a, **kw):
        raise AssertionError("the kernel was built before the settings were checked")

    monkeypatch.setattr(opt, "build_kernel", no_kernel)
    tp = ToolPath(plate, [_line(0.02, 0.22, 0.1)], "test")
    with pytest.raises(InputError, match=next(iter(bad))):
        optimise_feed(tp, TOOL, [FeedLimit(V_MAX)], target=1e-6, tolerance=1e-7, timing_rounds=0, **bad)


@pytest.fixture(scope="module")
def rim_pass():
    """A pass along y = 20 mm on a 1 mm plate whose region is only the pad's rim beyond y = 38.5 mm,
    mid-pass: ``(toolpath, kernel, region, edge, fastest)``, ``edge`` the touched samples outside
    the region, ``fastest`` the removal at the fastest feed."""
    fine = flat_plate(size_x=0.24, size_y=0.2, spacing=1e-3)
    tp = ToolPath(fine, [_line(0.02, 0.22, 0.02)], "test")
    k = build_kernel(tp, TOOL)
    x, y = k.samples.vertices[:, 0], k.samples.vertices[:, 1]
    touched = np.diff(k.matrix.tocsr().indptr) > 0
    region = touched & (y > 0.0385) & (np.abs(x - 0.12) < 0.06)
    return tp, k, region, touched & ~region, k.removal(k.dwell_at_speed(V_MAX))


def test_the_feed_does_not_slow_until_it_gouges_the_samples_beside_the_region(rim_pass):
    """Matching a target on the rim asks the feed to crawl, and the pass's own centre line (outside
    the region) would take many times the target.  Those samples stay under EDGE_CAP_RATIO times the
    region's cap, or under what the fastest feed removes there where that is more."""
    from swath.feed.optimise import EDGE_CAP_RATIO

    tp, k, region, edge, fastest = rim_pass
    target = np.full(len(fastest), 0.9 * fastest[region | edge].max())
    tol = 0.1 * target[0]
    cap = np.maximum(EDGE_CAP_RATIO * (target + tol), fastest)
    assert region.sum() > 50 and edge.sum() > 1000
    held = optimise_feed(tp, TOOL, [FeedLimit(V_MAX)], target=target, tolerance=tol, kernel=k, region=region,
                         v_min=0.002)
    assert np.all(held.predicted[edge] <= cap[edge] * (1 + 1e-3))
    assert held.predicted[edge].max() > 0.99 * cap[edge].max()          # it binds: the centre line is at it
    # not held, the feed crawls further for the rim and the centre line takes half as much again
    free = optimise_feed(tp, TOOL, [FeedLimit(V_MAX)], target=target, tolerance=tol, kernel=k, region=region,
                         v_min=0.002, edge_cap_ratio=math.inf)
    assert free.predicted[edge].max() > 1.3 * cap[edge].max()
    assert free.predicted[region].mean() > held.predicted[region].mean()


def test_the_edge_cap_reads_the_given_target_where_the_target_is_raised_to_the_fastest_feed(rim_pass):
    """With ``target_floor="fastest"`` a sample's target is raised to what the fastest feed removes
    there; beside the region that must not raise its cap too (twice the raised target let the
    feed slow down over a convex fold at the edge of bezier_dac_scan: 124 um where the fastest feed
    removes 84 um).  A target a third of the centre line's fastest removal: the centre line may take
    what the fastest feed removes, not twice that."""
    from swath.feed.optimise import EDGE_CAP_RATIO

    tp, k, region, edge, fastest = rim_pass
    target = np.full(len(fastest), fastest[region | edge].max() / 3)
    tol = 0.1 * target[0]
    cap = np.maximum(EDGE_CAP_RATIO * (target + tol), fastest)
    assert (fastest[edge] > EDGE_CAP_RATIO * (target[edge] + tol)).sum() > 100     # the centre line's band
    held = optimise_feed(tp, TOOL, [FeedLimit(V_MAX)], target=target, tolerance=tol, kernel=k, region=region,
                         v_min=0.002, target_floor="fastest")
    assert np.all(held.predicted[edge] <= cap[edge] * (1 + 1e-3))
    assert held.predicted[edge].max() > 0.99 * fastest[edge].max()
