"""The even-removal job's uniform direction: the evenest at constant feed among the near-cheapest."""

from __future__ import annotations

import math

import pytest

from swath.cli import uniform_direction as ud
from swath.core import ToolPath


def _plan(deg: float, **meta) -> ToolPath:
    return ToolPath(None, (), "uniform", dict(direction_rad=math.radians(deg), **meta))


def _rows(*costs):
    return [dict(direction_deg=30.0 * k, length_m=1.0, cost=c, predicted_coverage_fraction=1.0)
            for k, c in enumerate(costs)]


def test_contenders_are_the_ranked_directions_near_the_cheapest():
    rows = ud.contenders({"candidates": _rows(200.0, 194.0, None, 203.0, 204.0)})
    # within 5 % of 194 s (203.7 s): 60 deg, stopped early (no cost), and 120 deg over it are out
    assert [round(math.degrees(a)) for a, _ in rows] == [30, 0, 90]
    assert ud.COST_SHARE == pytest.approx(0.05)
    assert ud.contenders({"candidates": _rows(200.0), "pieces": [{}, {}]}) == []       # per piece
    assert ud.contenders({}) == []                                                   # a given direction


def test_the_evenest_direction_wins_and_near_ties_go_to_the_shorter_cycle(monkeypatch):
    # the blade's pattern: the cycle time prefers 60 deg, the removal 0 and 30 deg (almost a tie)
    covs = {0: (0.476, 195.2), 30: (0.4762, 195.6), 60: (0.660, 196.6), 90: (0.673, 196.5)}
    monkeypatch.setattr(ud, "constant_feed_cov",
                        lambda tp, surface, tool, settings: covs[round(math.degrees(tp.metadata["direction_rad"]))])
    first = _plan(60, candidates=_rows(199.9, 199.6, 194.2, 194.6))
    # the first plan's candidates as it laid them (uniform's candidate_paths), its own direction too
    paths = {math.radians(d): _plan(d) for d in (0, 30, 60, 90)}
    toolpath, angle = ud.evenest_direction(first, paths, None, None, None)
    assert round(math.degrees(angle)) == 0 and toolpath is paths[0.0]
    table = {round(r["direction_deg"]): r["interior_removal_cov"] for r in toolpath.metadata["direction_evenness"]}
    assert table == {d: c for d, (c, _) in covs.items()}
    assert toolpath.metadata["direction_rule"] == ud.DIRECTION_RULE
    assert len(toolpath.metadata["direction_candidates"]) == 4


def test_one_contender_is_no_choice():
    first = _plan(60, candidates=_rows(300.0, 300.0, 194.2))
    assert ud.evenest_direction(first, {}, None, None, None) == (first, None)
    # a contender whose passes the first plan did not hand over is not compared
    first = _plan(60, candidates=_rows(199.9, 199.6, 194.2))
    assert ud.evenest_direction(first, {}, None, None, None) == (first, None)
