"""Candidate directions that cannot beat a cheaper one already ranked stop after their contact
time: the bar they are held to, the split timing it reads, and the plan left unchanged."""

import importlib
import math

import numpy as np
import pytest

from swath.cli.job import cycle_time_cost
from swath.contact import Tool
from swath.examples import doubly_curved_panel, flat_plate
from swath.order import order_toolpath
from swath.plan.raster import raster
from swath.trajectory import (
    AngularSpeedLimit,
    CentripetalLimit,
    FeedLimit,
    LinkSettings,
    contact_duration,
    links_duration_bound,
    time_passes,
    time_path,
)

U = importlib.import_module("swath.plan.uniform")
LIMITS = [FeedLimit(0.05), AngularSpeedLimit(1.0), CentripetalLimit(2.0)]


def test_the_bar_comes_from_candidates_eligible_whenever_this_one_is():
    ranked = ((0.999, 100.0), (0.990, 50.0), (0.9955, 80.0))
    # 0.990 covers less and may fall below the floor; 0.9955 is above the 99.5 % the floor never exceeds
    assert U._bar(ranked, {"covered_pred": 0.998}) == 80.0
    assert U._bar(ranked, {"covered_pred": 0.9999}) == 80.0
    assert U._bar(ranked, {"covered_pred": 0.985}) == 50.0           # all cover at least as much
    assert U._bar(((0.990, 50.0),), {"covered_pred": 0.992}) == math.inf
    assert U._bar((), {"covered_pred": 0.9}) == math.inf


def test_timing_the_passes_first_gives_the_same_trajectory_and_a_lower_bound():
    s = flat_plate(size_x=0.2, size_y=0.15)
    tp = order_toolpath(raster(s, Tool(), spacing=0.04))
    timed = time_passes(tp, LIMITS)
    whole = time_path(tp, LIMITS, links=LinkSettings())
    split = time_path(tp, LIMITS, links=LinkSettings(), timed=timed)
    np.testing.assert_array_equal(split.t, whole.t)
    np.testing.assert_array_equal(split.position, whole.position)
    contact = contact_duration(timed)
    # the passes' own time is the trajectory's time in contact, and the links add to it
    in_contact = np.sum(np.diff(whole.t)[whole.contact[1:] & whole.contact[:-1]])
    assert contact == pytest.approx(in_contact, rel=0.02)
    assert 0 < contact < whole.duration
    # the links' bound: between the contact time and the cycle time
    links_least = links_duration_bound(tp, timed, LinkSettings())
    assert 0 < links_least and contact + links_least <= whole.duration
    # with the angular-speed limit: the snake's half turns between passes, pi s each at 1 rad/s
    turning = links_duration_bound(tp, timed, LinkSettings(), omega_max=1.0)
    assert turning >= links_least
    assert contact + turning <= whole.duration
    # approach and retreat alone: 2 cm at 1 m/s² from rest to rest, 2 sqrt(0.02 / 1) s each
    assert links_least >= 0.95 * 2 * 2 * math.sqrt(0.02)
    # no pass runs faster than the 0.05 m/s feed
    assert contact >= sum(p.length for p in tp.passes) / 0.05 * (1 - 1e-6)
    cost = cycle_time_cost(LIMITS, LinkSettings())
    assert cost.bounded(tp, math.inf) == cost(tp)
    value, why = cost.bounded(tp, 0.5 * contact)
    assert value is None and "more than the best" in why
    with pytest.raises(Exception, match="timed holds"):
        time_path(tp, LIMITS, timed=timed[:-1])


@pytest.mark.parametrize("workers", [1, 2])
def test_stopping_early_leaves_the_plan_and_the_ranked_costs_unchanged(monkeypatch, workers):
    surface = doubly_curved_panel(size_x=0.25, size_y=0.2, spacing=8e-3)
    cost = cycle_time_cost(LIMITS, LinkSettings())
    options = dict(work_spacing=Tool().pad_radius / 5, workers=workers, cost=cost)
    bars: list[float] = []
    real = U._ranked

    def recorded(surface, layout, point_spacing, cost, bar=math.inf):
        bars.append(bar)
        return real(surface, layout, point_spacing, cost, bar)

    monkeypatch.setattr(U, "_ranked", recorded)
    pruned = U.uniform(surface, Tool(), **options)
    monkeypatch.setattr(U, "_bar", lambda ranked, layout: math.inf)
    everything = U.uniform(surface, Tool(), **options)
    if workers == 1:
        assert any(math.isfinite(b) for b in bars)     # later candidates are held to a bar
    assert pruned.metadata["direction_rad"] == everything.metadata["direction_rad"]
    assert len(pruned.passes) == len(everything.passes)
    for a, b in zip(pruned.passes, everything.passes):
        np.testing.assert_array_equal(a.points, b.points)
        np.testing.assert_array_equal(a.normals, b.normals)
    full = {round(c["direction_deg"]): c["cost"] for c in everything.metadata["candidates"]}
    for c in pruned.metadata["candidates"]:
        if c["cost"] is not None:
            assert c["cost"] == full[round(c["direction_deg"])]
        elif full[round(c["direction_deg"])] is not None:
            # stopped early: it did cost more than the chosen direction
            assert full[round(c["direction_deg"])] > min(v for v in full.values() if v is not None)
