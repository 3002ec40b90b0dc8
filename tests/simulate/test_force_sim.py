"""The simulated force control on a flat plate against analytic answers, and the removal it feeds."""

import math

import numpy as np
import pytest

from swath.contact import Tool
from swath.examples import flat_plate
from swath.plan import Pass, ToolPath
from swath.simulate import (
    Disturbance,
    ForceController,
    gravity_for_tilt,
    simulate_force,
    simulate_removal,
    trajectory_with_force,
)
from swath.simulate.force_contact import contact_curves
from swath.trajectory import FeedLimit, read_csv, time_path


@pytest.fixture(scope="module")
def plate():
    return flat_plate()


@pytest.fixture(scope="module")
def two_passes(plate):
    n = np.array([[0, 0, 1.0]] * 2)
    ps = [Pass(np.array([[0.08, 0.1, 0], [0.28, 0.1, 0]]), n), Pass(np.array([[0.28, 0.2, 0], [0.08, 0.2, 0]]), n)]
    return time_path(ToolPath(plate, ps, "test"), [FeedLimit(0.05)])


def test_contact_curve_on_flat_is_k_pi_r2_times_offset(plate):
    tool = Tool()
    cv = contact_curves(plate.subdivided(2e-3), np.array([[0.2, 0.15, 0.0]]), np.array([[0, 0, -1.0]]), tool)
    area = tool.pad_area
    for delta in (2e-4, 1e-3, 3e-3):
        f, k = cv.force(0, delta)
        assert f == pytest.approx(tool.k * area * delta, rel=0.02)
        assert k == pytest.approx(tool.k * area, rel=0.02)
    assert cv.force(0, -1e-4) == (0.0, 0.0)
    assert cv.offsets(tool.force)[0] == pytest.approx(tool.flat_depression, rel=0.02)


def test_flat_plate_with_perfect_registration_holds_the_set_force(plate, two_passes):
    tool = Tool()
    trace = simulate_force(two_passes, plate, tool)
    m = trace.metrics
    assert m["rms_force_error_fraction"] < 0.005
    assert m["contact_loss_fraction"] == 0.0
    on = two_passes.contact
    assert np.all(trace.force[~on] == 0)
    assert np.allclose(trace.force[on], tool.force, rtol=0.02)
    assert np.allclose(trace.nominal_offset[on], tool.flat_depression, rtol=0.02)
    assert np.unique(trace.pass_index).tolist() == [0, 1]
    assert m["hold_time_s"] > 0 and np.all(np.diff(trace.t) > 0)


def test_gravity_compensation_on_and_off_on_a_tilted_cell(plate, two_passes):
    tool = Tool()
    mass, tilt = 2.0, math.radians(30)
    dist = Disturbance(tool_mass=mass, gravity=gravity_for_tilt(tilt))
    on = simulate_force(two_passes, plate, tool, disturbance=dist)
    off = simulate_force(two_passes, plate, tool, disturbance=dist,
                         controller=ForceController(gravity_compensation=False))
    assert on.metrics["rms_force_error_fraction"] < 0.005
    # uncompensated, the sensor over-reads the weight share m g (1 − cos θ), so the pad gets that much less
    share = mass * 9.80665 * (1 - math.cos(tilt))
    assert off.metrics["mean_force_n"] == pytest.approx(tool.force - share, abs=0.02)
    # the position baseline does not read the sensor at all
    pos = simulate_force(two_passes, plate, tool, disturbance=dist, controller=ForceController(mode="position"))
    assert pos.metrics["mean_force_n"] == pytest.approx(tool.force, rel=0.01)


def test_registration_error_on_position_control_and_force_control(plate, two_passes):
    tool = Tool()
    dz = 0.2e-3      # the real plate sits 0.2 mm higher: position control presses 0.2 mm deeper
    dist = Disturbance(part_offset=(0, 0, dz, 0, 0, 0))
    pos = simulate_force(two_passes, plate, tool, disturbance=dist, controller=ForceController(mode="position"))
    assert pos.metrics["mean_force_n"] == pytest.approx(tool.force * (1 + dz / tool.flat_depression), rel=0.01)
    hyb = simulate_force(two_passes, plate, tool, disturbance=dist)
    assert hyb.metrics["rms_force_error_fraction"] < 0.005
    # the force loop backs off by the registration error: offset e − dz beyond the planned TCP
    assert np.median(hyb.actual_offset[hyb.moving]) == pytest.approx(tool.flat_depression - dz, rel=0.02)


def test_part_stiffness_in_series_halves_the_position_controlled_force(plate, two_passes):
    tool = Tool()
    pad = tool.k * tool.pad_area
    pos = simulate_force(two_passes, plate, tool, controller=ForceController(mode="position"), part_stiffness=pad)
    assert pos.metrics["mean_force_n"] == pytest.approx(tool.force / 2, rel=0.01)
    hyb = simulate_force(two_passes, plate, tool, part_stiffness=pad)
    assert hyb.metrics["rms_force_error_fraction"] < 0.005


def test_sensor_noise_is_seeded(plate, two_passes):
    tool = Tool()
    a = simulate_force(two_passes, plate, tool, disturbance=Disturbance(force_noise=0.3, seed=4))
    b = simulate_force(two_passes, plate, tool, disturbance=Disturbance(force_noise=0.3, seed=4))
    assert np.array_equal(a.contact_force, b.contact_force)
    assert 0.001 < a.metrics["rms_force_error_fraction"] < 0.02


def test_removal_with_the_force_trace(plate, two_passes, tmp_path):
    tool = Tool()
    base = simulate_removal(two_passes, plate, tool)
    same = simulate_removal(two_passes, plate, tool, force=np.full(len(two_passes), tool.force))
    assert np.allclose(same.depth, base.depth, rtol=1e-6, atol=1e-15)
    half = simulate_removal(two_passes, plate, tool, force=np.full(len(two_passes), tool.force / 2))
    # on flat, depth is linear in force
    assert np.allclose(half.depth, base.depth / 2, rtol=1e-6, atol=1e-15)
    trace = simulate_force(two_passes, plate, tool, controller=ForceController(mode="position"),
                           disturbance=Disturbance(part_offset=(0, 0, 0.2e-3, 0, 0, 0)))
    sim = simulate_removal(two_passes, plate, tool, force=trace.force)
    assert sim.metrics["removal_mean_m"] == pytest.approx(1.2 * base.metrics["removal_mean_m"], rel=0.02)
    tr = trajectory_with_force(two_passes, trace)
    tr.write_csv(tmp_path / "trajectory.csv")
    back = read_csv(tmp_path / "trajectory.csv")
    assert np.allclose(back.extra["force"], trace.force, rtol=1e-5)
    with pytest.raises(ValueError):
        simulate_removal(two_passes, plate, tool, force=np.full(3, 1.0))


def test_cli_option_parsers():
    from swath.errors import InputError
    from swath.simulate.force import parse_mass, parse_part_offset

    assert parse_mass("2kg") == 2.0 and parse_mass("500g") == 0.5 and parse_mass("3") == 3.0
    off = parse_part_offset("0.5mm,0,-1mm,0.2deg,0,0")
    assert off == pytest.approx((5e-4, 0.0, -1e-3, math.radians(0.2), 0.0, 0.0))
    for bad in ("2 stone", "-1kg"):
        with pytest.raises(InputError):
            parse_mass(bad)
    with pytest.raises(InputError):
        parse_part_offset("1,2,3")


def test_a_part_far_below_the_plan_skips_the_pass_with_a_warning(plate, two_passes, caplog):
    tool = Tool()
    trace = simulate_force(two_passes, plate, tool, disturbance=Disturbance(part_offset=(0, 0, -8e-3, 0, 0, 0)))
    assert "no contact within 5 mm" in caplog.text
    assert not trace.moving.any() and np.all(trace.force == 0)
    assert np.isnan(trace.metrics["rms_force_error_n"])


def test_curved_part_with_registration_error_and_tilted_tool():
    from swath.examples import doubly_curved_panel

    part = doubly_curved_panel(size_x=0.24, size_y=0.2, radius_x=0.35, radius_y=0.9, spacing=4e-3)
    tool = Tool()
    ys = (-0.04, 0.04)
    xs = np.linspace(-0.08, 0.08, 33)
    passes = []
    for y in ys:
        z = (np.sqrt(0.35**2 - xs**2) - 0.35) + (np.sqrt(0.9**2 - y**2) - 0.9)
        pts = np.stack([xs, np.full_like(xs, y), z], axis=1)
        nrm = np.stack([xs / 0.35, np.full_like(xs, y / 0.9), np.sqrt(1 - (xs / 0.35) ** 2 - (y / 0.9) ** 2)], axis=1)
        passes.append(Pass(pts, nrm / np.linalg.norm(nrm, axis=1, keepdims=True)))
    tr = time_path(ToolPath(part, passes, "test"), [FeedLimit(0.05)])
    dist = Disturbance(part_offset=(0.2e-3, 0.1e-3, 0.45e-3, 5e-4, 5e-4, 0), tool_mass=2.0,
                       gravity=gravity_for_tilt(math.radians(30)))
    a = simulate_force(tr, part, tool, controller=ForceController(latency=0.008), disturbance=dist)
    b = simulate_force(tr, part, tool, controller=ForceController(latency=0.008, gravity_compensation=False),
                       disturbance=dist)
    c = simulate_force(tr, part, tool, controller=ForceController(latency=0.008, mode="position"), disturbance=dist)
    assert a.metrics["rms_force_error_fraction"] < 0.02
    assert b.metrics["rms_force_error_fraction"] > 0.10
    assert c.metrics["rms_force_error_fraction"] > 0.25
    # the nominal sink on a convex part is deeper than the flat depression
    assert np.nanmin(a.nominal_offset) > tool.flat_depression
