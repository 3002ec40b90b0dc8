"""The twist of passes oblique to the principal directions, in the curved ripple model."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from swath.contact import Tool
from swath.core import Pass, ToolPath
from swath.errors import InputError
from swath.feed.curved_ripple import (
    CELLS_PER_RADIUS,
    curved_ripple_spacing,
    pass_curvatures,
    pass_twist,
    quadric_cross_profile,
)

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shapes import cylinder_patch  # noqa: E402

TOOL = Tool()
R = TOOL.pad_radius
U = (np.arange(-2 * CELLS_PER_RADIUS, 2 * CELLS_PER_RADIUS) + 0.5) * (R / CELLS_PER_RADIUS)


def _rotated(k1: float, k2: float, phi: float) -> tuple[float, float, float]:
    """Normal curvatures along and across a feed at ``phi`` from the first principal direction, and the twist."""
    c, s = math.cos(phi), math.sin(phi)
    return k1 * c * c + k2 * s * s, k1 * s * s + k2 * c * c, (k2 - k1) * c * s


def _width(p: np.ndarray) -> float:
    touched = U[p > 0]
    return float(touched.max() - touched.min())


def test_helical_passes_on_a_cylinder_see_half_the_curvature_and_its_twist():
    rho = 0.2
    cyl = cylinder_patch(rho, 0.6, 0.3)
    y = np.linspace(-0.08, 0.08, 161)
    passes = []
    for start in (-0.1, 0.0, 0.1):
        th = start + y / rho                           # 45° helices: as far round as along
        pts = np.stack([rho * np.sin(th), y, rho * np.cos(th)], axis=1)
        passes.append(Pass(pts, np.stack([np.sin(th), 0 * th, np.cos(th)], axis=1)))
    tp = ToolPath(cyl, tuple(passes), planner="test")
    kf, kc = pass_curvatures(tp, cyl)
    assert kf == pytest.approx(0.5 / rho, rel=0.1) and kc == pytest.approx(0.5 / rho, rel=0.1)
    assert pass_twist(tp, cyl) == pytest.approx(0.5 / rho, rel=0.1)
    # along the axis: no twist
    axial = []
    for th in (-0.2, 0.0, 0.2):
        pts = np.stack([rho * np.sin(th) + 0 * y, y, rho * np.cos(th) + 0 * y], axis=1)
        axial.append(Pass(pts, np.tile([np.sin(th), 0.0, np.cos(th)], (len(y), 1))))
    assert pass_twist(ToolPath(cyl, tuple(axial), planner="test"), cyl) < 0.05 / rho


@pytest.mark.parametrize("lead_deg", [0.0, 11.0])
def test_twisted_profile_keeps_the_force_and_mirrors_with_its_sign(lead_deg):
    lead = math.radians(lead_deg)
    kf, kc, kt = _rotated(4.2, 0.4, math.radians(45))
    plus = quadric_cross_profile(TOOL, U, kf, kc, lead_angle=lead, k_twist=kt)
    minus = quadric_cross_profile(TOOL, U, kf, kc, lead_angle=lead, k_twist=-kt)
    flat = quadric_cross_profile(TOOL, U, 0.0, 0.0, lead_angle=lead)
    h = U[1] - U[0]
    # Preston: whatever the geometry, a pass removes k_p · F · v_rel / speed per unit length (the
    # sum over the cross profile); the quadric's area element is exact to (κR)², 1 % here
    assert plus.sum() * h == pytest.approx(flat.sum() * h, rel=0.02)
    np.testing.assert_allclose(plus, minus[::-1], rtol=0, atol=1e-3 * plus.max())
    assert not np.allclose(plus, quadric_cross_profile(TOOL, U, kf, kc, lead_angle=lead), atol=0.05 * plus.max())


def test_twisted_profile_is_the_rotated_quadric():
    """A patch well inside the pad on an elliptic quadric (flat pad): an ellipse of semi-axes
    ``sqrt(2 s / k_i)``, the sink ``s`` the same whatever the feed direction, so the swath across a
    feed at φ is ``2 sqrt(a1² sin² φ + a2² cos² φ)`` from the widths along the two principal axes."""
    k1, k2 = 40.0, 20.0
    w0 = _width(quadric_cross_profile(TOOL, U, k1, k2))         # feed along the first axis: a2 across
    w90 = _width(quadric_cross_profile(TOOL, U, k2, k1))
    assert w0 > w90 and w0 < 1.6 * R
    for deg in (30.0, 45.0, 60.0):
        phi = math.radians(deg)
        got = _width(quadric_cross_profile(TOOL, U, *_rotated(k1, k2, phi)[:2], k_twist=_rotated(k1, k2, phi)[2]))
        expect = math.sqrt(w90**2 * math.sin(phi) ** 2 + w0**2 * math.cos(phi) ** 2)
        assert got == pytest.approx(expect, abs=2.5 * (U[1] - U[0]))
        no_twist = _width(quadric_cross_profile(TOOL, U, *_rotated(k1, k2, phi)[:2]))
        assert abs(no_twist - expect) > abs(got - expect)


def test_oblique_passes_on_a_cylinder_like_part_space_wider_with_the_twist():
    # bezier_dac_cad's passes at 45° across k1 = 4.2, k2 = 0.4 1/m, flat pad: 48.5 mm without the
    # twist, 51.6 mm with it (the simulated job: 0.080 at 50.4 mm and 0.070 at 52 mm at constant feed)
    kf, kc, kt = _rotated(4.18, 0.41, math.radians(45))
    without = curved_ripple_spacing(TOOL, kf, kc, max_length_ratio=2.0)
    with_twist = curved_ripple_spacing(TOOL, kf, kc, k_twist=kt, max_length_ratio=2.0)
    assert without.spacing == pytest.approx(0.0485, abs=1e-3)
    assert with_twist.spacing == pytest.approx(0.0516, abs=1e-3)
    with pytest.raises(InputError, match="finite"):
        quadric_cross_profile(TOOL, U, kf, kc, k_twist=math.nan)
