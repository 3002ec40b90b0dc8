"""The default job's least-ripple spacing read from the part's curvature, within the length budget."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from shapes import bowl, two_radius_part
from swath.cli import curved_spacing
from swath.cli.main import main
from swath.cli.settings import settings_from_mapping
from swath.contact import Tool
from swath.contact.widths import coverage_lower_bound
from swath.feed import ripple_spacing
from swath.plan import get_planner

TOOL = Tool()


def _settings(**given):
    from swath.cli import even_default

    return even_default.resolve(settings_from_mapping({"part": "example:plate", "out": "unused", **given}))


def test_in_a_bowl_the_raster_spacing_is_the_quadrics_within_the_budget():
    """A 0.35 m bowl: the passes read its curvature (about -2.9 /m both ways) and the raster is
    re-planned at the quadric's least-ripple spacing for the half-pad lead, wider than the plane's
    (1.40 R) because the pad rides on its rim there; the contact length stays within 1.5 L*."""
    from swath.feed.curved_ripple import curved_ripple_spacing

    part = bowl(size=0.3, radius=0.35, n=61)
    settings = _settings()
    raster = get_planner("raster")
    tp = curved_spacing.curved_spacing_plan(part, TOOL, raster, settings, {})
    assert tp.metadata["ripple_model"] == "curved"
    plane, _ = ripple_spacing(TOOL, lead_angle=TOOL.half_pad_lead, max_length_ratio=1.5)
    quadric = curved_ripple_spacing(TOOL, -1 / 0.35, -1 / 0.35, lead_angle=TOOL.half_pad_lead)
    assert quadric.spacing > 1.1 * plane
    # the spacing asked is the quadric's at the curvature the passes read (within the curvature
    # estimate's spread over the bowl), or wider where the budget held it
    assert tp.metadata["ripple_spacing_m"] == pytest.approx(quadric.spacing, rel=0.08)
    ratio = tp.contact_length / coverage_lower_bound(part, TOOL)
    assert ratio == pytest.approx(tp.metadata["ripple_length_ratio"], rel=1e-9) and ratio <= 1.5 * 1.02


def test_on_a_plane_the_spacing_is_the_planes_held_within_the_budget():
    """On the plate the plane's spacing stays: its eight passes come to 1.52 L*, within the budget's
    2 % tolerance (seven passes would be 1.33 L*)."""
    from swath.examples import example_part

    plate = example_part("plate")
    settings = _settings()
    plane, _ = ripple_spacing(TOOL, lead_angle=TOOL.half_pad_lead, max_length_ratio=1.5)
    tp = curved_spacing.curved_spacing_plan(plate, TOOL, get_planner("raster"), settings, {})
    assert tp.metadata["ripple_model"] == "plane"
    assert tp.metadata["ripple_spacing_m"] == pytest.approx(plane, rel=1e-12)
    assert tp.metadata["ripple_length_ratio"] == pytest.approx(1.52, abs=0.01)
    assert tp.contact_length / coverage_lower_bound(plate, TOOL) == pytest.approx(tp.metadata["ripple_length_ratio"])


def test_the_default_job_may_choose_a_steeper_lead_in_the_bowl():
    """With ``choose_lead`` the bowl's quadric takes 11° (of 0°, 7.0°, 11° and 15°, judged within ±5 %
    of the spacing), as :func:`swath.feed.curved_ripple.curved_ripple_choice` finds for passes across it."""
    part = bowl(size=0.3, radius=0.35, n=61)
    tp = curved_spacing.curved_spacing_plan(part, TOOL, get_planner("raster"), _settings(), {}, choose_lead=True)
    assert math.degrees(tp.metadata["ripple_lead_rad"]) == pytest.approx(11.0)
    assert tp.metadata["ripple_length_ratio"] <= 1.5 * 1.02
    plain = curved_spacing.curved_spacing_plan(part, TOOL, get_planner("raster"), _settings(), {})
    assert tp.metadata["ripple_spacing_m"] < plain.metadata["ripple_spacing_m"]     # the steeper lead packs closer
    assert plain.metadata["ripple_lead_rad"] == pytest.approx(TOOL.half_pad_lead)


def test_on_a_dome_the_default_job_chooses_the_flat_pad():
    """A convex 0.4 m dome: led pads peak the narrowed cross-profile; the quadric ripples least with
    the pad flat (of 0°, 7.0°, 11° and 15°)."""
    dome = bowl(size=0.3, radius=-0.4, n=61)
    tp = curved_spacing.curved_spacing_plan(dome, TOOL, get_planner("raster"), _settings(), {}, choose_lead=True)
    assert tp.metadata["ripple_model"] == "curved" and tp.metadata["ripple_lead_rad"] == 0.0
    assert tp.metadata["ripple_length_ratio"] <= 1.5 * 1.02


def test_the_uniform_planner_gets_the_quadrics_overlap():
    part = bowl(size=0.3, radius=0.35, n=41)
    settings = _settings(planner="uniform")
    tp = curved_spacing.curved_spacing_plan(part, TOOL, get_planner("uniform"), settings, {})
    assert tp.metadata["ripple_model"] == "curved" and tp.metadata["ripple_length_ratio"] <= 1.5
    from swath.feed import ripple_overlap

    # wider passes than the plane's overlap in the bowl (the quadric's spacing is wider)
    assert tp.metadata["ripple_overlap_fraction"] < ripple_overlap(TOOL, lead_angle=TOOL.half_pad_lead, max_length_ratio=1.5)
    from swath.report.metrics import keys_without_unit

    # the plan's record goes into metrics.json's settings: every figure in it names its unit (W-METRIC-UNIT)
    assert keys_without_unit({"plan": dict(tp.metadata)}) == []


def _run_default(tmp_path, name):
    out = tmp_path / name
    job = tmp_path / f"{name}.toml"         # a job file: nothing but the part, the output and coarser samples
    job.write_text(f'part = "bowl.stl"\nout = "{name}"\nsample_spacing = "4mm"\npoint_spacing = "4mm"\n')
    assert main(["--quiet", "run", str(job)]) == 0
    return out, json.loads((out / "metrics.json").read_text())["metrics"]


def test_the_default_job_in_a_bowl_states_what_the_simulation_confirms_and_beats_the_plane_rule(tmp_path,
                                                                                                   monkeypatch):
    """Measured: the plane's rule 0.137 at 1.48 L* (six passes, 7°, the feed optimised); the
    quadric's lead and spacing 0.063 at 1.48 L* (11°; at the half-pad lead its spacing gave 0.089)."""
    import trimesh

    from swath.io.mesh import load_mesh
    from swath.simulate import simulate_removal
    from swath.trajectory import read_csv

    part = bowl(size=0.3, radius=0.35, n=61)
    trimesh.Trimesh(part.vertices, part.faces, process=False).export(tmp_path / "bowl.stl")
    out, m = _run_default(tmp_path, "curved")
    # the job's figures are the simulation of the trajectory it wrote
    surface = load_mesh(tmp_path / "bowl.stl", units="m")
    removal = simulate_removal(read_csv(out / "trajectory.csv"), surface, TOOL, sample_spacing=4e-3)
    assert removal.metrics["interior_removal_cov"] == pytest.approx(m["interior_removal_cov"], abs=0.005)
    assert m["contact_length_m"] / m["coverage_lower_bound_m"] <= 1.5 * 1.02
    assert m["lead_angle_deg"] == pytest.approx(11.0)       # the quadric's choice among 0, 7.0, 11 and 15°
    # the raster's planes do not spread in a bowl: the passes stay, their lead checked by simulation
    assert m["spacing_spread_ratio"] < 1.1 and "equidistant_kept" not in m
    # the led pad is laid flat at each pass end: the patch ahead of the ends is touched too
    assert m["coverage_fraction"] > 0.999 and m["lead_end_ramp_m"] == pytest.approx(
        math.radians(11.0) * 0.05 / 0.95, rel=1e-6)
    # the plane's rule, as the default job had it: the spacing of a plane, the budget unchecked
    monkeypatch.setattr(curved_spacing, "FLAT_SAGITTA", math.inf)
    monkeypatch.setattr(curved_spacing, "BUDGET_ROUNDS", 0)
    _, old = _run_default(tmp_path, "plane")
    assert old["lead_angle_deg"] == pytest.approx(math.degrees(TOOL.half_pad_lead))
    assert m["interior_removal_cov"] < 0.7 * old["interior_removal_cov"]
    assert np.isfinite(old["interior_removal_cov"])


def test_a_raster_over_the_budget_widens_only_as_far_as_its_planes_need():
    """The panel's 403 mm across the passes: 49.5 mm gives nine planes; 15.8 % wider (57.3 mm)
    eight, and the least spacing with eight planes is 403/8 = 50.4 mm; a widening that drops no
    plane goes to the least spacing that drops one (403/8 mm again)."""
    s = 0.403
    assert math.ceil(s / 0.0495) == 9
    wide = curved_spacing.fewest_planes_spacing(0.0495, 0.0495 * 1.158, [s])
    assert wide == pytest.approx(s / 8, rel=1e-5) and math.ceil(s / wide) == 8
    wider = curved_spacing.fewest_planes_spacing(0.0495, 0.0495 * 1.3, [s])       # 64.4 mm: seven planes
    assert wider == pytest.approx(s / 7, rel=1e-5) and math.ceil(s / wider) == 7
    drop_one = curved_spacing.fewest_planes_spacing(0.0495, 0.0496, [s])
    assert drop_one == pytest.approx(s / 8, rel=1e-5) and math.ceil(s / drop_one) == 8
    # two pieces: each keeps the count the widened spacing gives it; the spacing is the least that does
    two = curved_spacing.fewest_planes_spacing(0.05, 0.06, [0.403, 0.12])
    assert two == pytest.approx(max(0.403 / 7, 0.12 / 2), rel=1e-5)
    assert curved_spacing.fewest_planes_spacing(0.05, 0.06, None) == 0.06


def test_the_default_jobs_panel_passes_lie_along_it_within_a_point_of_the_planes_floor():
    """The built-in doubly curved panel (radii 0.35 m along x, 0.9 m along y): the default job's
    least-ripple passes, as ``make_plan`` plans them, run along x at 50.4 mm on the surface with
    the 11° lead, 1.51 L*; simulated at constant feed, interior CoV 0.050 (measured; the plane's
    floor is 4.6 % at 1.5 L*).  Before, the re-plan at the widened spacing turned the passes
    across the 0.35 m radius: 0.238 at 1.37 L*.  The default job's optimised feed is kept only
    where it is evener still (0.049 measured with ``swath plan example:panel``)."""
    from swath.cli.job import make_plan
    from swath.examples import example_part
    from swath.simulate import simulate_removal
    from swath.trajectory import time_path

    settings = _settings(part="example:panel")
    panel = example_part("panel")
    tp = make_plan(panel, settings, tool=TOOL, choose_lead=True)
    m = tp.metadata
    assert m["ripple_model"] == "curved" and m["spacing_on"] == "surface" and m["angle_rad"] == 0.0
    assert m["n_planes"] == 8 and m["spacing_m"] == pytest.approx(m["plane_extent_m"][0] / 8, rel=1e-5)
    # the pad touches with its whole face all over the panel: no level's swath is narrow
    assert curved_spacing.narrow_share(panel, TOOL, m["cross_direction"], m["spacing_m"]) == 0.0
    assert m["ripple_length_ratio"] <= 1.5 * 1.02
    trajectory = time_path(tp, settings.constraints(), links=settings.links(), lead_angle=m["ripple_lead_rad"])
    removal = simulate_removal(trajectory, panel, TOOL)
    assert removal.metrics["interior_removal_cov"] < 0.065


def test_the_least_ripple_planes_follow_the_swath_where_it_narrows():
    """Two tangent arcs of 0.15 m and 0.6 m radius, passes along their axis: the swath is 48 mm on
    the first arc (a third of the extent) and the whole 76 mm pad on the second, so the default
    job's re-plans follow it; on the example hub only a band at the rim is narrow, and on the panel
    nothing is (its test above)."""
    from swath.cli.job import make_plan
    from swath.examples import example_part

    surface, _, _ = two_radius_part(step=3e-3, length=0.4)
    settings = _settings(direction=0.0)
    tp = make_plan(surface, settings, tool=TOOL, choose_lead=True)
    m = tp.metadata
    share = curved_spacing.narrow_share(surface, TOOL, m["cross_direction"], m["ripple_spacing_m"])
    assert abs(m["cross_direction"][1]) < 1e-6 and share == pytest.approx(1 / 3, abs=0.08)
    assert m["spacing_on"] == "swath" and m["swath_reference_width_m"] == pytest.approx(2 * TOOL.pad_radius, rel=1e-3)
    assert m["ripple_length_ratio"] <= 1.5 * 1.02
    # the job's planner options decide when they say
    given = make_plan(surface, _settings(direction=0.0, planner_options={"spacing_on": "surface"}), tool=TOOL,
                      choose_lead=True)
    assert given.metadata["spacing_on"] == "surface"
    hub = example_part("hub")
    hub_plan = make_plan(hub, _settings(part="example:hub"), tool=TOOL, choose_lead=True)
    hub_share = curved_spacing.narrow_share(hub, TOOL, hub_plan.metadata["cross_direction"],
                                            hub_plan.metadata["ripple_spacing_m"])
    assert 0 < hub_share < curved_spacing.NARROW_SHARE and hub_plan.metadata["spacing_on"] == "surface"


def test_each_plan_of_the_search_is_a_step_of_its_own_numbered():
    from swath.cli.curved_spacing import search_progress
    from swath.plan.uniform import TRYING_STAGE
    from swath.plan.uniform_model import SETUP_STAGE

    heard = []
    setup = SETUP_STAGE + " (75,668 vertices, about 1 s)"
    for plan in (1, 2, 3):
        told = search_progress(lambda *a: heard.append(a), plan, 4)
        if plan == 1:
            told(setup, 0, 1)                           # the working mesh: built once, by the first plan
        for done in (0, 6, 13):
            told(TRYING_STAGE, done, 13)
    assert heard[0] == (setup, 0, 1)
    stage = TRYING_STAGE + " (plan {}, at most 4)"
    assert heard[1:] == [(stage.format(p), done, 13) for p in (1, 2, 3) for done in (0, 6, 13)]


def test_a_plan_of_one_given_direction_is_said_with_the_time_the_plan_before_took():
    from swath.cli.curved_spacing import search_progress
    from swath.plan.uniform import LAYING_STAGE, uniform

    heard = []
    told = search_progress(lambda *a: heard.append(a), 2, 4, expected_s=6.8)
    told(LAYING_STAGE, 0, 1)
    told(LAYING_STAGE, 1, 1)
    stage = LAYING_STAGE + " (plan 2, at most 4), about 7 s as the plan before"
    assert heard == [(stage, 0, 1), (stage, 1, 1)]          # one stage line, its estimate in it
    heard.clear()
    search_progress(lambda *a: heard.append(a), 2, 4)(LAYING_STAGE, 0, 1)   # no time known: no estimate
    assert heard == [(LAYING_STAGE + " (plan 2, at most 4)", 0, 1)]
    # the planner says the step, before and after, for a given direction
    heard.clear()
    from swath.examples import flat_plate

    uniform(flat_plate(size_x=0.3, size_y=0.2), TOOL, direction=0.0, progress=lambda *a: heard.append(a), workers=1)
    laid = [h for h in heard if h[0] == LAYING_STAGE]
    assert laid == [(LAYING_STAGE, 0, 1), (LAYING_STAGE, 1, 1)]
