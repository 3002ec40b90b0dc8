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


def test_time_path_tilts_every_contact_pose_and_keeps_the_timing():
    plate = flat_plate()
    tp = raster(plate, TOOL)
    cons = [FeedLimit(0.05), AngularSpeedLimit(1.0)]
    flat = time_path(tp, cons)
    theta = math.radians(6.0)
    led = time_path(tp, cons, lead_angle=theta)
    c = led.contact
    z, x = led.tool_z()[c], led.tool_x()[c]
    np.testing.assert_allclose(z @ [0.0, 0.0, -1.0], math.cos(theta), atol=1e-9)
    # the leading edge (tool x) lifts off the part: it points out along the normal by sin θ
    np.testing.assert_allclose(x @ [0.0, 0.0, 1.0], math.sin(theta), atol=1e-9)
    np.testing.assert_array_equal(led.t, flat.t)
    np.testing.assert_array_equal(led.position, flat.position)
    for k in ("wx", "wy", "wz"):
        np.testing.assert_allclose(led.extra[k], flat.extra[k], atol=1e-9)
    assert led.metadata["lead_angle_rad"] == theta
    assert "lead 6.00 deg" in led.metadata["tool_tilt"] and "leading edge lifted" in led.metadata["tool_tilt"]
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
    traj = read_csv(out / "trajectory.csv")
    z = traj.tool_z()[traj.contact]
    np.testing.assert_allclose(np.degrees(np.arccos(z @ [0.0, 0.0, -1.0])), math.degrees(theta), atol=1e-3)
    assert main(["-q", "plan", "--constant-feed", "example:plate", "--lead-angle", "60deg", "--out", str(tmp_path / "bad")]) == 2
    assert not (tmp_path / "bad").exists()



def test_a_lead_changes_no_cycle_time_so_candidates_rank_alike():
    """Planners rank candidate directions by the cycle time the job's cost times untilted.  On a
    curved part with the job's air links that is the tilted cycle time too, sample for sample:
    the passes keep their timing, and every link turns the tool through the same angle, because
    tilting both end frames by the same lead about their own y-axes only conjugates the turn
    between them (``(R_a L)^T R_b L = L^T (R_a^T R_b) L``)."""
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
    np.testing.assert_allclose(led.t, flat.t, rtol=0, atol=1e-9)        # rounding in the links' turns only
    np.testing.assert_allclose(led.position, flat.position, rtol=0, atol=1e-12)

    def step_turns(tr):          # angle (rad) the tool frame turns between consecutive samples
        x, z = tr.tool_x(), tr.tool_z()
        frames = np.stack([x, np.cross(z, x), z], axis=2)
        rel = np.einsum("nji,njk->nik", frames[:-1], frames[1:])
        return np.arccos(np.clip((np.trace(rel, axis1=1, axis2=2) - 1) / 2, -1, 1))

    turns = step_turns(flat)
    assert turns[~flat.contact[1:]].max() > 0.01                 # the links do turn the tool
    np.testing.assert_allclose(step_turns(led), turns, atol=2e-7)
