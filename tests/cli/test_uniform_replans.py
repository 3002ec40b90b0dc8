"""The default job's uniform re-plans: straight to the overlap the length budget asks for when the
first plan says the least-ripple overlap would be too long, and no re-plan at an overlap just planned."""

from __future__ import annotations

import math

import pytest

from shapes import bowl
from swath.cli import curved_spacing, even_default
from swath.cli.curved_spacing import BUDGET_MARGIN, BUDGET_TOLERANCE, curved_choice, uniform_replan_overlap
from swath.cli.settings import settings_from_mapping
from swath.contact import Tool
from swath.contact.widths import coverage_lower_bound
from swath.examples import flat_plate
from swath.feed import ripple_overlap
from swath.plan import get_planner

TOOL = Tool()


def _settings(budget: float):
    return even_default.resolve(settings_from_mapping({"part": "example:plate", "out": "unused", "planner": "uniform",
                                                       "length_budget": budget}))


class _Counting:
    """The uniform planner, recording the overlap of every call."""

    def __init__(self):
        self.overlaps: list[float] = []
        self.planner = get_planner("uniform")

    def __call__(self, surface, tool, **options):
        self.overlaps.append(options["overlap"])
        return self.planner(surface, tool, **options)


def test_the_predicted_length_scales_with_the_gap_between_passes():
    # 1.4 L* at overlap 0.3 -> 1.4 * 0.7 / (2/3) = 1.47 L* at 1/3: within 1.5 (+2 %), the overlap stays
    overlap, predicted = uniform_replan_overlap(1.4, 0.3, 1.0 / 3.0, 1.5)
    assert predicted == pytest.approx(1.47, rel=1e-12) and overlap == 1.0 / 3.0
    # 1.5 L* -> 1.575 L*, over 1.53: widened as a budget round would, from the predicted length
    overlap, predicted = uniform_replan_overlap(1.5, 0.3, 1.0 / 3.0, 1.5)
    assert predicted == pytest.approx(1.575, rel=1e-12)
    assert overlap == pytest.approx(1.0 - (2.0 / 3.0) * (1.575 / 1.5) * BUDGET_MARGIN, rel=1e-12)
    assert 0.28 < overlap < 0.29
    # right at the tolerance it stays; far over, the overlap is held at none
    at_edge = 1.5 * (1.0 + BUDGET_TOLERANCE) * (2.0 / 3.0) / 0.7
    assert uniform_replan_overlap(at_edge, 0.3, 1.0 / 3.0, 1.5)[0] == 1.0 / 3.0
    assert uniform_replan_overlap(3.0, 0.3, 1.0 / 3.0, 1.5)[0] == 0.0
    # no coverage bound (NaN ratio): no prediction, the least-ripple overlap
    assert uniform_replan_overlap(math.nan, 0.3, 1.0 / 3.0, 1.5)[0] == 1.0 / 3.0


def test_no_re_plan_at_the_overlap_just_planned():
    """On a 12 cm square a budget of 1.0 L* cannot be met: the first plan is at no overlap already
    (1.76 L*), and a budget round could only plan it again at no overlap: it is not made."""
    part = flat_plate(size_x=0.12, size_y=0.12)
    planner = _Counting()
    tp = curved_spacing.curved_spacing_plan(part, TOOL, planner, _settings(1.0), {})
    assert planner.overlaps == [0.0]
    ratio = tp.contact_length / coverage_lower_bound(part, TOOL)
    assert ratio > 1.0 * (1.0 + BUDGET_TOLERANCE)
    assert tp.metadata["ripple_length_ratio"] == ratio and tp.metadata["ripple_overlap_fraction"] == 0.0
    # and it is the plan at no overlap
    again = get_planner("uniform")(part, TOOL, overlap=0.0)
    assert [len(p.points) for p in again.passes] == [len(p.points) for p in tp.passes]
    assert again.contact_length == pytest.approx(tp.contact_length, rel=1e-12)


def test_a_least_ripple_overlap_equal_to_the_first_plans_is_not_planned_again():
    """In a 0.3 m bowl with a 1.2 L* budget the least-ripple overlap is the first plan's own (1/6):
    it is not planned again; then the budget rounds widen it, each to a new overlap (the first to
    the overlap the prediction gives, the first plan's length being the one predicted)."""
    part = bowl(size=0.3, radius=0.35, n=41)
    settings = _settings(1.2)
    planner = _Counting()
    tp = curved_spacing.curved_spacing_plan(part, TOOL, planner, settings, {})
    bound = coverage_lower_bound(part, TOOL)
    first = get_planner("uniform")(part, TOOL, overlap=planner.overlaps[0])
    lead, choice = curved_choice(first, part, TOOL, [settings.lead()], 1.2)
    assert choice.overlap == planner.overlaps[0]
    expected, predicted = uniform_replan_overlap(first.contact_length / bound, planner.overlaps[0], choice.overlap, 1.2)
    assert predicted > 1.2 * (1.0 + BUDGET_TOLERANCE) and expected < choice.overlap
    assert planner.overlaps[1] == expected
    assert len(set(planner.overlaps)) == len(planner.overlaps)        # no overlap planned twice
    assert planner.overlaps == sorted(planner.overlaps, reverse=True)  # each round widens
    assert tp.metadata["ripple_length_ratio"] <= 1.2 * (1.0 + BUDGET_TOLERANCE)


def test_within_the_budget_the_re_plan_is_at_the_least_ripple_overlap():
    """The default 1.5 budget in the same bowl: the first plan predicts the least-ripple overlap
    within it, so the re-plan is made there, unwidened."""
    part = bowl(size=0.3, radius=0.35, n=41)
    settings = _settings(1.5)
    planner = _Counting()
    tp = curved_spacing.curved_spacing_plan(part, TOOL, planner, settings, {})
    assert planner.overlaps[0] == ripple_overlap(TOOL, lead_angle=settings.lead(), max_length_ratio=1.5)
    first = get_planner("uniform")(part, TOOL, overlap=planner.overlaps[0])
    _, choice = curved_choice(first, part, TOOL, [settings.lead()], 1.5)
    ratio = first.contact_length / coverage_lower_bound(part, TOOL)
    assert uniform_replan_overlap(ratio, planner.overlaps[0], choice.overlap, 1.5)[0] == choice.overlap
    assert planner.overlaps == [planner.overlaps[0], choice.overlap]
    assert tp.metadata["ripple_overlap_fraction"] == choice.overlap


def test_the_spread_of_the_candidate_lengths():
    def row(length, coverage):
        return {"length_m": length, "predicted_coverage_fraction": coverage, "direction_deg": 0.0, "cost": 1.0}

    meta = {"candidates": [row(4.0, 0.999), row(4.2, 0.9995), row(5.0, 0.990)]}
    # 5.0 m covers 0.990, below the floor 0.9975 of the best 0.9995: it could not be chosen
    assert curved_spacing.direction_length_spread(meta) == pytest.approx(0.05, rel=1e-12)
    meta["candidates"][2] = row(5.0, 0.998)
    assert curved_spacing.direction_length_spread(meta) == pytest.approx(0.25, rel=1e-12)
    # a multi-piece plan: the widest piece's spread; a given direction: none
    assert curved_spacing.direction_length_spread({"pieces": [meta, {"candidates": [row(1.0, 1.0)]}]}) == \
        pytest.approx(0.25, rel=1e-12)
    assert curved_spacing.direction_length_spread({"direction_rad": 0.3}) == 0.0


def test_directions_of_different_lengths_keep_the_least_ripple_re_plan(monkeypatch):
    """In the bowl with a 1.3 budget the first plan (overlap 0.231, 1.48 L*) predicts the
    least-ripple overlap 0.200 over the budget, but its directions came to lengths 14 % apart: the
    re-plan is made at 0.200 all the same.  Allowed that spread, it goes straight to the widened
    overlap, one plan fewer."""
    part = bowl(size=0.3, radius=0.35, n=41)
    settings = _settings(1.3)
    kept = _Counting()
    curved_spacing.curved_spacing_plan(part, TOOL, kept, settings, {})
    first = get_planner("uniform")(part, TOOL, overlap=kept.overlaps[0])
    _, choice = curved_choice(first, part, TOOL, [settings.lead()], 1.3)
    spread = curved_spacing.direction_length_spread(first.metadata)
    assert spread > curved_spacing.DIRECTION_LENGTH_SPREAD
    ratio = first.contact_length / coverage_lower_bound(part, TOOL)
    widened, predicted = uniform_replan_overlap(ratio, kept.overlaps[0], choice.overlap, 1.3)
    assert predicted > 1.3 * (1.0 + BUDGET_TOLERANCE) and widened < choice.overlap
    assert kept.overlaps[:2] == [kept.overlaps[0], choice.overlap]
    monkeypatch.setattr(curved_spacing, "DIRECTION_LENGTH_SPREAD", spread + 0.01)
    straight = _Counting()
    curved_spacing.curved_spacing_plan(part, TOOL, straight, settings, {})
    assert straight.overlaps[:2] == [kept.overlaps[0], widened]
    assert len(straight.overlaps) == len(kept.overlaps) - 1


def test_the_shift_of_a_re_plans_passes():
    # 12 generations, overlap 0.30 -> 0.31 with a 70 mm swath: the last pass moves 12 * 0.01 * 70 mm
    assert curved_spacing.replan_shift({"n_generations": 12}, 0.30, 0.31, 0.07) == pytest.approx(8.4e-3, rel=1e-9)
    pieces = {"pieces": [{"n_generations": 3}, {"n_generations": 20}], "n_generations": 3}
    assert curved_spacing.replan_shift(pieces, 0.31, 0.30, 0.07) == pytest.approx(14e-3, rel=1e-9)


def test_a_re_plan_moving_the_passes_within_an_edge_keeps_the_first_plan(monkeypatch):
    """The bowl's least-ripple overlap at the default budget moves the first plan's passes by many
    working-mesh edges: it is planned (above).  Were that shift allowed, the first plan would be
    kept, with its own overlap recorded."""
    part = bowl(size=0.3, radius=0.35, n=41)
    settings = _settings(1.5)
    probe = ripple_overlap(TOOL, lead_angle=settings.lead(), max_length_ratio=1.5)
    first = get_planner("uniform")(part, TOOL, overlap=probe)
    _, choice = curved_choice(first, part, TOOL, [settings.lead()], 1.5)
    edges = curved_spacing.replan_shift(first.metadata, probe, choice.overlap, choice.width) / \
        first.metadata["work_spacing_m"]
    assert edges > 5 * curved_spacing.KEEP_WITHIN_EDGES
    monkeypatch.setattr(curved_spacing, "KEEP_WITHIN_EDGES", edges * 1.01)
    planner = _Counting()
    tp = curved_spacing.curved_spacing_plan(part, TOOL, planner, settings, {})
    assert planner.overlaps == [probe]
    assert tp.metadata["ripple_overlap_fraction"] == probe and tp.metadata["ripple_model"] == "curved"
    assert tp.contact_length == pytest.approx(first.contact_length, rel=1e-12)
