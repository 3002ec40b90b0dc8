"""Raster planes whose steps follow the local swath width (``spacing_on = "swath"``)."""

import math

import numpy as np
import pytest

from shapes import A1, A2, R1, R2, two_radius_part
from swath.contact import Tool
from swath.contact.model import local_patch
from swath.examples import flat_plate
from swath.plan.raster import raster
from swath.plan.surface_planes import level_widths

TOOL = Tool()
def test_steps_follow_the_swath_width_of_each_radius():
    surface, x, arc = two_radius_part()
    d = 0.02
    tp = raster(surface, TOOL, spacing=d, direction=(0.0, 1.0, 0.0), fill_gaps=False, spacing_on="swath")
    # the contact model's widths across passes along the axis of each cylinder, solved here on their own
    w1, w2 = local_patch(np.array([1 / R1, 1 / R2]), np.zeros(2), TOOL).width_across(np.zeros(2))
    assert w1 < 0.7 * w2                                        # 48 mm on the 0.15 m radius, 76 mm on the 0.6 m one
    w_ref = tp.metadata["swath_reference_width_m"]
    assert w_ref == pytest.approx(w2, rel=0.01)                 # two thirds of the area lie on the wider arc
    s = np.sort([np.interp(p.points[:, 0].mean(), x, arc) for p in tp.passes])
    steps, middle = np.diff(s), 0.5 * (s[1:] + s[:-1])
    junction = R1 * A1
    # away from the junction (the pad-scale curvature blends over a pad radius, the level widths over
    # half a spacing) every step is d * w / w_ref
    first = middle < junction - TOOL.pad_radius - d
    second = middle > junction + TOOL.pad_radius + d
    assert first.sum() >= 4 and second.sum() >= 6
    np.testing.assert_allclose(steps[first], d * w1 / w_ref, rtol=0.01)
    np.testing.assert_allclose(steps[second], d * w2 / w_ref, rtol=0.01)
    assert np.all(np.diff(steps) > -1e-4)                       # widening monotonically across the junction
    # the planes fill the extent in steps at the reference width: about 120 mm * w_ref / w1 + 240 mm of it
    extent = tp.metadata["plane_extent_m"][0]
    assert extent == pytest.approx(junction * w_ref / w1 + R2 * A2, rel=0.03)
    assert tp.metadata["n_planes"] == math.ceil(extent / d)
    # the same spacing measured on the surface: equal 20 mm steps
    plain = raster(surface, TOOL, spacing=d, direction=(0.0, 1.0, 0.0), fill_gaps=False)
    s_plain = np.sort([np.interp(p.points[:, 0].mean(), x, arc) for p in plain.passes])
    np.testing.assert_allclose(np.diff(s_plain), d, atol=2e-4)


def test_flat_plate_keeps_the_surface_planes():
    plate = flat_plate()
    a = raster(plate, TOOL, spacing=0.05, direction=0.0, fill_gaps=False, spacing_on="swath")
    b = raster(plate, TOOL, spacing=0.05, direction=0.0, fill_gaps=False, spacing_on="surface")
    assert a.metadata["swath_reference_width_m"] == pytest.approx(2 * TOOL.pad_radius, rel=1e-3)
    assert len(a.passes) == len(b.passes)
    for p, q in zip(a.passes, b.passes):
        np.testing.assert_allclose(p.points, q.points, atol=1e-9)


def test_without_a_spacing_the_covering_planes_stay_projected():
    plate = flat_plate()
    tp = raster(plate, TOOL, direction=0.0, spacing_on="swath")
    assert tp.metadata["spacing_on"] == "projection" and "swath_reference_width_m" not in tp.metadata


def test_level_widths_median_and_empty_bands():
    h = np.array([0.0, 0.01, 0.02, 0.10, 0.11])
    w = np.array([0.04, 0.05, 0.09, 0.07, 0.07])
    a = np.array([1.0, 1.0, 1.0, 1.0, 3.0])
    grid = np.array([0.01, 0.06, 0.105])
    out = level_widths(h, w, a, grid, 0.012)
    # 0.01: the three first samples, median 0.05; 0.06: no sample, the bands beside it interpolated;
    # 0.105: 0.07 either way
    np.testing.assert_allclose(out, [0.05, 0.05 + (0.07 - 0.05) * 0.05 / 0.095, 0.07])


def test_at_constant_feed_the_depth_goes_as_one_over_the_step():
    # Preston: a pass removes the volume k_p F v_rel per metre whatever its width, so under planes that
    # follow the swath the mean depth goes as 1 / step, w2 / w1 times deeper on the tighter arc: the
    # ripple ratio is kept, the level is left to the feed
    from swath.simulate import simulate_removal
    from swath.trajectory import time_path

    surface, x, arc = two_radius_part(step=2e-3, length=0.24)
    d = 0.02
    tp = raster(surface, TOOL, spacing=d, direction=(0.0, 1.0, 0.0), fill_gaps=False, spacing_on="swath")
    removal = simulate_removal(time_path(tp), surface, TOOL, sample_spacing=3e-3)
    w1, w2 = local_patch(np.array([1 / R1, 1 / R2]), np.zeros(2), TOOL).width_across(np.zeros(2))
    v = removal.surface.vertices
    s = np.interp(v[:, 0], x, arc)
    inner = (v[:, 1] > TOOL.pad_radius) & (v[:, 1] < 0.24 - TOOL.pad_radius)
    a = removal.surface.vertex_areas

    def mean(lo, hi):
        m = inner & (s > lo) & (s < hi)
        return np.sum(a[m] * removal.depth[m]) / a[m].sum()

    # a pad radius from the part's edges and about half a pad from the junction, where the steps blend
    narrow, wide = mean(TOOL.pad_radius, 0.09), mean(0.18, 0.30)
    assert narrow / wide == pytest.approx(w2 / w1, rel=0.05)
