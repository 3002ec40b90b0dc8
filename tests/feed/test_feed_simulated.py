"""The simulator-in-the-loop correction of :func:`swath.feed.optimise_feed` (``simulate=``)."""

from types import SimpleNamespace

import numpy as np
import pytest

from swath.contact import Tool
from swath.examples import doubly_curved_panel
from swath.feed import build_kernel, interior_mask, optimise_feed, trajectory_node_dwell
from swath.plan import raster
from swath.simulate.removal import simulate_removal
from swath.trajectory import AngularSpeedLimit, CentripetalLimit, FeedLimit, TangentialAccelLimit, time_path

TOOL = Tool(pad_radius=0.02, force=20.0)
CONS = [FeedLimit(0.05), CentripetalLimit(2.0), AngularSpeedLimit(1.0), TangentialAccelLimit(1.0)]


@pytest.fixture(scope="module")
def curved():
    """A small doubly curved panel (radii 0.15 m and 0.25 m), raster passes, its kernel on the
    timed poses and a target depth D the fastest feed reaches nowhere above 0.9 D."""
    surface = doubly_curved_panel(size_x=0.16, size_y=0.12, radius_x=0.15, radius_y=0.25, spacing=3e-3)
    tp = raster(surface, TOOL)
    k = build_kernel(tp, TOOL, trajectory=time_path(tp, CONS))
    fastest = k.removal(trajectory_node_dwell(time_path(tp, CONS), k.nodes, tp))
    inside = interior_mask(k.samples, TOOL.pad_radius) & (fastest > 0)
    D = float(fastest[inside].max()) / 0.9
    return surface, tp, k, D, float(fastest[inside].max())


def test_scaled_simulator_is_held_back_by_its_ratio(curved):
    """A 'simulator' that removes 1.3 times what the kernel predicts for the timed dwell: after the
    correction its largest removal is within the tolerance, and the hold-back found is 30 %."""
    surface, tp, k, _, fastest = curved
    D = fastest / 0.7                         # 1.3 x the fastest feed's removal stays below D + tolerance
    tol = 0.1 * D

    def simulate(traj):
        return SimpleNamespace(surface=k.samples, depth=1.3 * k.removal(trajectory_node_dwell(traj, k.nodes, tp)))

    plain = optimise_feed(tp, TOOL, CONS, target=D, tolerance=tol, kernel=k)
    over_plain = (simulate(time_path(tp, CONS + [plain.profile])).depth - D)[plain.region].max()
    assert over_plain > tol                                   # the uncorrected feed does over-grind
    res = optimise_feed(tp, TOOL, CONS, target=D, tolerance=tol, kernel=k, simulate=simulate, simulate_rounds=3)
    rounds = res.metrics["simulated_rounds"]
    assert rounds[0]["held_back_ratio"] == pytest.approx(0.3, abs=0.01)
    assert rounds[-1]["samples_over"] == 0
    final = simulate(time_path(tp, CONS + [res.profile])).depth
    assert (final - D)[res.region].max() <= tol * (1 + 1e-6)
    assert res.metrics["simulated_max_over_target_m"] == pytest.approx((final - D)[res.region].max(), rel=1e-9)


def test_real_simulator_never_over_grinds_after_correction(curved):
    """With :func:`simulate_removal` in the loop, the simulated depth of the final timed trajectory
    is at most target + tolerance at every optimised sample."""
    surface, tp, k, D, _ = curved
    tol = 0.1 * D
    res = optimise_feed(tp, TOOL, CONS, target=D, tolerance=tol, kernel=k, simulate_rounds=3,
                        simulate=lambda traj: simulate_removal(traj, surface, TOOL))
    final = simulate_removal(time_path(tp, CONS + [res.profile]), surface, TOOL)
    assert np.array_equal(final.surface.vertices, k.samples.vertices)
    assert (final.depth - D)[res.region].max() <= tol
    assert res.metrics["simulated_rounds"][-1]["samples_over"] == 0


def test_simulated_depth_maps_to_the_nearest_kernel_sample(curved):
    """A simulator sampling the part differently: each kernel sample gets the largest simulated depth
    of the simulator samples nearest to it."""
    from swath.feed.timed import simulated_on_kernel

    k = curved[2]
    v = k.samples.vertices
    rng = np.random.default_rng(3)
    depth = rng.uniform(0, 1e-6, len(v))
    # every kernel sample twice, moved 10 µm off: the second copy 0.5 µm deeper
    moved = np.vstack([v + 1e-5, v - 1e-5])
    sim = SimpleNamespace(surface=SimpleNamespace(vertices=moved), depth=np.concatenate([depth, depth + 5e-7]))
    np.testing.assert_allclose(simulated_on_kernel(sim, k.samples), depth + 5e-7)
    same = SimpleNamespace(surface=k.samples, depth=depth)
    assert simulated_on_kernel(same, k.samples) is depth


def test_loop_stops_when_no_cap_can_be_tightened(curved, caplog):
    """A 'simulator' that reads one sample over the tolerance whatever the feed (as where the limits
    hold the tool slower than the target allows): the loop stops once its caps stop changing, with
    a warning, instead of solving the same programme for every remaining round."""
    surface, tp, k, D, _ = curved
    tol = 0.1 * D
    inside = np.flatnonzero(interior_mask(k.samples, TOOL.pad_radius))
    j = inside[len(inside) // 2]

    def simulate(traj):
        depth = k.removal(trajectory_node_dwell(traj, k.nodes, tp))
        depth[j] = D + 2 * tol
        return SimpleNamespace(surface=k.samples, depth=depth)

    with caplog.at_level("INFO", logger="swath.feed.optimise"):
        res = optimise_feed(tp, TOOL, CONS, target=D, tolerance=tol, kernel=k, simulate=simulate, simulate_rounds=5,
                            trim_rounds=3)
    rounds = res.metrics["simulated_rounds"]
    solves = [r for r in rounds if r["kind"] == "solve"]
    assert len(solves) < 6
    assert "cannot be tightened" in caplog.text
    # then the trim rounds speed up the nodes over it while they can, and say that it is still over
    assert all(r["kind"] == "trim" for r in rounds[len(solves):]) and len(rounds) <= len(solves) + 3
    assert rounds[-1]["samples_over"] == 1
    assert any(r.levelname == "WARNING" and ("still simulated over" in r.message or "as fast as" in r.message)
               for r in caplog.records)


def test_trim_rounds_only_ever_speed_up(curved):
    """A 'simulator' that reads 1.15 times the kernel in a band across the panel, with no re-solve
    round: the trim rounds alone bring every sample within the tolerance, and no sample anywhere
    gets more removal than without them (the commanded feed only rises)."""
    surface, tp, k, D, _ = curved
    tol = 0.1 * D
    y = k.samples.vertices[:, 1]
    band = np.abs(y - np.median(y)) < 0.02

    def simulate(traj):
        depth = k.removal(trajectory_node_dwell(traj, k.nodes, tp))
        return SimpleNamespace(surface=k.samples, depth=np.where(band, 1.15 * depth, depth))

    kw = dict(target=D, tolerance=tol, kernel=k, simulate=simulate, simulate_rounds=0)
    untrimmed = optimise_feed(tp, TOOL, CONS, trim_rounds=0, **kw)
    before = simulate(time_path(tp, CONS + [untrimmed.profile])).depth
    assert (before - D)[untrimmed.region].max() > tol                 # over without the trim
    heard = []
    res = optimise_feed(tp, TOOL, CONS, trim_rounds=8, progress=lambda *a: heard.append(a), **kw)
    after = simulate(time_path(tp, CONS + [res.profile])).depth
    assert (after - D)[res.region].max() <= tol
    assert np.all(after <= before * (1 + 1e-9) + 1e-15)
    rounds = res.metrics["simulated_rounds"]
    # progress: each HiGHS solve, the simulated round, then each trim round under its own name
    stages = [a[0] for a in heard]
    assert stages[0] == "solve" and stages.count("simulate") == 1
    assert stages.count("trim") == sum(r["kind"] == "trim" for r in rounds) and stages[-1] == "trim"
    assert rounds[0]["kind"] == "solve" and rounds[-1] == {**rounds[-1], "kind": "trim", "samples_over": 0}
    assert res.metrics["simulated_max_over_target_m"] == pytest.approx((after - D)[res.region].max(), rel=1e-9)
    # the reported feeds are the trimmed ones: faster where the band was over, the same elsewhere
    assert np.all(res.speed >= untrimmed.speed * (1 - 1e-9)) and np.any(res.speed > 1.01 * untrimmed.speed)


def test_spread_check_trims_what_the_simulator_misses(curved):
    """A 'simulator' that under-reads (0.9 times the kernel) finds nothing over, while the programme's
    cap sits at target + tolerance (no hold-back): the timed-spread kernel then reads samples over
    the tolerance, and the spread check trims them; without it they stay over."""
    from swath.feed.timed import timed_spread_removal

    surface, tp, k, D, _ = curved
    tol = 0.1 * D

    def simulate(traj):
        return SimpleNamespace(surface=k.samples, depth=0.9 * k.removal(trajectory_node_dwell(traj, k.nodes, tp)))

    kw = dict(target=D, tolerance=tol, kernel=k, simulate=simulate, cap_margin=0.0, model_error=0.0)
    unchecked = optimise_feed(tp, TOOL, CONS, spread_check=False, **kw)
    spread_before = timed_spread_removal(k, time_path(tp, CONS + [unchecked.profile]))
    assert (spread_before - D)[unchecked.region].max() > tol
    res = optimise_feed(tp, TOOL, CONS, spread_check=True, **kw)
    rounds = res.metrics["simulated_rounds"]
    assert rounds[0]["samples_over"] == 0 and rounds[0]["spread_samples_over"] > 0
    assert rounds[-1]["kind"] == "trim" and rounds[-1]["samples_over"] == 0
    spread_after = timed_spread_removal(k, time_path(tp, CONS + [res.profile]))
    assert (spread_after - D)[res.region].max() <= tol
