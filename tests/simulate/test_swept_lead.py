"""A led pad on a plane: the simulator, ``feed.ripple.cross_profile`` and an independent
integration of FORMATS.md's tool model agree.

The independent integration below shares no code with swath's contact model: a fine grid over the
plane, the pad's axis tilted by the lead toward the travel, contact where a point lies within
``R`` of the axis and above the sunk pad face, the sink found by bisection on the force balance,
and the removal at each lateral offset the pressure summed along the travel.
"""

import math

import numpy as np
import pytest

from swath.contact import Tool
from swath.contact.swept import quadratic_coefficients, swept_mean_height
from swath.core import Pass, ToolPath
from swath.examples import flat_plate
from swath.feed.ripple import cross_profile, ripple_cov, ripple_spacing
from swath.plan import raster
from swath.simulate.removal import simulate_removal
from swath.trajectory import FeedLimit, time_path

TOOL = Tool()
R = TOOL.pad_radius
SPEED = 0.05
OFFSETS = np.array([0.0, 0.01, 0.02, 0.03, 0.035])


def independent_profile(tool: Tool, lead: float, offsets, speed: float, h: float = 1e-4) -> np.ndarray:
    """Depth (m) at lateral ``offsets`` (m) of one straight pass at ``speed`` (m/s) over the plane
    z = 0 (normal +z), the tool axis ``(sin θ, 0, −cos θ)`` for travel along +x (FORMATS.md)."""
    R = tool.pad_radius
    u = np.arange(-1.1 * R, 1.1 * R, h) + 0.5 * h
    U, V = np.meshgrid(u, u, indexing="ij")
    z = U * math.sin(lead)                              # height along tool z of the plane point (U, V, 0)
    r2 = U * U + V * V - z * z                          # squared distance from the tool axis
    zin = np.where(r2 < R * R, z, np.inf)
    lo, hi = -R, R
    for _ in range(80):                                 # F = k ∫ (s − z)⁺ dA
        s = 0.5 * (lo + hi)
        if tool.k * np.clip(s - zin, 0.0, None).sum() * h * h > tool.force:
            hi = s
        else:
            lo = s
    pressure = tool.k * np.clip(s - zin, 0.0, None)
    profile = tool.preston * tool.relative_speed(0.0) * pressure.sum(axis=0) * h / speed
    return np.interp(np.abs(offsets), u, profile)


@pytest.mark.parametrize("degrees", [7.0, 15.0])
def test_cross_profile_is_the_independent_integration(degrees):
    lead = math.radians(degrees)
    expect = independent_profile(TOOL, lead, OFFSETS, SPEED)
    got = cross_profile(TOOL, OFFSETS, speed=SPEED, lead_angle=lead)
    np.testing.assert_allclose(got, expect, rtol=0.01, atol=0.005 * expect.max())


def _one_pass_removal(lead: float, swept: bool):
    plate = flat_plate(size_x=0.3, size_y=0.16, spacing=2e-3)
    x = np.linspace(0.02, 0.28, 131)
    pts = np.stack([x, np.full_like(x, 0.081), np.zeros_like(x)], axis=1)
    tp = ToolPath(plate, (Pass(pts, np.tile([0.0, 0.0, 1.0], (len(x), 1))),), planner="test")
    rm = simulate_removal(time_path(tp, [FeedLimit(SPEED)], lead_angle=lead), plate, TOOL, swept=swept)
    return rm.surface.vertices, rm.depth


def test_simulated_led_pass_is_the_independent_profile_sample_by_sample():
    """15° lead, 35 mm off the pass: 0.54e-7 m (not 8.3e-7).  Every sample of the middle of the
    pass within 2 % of the pad's peak depth of the independent profile; the pose-only Riemann sum
    (``swept=False``) misses by several times that on the same samples."""
    lead = math.radians(15.0)
    v, depth = _one_pass_removal(lead, swept=True)
    mid = np.abs(v[:, 0] - 0.15) < 0.05
    expect = independent_profile(TOOL, lead, v[mid, 1] - 0.081, SPEED)
    peak = expect.max()
    err = np.abs(depth[mid] - expect)
    assert err.max() < 0.02 * peak
    near35 = np.abs(np.abs(v[mid, 1] - 0.081) - 0.035) < 1e-4
    assert near35.sum() >= 10
    assert depth[mid][near35].mean() == pytest.approx(0.54e-7, rel=0.05)
    _, point = _one_pass_removal(lead, swept=False)
    assert np.abs(point[mid] - expect).max() > 3 * err.max()


def test_led_raster_ripple_is_the_analytic_ripple():
    """Passes 1.22 R apart (2 L*) led by 15°: ripple_cov says 3.7 %.  The simulated CoV over a
    window a whole number of periods wide matches within 0.3 points; the pose-only sum read 6 %."""
    lead = math.radians(15.0)
    d, cov = ripple_spacing(TOOL, lead_angle=lead, max_length_ratio=2.0)
    assert cov == pytest.approx(0.0372, abs=0.0005)
    plate = flat_plate(size_x=0.4, size_y=0.4, spacing=4e-3)
    tp = raster(plate, TOOL, spacing=d, direction=0.0)
    tr = time_path(tp, [FeedLimit(SPEED)], lead_angle=lead)
    ys = sorted(p.points[0, 1] for p in tp.passes)
    mid = ys[len(ys) // 2]
    out = {}
    for swept in (True, False):
        rm = simulate_removal(tr, plate, TOOL, swept=swept)
        p = rm.surface.vertices
        win = (np.abs(p[:, 0] - 0.2) < 0.1) & (p[:, 1] >= mid - 2 * d) & (p[:, 1] < mid + 2 * d)
        z, a = rm.depth[win], rm.surface.vertex_areas[win]
        mean = np.average(z, weights=a)
        out[swept] = math.sqrt(np.average((z - mean) ** 2, weights=a)) / mean
    assert out[True] == pytest.approx(ripple_cov(TOOL, d, lead_angle=lead), abs=0.003)
    assert out[False] > out[True] + 0.01


@pytest.mark.parametrize("rotary", [False, True])
def test_swept_mean_is_the_fine_quadrature(rotary):
    """The piecewise exact integral against a midpoint rule of 20 000 points on random quadratic
    heights and radii (rims crossed, contact lost and regained within the stretch)."""
    rng = np.random.default_rng(7)
    n = 200
    Rr = 0.04
    z = rng.normal(0.0, 1e-3, (n, 3))
    r2 = rng.uniform(0.6, 1.4, (n, 3)) * Rr * Rr
    sink = rng.normal(0.0, 1e-3, n)
    got = swept_mean_height(z, r2, sink, Rr, rotary=rotary)
    t = (np.arange(20000) + 0.5) / 20000 - 0.5
    zc = quadratic_coefficients(*z.T)
    rc = quadratic_coefficients(*r2.T)
    zt = zc[0][:, None] + t * (zc[1][:, None] + t * zc[2][:, None])
    rt = rc[0][:, None] + t * (rc[1][:, None] + t * rc[2][:, None])
    f = np.clip(sink[:, None] - zt, 0.0, None) * (rt <= Rr * Rr)
    if rotary:
        f = f * np.sqrt(np.maximum(rt, 0.0))
    expect = f.mean(axis=1)
    assert (expect > 0).sum() > 50 and ((expect > 0) & (expect < np.max(expect))).any()
    np.testing.assert_allclose(got, expect, rtol=0, atol=2e-3 * expect.max())
    # a stretch that does not move is the point evaluation
    still = np.repeat(z[:, 1:2], 3, axis=1), np.repeat(r2[:, 1:2], 3, axis=1)
    point = np.clip(sink - z[:, 1], 0, None) * (r2[:, 1] <= Rr * Rr)
    if rotary:
        point = point * np.sqrt(r2[:, 1])
    np.testing.assert_allclose(swept_mean_height(*still, sink, Rr, rotary=rotary), point, rtol=1e-12, atol=1e-18)
