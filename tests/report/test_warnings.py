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
