"""The raster's feed held round a sharp ridge by the angular speed limit (swath.cli.ridge_turn)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from swath.cli import ridge_turn
from swath.core import Pass, ToolPath
from swath.plan.folds import rotation_per_metre


def _arc_pass(radius: float, angle: float, flat: float, step: float = 1e-4) -> Pass:
    """A pass in the xz-plane: ``flat`` m straight along x, then round an arc of ``radius`` m through
    ``angle`` rad (a ridge), the normals pointing out of the arc's centre (on the flat, +z)."""
    x_flat = np.arange(0.0, flat, step)
    flat_pts = np.stack([x_flat, np.zeros_like(x_flat), np.full_like(x_flat, radius)], axis=1)
    phi = np.linspace(0.0, angle, int(math.ceil(radius * angle / step)) + 1)
    arc_n = np.stack([np.sin(phi), np.zeros_like(phi), np.cos(phi)], axis=1)
    arc_pts = np.array([flat, 0.0, 0.0]) + radius * arc_n
    points = np.vstack([flat_pts, arc_pts])
    normals = np.vstack([np.tile([0.0, 0.0, 1.0], (len(x_flat), 1)), arc_n])
    return Pass(points, normals)


def test_the_normal_turns_at_one_over_the_radius_round_an_arc():
    p = _arc_pass(6.35e-3, math.pi, 0.0)
    rate, length = rotation_per_metre(p.points, p.normals)
    assert length.sum() == pytest.approx(6.35e-3 * math.pi, rel=1e-3)     # chords of a fine arc
    np.testing.assert_allclose(rate, 1.0 / 6.35e-3, rtol=1e-3)


def test_the_held_share_is_the_arcs_share_of_the_pass_where_the_limit_holds_the_feed():
    r, flat = 6.35e-3, 0.1
    toolpath = ToolPath(None, (_arc_pass(r, math.pi, flat),), "test")
    held = ridge_turn.held_share(toolpath, 0.05, 1.0)       # 1 rad/s round 6.35 mm: 6.35 mm/s < 25 mm/s
    arc = r * math.pi
    assert held["held_share"] == pytest.approx(arc / (arc + flat), rel=0.02)
    assert held["held_feed_m_per_s"] == pytest.approx(1.0 * r, rel=1e-3)
    assert held["held_radius_m"] == pytest.approx(r, rel=1e-3)
    assert held["tightest_radius_m"] == pytest.approx(r, rel=1e-3)
    # the extra contact time the limit costs, over the time at the feed: (feed / (ω r) - 1) on the arc
    assert held["extra_dwell"] == pytest.approx(arc * (0.05 / r - 1.0) / (arc + flat), rel=0.02)


def test_a_limit_that_allows_half_the_feed_or_more_holds_nothing():
    toolpath = ToolPath(None, (_arc_pass(6.35e-3, math.pi, 0.1),), "test")
    assert ridge_turn.held_share(toolpath, 0.05, None)["held_share"] == 0.0
    # 4 rad/s round 6.35 mm allows 25.4 mm/s, just over half of 50 mm/s
    assert ridge_turn.held_share(toolpath, 0.05, 4.0)["held_share"] == 0.0
    assert ridge_turn.held_share(toolpath, 0.05, 3.9)["held_share"] > 0.0


def test_a_raster_whose_feed_is_not_held_is_kept_as_it_is():
    toolpath = ToolPath(None, (_arc_pass(0.5, 0.2, 0.1),), "test")
    held = ridge_turn.held_share(toolpath, 0.05, 1.0)
    assert held["held_share"] == 0.0
    kept = ridge_turn.uniform_if_evener(toolpath, None, None, None, held)
    assert kept is toolpath and "ridge_held_fraction" not in kept.metadata


def test_the_blades_raster_is_held_round_its_nose_and_the_plates_is_not():
    from swath.cli.settings import settings_from_mapping
    from swath.cli.stages import job_tool
    from swath.examples import example_part
    from swath.plan import get_planner

    settings = settings_from_mapping({"part": "example:blade", "out": "unused"})
    tool = job_tool(settings)
    raster = get_planner("raster")
    blade = raster(example_part("blade"), tool, spacing=0.05)
    plate = raster(example_part("plate"), tool, spacing=0.05)
    held = ridge_turn.held_share(blade, settings.feed, settings.max_angular)
    # the passes run along the chord, round the 6.35 mm nose: 1 rad/s allows under 25 mm/s on
    # the arc where the radius is under 25 mm, a few per cent of every pass
    assert 0.02 < held["held_share"] < 0.08
    assert held["held_radius_m"] < 0.025
    assert ridge_turn.held_share(plate, settings.feed, settings.max_angular)["held_share"] == 0.0


@pytest.mark.slow
def test_on_a_small_blade_the_default_plans_with_the_uniform_planner_which_removes_more_evenly():
    from swath.cli import even_default
    from swath.cli.curved_spacing import curved_spacing_plan
    from swath.cli.job import planner_arguments
    from swath.cli.settings import settings_from_mapping
    from swath.cli.stages import job_tool
    from swath.examples.parts import blade
    from swath.plan import get_planner

    settings = even_default.resolve(settings_from_mapping({"part": "example:blade", "out": "unused"}))
    tool = job_tool(settings)
    surface = blade(chord=0.15, span=0.2, max_spacing=8e-3)
    heard: list[str] = []
    planned = curved_spacing_plan(surface, tool, get_planner("raster"), settings, planner_arguments(settings),
                                  choose_lead=True, ridge=True, progress=lambda stage, done, total: heard.append(stage))
    meta = planned.metadata
    # the user hears the turn and the uniform planner's own steps, not seconds of silence
    assert heard[0].startswith("the raster's feed is held round a ridge")
    assert any(stage.startswith("planning (uniform): trying pass directions") for stage in heard)
    assert heard[-1] == "comparing the raster's and the uniform planner's passes by their removal"
    # the raster's passes run round the nose (radius 1.1019 t² c = 2.4 mm at the apex)
    assert meta["ridge_held_fraction"] >= ridge_turn.HOLD_SHARE
    assert meta["ridge_planner"] == "uniform"
    assert planned.planner == "uniform"
    # kept because it is evener at constant feed (simulated: about 1.03 against 1.09) and its passes
    # are held over less than half the raster's share
    assert meta["ridge_uniform_cov_fraction"] < meta["ridge_raster_cov_fraction"]
    turned = ridge_turn.held_share(planned, settings.feed, settings.max_angular)["held_share"]
    assert turned < ridge_turn.RELIEF * meta["ridge_held_fraction"]


def test_the_note_says_where_the_feed_is_held_which_plan_is_written_and_what_limit_would_free_it():
    from swath.cli.settings import settings_from_mapping
    from swath.report.warncodes import code_for

    settings = settings_from_mapping({"part": "example:blade", "out": "unused"})
    assert ridge_turn.ridge_warnings({}, settings) == []
    meta = {"ridge_held_fraction": 0.039, "ridge_held_feed_m_per_s": 0.0118, "ridge_radius_m": 0.0118,
            "ridge_tightest_radius_m": 0.00597,
            "ridge_raster_cov_fraction": 0.733, "ridge_uniform_cov_fraction": 0.512, "ridge_planner": "uniform"}
    (text,) = ridge_turn.ridge_warnings(meta, settings)
    assert "1 rad/s" in text and "12 mm/s over 3.9 %" in text and "12 mm radius" in text
    assert "0.512 against 0.733" in text and "uniform planner's passes" in text
    assert "8.4 rad/s" in text                            # 50 mm/s round the tightest 5.97 mm
    assert code_for(text) == "W-EVEN-RIDGE"
    del meta["ridge_planner"]
    assert "so the raster's stay" in ridge_turn.ridge_warnings(meta, settings)[0]


def test_only_stretches_that_turn_round_a_ridge_count_not_a_scans_jitter():
    from swath.plan.folds import RIDGE_NET_TURN, ridge_runs

    # a pass over a 6 mm half cylinder: its normals turn by pi along one held run
    phi = np.linspace(0.0, np.pi, 31)
    nose = np.column_stack([np.cos(phi), np.zeros_like(phi), np.sin(phi)])
    held = np.ones(30, bool)
    assert ridge_runs(nose, held).all()
    # a flat scan whose normals jitter by +-0.1 rad from point to point: held everywhere by the rate,
    # but the normal never turns more than 0.2 rad from a run's start to its end
    tilt = 0.1 * (-1.0) ** np.arange(31)
    jitter = np.column_stack([np.sin(tilt), np.zeros_like(tilt), np.cos(tilt)])
    assert 0.2 < RIDGE_NET_TURN
    assert not ridge_runs(jitter, held).any()
    # two runs on one pass: the ridge's kept, the jitter's dropped, unheld segments stay unheld
    both = np.vstack([jitter[:10], nose])
    mask = np.r_[np.ones(9, bool), False, np.ones(30, bool)]
    kept = ridge_runs(both, mask)
    assert not kept[:10].any() and kept[10:].all()
