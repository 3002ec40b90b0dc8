"""The default job's raster passes against geodesic-parallel ones where the raster's spacing spreads."""

import math

import numpy as np
import pytest

from shapes import cylinder_patch
from swath.cli.even_spacing import SPREAD_RATIO, evener_passes, spread_ratio
from swath.cli.jobsettings import JobSettings
from swath.contact import Tool
from swath.core import Pass, ToolPath

TOOL = Tool()
RHO = 0.3
LEAD = math.radians(11.0)


def _axial_passes(angles, *, planner="raster", spacing=0.05, lead=LEAD):
    """Passes along the axis of a 0.3 m cylinder at the given angles round it (rad)."""
    cyl = cylinder_patch(RHO, 0.6, 0.4, n_theta=240, n_len=81)
    y = np.linspace(-0.15, 0.15, 151)
    passes = [Pass(np.stack([RHO * np.sin(a) + 0 * y, y, RHO * np.cos(a) + 0 * y], axis=1),
                   np.tile([np.sin(a), 0.0, np.cos(a)], (len(y), 1))) for a in angles]
    meta = {"spacing_m": spacing, "ripple_lead_rad": lead, "ripple_model": "curved"}
    return cyl, ToolPath(cyl, tuple(passes), planner=planner, metadata=meta)


def test_equal_passes_do_not_spread_and_uneven_ones_do():
    d = 0.05
    _, even = _axial_passes(np.arange(-3, 4) * d / RHO, spacing=d)
    ratio, ripple = spread_ratio(even, even.surface, TOOL)
    assert ratio == pytest.approx(1.0, abs=0.01)           # chords 0.1 % short of the arcs
    assert 0 < ripple < 0.2
    # passes 65 mm apart at one side narrowing to 40 mm at the other
    steps = np.array([0.0, 0.065, 0.125, 0.18, 0.23, 0.275, 0.315])
    _, spread = _axial_passes((steps - steps.mean()) / RHO, spacing=d)
    ratio_spread, ripple_spread = spread_ratio(spread, spread.surface, TOOL)
    assert ripple_spread == pytest.approx(ripple, rel=1e-9)      # the same quadric and spacing asked
    assert ratio_spread > SPREAD_RATIO


def test_only_the_raster_at_the_curved_spacing_is_checked():
    steps = np.array([0.0, 0.04, 0.10, 0.14, 0.20, 0.24, 0.30])
    _, flat = _axial_passes((steps - 0.15) / RHO)
    flat.metadata["ripple_model"] = "plane"
    assert evener_passes(flat, flat.surface, TOOL, settings=None) == (flat, None)
    _, other = _axial_passes((steps - 0.15) / RHO, planner="uniform")
    assert evener_passes(other, other.surface, TOOL, settings=None) == (other, None)
    assert "spacing_spread_ratio" not in other.metadata and "spacing_spread_ratio" not in flat.metadata


def test_passes_under_the_ratio_stay_and_their_lead_is_the_evenest_simulated():
    _, even = _axial_passes(np.arange(-3, 4) * 0.05 / RHO)
    settings = JobSettings(part="example:plate", out="unused", sample_spacing=0.006)
    kept, run = evener_passes(even, even.surface, TOOL, settings)
    assert kept is even and even.metadata["spacing_spread_ratio"] < SPREAD_RATIO    # not re-planned
    tried = dict(map(tuple, even.metadata["lead_simulated_interior_removal_cov"]))
    assert sorted(tried) == [0.0, 7.0, 11.0, 15.0]                 # the flat pad among them here
    covered = dict(map(tuple, even.metadata["lead_simulated_coverage_fraction"]))
    lead = even.metadata["ripple_lead_rad"]
    # the evenest of the leads that cover as much as the job's 11°
    from swath.cli.even_spacing import covers_as_much

    eligible = [a for a in tried if covers_as_much(covered[a], covered[11.0])]
    assert 11.0 in eligible and tried[round(math.degrees(lead), 1)] == min(tried[a] for a in eligible)
    trajectory, removal = run                                      # the kept lead's run, for the job
    assert removal.metrics["interior_removal_cov"] == pytest.approx(tried[round(math.degrees(lead), 1)], rel=1e-12)
    # ... the job's own timing of the passes at that lead, so the job need not time them again
    from dataclasses import replace

    from swath.trajectory import time_path

    at_lead = replace(settings, lead_angle=lead)
    again = time_path(kept, at_lead.constraints(), links=at_lead.links(), lead_angle=at_lead.lead())
    assert trajectory.duration == pytest.approx(again.duration, rel=1e-12) and len(trajectory) == len(again)
    np.testing.assert_allclose(trajectory.quaternion, again.quaternion, atol=1e-12)
    np.testing.assert_allclose(trajectory.t, again.t, atol=1e-9)


def test_the_leads_simulated_are_the_half_pad_lead_and_the_steeper_ones():
    from swath.cli.even_spacing import lead_choices

    leads = lead_choices(TOOL)
    assert leads == sorted(leads) and 0.0 not in leads
    assert lead_choices(TOOL, flat=True) == [0.0, *leads]
    assert leads[0] == pytest.approx(TOOL.half_pad_lead) and TOOL.half_pad_lead == pytest.approx(math.radians(7.0), abs=0.01)
    assert leads[1:] == pytest.approx([math.radians(11.0), math.radians(15.0)])


def test_other_passes_or_leads_must_cover_as_much_as_the_raster():
    from swath.cli.even_spacing import covers_as_much

    assert covers_as_much(0.9956, 0.9971)            # crs_part_5's 15° lead: 0.15 point less, above 99 %
    assert not covers_as_much(0.9919, 0.9994)        # bezier_complex_shape's equidistant passes: 0.75 point less
    assert not covers_as_much(0.9890, 0.9920)        # below the 99 % warning where the raster was above it
    assert covers_as_much(0.9650, 0.9640)            # a part the raster covers less: no less than it is fine
    assert not covers_as_much(0.9630, 0.9640)


def test_the_comparison_goes_into_the_metrics_with_every_figure_naming_its_unit():
    # what evener_passes leaves in the plan's metadata where the equidistant passes were tried
    # (crs_part_5's default job), beside the planner's own entries
    from swath.cli.jobwrap import plan_figures
    from swath.report.metrics import keys_without_unit

    meta = {"spacing_m": 0.0504, "n_passes": 34, "angle_rad": 0.0, "ripple_model": "curved",
            "spacing_spread_ratio": 1.2546, "raster_interior_removal_cov": 0.193,
            "equidistant_interior_removal_cov": 0.150, "equidistant_kept": True, "pulled_in": [],
            "fill_gaps": False, "plan_s": 0.1}
    figures = plan_figures(meta, taken={"plan_s": 0.2})
    assert figures == {"spacing_m": 0.0504, "angle_rad": 0.0, "spacing_spread_ratio": 1.2546,
                       "raster_interior_removal_cov": 0.193, "equidistant_interior_removal_cov": 0.150,
                       "equidistant_kept": True}
    assert figures["equidistant_kept"] is True                      # a flag, not the number 1.0
    assert keys_without_unit(figures) == []                          # no W-METRIC-UNIT in the job's log
    assert plan_figures({**meta, "equidistant_kept": False}, taken={})["equidistant_kept"] is False


def test_trying_equidistant_passes_is_a_stage_of_four_steps_that_ends_at_all_four():
    # passes 65 mm apart at one side narrowing to 40 mm at the other: equidistant passes are tried
    steps = np.array([0.0, 0.065, 0.125, 0.18, 0.23, 0.275, 0.315])
    _, spread = _axial_passes((steps - steps.mean()) / RHO)
    settings = JobSettings(part="example:plate", out="unused", sample_spacing=0.006)
    calls = []
    evener_passes(spread, spread.surface, TOOL, settings, progress=lambda stage, done, total: calls.append(
        (stage, done, total)))
    trying = [(done, total) for stage, done, total in calls if stage.endswith("trying equidistant passes")]
    assert trying == [(0, 4), (2, 4), (3, 4), (4, 4)]       # the plan counts two steps, each simulation one
    assert "equidistant_kept" in spread.metadata
