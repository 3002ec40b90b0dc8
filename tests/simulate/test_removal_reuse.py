"""What the removal simulation keeps between calls on one part (the lattice samples, their interior
masks, the coverage bound's density) gives the very numbers computing them afresh gives."""

import numpy as np
import pytest

from shapes import sphere_cap
from swath.contact import Tool
from swath.plan import Pass, ToolPath
from swath.simulate import simulate_removal
from swath.surface import Surface
from swath.surface.surface import farther_from_boundary
from swath.trajectory import FeedLimit, time_path


def _cap_and_trajectory():
    s = sphere_cap(0.2, 0.5, n=24)                                   # an open cap: it has a boundary
    x = np.linspace(-0.07, 0.07, 60)
    passes = []
    for y in (-0.03, 0.0, 0.03):
        d = np.stack([x, np.full_like(x, y), np.sqrt(0.2**2 - x**2 - y**2)], 1)
        passes.append(Pass(d, d / np.linalg.norm(d, axis=1, keepdims=True)))
    return s, time_path(ToolPath(s, passes, "test"), [FeedLimit(0.05)])


def test_the_kept_samples_give_the_numbers_of_fresh_ones():
    s, tr = _cap_and_trajectory()
    tool = Tool()
    first = simulate_removal(tr, s, tool, sample_spacing=3e-3, sampling="lattice")
    s.forget()                                   # the planners' models go; the samples stay
    again = simulate_removal(tr, s, tool, sample_spacing=3e-3, sampling="lattice")
    assert again.surface is first.surface
    fresh_part = Surface(s.vertices, s.faces, name=s.name)          # nothing kept on it yet
    fresh = simulate_removal(tr, fresh_part, tool, sample_spacing=3e-3, sampling="lattice")
    assert fresh.surface is not first.surface
    assert np.array_equal(fresh.surface.vertices, again.surface.vertices)
    # the compiled kernel adds per pose in threads: the same sums, to rounding
    assert np.allclose(again.depth, fresh.depth, rtol=1e-12, atol=0.0)
    for key in ("coverage_fraction", "removal_cov", "interior_removal_cov", "coverage_lower_bound_m",
                "covered_lower_bound_m", "efficiency", "interior_area_m2"):
        assert again.metrics[key] == pytest.approx(fresh.metrics[key], rel=1e-12), key
    assert 0 < again.metrics["interior_area_m2"] < again.metrics["surface_area_m2"]
    # another spacing is other samples
    coarse = simulate_removal(tr, s, tool, sample_spacing=4e-3, sampling="lattice")
    assert len(coarse.surface) < len(first.surface)


def test_the_interior_mask_is_kept_per_margin_and_read_only():
    s, tr = _cap_and_trajectory()
    samples = simulate_removal(tr, s, Tool(), sample_spacing=3e-3, sampling="lattice").surface
    for margin in (0.0125, 0.03):
        kept = samples.farther_from_boundary(margin)
        direct = farther_from_boundary(samples.vertices, s, margin, step=0.5 * samples.spacing)
        assert np.array_equal(kept, direct)
        assert samples.farther_from_boundary(margin) is kept
        assert not kept.flags.writeable
    # a wider margin keeps fewer samples
    assert samples.farther_from_boundary(0.03).sum() < samples.farther_from_boundary(0.0125).sum()


def test_the_pass_period_is_measured_once_per_trajectory():
    from swath.simulate.ripple import _pass_period, pass_period

    _, tr = _cap_and_trajectory()
    first = pass_period(tr)
    assert first == pytest.approx(0.03, rel=0.02)            # the passes lie 30 mm apart (in y, on the cap)
    assert pass_period(tr) == first == _pass_period(tr, 2e-3)
    assert pass_period(tr, step=4e-3) == _pass_period(tr, 4e-3)
