"""The split of the interior removal CoV (swath.simulate.evenness) on designed depth fields."""

import numpy as np
import pytest

from shapes import timed_plate_raster
from swath.simulate.evenness import evenness_split
from swath.simulate.removal import RemovalMap

SPACING = 0.05


@pytest.fixture(scope="module")
def plate():
    surface, tool, trajectory = timed_plate_raster(SPACING)
    samples = surface.subdivided(2e-3)
    # the passes' own frame: along (travel) and across, from the first pass
    live = np.flatnonzero(trajectory.contact & (trajectory.pass_index == 0))
    along = trajectory.position[live[-1]] - trajectory.position[live[0]]
    along /= np.linalg.norm(along)
    across = np.cross([0.0, 0.0, 1.0], along)
    y0 = trajectory.position[live[0]] @ across
    return tool, trajectory, samples, along, across, y0


def _split(plate, depth_of):
    tool, trajectory, samples, along, across, y0 = plate
    x = samples.vertices @ along
    y = samples.vertices @ across - y0
    removal = RemovalMap(samples, depth_of(x, y))
    return evenness_split(removal, trajectory, tool, spacing=SPACING, band_width=0.0)


def test_a_ripple_across_the_passes_is_all_within_cells(plate):
    # depth = 1 + 0.1 cos(2π y / d), peaks on the passes: CoV 0.1 / √2, all of it within one period
    s = _split(plate, lambda x, y: 1e-6 * (1 + 0.1 * np.cos(2 * np.pi * y / SPACING)))
    assert s["interior_cov"] == pytest.approx(0.1 / np.sqrt(2), rel=0.05)
    # the interior's edge cuts the outer passes' strips part way through a period, so their means
    # differ a little (measured 0.924 within cells)
    assert s["within_cells_variance_fraction"] > 0.88
    assert s["across_profile_cov"] == pytest.approx(s["interior_cov"], rel=0.1)
    assert s["band_variance_fraction"] == 0.0


def test_passes_removing_alternately_more_and_less_are_between_passes(plate):
    # each pass's strip (|y - j d| < d / 2) at 1 ± 0.1: CoV 0.1, between passes
    s = _split(plate, lambda x, y: 1e-6 * (1 + 0.1 * (-1.0) ** np.round(y / SPACING)))
    assert s["interior_cov"] == pytest.approx(0.1, rel=0.05)
    assert s["between_passes_variance_fraction"] > 0.9
    assert s["along_passes_variance_fraction"] < 0.02


def test_a_slow_change_along_the_passes_is_along_passes(plate):
    # a ramp along the passes (no change across): the cell means carry it, all but (d / L)² of it
    s = _split(plate, lambda x, y: 1e-6 * (1 + 0.2 * np.sin(2 * np.pi * x / 0.4)))
    assert s["along_passes_variance_fraction"] > 0.9
    assert s["between_passes_variance_fraction"] < 0.05


def test_the_parts_add_up_and_the_band_is_what_lies_near_the_edge(plate):
    tool, trajectory, samples, along, across, y0 = plate
    rng = np.random.default_rng(7)
    depth = 1e-6 * (1 + 0.05 * rng.standard_normal(len(samples.vertices)))
    inner = samples.farther_from_boundary(tool.pad_radius)
    band = inner & ~samples.farther_from_boundary(tool.pad_radius + SPACING)
    depth[band] *= 0.8                                    # the band under-removed by a fifth
    s = evenness_split(RemovalMap(samples, depth), trajectory, tool, spacing=SPACING)
    parts = [s[f"{k}_variance_fraction"] for k in ("band", "between_passes", "along_passes", "within_cells")]
    assert sum(parts) == pytest.approx(1.0, abs=1e-9)
    assert s["band_mean_over_core_mean_ratio"] == pytest.approx(0.8, abs=0.01)
    f = s["band_area_fraction"]
    mu = 1 - 0.2 * f
    band_var, core_var = f * ((0.8 - mu) ** 2 + (0.05 * 0.8) ** 2), (1 - f) * ((1 - mu) ** 2 + 0.05**2)
    assert s["band_variance_fraction"] == pytest.approx(band_var / (band_var + core_var), rel=0.05)
    assert s["core_cov"] == pytest.approx(0.05, rel=0.1)


def test_the_metrics_name_their_units(plate):
    from swath.report.metrics import keys_without_unit
    from swath.simulate.evenness import evenness_metrics

    tool, trajectory, samples, *_ = plate
    m = evenness_metrics(RemovalMap(samples, np.full(len(samples.vertices), 1e-6)), trajectory, tool)
    assert m and keys_without_unit(m) == []
    assert m["evenness_interior_cov"] == pytest.approx(0.0, abs=1e-9)


def test_a_part_whose_interior_is_all_band_is_split_by_its_passes_as_a_whole(plate):
    # a band wider than the plate's half-width: no sample is farther than R + band from the edge,
    # as on a part of holes and narrow strips (the hub, noether_raw_mesh), whose line used to read
    # "nan % is the ripple across the passes"
    from swath.simulate.evenness import split_line

    tool, trajectory, samples, along, across, y0 = plate
    y = samples.vertices @ across - y0
    depth = 1e-6 * (1 + 0.1 * np.cos(2 * np.pi * y / SPACING))       # the ripple of the first test
    s = evenness_split(RemovalMap(samples, depth), trajectory, tool, spacing=SPACING, band_width=1.0)
    assert s["band_area_fraction"] == 1.0
    assert np.isnan(s["core_cov"]) and np.isnan(s["band_variance_fraction"])
    parts = [s[f"{k}_variance_fraction"] for k in ("between_passes", "along_passes", "within_cells")]
    assert sum(parts) == pytest.approx(1.0, abs=1e-9)         # the passes split the whole interior
    assert s["within_cells_variance_fraction"] > 0.88
    line = split_line({f"evenness_{k}": v for k, v in s.items()})
    assert "nan" not in line
    assert line.startswith(f"  interior CoV {s['interior_cov']:.3f}: every interior sample lies within one spacing (50 mm)")
    assert f"{100 * s['within_cells_variance_fraction']:.0f} % is the ripple across the passes" in line
    # the job's metrics.json holds the missing figures as null: the same line
    assert split_line({f"evenness_{k}": (None if isinstance(v, float) and np.isnan(v) else v) for k, v in s.items()}) == line
