"""The placement search counted in work: the same answer whatever the clock, its budget, its
progress, its safety cap, and the distance grid that answers the arm-in-part test as the k-d tree does."""

import math
import time

import numpy as np
import pytest

from swath.errors import InfeasibleError
from swath.robot import Cell, get_robot
from swath.robot.arm_part import ArmPartCheck
from swath.robot.placement import _decimate
from swath.robot.placement_grid import GridArmPartCheck
from swath.robot.solve import solve_trajectory as real_solve

SMALL = {"n_xy": 4, "yaws": (0.0, math.pi / 2), "n_sample": 40, "n_refine": 2, "max_refine": 4, "keep_out": 0.2,
         "refine_samples": 800}


def _wavy_sheet(nx: int = 31, ny: int = 21):
    """A 0.6 m x 0.4 m sheet with a 30 mm wave, as a triangle mesh (part frame, m)."""
    x, y = np.meshgrid(np.linspace(0, 0.6, nx), np.linspace(0, 0.4, ny), indexing="ij")
    z = 0.03 * np.sin(2 * math.pi * x / 0.3) * np.cos(2 * math.pi * y / 0.4)
    v = np.c_[x.ravel(), y.ravel(), z.ravel()]
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), indexing="ij")
    a = (i * ny + j).ravel()
    f = np.r_[np.c_[a, a + ny, a + ny + 1], np.c_[a, a + ny + 1, a + 1]]
    return v, f


@pytest.mark.parametrize("cell", [0.04, 0.015])
def test_the_distance_grid_gives_the_k_d_trees_answers(cell):
    """Configuration for configuration, the grid's arm-in-part answers are the tree's; both hits and
    misses occur (the sheet stands in front of a UR10e, the configurations are random)."""
    model = get_robot("ur10e")
    tree = ArmPartCheck(model, *_wavy_sheet())
    grid = GridArmPartCheck(tree, cell=cell)
    part2base = np.eye(4)
    part2base[:3, 3] = [0.25, -0.2, 0.05]
    q = np.random.default_rng(7).uniform(-math.pi, math.pi, (4000, 6))
    want = tree.hits(q, part2base)
    got = grid.hits(q, part2base, chunk=1500)
    assert 200 < want.sum() < 3800
    np.testing.assert_array_equal(got, want)


def test_a_large_part_gets_a_coarser_grid_with_the_same_answers(monkeypatch):
    import swath.robot.placement_grid as pg

    model = get_robot("ur10e")
    tree = ArmPartCheck(model, *_wavy_sheet())
    monkeypatch.setattr(pg, "MAX_NODES", 3000)
    grid = pg.GridArmPartCheck(tree, cell=0.01)
    assert grid.distance.size <= 3000 and grid.cell > 0.05
    q = np.random.default_rng(3).uniform(-math.pi, math.pi, (1500, 6))
    part2base = np.eye(4)
    part2base[:3, 3] = [0.25, -0.2, 0.05]
    np.testing.assert_array_equal(grid.hits(q, part2base), tree.hits(q, part2base))


def _search(trajectory, monkeypatch, clock=None, **kw):
    import swath.robot.placement as placement

    if clock is not None:
        monkeypatch.setattr(placement, "_now", clock)
    calls = []

    def spy(*args, **kwargs):
        calls.append(len(args[0]))
        return real_solve(*args, **kwargs)

    monkeypatch.setattr(placement, "solve_trajectory", spy)
    seen = []
    best = placement.search_placement(trajectory, get_robot("ur3e"), Cell(),
                                      progress=lambda m, d, t: seen.append((m, d, t)), **{**SMALL, **kw})
    return best, calls, seen


def _slow_clock(step: float):
    """A clock that runs ``step`` s per reading (a machine that many times slower)."""
    now = [0.0]

    def clock():
        now[0] += step
        return now[0]
    return clock


def test_the_placement_does_not_depend_on_the_clock(plate_trajectory, monkeypatch):
    """Read on a clock 20 s per reading (each solve seems to take 20 s; a 40 s wall-clock budget would
    have stopped after two), the search solves the same cells and chooses the same placement."""
    quick, calls_quick, _ = _search(plate_trajectory, monkeypatch)
    slow, calls_slow, _ = _search(plate_trajectory, monkeypatch, clock=_slow_clock(20.0))
    assert calls_quick == calls_slow and len(calls_quick) >= 3
    assert slow.trials == quick.trials and not slow.warnings and not quick.warnings
    np.testing.assert_array_equal(slow.cell.part2base, quick.cell.part2base)
    np.testing.assert_array_equal(slow.cell.tcp2flange, quick.cell.tcp2flange)
    assert slow.reachable_fraction == quick.reachable_fraction


def test_the_work_budget_is_honoured_and_counted(plate_trajectory, monkeypatch):
    best, calls, seen = _search(plate_trajectory, monkeypatch, n_refine=3, max_refine=3,
                                tool_rotations=(0.0, math.pi))
    # at most max_refine cells and the one other tool rotation solved, each on the decimated trajectory
    coarse = len(_decimate(plate_trajectory, 800))
    assert len(calls) == best.solved == len(best.trials) <= 3 + 1
    assert set(calls) == {coarse} and 700 < coarse < 900
    n_sample = min(40, int(plate_trajectory.contact.sum()))
    assert best.ik_poses == best.evaluated * n_sample + best.solved * coarse
    # the best trial is the answer
    top = max(best.trials, key=lambda t: (t["reachable_fraction"], t["thresholds_kept"], -t["arm_changes"],
                                          min(t["min_joint_limit_margin_rad"], math.radians(10)),
                                          t["mean_manipulability"]))
    assert best.reachable_fraction == top["reachable_fraction"]
    assert (best.x, best.y) == pytest.approx((top["x_m"], top["y_m"]), abs=1e-12)
    # progress: one message, done never going back, ending at the budget's total
    assert len({m for m, _, _ in seen}) == 1 and "placement search for ur3e" in seen[0][0]
    done = [d for _, d, _ in seen]
    assert done == sorted(done) and done[-1] == seen[-1][2] and len({t for _, _, t in seen}) == 1


def test_the_safety_cap_stops_the_search_and_warns(plate_trajectory, monkeypatch):
    best, calls, _ = _search(plate_trajectory, monkeypatch, clock=_slow_clock(1000.0))
    assert len(calls) == best.solved == 1
    assert len(best.warnings) == 1 and "[W-ROBOT-PLACE-CAPPED]" in best.warnings[0]
    assert "600 s safety cap after solving 1 of up to" in best.warnings[0]


def test_the_cli_shows_the_placement_time_left(plate_trajectory, monkeypatch, capsys):
    """The search's progress on the CLI's progress lines: percentages with the time left once the
    step has run 5 s (a clock one second per call)."""
    from swath.cli.main import _Progress

    _, _, seen = _search(plate_trajectory, monkeypatch)
    show = _Progress(False, clock=_slow_clock(1.0))
    for m, d, t in seen:
        show(m, d, t)
    err = capsys.readouterr().err.splitlines()
    assert err[0].endswith(seen[0][0])
    assert any(line.endswith("s left") and "%" in line for line in err)
    assert err[-1].endswith("100.0 %")


def test_an_oversized_part_is_refused_by_the_search_in_under_two_seconds(plate_trajectory):
    from conftest import shared_mesh
    from swath.io.mesh import load_mesh

    crs = load_mesh(shared_mesh("crs_part_5.stl"), units="m")
    t0 = time.perf_counter()
    with pytest.raises(InfeasibleError, match="does not fit the reach of ur10e"):
        from swath.robot import search_placement

        search_placement(plate_trajectory, get_robot("ur10e"), Cell.from_text(None, "0,0,150mm,0,0,0"),
                         points=crs.vertices)
    assert time.perf_counter() - t0 < 2.0
