"""The pad's analytic cross-profile and the ripple of parallel passes."""

import math

import numpy as np
import pytest

from swath.contact import Tool
from swath.errors import InputError
from swath.feed.ripple import cross_profile, ripple_cov, ripple_spacing

ORBITAL = Tool(pad_radius=0.02, force=20.0)
ROTARY = Tool(pad_radius=0.02, force=20.0, motion="rotary")
R = 0.02


def test_orbital_profile_is_the_chord():
    y = np.array([0.0, 0.5 * R, 0.9 * R, 1.2 * R])
    rate = ORBITAL.preston * ORBITAL.force / (math.pi * R**2) * ORBITAL.relative_speed(0.0)
    expect = rate * 2 * np.sqrt(np.clip(R**2 - y**2, 0, None)) / 0.04
    np.testing.assert_allclose(cross_profile(ORBITAL, y, speed=0.04), expect, rtol=1e-12, atol=1e-20)


def test_rotary_profile_closed_form_and_volume():
    """Centre: k_p p ω R² / v; off-centre: k_p p ω (c R + y² asinh(c/y)) / v; the profile's
    integral across the pass is the volume rate k_p F ω (2R/3) / v (mean radius 2R/3)."""
    p = ROTARY.force / (math.pi * R**2)
    w = ROTARY.spindle_speed
    y = np.array([0.3 * R, 0.7 * R])
    c = np.sqrt(R**2 - y**2)
    expect = ROTARY.preston * p * w * (c * R + y**2 * np.arcsinh(c / y))
    np.testing.assert_allclose(cross_profile(ROTARY, y), expect, rtol=1e-6)
    assert cross_profile(ROTARY, [0.0])[0] == pytest.approx(ROTARY.preston * p * w * R**2, rel=1e-9)
    yy = np.linspace(-R, R, 4001)
    volume = np.trapezoid(cross_profile(ROTARY, yy), yy)
    assert volume == pytest.approx(ROTARY.preston * ROTARY.force * w * 2 * R / 3, rel=1e-3)


def test_ripple_at_full_pad_spacing_is_the_semicircle_cov():
    """Passes 2R apart: the sum is one semicircle per period, CoV sqrt(8/3 − π²/4) / (π/2)."""
    assert ripple_cov(ORBITAL, 2 * R) == pytest.approx(math.sqrt(8 / 3 - math.pi**2 / 4) / (math.pi / 2), rel=1e-3)


def test_least_ripple_spacing_within_the_length_bound():
    """Orbital: the first harmonic of the semicircle vanishes at 2πR/d = 3.8317 (d = 1.64 R); the
    least ripple with L <= 1.5 L* lies just past it, at about 1.68 R, and is still 9 %."""
    d, cov = ripple_spacing(ORBITAL, max_length_ratio=1.5)
    assert 1.62 * R < d < 1.75 * R
    assert 0.085 < cov < 0.10
    assert cov <= min(ripple_cov(ORBITAL, f * R) for f in np.linspace(1.34, 2.0, 34)) + 1e-9
    d_rot, cov_rot = ripple_spacing(ROTARY, max_length_ratio=1.5)
    assert 1.8 * R < d_rot < 1.95 * R and cov_rot < cov
    # allowed a longer path, the ripple falls under 5 %
    d2, cov2 = ripple_spacing(ORBITAL, max_length_ratio=2.5)
    assert cov2 < 0.05 and d2 >= 0.8 * R


def test_bad_input_refused():
    with pytest.raises(InputError, match="positive length"):
        ripple_cov(ORBITAL, 0.0)
    with pytest.raises(InputError, match="max_length_ratio"):
        ripple_spacing(ORBITAL, max_length_ratio=0.5)
