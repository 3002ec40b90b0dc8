"""The default job's plain plan made in a child process while the job optimises the feed: the same
plan, trajectory and removal as made here."""

from __future__ import annotations

import os

import numpy as np
import pytest

from swath.cli import even_default, stages
from swath.cli.job import load_part_info
from swath.cli.settings import settings_from_mapping
from swath.core import beside
from swath.plan.uniform import TRYING_STAGE


@pytest.fixture
def two_cpus(monkeypatch):
    """Two CPUs, unless ``OMP_NUM_THREADS`` says one (as :func:`swath.core.cpus.usable_cpus` reads it)."""
    monkeypatch.setattr(beside, "usable_cpus", lambda: 1 if os.environ.get("OMP_NUM_THREADS") == "1" else 2)


def _plain_of(planner: str):
    settings = settings_from_mapping({"part": "example:plate", "out": "unused", "planner": planner,
                                      "sample_spacing": "6mm", "point_spacing": "4mm"})
    plain = even_default.plain_alternative(settings)
    assert plain is not None and plain.constant_feed
    surface, info = load_part_info(plain)
    return surface, stages.job_tool(plain), plain, info.get("part")


@pytest.mark.parametrize("planner", ["raster", "uniform"])
def test_the_plain_plan_made_beside_is_the_one_made_here(two_cpus, planner):
    surface, tool, plain, part = _plain_of(planner)
    heard: list = []
    here = even_default.plain_run(surface, tool, plain, part=part, progress=lambda *a: heard.append(a))
    # the stages the child's share is read from: the uniform planner's directions, then the simulation
    trying = [h for h in heard if h[0].startswith(TRYING_STAGE)]
    assert (trying[-1][1] == trying[-1][2] > 0) if planner == "uniform" else not trying
    assert heard[-1][0] == even_default.PLAIN_SIMULATING and heard[-1][1] == heard[-1][2] > 0
    surface.forget()                          # the child builds the planner's models itself
    wait = even_default.plain_beside(surface, tool, plain, part=part)
    there = wait()
    if wait.share is not None:              # forked: the planner's directions and the simulation say how far it is
        assert wait.share() == 1.0
    assert len(there[0].passes) == len(here[0].passes) > 0
    for a, b in zip(there[0].passes, here[0].passes):
        np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(there[1].position, here[1].position)
    np.testing.assert_array_equal(there[1].feed, here[1].feed)
    np.testing.assert_array_equal(there[2].depth, here[2].depth)
    assert there[2].metrics["interior_removal_cov"] == here[2].metrics["interior_removal_cov"]


def _starts_a_worker(x):
    import multiprocessing

    with multiprocessing.get_context("fork").Pool(1) as pool:
        return os.getpid(), pool.apply(os.getpid) if x else None


def test_a_child_with_workers_may_start_processes_of_its_own(two_cpus):
    """The plain plan's child may fork the uniform planner's workers (a daemon child may not)."""
    pid, worker = beside.Beside(_starts_a_worker, 1, workers=True).result()
    assert pid != os.getpid() and worker not in (None, pid, os.getpid())
    with pytest.raises(AssertionError, match="daemonic"):
        beside.Beside(_starts_a_worker, 1).result()


def test_an_unread_child_with_workers_is_stopped_at_exit(two_cpus):
    import time

    b = beside.Beside(time.sleep, 30.0, workers=True)
    assert b.forked and b._process.is_alive()
    b._stop()                                   # what runs at exit when the result was never asked for
    assert not b._process.is_alive()


def test_an_unread_child_is_stopped_even_when_the_parent_handles_sigterm(two_cpus):
    # the CLI exits cleanly on SIGTERM (swath.cli.main); a child forked from it must still die at once
    import signal
    import time

    def clean_exit(signum, frame):
        time.sleep(30.0)                 # a handler that does not end the process promptly
        raise SystemExit(signum)

    previous = signal.signal(signal.SIGTERM, clean_exit)
    try:
        b = beside.Beside(time.sleep, 30.0, workers=True)
        assert b.forked and b._process.is_alive()
        time.sleep(1.0)                  # the child is serving (a SIGTERM before that is met by the kill)
        started = time.monotonic()
        b._stop()
        assert not b._process.is_alive()
        assert time.monotonic() - started < 4.0       # terminated, not left to the kill after 5 s
    finally:
        signal.signal(signal.SIGTERM, previous)


def test_a_raster_job_starts_the_plain_plan_before_its_own_plan(two_cpus, tmp_path, monkeypatch):
    """The raster plans in the job's process alone, so the plain plan's child starts with the job
    (its spacing search then runs beside it) and is asked for where it was."""
    from swath.cli import job

    events = []
    original_beside, original_plan = even_default.plain_beside, job.make_plan

    def beside_spy(*args, **kwargs):
        events.append("plain started")
        wait = original_beside(*args, **kwargs)
        return lambda: (events.append("plain asked for"), wait())[1]

    def plan_spy(*args, **kwargs):
        events.append("job planned")
        return original_plan(*args, **kwargs)

    monkeypatch.setattr(even_default, "plain_beside", beside_spy)
    monkeypatch.setattr(job, "make_plan", plan_spy)
    settings = settings_from_mapping({"part": "example:plate", "out": str(tmp_path / "o"), "sample_spacing": "6mm",
                                      "point_spacing": "4mm"})
    metrics = job.run_job(settings)
    assert events == ["plain started", "job planned", "plain asked for"]
    assert metrics["plain_interior_removal_cov"] > metrics["interior_removal_cov"] > 0


def test_a_child_is_ready_once_it_has_answered(two_cpus):
    import time

    b = beside.Beside(time.sleep, 0.5)
    assert b.forked and not b.ready()
    time.sleep(2.0)
    assert b.ready() and b.result() is None and b.ready()
    assert beside.Beside(time.sleep, 0.0, allowed=False).ready()   # nothing forked: computed when asked


def test_a_job_waiting_for_the_plain_plan_says_how_far_it_is(monkeypatch):
    from types import SimpleNamespace

    monkeypatch.setattr(stages, "PLAIN_POLL_S", 0.0)
    shares, readiness = iter([0.2, 0.5, 0.9]), iter([False, False, True])

    def plain():
        return None, SimpleNamespace(duration=10.0), SimpleNamespace(metrics={"interior_removal_cov": 0.5})

    plain.share = lambda: next(shares)
    plain.ready = lambda: next(readiness)
    heard: list = []
    even: dict = {}
    wins = stages._plain_wins(plain, SimpleNamespace(metrics={"interior_removal_cov": 0.3}), even,
                              lambda *a: heard.append(a))
    stage = "the plain plan (covering spacing, flat pad, constant feed) to compare"
    assert heard == [(stage, 200, 1000), (stage, 500, 1000), (stage, 900, 1000)]
    assert not wins and even["plain_interior_removal_cov"] == 0.5


def test_the_closest_point_tree_is_built_once_before_the_child_is_forked(two_cpus, monkeypatch):
    # Both plans route air moves round the part; built before the fork, the child inherits the
    # tree and this process's own plan stage does not build it again.
    surface, tool, plain, part = _plain_of("raster")
    surface.__dict__.pop("_closest_point_tree", None)
    wait = even_default.plain_beside(surface, tool, plain, part=part)
    built_here = "_closest_point_tree" in surface.__dict__
    answer = wait()
    assert len(answer[0].passes) > 0
    assert built_here == beside.can_fork()
