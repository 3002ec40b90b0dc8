"""Plain-language warnings about a job's result (:func:`swath.report.plan_warnings`)."""

from __future__ import annotations

import pytest

from swath.contact import Tool
from swath.examples import flat_plate
from swath.plan import raster
from swath.report import plan_warnings
from swath.trajectory import FeedLimit, time_path


@pytest.fixture(scope="module")
def slow_job():
    """A plate raster timed at 10 mm/s while the job's feed is 50 mm/s: all contact time is below
    half the feed."""
    surface = flat_plate(size_x=0.2, size_y=0.1, spacing=5e-3)
    tool = Tool()
    tp = raster(surface, tool)
    return surface, tp, time_path(tp, [FeedLimit(0.01)]), tool


def test_slow_contact_warns_unless_the_feed_was_optimised(slow_job):
    surface, tp, traj, tool = slow_job
    plain = plan_warnings(surface, tp, traj, {}, 0.05, tool.pad_radius)
    assert any("below half the feed for 100 %" in w for w in plain)
    optimised = {"feed_target_mean_m": 2e-5, "feed_removal_mean_m": 1.95e-5, "feed_v_min_m_per_s": 0.005}
    assert not any("below half the feed" in w for w in plan_warnings(surface, tp, traj, optimised, 0.05,
                                                                        tool.pad_radius))


def test_an_unreachable_target_depth_is_named_with_what_to_change(slow_job):
    """5 mm asked, 13.8 um predicted: the warning gives both depths, the share and the remedies;
    within 90 % of the target there is no warning."""
    surface, tp, traj, tool = slow_job
    short = {"feed_target_mean_m": 5e-3, "feed_removal_mean_m": 13.8e-6, "feed_v_min_m_per_s": 0.005}
    (w,) = [w for w in plan_warnings(surface, tp, None, short, 0.05, tool.pad_radius) if "optimised feed" in w]
    assert "removes 13.8 um on average, 0.28 % of the target 5 mm" in w
    assert "down to 5 mm/s" in w and "lower the target" in w and "raise the force" in w
    close = {"feed_target_mean_m": 2e-5, "feed_removal_mean_m": 1.85e-5}
    assert not [w for w in plan_warnings(surface, tp, None, close, 0.05, tool.pad_radius) if "optimised feed" in w]


def test_coverage_just_under_the_threshold_does_not_read_as_on_it(slow_job):
    """98.96 % used to be written "coverage is 99.0 % (below 99 %)"; at 99 % there is no warning."""
    surface, tp, _, tool = slow_job
    (w,) = [w for w in plan_warnings(surface, tp, None, {"coverage_fraction": 0.98962}, 0.05, tool.pad_radius)
            if w.startswith("coverage")]
    assert w.startswith("coverage is 98.96 % (below 99 %): 1.04 % of the part is never touched")
    assert not [w for w in plan_warnings(surface, tp, None, {"coverage_fraction": 0.99}, 0.05, tool.pad_radius)
                if w.startswith("coverage")]


def test_a_short_target_is_put_down_to_the_tolerance_where_it_holds_more_nodes_than_the_slowest_feed(slow_job):
    """crs_part_5's uniform job: the feed reached its 5 mm/s floor at 0.2 % of the nodes, while the
    tolerance held 47 % at their fastest; the warning used to blame the slowest feed."""
    surface, tp, _, tool = slow_job
    base = {"feed_target_mean_m": 3.21e-6, "feed_removal_mean_m": 2.43e-6, "feed_v_min_m_per_s": 0.005,
            "feed_speed_min_m_per_s": 0.005}

    def short(extra):
        (w,) = [w for w in plan_warnings(surface, tp, None, {**base, **extra}, 0.05, tool.pad_radius)
                if "optimised feed" in w]
        return w

    w = short({"feed_nodes_held_by_cap_fraction": 0.473, "feed_nodes_at_slowest_fraction": 0.0022})
    assert "76 % of the target" in w and "47 % of the feed nodes run at their fastest" in w
    assert "0.2 % at the slowest feed (5 mm/s)" in w and "the tolerance holds it back, not the feed" in w
    assert "the slowest feed holds it back" not in w and "raise --depth-tolerance" in w
    # most nodes at the slowest feed: the feed range is the cause
    w = short({"feed_nodes_held_by_cap_fraction": 0.05, "feed_nodes_at_slowest_fraction": 0.6})
    assert "down to 5 mm/s where needed: the slowest feed holds it back" in w and "tolerance" not in w
