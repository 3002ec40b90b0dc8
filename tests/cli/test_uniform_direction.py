"""The even-removal job's uniform direction: the evenest at constant feed among the near-cheapest."""

from __future__ import annotations

import math

import numpy as np
import pytest

from swath.cli import uniform_direction as ud
from swath.core import Pass, ToolPath


def _plan(deg: float, passes_of: float | None = None, **meta) -> ToolPath:
    """A plan with one straight pass at ``passes_of`` degrees (default ``deg``): plans of equal
    ``passes_of`` have the same passes."""
    a = math.radians(deg if passes_of is None else passes_of)
    points = np.outer(np.linspace(0.0, 0.1, 5), [math.cos(a), math.sin(a), 0.0])
    normals = np.tile([0.0, 0.0, 1.0], (5, 1))
    return ToolPath(None, (Pass(points, normals),), "uniform", dict(direction_rad=math.radians(deg), **meta))


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


def test_the_planners_choice_stands_when_it_is_the_evenest(monkeypatch):
    # crs_part_5's pattern: the cheapest is also the evenest; 120 and 150 degrees share their passes
    covs = {0: (0.194, 1464.6), 30: (0.224, 1542.8), 120: (0.231, 1473.8)}
    simulated = []

    def cov(tp, surface, tool, settings):
        deg = round(math.degrees(tp.metadata["direction_rad"]))
        simulated.append(deg)
        return covs[deg]

    monkeypatch.setattr(ud, "constant_feed_cov", cov)
    rows = _rows(1342.0, 1402.0) + [dict(direction_deg=d, length_m=1.0, cost=1409.0, predicted_coverage_fraction=1.0)
                                    for d in (120.0, 150.0)]
    first = _plan(0, candidates=rows)
    paths = {math.radians(30): _plan(30), math.radians(120): _plan(120), math.radians(150): _plan(150, passes_of=120)}
    assert ud.evenest_direction(first, paths, None, None, None) == (first, None)
    assert "direction_evenness" not in first.metadata and simulated[0] == 0
    # 150 degrees lays 120's passes: one simulation stands for both
    assert ud._passes_key(paths[math.radians(150)]) == ud._passes_key(paths[math.radians(120)])
    assert ud._passes_key(paths[math.radians(30)]) != ud._passes_key(paths[math.radians(120)])


def test_one_contender_is_no_choice():
    first = _plan(60, candidates=_rows(300.0, 300.0, 194.2))
    assert ud.evenest_direction(first, {}, None, None, None) == (first, None)
    # a contender whose passes the first plan did not hand over is not compared
    first = _plan(60, candidates=_rows(199.9, 199.6, 194.2))
    assert ud.evenest_direction(first, {}, None, None, None) == (first, None)


def test_straight_links_lift_cross_and_land():
    a, b = _plan(0), _plan(90)
    tp = ToolPath(None, a.passes + b.passes, "uniform", {})
    (link,) = ud.straight_links(tp, 0.02)
    np.testing.assert_allclose(link.waypoints, [a.passes[0].points[-1], a.passes[0].points[-1] + [0, 0, 0.02],
                                                b.passes[0].points[0] + [0, 0, 0.02], b.passes[0].points[0]])
