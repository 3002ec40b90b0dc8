"""The default job's judgement of whether a feed along the passes can even the removal
(swath.cli.feed_reach): it fires where the variance lies across the passes (the ripple of passes
laid wide apart, each at the same feed) and not where a feed along them changes it (every other
pass run at half the feed, a pass slowed down over half its length)."""

import numpy as np
import pytest

from swath.cli.feed_reach import FEED_REACH_MIN, feed_cannot_help, feed_reach
from swath.contact import Tool
from swath.examples import flat_plate
from swath.plan import Pass, ToolPath
from swath.simulate import simulate_removal
from swath.simulate.evenness import evenness_split
from swath.trajectory import FeedLimit, FeedProfile, time_path

PLATE = flat_plate(spacing=0.01)                                     # 400 x 300 mm
# 6 passes 56 mm apart (1.47 pad radii: the pad's radius is 38.1 mm), the midlines between them on the
# interior's edges (a pad radius in from y = 0 and y = 0.3): each interior sample lies in the cell of a pass
# with a neighbour on either side, so passes at one feed leave the ripple across them and little else
STEP = (0.3 - 2 * 0.0381) / 4
YS = 0.0381 - STEP / 2 + np.arange(6) * STEP


def _passes():
    x = np.linspace(0.0, 0.4, 101)                                   # 4 mm points
    out = []
    for i, y in enumerate(YS):
        p = Pass(np.stack([x, np.full_like(x, y), np.zeros_like(x)], 1), np.tile([0.0, 0.0, 1.0], (len(x), 1)))
        out.append(p if i % 2 == 0 else p.reversed())
    return ToolPath(PLATE, out, "test")


def _run(feeds=None):
    tool = Tool()
    toolpath = _passes()
    constraints = [FeedLimit(0.05)] + ([] if feeds is None else [FeedProfile(tuple(feeds))])
    tr = time_path(toolpath, constraints)
    return simulate_removal(tr, PLATE, tool, sample_spacing=4e-3, sampling="lattice"), tr, tool


def test_passes_at_one_feed_leave_only_the_ripple_and_the_rule_fires():
    removal, tr, tool = _run()
    reach = feed_reach(removal, tr, tool)
    # the shares are evenness_split's over the whole interior (no band apart), which add up to 1
    split = evenness_split(removal, tr, tool, band_width=0.0)
    assert split["between_passes_variance_fraction"] + split["along_passes_variance_fraction"] \
        + split["within_cells_variance_fraction"] == pytest.approx(1.0, abs=1e-9)
    assert reach["feed_reachable_variance_fraction"] == pytest.approx(
        split["between_passes_variance_fraction"] + split["along_passes_variance_fraction"], abs=1e-12)
    assert reach["feed_reach_interior_cov"] == pytest.approx(removal.metrics["interior_removal_cov"], rel=1e-9)
    # measured: 2.2 % between and along, the ripple of passes 1.47 R apart the rest (CoV 0.18)
    assert reach["feed_reachable_variance_fraction"] < 0.05
    assert reach["feed_reach_interior_cov"] > 0.1
    assert feed_cannot_help(reach)


def test_every_other_pass_at_half_the_feed_is_within_reach_and_the_rule_holds_off():
    toolpath = _passes()
    feeds = [np.full(len(p.points), 0.05 if i % 2 == 0 else 0.025) for i, p in enumerate(toolpath.passes)]
    removal, tr, tool = _run(feeds)
    reach = feed_reach(removal, tr, tool)
    # a pass at half the feed removes twice as deep (measured: 51 % of the variance between the passes)
    assert reach["feed_reachable_variance_fraction"] > 0.3
    assert not feed_cannot_help(reach)


def test_a_pass_slowed_over_half_its_length_is_within_reach():
    toolpath = _passes()
    feeds = []
    for p in toolpath.passes:
        v = np.full(len(p.points), 0.05)
        v[p.points[:, 0] > 0.2] = 0.025                              # the right half of the plate, every pass
        feeds.append(v)
    removal, tr, tool = _run(feeds)
    split = evenness_split(removal, tr, tool, band_width=0.0)
    reach = feed_reach(removal, tr, tool)
    assert split["along_passes_variance_fraction"] > 0.3 > split["between_passes_variance_fraction"]   # 0.69, 0.003
    assert not feed_cannot_help(reach)


def test_nothing_to_judge_is_never_skipped():
    assert not feed_cannot_help({})
    assert feed_cannot_help({"feed_reachable_variance_fraction": 0.5 * FEED_REACH_MIN})
    assert not feed_cannot_help({"feed_reachable_variance_fraction": FEED_REACH_MIN})


def test_the_printed_line_says_the_feed_was_not_optimised_and_why():
    from swath.cli.even_default import summary_line

    m = {"even_removal_default": True, "constant_feed_kept": True, "feed_optimisation_skipped": True,
         "feed_reachable_variance_fraction": 0.108, "feed_reach_interior_cov": 0.127, "target_depth_m": 3.2e-6,
         "cycle_time_ratio": 1.0, "cycle_time_allowed_ratio": 1.5, "interior_removal_mean_m": 2.09e-6,
         "length_ratio": 1.51, "lead_angle_deg": 15.0}
    text = summary_line(m)
    assert "the constant feed is written, the feed not optimised: 11 % of the interior variance" in text
    assert "W-EVEN-FEED-WORSE" not in text and "% of the target" not in text


def test_the_feed_stage_skips_the_programme_and_says_so(tmp_path):
    from swath.cli import even_default, stages
    from swath.cli.settings import settings_from_mapping

    settings = even_default.resolve(settings_from_mapping({"part": "example:plate", "out": str(tmp_path / "o"),
                                                          "sample_spacing": "4mm"}))
    removal, tr, tool = _run()
    even: dict = {}
    out_settings, trajectory, feed, metrics = stages.even_feed_stage(_passes(), tool, settings, tr, PLATE, even,
                                                                     constant=removal)
    assert trajectory is tr and feed is None and metrics == {}
    assert even["feed_optimisation_skipped"] and even["constant_feed_kept"]
    assert even["_simulated"] == (tr, removal)                       # the job reuses this simulation
    assert out_settings.target_depth > 0                             # the target the default chose, stated
    assert len(even["warnings"]) == 1 and even["warnings"][0].endswith("[W-EVEN-FEED-SKIPPED]")
    assert "2 % of the interior removal variance" in even["warnings"][0]


@pytest.mark.parametrize("plain_cov", [0.01, 0.9])                  # the plain plan removes more / less evenly
def test_a_plain_plan_not_ready_yet_is_judged_after_the_feed_with_the_same_outcome(tmp_path, plain_cov):
    from types import SimpleNamespace

    from swath.cli import even_default, stages
    from swath.cli.settings import settings_from_mapping

    settings = even_default.resolve(settings_from_mapping({"part": "example:plate", "out": str(tmp_path / "o"),
                                                          "sample_spacing": "4mm"}))
    removal, tr, tool = _run()
    run = (None, SimpleNamespace(duration=99.0), SimpleNamespace(metrics={"interior_removal_cov": plain_cov}))
    outcomes = []
    for ready in (True, False):
        asked = []

        def plain():
            asked.append(True)
            return run

        plain.ready = lambda: ready
        even: dict = {}
        out = stages.even_feed_stage(_passes(), tool, settings, tr, PLATE, even, constant=removal, plain=plain)
        assert asked == [True]
        outcomes.append((out[0], out[1] is tr, out[2], out[3], even))
    assert outcomes[0] == outcomes[1]
    even = outcomes[0][-1]
    assert even["_plain"] is run and even["plain_interior_removal_cov"] == plain_cov
    if plain_cov < 0.5:                                              # kept: the feed is chosen on its passes
        assert even["plain_plan_kept"] and "feed_optimisation_skipped" not in even
        assert [w[-19:] for w in even["warnings"]] == ["[W-EVEN-PLAIN-KEPT]"]
    else:
        assert "plain_plan_kept" not in even and even["feed_optimisation_skipped"]
