"""Progress lines: percentages, and an estimate of the time left on a step that runs over 5 s."""

from __future__ import annotations

import pytest

from swath.cli.main import ESTIMATE_AFTER_S, _Progress, _time_left


def test_time_left_extrapolates_the_rate_so_far():
    # a quarter done in 10 s: three quarters left at that rate is 30 s
    assert _time_left(10.0, 25, 100) == ", about 30 s left"
    assert _time_left(60.0, 1, 4) == ", about 3 min left"
    assert _time_left(20.0, 99, 100) == ", under a second left"        # 0.2 s: not "about 0 s"


@pytest.mark.parametrize("elapsed, done, total", [(0.4 * ESTIMATE_AFTER_S, 50, 100), (20.0, 0, 100),
                                                  (20.0, 100, 100)])
def test_no_estimate_for_a_short_step_before_the_first_unit_or_when_done(elapsed, done, total):
    # half done in 2 s: the step takes 4 s, under the 5 s that earn an estimate
    assert _time_left(elapsed, done, total) == ""


def test_a_step_of_few_units_is_estimated_by_where_its_rate_leads():
    # two of four candidate directions compared in 3 s: 6 s in all, so the line says what is left,
    # though the step has run for less than 5 s (its next line would be its last)
    assert 3.0 < ESTIMATE_AFTER_S < 6.0
    assert _time_left(3.0, 2, 4) == ", about 3 s left"


def test_progress_lines_carry_the_estimate(capsys):
    clock = iter([0.0, 0.0, 8.0, 16.0])            # start, stage begins, 20 % at 8 s, 50 % at 16 s
    progress = _Progress(quiet=False, clock=lambda: next(clock))
    progress("simulating removal", 0, 10)
    progress("simulating removal", 2, 10)
    progress("simulating removal", 5, 10)
    lines = capsys.readouterr().err.splitlines()
    assert lines[0].endswith("simulating removal")
    assert lines[1].endswith("20.0 %, about 32 s left")           # 8 s for 2 of 10: 8 left at 4 s each
    assert lines[2].endswith("50.0 %, about 16 s left")


def test_a_step_run_again_is_estimated_from_its_own_start(capsys):
    # the spacing search runs the planner's candidate directions once per spacing: the percentages
    # start again, and the estimate must not read the first round's time as the second's first unit
    clock = iter([0.0, 0.0, 4.0, 9.0, 9.0, 12.0, 15.0])
    progress = _Progress(quiet=False, clock=lambda: next(clock))
    progress("trying pass directions", 0, 10)
    progress("trying pass directions", 4, 10)          # 4 s
    progress("trying pass directions", 10, 10)         # 9 s: done
    progress("trying pass directions", 1, 10)          # a second round starts, 1 of 10 at once
    progress("trying pass directions", 3, 10)          # 12 s: two more units in 3 s
    progress("trying pass directions", 5, 10)          # 15 s: four units in 6 s
    lines = capsys.readouterr().err.splitlines()
    assert lines[-1].endswith("50.0 %, about 8 s left")          # 5 left at 1.5 s each (not 15 s / 5 * 5 = 15)
    assert not any("min left" in line for line in lines)


def test_a_highs_solve_line_gives_the_time_of_the_solve_before_it():
    from swath.cli.stages import SOLVE_ESTIMATE_AFTER_S, FeedProgress

    lines = []
    clock = iter([0.0, 2.0, 6.0, 6.5, 9.0, 9.2, 9.4])
    report = FeedProgress(lambda stage, done, total: lines.append(stage), clock=lambda: next(clock))
    report("kernel", 10, 10)          # 0 s
    report("solve", 0, 0)             # 2 s: the first solve, nothing to go by
    report("solve", 1, 0)             # 6 s: the first took 4 s
    report("simulate", 0, 7)          # 6.5 s: the second took 0.5 s (a cap-row round)
    report("solve", 2, 0)             # 9 s: a re-solve after the simulated check
    report("solve", 3, 0)             # 9.2 s: the third took 0.2 s
    report("trim", 0, 8)
    assert lines[1] == "optimising the feed: dwell programme, HiGHS solve 1"
    assert lines[2] == "optimising the feed: dwell programme, HiGHS solve 2, about 4 s as solve 1"
    assert 0.5 < SOLVE_ESTIMATE_AFTER_S                # a half-second solve is no guide: no figure
    assert lines[4] == "optimising the feed: dwell programme, HiGHS solve 3"
    assert lines[5] == "optimising the feed: dwell programme, HiGHS solve 4"
    assert lines[6] == "optimising the feed: speeding up where the simulation is over, round 1"
