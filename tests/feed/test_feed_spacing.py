"""Raster passes at given offsets and the greedy pass spacing."""

import numpy as np
import pytest

from swath.contact import Tool
from swath.errors import InfeasibleError
from swath.examples import flat_plate
from swath.feed.spacing import greedy_offsets, raster_at_offsets
from swath.plan.common import feed_and_cross
from swath.trajectory import FeedLimit

TOOL = Tool(pad_radius=0.02)


@pytest.fixture(scope="module")
def plate():
    return flat_plate(size_x=0.2, size_y=0.12, spacing=4e-3)


def test_passes_lie_on_the_given_planes(plate):
    _, cross = feed_and_cross(plate, angle=0.0)
    heights = plate.vertices @ cross
    offsets = [heights.min() + 0.015, heights.min() + 0.04, heights.min() + 0.09]
    tp = raster_at_offsets(plate, TOOL, offsets[::-1])
    assert len(tp.passes) == 3
    got = [float(np.mean(p.points @ cross)) for p in tp.passes]
    np.testing.assert_allclose(got, offsets, atol=1e-9)                 # sorted, snake order
    d0 = tp.passes[0].points[-1] - tp.passes[0].points[0]
    d1 = tp.passes[1].points[-1] - tp.passes[1].points[0]
    assert d0 @ d1 < 0                                                    # alternating travel


def test_offsets_off_the_part_are_infeasible(plate):
    with pytest.raises(InfeasibleError, match="no cutting plane"):
        raster_at_offsets(plate, TOOL, [10.0, 11.0])


def test_greedy_steps_stay_in_range_and_cover_the_part(plate):
    R = TOOL.pad_radius
    res = greedy_offsets(plate, TOOL, [FeedLimit(0.05)], target=5e-6, step_range=(0.5 * R, 2 * R))
    steps = np.diff(res.offsets)
    assert (steps >= 0.5 * R - 1e-12).all() and (steps <= 2 * R + 1e-12).all()
    _, cross = feed_and_cross(plate, angle=0.0)
    h = plate.vertices @ cross
    # the last plane leaves less than one step plus a quarter radius uncovered at the far edge
    assert h.max() - res.offsets[-1] <= steps.max() + 0.25 * R + 1e-9
    assert res.metrics["n_planes"] == len(res.toolpath.passes) == len(res.offsets)


def test_joint_spacing_finds_the_least_ripple_spacing():
    """On a plate the feed cannot flatten the ripple across parallel passes, so the joint search's
    best equal spacing within L <= 1.5 L* is the analytic least-ripple spacing (about 1.68 R for a
    flat orbital pad), and its optimised removal CoV is the analytic ripple there."""
    from swath.feed import joint_spacing, ripple_cov, ripple_spacing

    R = TOOL.pad_radius
    plate = flat_plate(size_x=0.2, size_y=0.2, spacing=4e-3)
    rate = TOOL.preston * TOOL.force / (np.pi * R**2) * TOOL.relative_speed(0.0)
    D = 2.0 * rate * 2 * R / 0.05                       # twice a single pass at the feed limit
    res = joint_spacing(plate, TOOL, [FeedLimit(0.05)], target=D, tolerance=0.1 * D, n_coarse=5, n_refine=3,
                        sample_spacing=4e-3)
    steps = np.diff(res.offsets)
    np.testing.assert_allclose(steps, steps[0], rtol=1e-9)                # equal spacing
    d_best, _ = ripple_spacing(TOOL)
    assert abs(steps[0] - d_best) < 0.12 * R
    assert (steps >= 2 * R / 1.5 - 1e-12).all()                          # default range keeps L <= 1.5 L*
    cov = res.feed.metrics["removal_cov"]
    assert abs(cov - ripple_cov(TOOL, steps[0])) < 0.03
    assert res.feed.metrics["max_over_removal_m"] <= 0.1 * D * (1 + 1e-9)
    full = [t for t in res.trials if abs(t["spacing_m"] - 2 * R) < 1e-9]
    assert full and full[0]["removal_cov"] > cov + 0.1                  # pads edge to edge ripple far more
    assert res.metrics["evaluations"] == len(res.trials) <= 5 + 2 * 3
