"""The mid-spatial ripple figure (swath.simulate.ripple) against the summed pad cross-profiles."""

import numpy as np
import pytest

from swath.cli.job import JobSettings, make_plan
from swath.examples import example_part
from swath.feed.ripple import cross_profile
from swath.simulate import simulate_removal
from swath.simulate.ripple import pass_period, removal_ripple
from swath.trajectory import time_path


def _plate_run(spacing):
    settings = JobSettings(part="example:plate", out="unused", spacing=spacing)
    surface, tool = example_part("plate"), settings.tool()
    toolpath = make_plan(surface, settings)
    trajectory = time_path(toolpath, settings.constraints(), links=settings.links())
    removal = simulate_removal(trajectory, surface, tool, sample_spacing=2e-3)
    return settings, tool, trajectory, removal


def _summed_profile(tool, spacing, speed):
    """Depth (m) over one period of infinitely many straight passes ``spacing`` apart at ``speed``."""
    y = (np.arange(1024) + 0.5) / 1024 * spacing
    images = np.arange(-4, 5) * spacing
    rel = (y[:, None] - images[None, :]).ravel()
    return cross_profile(tool, rel, speed=speed).reshape(len(y), -1).sum(axis=1)


@pytest.mark.parametrize("spacing", [0.06, 0.07])
def test_ripple_on_a_plate_raster_matches_the_summed_cross_profiles(spacing):
    settings, tool, trajectory, removal = _plate_run(spacing)
    ripple = removal_ripple(removal, trajectory, tool)
    assert ripple["ripple_period_m"] == pytest.approx(spacing, rel=0.01)     # measured on the trajectory
    assert ripple["n_ripple_lines"] > 100
    total = _summed_profile(tool, spacing, settings.feed)
    # the removal samples (2 mm) and their interpolation blur the cusp where two semicircles meet
    # (infinite slope at the pad's rim): measured 2 % high at 60 mm, 6 % low at 70 mm
    assert ripple["ripple_pv_m"] == pytest.approx(total.max() - total.min(), rel=0.09)
    assert ripple["ripple_rms_m"] == pytest.approx(total.std(), rel=0.05)


def test_ripple_is_undefined_with_a_single_pass():
    settings, tool, trajectory, removal = _plate_run(0.06)
    first = trajectory.pass_index == 0
    assert not np.isnan(pass_period(trajectory))
    from dataclasses import replace

    one = replace(trajectory, contact=trajectory.contact & first)
    assert np.isnan(pass_period(one))
    assert np.isnan(removal_ripple(removal, one, tool)["ripple_pv_m"])
