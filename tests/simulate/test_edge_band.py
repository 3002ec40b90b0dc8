"""The edge band split by cause (swath.simulate.edge_band): designed depth fields and a simulated plane."""

import math

import numpy as np
import pytest

from shapes import plate_with_straight_passes, timed_plate_raster
from swath.cli.job import JobSettings
from swath.simulate import simulate_removal
from swath.simulate.edge_band import GROUPS, band_causes, band_line
from swath.simulate.evenness import evenness_metrics, evenness_split
from swath.simulate.removal import RemovalMap
from swath.trajectory import time_path

SPACING = 0.05


@pytest.fixture(scope="module")
def plate():
    """The plate's raster (passes along x, 50 mm apart) and samples every 4 mm."""
    surface, tool, trajectory = timed_plate_raster(SPACING)
    return tool, trajectory, surface.subdivided(4e-3), surface


def _causes(plate, depth_of):
    tool, trajectory, samples, _ = plate
    removal = RemovalMap(samples, depth_of(samples.vertices))
    return band_causes(removal, trajectory, tool, spacing=SPACING), evenness_split(removal, trajectory, tool,
                                                                                  spacing=SPACING)


def _edge_distances(plate, v):
    """Distance (m) of points ``v`` from the plate's edges across x (pass ends) and across y (sides)."""
    surface = plate[3]
    lo, hi = surface.bounds
    return np.minimum(v[:, 0] - lo[0], hi[0] - v[:, 0]), np.minimum(v[:, 1] - lo[1], hi[1] - v[:, 1])


def test_a_band_raised_by_a_constant_is_all_mean_offset(plate):
    tool = plate[0]
    band_reach = tool.pad_radius + SPACING

    def depth(v):
        dx, dy = _edge_distances(plate, v)
        return 1e-6 * (1.0 + 0.1 * (np.minimum(dx, dy) <= band_reach))

    c, split = _causes(plate, depth)
    # with f the band's area share, the interior mean is 1 + 0.1 f and V = 0.01 f (1 - f): the band's
    # share is 1 - f, all of it its mean; a band like the (flat) core would hold f² / (1 - f) of V
    f = c["band_area_fraction"]
    assert 0.3 < f < 0.9
    assert c["band_variance_fraction"] == pytest.approx(split["band_variance_fraction"], rel=1e-9)
    assert c["band_variance_fraction"] == pytest.approx(1 - f, rel=1e-9)
    assert c["band_mean_offset_variance_fraction"] == pytest.approx(1 - f, rel=1e-9)
    assert c["band_excess_variance_fraction"] == pytest.approx((1 - f) - f**2 / (1 - f), rel=1e-9)
    assert c["band_mean_over_core_mean_ratio"] == pytest.approx(1.1, rel=1e-9)
    assert c["band_own_cov"] == pytest.approx(0.0, abs=1e-9)
    assert c["band_side_profile"] == pytest.approx([1.1] * 6, rel=1e-9)


def test_the_groups_add_up_to_the_band_and_a_raised_side_shows_beside_the_passes(plate):
    tool = plate[0]
    rng = np.random.default_rng(7)
    band_reach = tool.pad_radius + SPACING

    def depth(v):
        _, dy = _edge_distances(plate, v)
        # 20 % more within the band's reach of the edges the passes run along (y), noise everywhere
        return 1e-6 * (1.0 + 0.2 * (dy <= band_reach) + 0.05 * rng.standard_normal(len(v)))

    c, _ = _causes(plate, depth)
    assert sum(c[f"band_{g}_variance_fraction"] for g in GROUPS) == pytest.approx(c["band_variance_fraction"],
                                                                                 rel=1e-9)
    assert sum(c[f"band_{g}_area_fraction"] for g in GROUPS) == pytest.approx(c["band_area_fraction"], rel=1e-9)
    # every side sample lies within the band's reach of a y edge; the pass ends' only at the corners
    assert c["band_side_mean_over_core_mean_ratio"] == pytest.approx(1.2, abs=0.01)
    assert c["band_ends_mean_over_core_mean_ratio"] < 1.12
    assert c["band_excess_variance_fraction"] > 0.1
    assert np.nanmin(c["band_side_profile"]) > 1.15


def test_noise_alike_everywhere_is_no_excess(plate):
    rng = np.random.default_rng(11)
    c, _ = _causes(plate, lambda v: 1e-6 * (1.0 + 0.05 * rng.standard_normal(len(v))))
    # the band's share is its area share, within the sampling noise of a few thousand samples
    assert c["band_excess_variance_fraction"] == pytest.approx(0.0, abs=0.05)
    assert c["band_variance_fraction"] == pytest.approx(c["band_area_fraction"], abs=0.05)
    assert c["band_mean_over_core_mean_ratio"] == pytest.approx(1.0, abs=0.005)


def test_the_metrics_carry_the_band_causes(plate):
    tool, trajectory, samples, _ = plate
    removal = RemovalMap(samples, np.full(len(samples.vertices), 1e-6) + 1e-8 * samples.vertices[:, 1])
    m = evenness_metrics(removal, trajectory, tool)
    assert m["evenness_band_side_area_fraction"] > 0
    assert "evenness_band_side_profile" not in m           # scalars only
    assert m["evenness_band_variance_fraction"] == pytest.approx(
        evenness_split(removal, trajectory, tool, spacing=m["evenness_split_spacing_m"])["band_variance_fraction"])
    assert "beside the outermost passes" in band_line(m)


def _plane_band(margin_over_spacing: float) -> dict:
    """Six straight passes 1.4 R apart along a plate 0.3 m long, the outermost ``margin`` in from
    the sides (both), the half-pad lead, constant feed: the band's causes as simulated."""
    settings = JobSettings(part="example:plate", out="unused")
    tool = settings.tool()
    d = 1.4 * tool.pad_radius
    surface, toolpath = plate_with_straight_passes(d, margin_over_spacing * d)
    trajectory = time_path(toolpath, settings.constraints(), links=settings.links(), lead_angle=tool.half_pad_lead)
    removal = simulate_removal(trajectory, surface, tool, sample_spacing=4e-3)
    return band_causes(removal, trajectory, tool, spacing=d)


@pytest.mark.parametrize(("margin", "side_ratio", "tolerance"), [(0.3, 1.045, 0.015), (0.0, 1.0, 0.01)])
def test_on_a_plane_the_outermost_pass_partly_off_the_edge_over_grinds_the_band(margin, side_ratio, tolerance):
    # The pad of the outermost pass hangs over the side by R - m: the force balance presses its part
    # on the plate harder, and reaches R + m in, over the band's first m.  On the edge (m = 0) the
    # pass reaches only R in: the band gets the core's dose from the passes beyond it.  Measured
    # (samples every 4 mm): 1.039 at 0.3 d against 1.002 on the edge.
    c = _plane_band(margin)
    assert c["band_side_mean_over_core_mean_ratio"] == pytest.approx(side_ratio, abs=tolerance)
    assert c["band_ends_mean_over_core_mean_ratio"] == pytest.approx(1.0, abs=0.01)
    if margin > 0:
        assert c["band_side_profile"][0] > 1.1               # the first sixth of the band, nearest the edge
        assert c["band_side_own_cov"] > 1.5 * c["core_cov"]
    else:
        assert c["band_side_own_cov"] < 1.2 * c["core_cov"]
    assert math.isfinite(c["band_excess_variance_fraction"])


def test_the_band_line_says_which_way_and_reads_null_figures():
    assert band_line({"evenness_band_excess_variance_fraction": None}) == ""       # NaN, as metrics.json writes it
    m = {"evenness_band_excess_variance_fraction": -0.07,
         "evenness_band_side_area_fraction": 0.40, "evenness_band_side_variance_fraction": 0.37,
         "evenness_band_side_mean_over_core_mean_ratio": 0.999,
         "evenness_band_ends_area_fraction": 0.25, "evenness_band_ends_variance_fraction": 0.26,
         "evenness_band_ends_mean_over_core_mean_ratio": 0.998,
         "evenness_band_oblique_area_fraction": 0.0, "evenness_band_oblique_variance_fraction": 0.0,
         "evenness_band_oblique_mean_over_core_mean_ratio": None}
    line = band_line(m)
    assert "more evenly than the core (it holds 7 points less of the interior's variance than a band removed " \
        "like the core would)" in line
    assert "beside the outermost passes 37 % of the variance on 40 % of the interior (mean 0.999" in line
    assert "oblique" not in line                                  # an empty group is left out
    worse = band_line({**m, "evenness_band_excess_variance_fraction": 0.14})
    assert "less evenly than the core (it holds 14 points more of the interior's variance" in worse
    same = band_line({**m, "evenness_band_excess_variance_fraction": 0.003})
    assert "as evenly as the core (it holds the share of the variance a band removed like the core would)" in same
