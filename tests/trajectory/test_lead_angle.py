"""A lead angle: the pad tilted about the axis across the feed, its leading edge lifted.

Analytic answers on a plane (FORMATS.md tool model): at ``Tool.half_pad_lead`` the pad presses on
exactly its trailing half with pressure falling linearly to zero at the centre line, and a straight
pass removes the parabola ``R² − y²`` across its width; the ripple of parallel passes drops from
the semicircle's 9.2 % to 5.3 % within 1.5 L*.
"""

import json
import math

import numpy as np
import pytest

from swath.contact import Tool, mesh_contact
from swath.errors import InputError
from swath.examples import flat_plate
from swath.feed import optimise_feed
from swath.feed.ripple import cross_profile, ripple_cov, ripple_spacing, tilted_sink
from swath.plan import raster
from swath.simulate.removal import simulate_removal
from swath.surface.surface import farther_from_boundary
from swath.trajectory import AngularSpeedLimit, FeedLimit, time_path
from swath.trajectory.orientation import tool_frames, with_lead

TOOL = Tool()
R = TOOL.pad_radius


def _tilted_axis(theta: float) -> np.ndarray:
    """Tool z of a pass travelling along +x over the plate z = 0 (normal +z), led by ``theta``."""
    frames = with_lead(tool_frames(np.array([[0.0, 0.0, 1.0]]), np.array([[1.0, 0.0, 0.0]])), theta)
    return frames[0][:, 2]


def test_half_pad_lead_is_the_closed_form():
    q = 3 * math.pi * TOOL.flat_depression / (2 * R)
    theta = TOOL.half_pad_lead
    assert math.sin(theta) / math.cos(theta) ** 2 == pytest.approx(q, rel=1e-12)
    assert math.degrees(theta) == pytest.approx(7.0, abs=0.01)        # 1 mm on a 38.1 mm pad
    assert tilted_sink(TOOL, theta) == pytest.approx(0.0, abs=1e-15)
    assert tilted_sink(TOOL, 0.0) == pytest.approx(TOOL.flat_depression, rel=1e-12)


def test_half_pad_lead_presses_the_trailing_half_of_the_pad_on_a_plate():
    """The exact mesh contact of the tilted pad: sink 0, every touched point behind the TCP, the
    touched area half the pad's ellipse on the plane, pressure k·u·sin θ growing toward the rim."""
    theta = TOOL.half_pad_lead
    s = flat_plate(spacing=1e-3)
    centre = np.array([0.2, 0.15, 0.0])
    mc = mesh_contact(s.vertices, s.normals, s.vertex_areas, s.kdtree, centre[None], _tilted_axis(theta)[None], TOOL)
    u = s.vertices[mc.sample, 0] - centre[0]
    assert abs(mc.sink[0]) < 0.01 * TOOL.flat_depression
    assert u.max() <= 1e-3                                           # one grid step at most ahead
    half_ellipse = 0.5 * math.pi * R * R / math.cos(theta)
    assert s.vertex_areas[mc.sample].sum() == pytest.approx(half_ellipse, rel=0.02)
    np.testing.assert_allclose(mc.pressure, TOOL.k * (mc.sink[0] - u * math.sin(theta)), rtol=1e-9, atol=1e-6)
    assert (mc.pressure * s.vertex_areas[mc.sample]).sum() == pytest.approx(TOOL.force, rel=1e-9)


def test_untilted_pad_is_unchanged():
    y = np.linspace(0.0, 1.1 * R, 7)
    np.testing.assert_array_equal(cross_profile(TOOL, y), cross_profile(TOOL, y, lead_angle=0.0))
    np.testing.assert_allclose(cross_profile(TOOL, y, lead_angle=1e-9), cross_profile(TOOL, y), rtol=1e-9)
    # a trailing edge lifted instead removes the same profile (the mirror image along the pass)
    theta = TOOL.half_pad_lead
    np.testing.assert_allclose(cross_profile(TOOL, y, lead_angle=-theta), cross_profile(TOOL, y, lead_angle=theta),
                               rtol=1e-12)


def test_half_pad_profile_is_the_parabola_and_removes_the_same_volume():
    theta, v = TOOL.half_pad_lead, 0.04
    y = np.array([0.0, 0.3 * R, 0.8 * R, 1.0 * R, 1.2 * R])
    # ∫_{−w}^{0} k (−x tan θ) v_rel dx / (v cos θ), w² = R² − y²
    expect = (TOOL.preston * TOOL.k * TOOL.relative_speed(0.0) * math.tan(theta) / (v * math.cos(theta))
              * np.clip(R * R - y * y, 0, None) / 2)
    np.testing.assert_allclose(cross_profile(TOOL, y, speed=v, lead_angle=theta), expect, rtol=1e-12, atol=1e-22)
    # Preston: the volume removed per metre of pass is k_p F v_rel / v whatever the tilt
    Y = np.linspace(-R, R, 40001)
    flat = np.trapezoid(cross_profile(TOOL, Y, speed=v), Y)
    tilted = np.trapezoid(cross_profile(TOOL, Y, speed=v, lead_angle=theta), Y)
    assert tilted == pytest.approx(TOOL.preston * TOOL.force * TOOL.relative_speed(0.0) / v, rel=1e-6)
    assert tilted == pytest.approx(flat, rel=1e-4)


def test_half_pad_ripple_is_the_sum_of_parabolas():
    theta = TOOL.half_pad_lead
    for d in (1.4 * R, 1.6 * R):
        y = (np.arange(4000) + 0.5) / 4000 * d
        total = sum(np.clip(1 - ((y - j * d) / R) ** 2, 0, None) for j in range(-3, 4))
        assert ripple_cov(TOOL, d, lead_angle=theta) == pytest.approx(total.std() / total.mean(), rel=1e-3)
    d_flat, cov_flat = ripple_spacing(TOOL)
    d_lead, cov_lead = ripple_spacing(TOOL, lead_angle=theta)
    assert cov_flat == pytest.approx(0.092, abs=0.001) and d_flat / R == pytest.approx(1.68, abs=0.01)
    assert cov_lead == pytest.approx(0.0533, abs=0.0005) and d_lead / R == pytest.approx(1.40, abs=0.01)


def test_time_path_tilts_every_contact_pose_lays_the_pad_flat_at_pass_ends_and_keeps_the_timing():
    plate = flat_plate()
    tp = raster(plate, TOOL)
    cons = [FeedLimit(0.05), AngularSpeedLimit(1.0)]
    flat = time_path(tp, cons)
    theta = math.radians(6.0)
    led = time_path(tp, cons, lead_angle=theta)
    ramp = led.metadata["lead_end_ramp_m"]
    assert ramp == pytest.approx(theta * 0.05 / 0.95)             # the turn at 0.95 rad/s at the full feed
    c = led.contact
    # arc length to each contact sample's pass end
    left = np.zeros(len(led.t))
    for i in np.unique(led.pass_index[c]):
        k = np.flatnonzero(c & (led.pass_index == i))
        step = np.linalg.norm(np.diff(led.position[k], axis=0), axis=1)
        left[k] = np.concatenate([np.cumsum(step[::-1])[::-1], [0.0]])
    tilt = np.arccos(np.clip(led.tool_z() @ [0.0, 0.0, -1.0], -1, 1))
    before = c & (left >= ramp + 1e-6)
    np.testing.assert_allclose(tilt[before], theta, atol=1e-6)
    # the leading edge (tool x) lifts off the part: it points out along the normal by sin θ
    np.testing.assert_allclose(led.tool_x()[before] @ [0.0, 0.0, 1.0], math.sin(theta), atol=1e-9)
    # over the last ramp the turn falls linearly to none: the pad is flat at every pass end
    ramped = c & (left < ramp)
    np.testing.assert_allclose(tilt[ramped], theta * left[ramped] / ramp, atol=2e-3)
    ends = c & (left == 0.0)
    assert ends.sum() == len(np.unique(led.pass_index[c])) and np.all(tilt[ends] < 1e-6)
    # at 0.95 of the angular speed limit the ramp slows nothing: the same times and positions
    np.testing.assert_array_equal(led.t, flat.t)
    np.testing.assert_array_equal(led.position, flat.position)
    w = np.linalg.norm(np.stack([led.extra[k] for k in ("wx", "wy", "wz")], axis=1), axis=1)
    assert w[c].max() <= 1.0
    clear = c & (left >= ramp + 3e-3)                 # a sample step clear of the ramp
    for k in ("wx", "wy", "wz"):                      # elsewhere the constant turn changes no angular velocity
        np.testing.assert_allclose(led.extra[k][clear], flat.extra[k][clear], atol=1e-9)
    assert led.metadata["lead_angle_rad"] == theta
    assert "lead 6.00 deg" in led.metadata["tool_tilt"] and "leading edge lifted" in led.metadata["tool_tilt"]
    assert "flat where the pass ends" in led.metadata["tool_tilt"]
    assert flat.metadata["tool_tilt"].startswith("none")
    with pytest.raises(InputError, match="within ±45°"):
        time_path(tp, cons, lead_angle=math.radians(50))


def test_half_pad_lead_evens_the_simulated_removal_between_passes():
    """Passes at the lead's least-ripple spacing on a plate: the simulated interior CoV falls to
    near the parabolas' 5.3 % from the semicircles' ripple at that spacing, with the same mean."""
    plate = flat_plate(spacing=4e-3)
    theta = TOOL.half_pad_lead
    d, _ = ripple_spacing(TOOL, lead_angle=theta)
    tp = raster(plate, TOOL, spacing=d)
    cons = [FeedLimit(0.05), AngularSpeedLimit(1.0)]
    out = {}
    for lead in (0.0, theta):
        rm = simulate_removal(time_path(tp, cons, lead_angle=lead), plate, TOOL)
        inner = farther_from_boundary(rm.surface.vertices, plate, R)
        z, a = rm.depth[inner], rm.surface.vertex_areas[inner]
        mean = np.average(z, weights=a)
        out[lead] = (mean, math.sqrt(np.average((z - mean) ** 2, weights=a)) / mean)
    assert out[theta][0] == pytest.approx(out[0.0][0], rel=0.03)
    assert ripple_cov(TOOL, d) > 0.15                                # the semicircles at this spacing
    assert out[0.0][1] > 0.15
    assert out[theta][1] < 0.10 and out[theta][1] < 0.5 * out[0.0][1]


def test_feed_optimisation_refuses_a_trajectory_timed_with_another_lead():
    plate = flat_plate()
    tp = raster(plate, TOOL)
    cons = [FeedLimit(0.05)]
    flat = time_path(tp, cons)
    with pytest.raises(InputError, match="lead angle"):
        optimise_feed(tp, TOOL, cons, target=20e-6, tolerance=2e-6, trajectory=flat, lead_angle=0.1)


def test_job_with_auto_lead_states_the_tilt(tmp_path):
    from swath.cli.main import main
    from swath.trajectory import read_csv

    out = tmp_path / "lead"
    assert main(["-q", "plan", "--constant-feed", "example:plate", "--lead-angle", "auto", "--out", str(out)]) == 0
    doc = json.loads((out / "metrics.json").read_text())
    theta = Tool().half_pad_lead
    assert doc["settings"]["lead_angle_rad"] == pytest.approx(theta)
    assert doc["metrics"]["lead_angle_rad"] == pytest.approx(theta)
    assert "leading edge lifted" in doc["metrics"]["tool_tilt"]
    assert doc["metrics"]["lead_end_ramp_m"] > 0 and "flat where the pass ends" in doc["metrics"]["tool_tilt"]
    traj = read_csv(out / "trajectory.csv")
    tilt = np.degrees(np.arccos(np.clip(traj.tool_z()[traj.contact] @ [0.0, 0.0, -1.0], -1, 1)))
    # the lead everywhere but over each pass's last few millimetres, where the pad is laid flat
    assert np.mean(np.abs(tilt - math.degrees(theta)) < 1e-3) > 0.9
    assert tilt.min() < 1e-3 and tilt.max() == pytest.approx(math.degrees(theta), abs=1e-3)
    assert main(["-q", "plan", "--constant-feed", "example:plate", "--lead-angle", "60deg", "--out", str(tmp_path / "bad")]) == 2
    assert not (tmp_path / "bad").exists()



def test_a_lead_changes_the_cycle_time_too_little_to_rank_candidates_otherwise():
    """Planners rank candidate directions by the cycle time the job's cost times untilted.  On a
    curved part with the job's air links the tilted cycle time is within a fraction of a percent of
    it: the passes keep their timing but over their last few millimetres, where the pad is laid flat
    at 0.95 of the angular speed limit, and a link then turns the tool from the flat pad at one pass's
    end to the led pad at the next pass's start (without the flat ends, tilting both end frames by
    the same lead about their own y-axes only conjugates the turn between them)."""
    from swath.cli.job import planner_arguments, settings_from_mapping
    from swath.examples import blade
    from swath.order import order_toolpath

    settings = settings_from_mapping({"part": "example:blade", "out": "unused", "planner": "uniform",
                                      "lead_angle": "auto"})
    cost = planner_arguments(settings)["cost"]
    tp = raster(blade(), Tool(), spacing=0.07, point_spacing=4e-3)
    ordered = order_toolpath(tp)
    flat = time_path(ordered, list(cost.constraints), links=cost.links)
    led = time_path(ordered, list(cost.constraints), links=cost.links, lead_angle=settings.lead())
    assert (~flat.contact).sum() > 100                           # air links with turns in them
    assert cost(tp)[0] == flat.duration
    assert led.duration == pytest.approx(flat.duration, rel=5e-3)
    # in contact the TCP runs the same path
    for i in np.unique(flat.pass_index[flat.contact]):
        a, b = flat.contact & (flat.pass_index == i), led.contact & (led.pass_index == i)
        np.testing.assert_allclose(led.position[b], flat.position[a], rtol=0, atol=1e-12)
