"""The efficiency of a trajectory cut at unreachable stretches stays a ratio to a true bound."""

import math

import pytest

from swath.cli.stages import efficiency_after_gaps


def test_each_gap_lowers_the_bound_by_two_half_pads():
    # a 1 m pass on a flat plate with a 76.2 mm pad, cut once: the pad touches a half disc beyond
    # each new end, pi R^2 / 2 of area, which over the widest swath 2 R is pi R / 4 of bound
    r = 0.0381
    metrics = {"covered_lower_bound_m": 1.0 + 2 * math.pi * r / 4, "contact_length_m": 1.05}
    out = efficiency_after_gaps(metrics, 1, r)
    assert out["gap_end_allowance_m"] == pytest.approx(math.pi * r / 2)
    assert out["covered_lower_bound_m"] == pytest.approx(1.0)
    assert out["efficiency"] == pytest.approx(1.0 / 1.05)
    # more gaps than the touched area can pay for: the bound stops at zero
    assert efficiency_after_gaps(metrics, 100, r)["efficiency"] == 0.0
