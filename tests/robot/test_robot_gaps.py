"""Unreachable stretches: the pass is split with a retract and an approach, and the job's removal is
simulated on what the robot runs."""

import numpy as np
import pytest

from swath.robot import Cell, get_robot, run_robot_stage, solve_trajectory
from swath.robot.gaps import split_unreachable


@pytest.fixture(scope="module")
def far_plate(plate_trajectory):
    """The plate with its far end beyond a UR10e's reach (x from 1.0 m to 1.4 m from the base)."""
    cell = Cell.from_text("1.0,-0.15,0,0,0,0", "0,0,150mm,0,0,0")
    return plate_trajectory, cell, run_robot_stage(plate_trajectory, robot="ur10e", cell=cell, programs=[], warn=False)


def test_unreachable_stretches_become_air_with_retract_and_approach(far_plate):
    tr, cell, result = far_plate
    model = result.model
    first = solve_trajectory(tr, model, cell, warn=False)
    dropped_contact = int((~first.reachable & tr.contact).sum())
    assert dropped_contact > 100                                  # the far end is out of reach
    run = result.trajectory
    sol = result.solution
    # every sample the robot runs is reached, on rows whose FK is the trajectory's pose
    assert sol.reachable.all()
    assert result.metrics["max_fk_position_error_m"] < 1e-9
    assert result.metrics["max_fk_angle_error_rad"] < 1e-9
    # the contact samples are the reachable ones of the plan (re-sampled to 20 ms where re-timing stretched
    # them: never fewer); the contact length below says no more is sanded
    assert int(run.contact.sum()) >= int(tr.contact.sum()) - dropped_contact
    # each gap: the last contact sample before it, then a retract 20 mm straight up its tool axis
    gaps = result.metrics["gaps"]
    assert result.metrics["n_gaps"] == len(gaps) > 0
    ends = np.flatnonzero(run.contact[:-1] & ~run.contact[1:])
    up = run.position[ends + 1] - run.position[ends]           # the plate's tool z is -Z: a retract goes up
    lifted = [i for i, d in zip(ends, up) if np.allclose(d[:2], 0, atol=1e-9) and 0.004 < d[2] <= 0.02 + 1e-9]
    starts = np.flatnonzero(~run.contact[:-1] & run.contact[1:])
    down = run.position[starts + 1] - run.position[starts]
    landed = [i for i, d in zip(starts, down) if np.allclose(d[:2], 0, atol=1e-9) and -0.02 - 1e-9 <= d[2] < -0.004]
    assert len(lifted) == len([g for g in gaps if tr.contact[g["start_sample"] - 1]]) > 0
    assert len(landed) >= len([g for g in gaps if g["stop_sample"] < len(tr) and tr.contact[g["stop_sample"]]]) > 0
    # nothing jumps: no joint step is larger than the plan's own largest (on its air links)
    ok = first.reachable[1:] & first.reachable[:-1]
    assert np.abs(np.diff(sol.q, axis=0)).max() <= np.abs(np.diff(first.q, axis=0))[ok].max() + 1e-9
    # the dropped contact length is the plan's contact length minus what the robot runs
    seg = np.linalg.norm(np.diff(run.position, axis=0), axis=1)
    ran = seg[run.contact[1:] & run.contact[:-1]].sum()
    seg0 = np.linalg.norm(np.diff(tr.position, axis=0), axis=1)
    planned = seg0[tr.contact[1:] & tr.contact[:-1]].sum()
    dropped = result.metrics["gap_contact_length_m"]
    assert ran + dropped == pytest.approx(planned, abs=0.03)        # a few boundary steps either way
    assert np.all(np.diff(run.t) > 0)                               # no sample repeats a time
    assert np.isfinite(result.metrics["max_joint_speed_ratio"]) and result.metrics["max_joint_speed_ratio"] <= 1.0


def test_coverage_is_computed_on_what_the_robot_runs(far_plate):
    from swath.contact import Tool
    from swath.examples import example_part
    from swath.simulate import simulate_removal

    tr, _, result = far_plate
    surface = example_part("plate")
    planned = simulate_removal(tr, surface, Tool()).metrics["coverage_fraction"]
    ran = simulate_removal(result.trajectory, surface, Tool()).metrics["coverage_fraction"]
    assert planned > 0.99
    # the plate is 0.4 m long; x > 0.3 m is out of reach on the passes: about a quarter is left
    assert 0.6 < ran < 0.9


def test_no_split_keeps_the_old_behaviour(plate_trajectory):
    cell = Cell.from_text("1.0,-0.15,0,0,0,0", "0,0,150mm,0,0,0")
    r = run_robot_stage(plate_trajectory, robot="ur10e", cell=cell, programs=[], warn=False, split_gaps=False)
    assert r.metrics["n_poses"] == len(plate_trajectory) and r.metrics["n_gaps"] == 0
    assert not r.solution.reachable.all()
    assert any("moves straight across" in w for w in r.warnings)


def test_split_of_a_fully_reached_trajectory_is_the_identity(plate_trajectory):
    cell = Cell.from_text("0.55,-0.15,0,0,0,0", "0,0,150mm,0,0,0")
    model = get_robot("ur10e")
    sol = solve_trajectory(plate_trajectory, model, cell)
    run, q, gaps, src = split_unreachable(plate_trajectory, sol, model, cell)
    assert np.array_equal(src, np.arange(len(plate_trajectory)))
    assert run is plate_trajectory and gaps == [] and np.array_equal(q, sol.q, equal_nan=True)


def _lowest_clear_floor(model, cell, q):
    """The highest table top (m, base frame) that the arm and tool at ``q`` stay above, by bisection."""
    from swath.robot.gaps import _clear_of_floor

    lo, hi = -3.0, 3.0
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _clear_of_floor(model, cell, q, mid) else (lo, mid)
    return lo


def test_a_lift_at_a_downward_facing_edge_never_takes_the_wrist_into_the_table():
    """At a pass along the part's lower edge the surface faces 25° below the horizon; a lift back along
    the tool axis goes down by sin 25° of the clearance and the arm, 0.5 mm above the table at the
    contact pose, dips into it.  The lift keeps the arm and the tool above the table and still moves
    the pad away from the surface."""
    from swath.cell import default_sander
    from swath.robot.gaps import _clear_of_floor, _lift, _nearest_ik, lift_directions

    tilt = np.radians(25.0)
    c, s = np.cos(tilt), np.sin(tilt)
    tcp2part = np.eye(4)
    # tool z (into the part) points out and 25° up, so the surface normal points 25° down
    tcp2part[:3, 0], tcp2part[:3, 1], tcp2part[:3, 2] = (-s, 0.0, c), (0.0, -1.0, 0.0), (c, 0.0, s)
    tcp2part[:3, 3] = (0.8, 0.0, 0.2)
    model = get_robot("ur10e")
    cell = Cell(tcp2flange=np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0.175], [0, 0, 0, 1.0]]),
                tool=default_sander())
    raw = model.ik(cell.flange2base(tcp2part[None]))[0]
    q_ref = raw[np.all(np.isfinite(raw), axis=1)][0]
    q_contact = _nearest_ik(model, cell, tcp2part, q_ref)
    floor = _lowest_clear_floor(model, cell, q_contact) - 0.5e-3
    assert _clear_of_floor(model, cell, q_contact, floor)
    # the tool-axis lift goes 20 sin 25° = 8.5 mm down and puts the arm or the tool into the table
    dirs = lift_directions(cell, tcp2part)
    np.testing.assert_allclose(dirs[0], (-c, 0.0, -s), atol=1e-12)
    np.testing.assert_allclose(dirs[1], (-1.0, 0.0, 0.0), atol=1e-12)
    old = _lift(model, cell, tcp2part, q_contact, 0.02)
    assert not _clear_of_floor(model, cell, old, floor)
    new = _lift(model, cell, tcp2part, q_contact, 0.02, floor)
    assert _clear_of_floor(model, cell, new, floor)
    lifted = cell.tcp2part(model.fk(new[None]))[0]
    move = lifted[:3, 3] - tcp2part[:3, 3]
    # level, 20 mm out, away from the surface's tangent plane by 20 cos 25° = 18.1 mm
    np.testing.assert_allclose(move, (-0.02, 0.0, 0.0), atol=1e-6)
    assert float(move @ (-tcp2part[:3, 2])) == pytest.approx(0.02 * c, abs=1e-6)
    # above a table the lift never needs, it stays on the tool axis
    np.testing.assert_allclose(_lift(model, cell, tcp2part, q_contact, 0.02, floor - 0.05), old, atol=1e-12)


def test_an_upward_lift_has_one_direction():
    from swath.robot.gaps import lift_directions

    pose = np.eye(4)
    pose[:3, 2] = (0.0, 0.0, -1.0)
    pose[:3, 1] = (0.0, -1.0, 0.0)
    dirs = lift_directions(Cell(), pose)
    assert len(dirs) == 1
    np.testing.assert_allclose(dirs[0], (0.0, 0.0, 1.0), atol=1e-12)


def test_a_gap_along_a_downward_facing_edge_keeps_the_arm_above_the_table():
    """A pass along a lower edge facing 25° below the horizon, with a gap in its middle: the split's
    retract and approach rows stay above a table the arm clears by 0.5 mm on the pass."""
    from dataclasses import replace

    from swath.cell import default_sander
    from swath.robot.gaps import _clear_of_floor
    from swath.robot.pose import matrix_to_quat
    from swath.trajectory import Trajectory

    c, s = np.cos(np.radians(25.0)), np.sin(np.radians(25.0))
    n = 21
    rot = np.array([[-s, 0.0, c], [0.0, -1.0, 0.0], [c, 0.0, s]])
    position = np.column_stack([np.full(n, 0.8), np.linspace(-0.05, 0.05, n), np.full(n, 0.2)])
    tr = Trajectory(t=0.02 * np.arange(n), position=position, quaternion=np.tile(matrix_to_quat(rot[None])[0], (n, 1)),
                    contact=np.ones(n, bool), feed=np.full(n, 0.05), pass_index=np.zeros(n, int))
    model = get_robot("ur10e")
    cell = Cell(tcp2flange=np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0.175], [0, 0, 0, 1.0]]),
                tool=default_sander())
    sol = solve_trajectory(tr, model, cell, warn=False)
    assert sol.reachable.all()
    floor = min(_lowest_clear_floor(model, cell, q) for q in sol.q) - 0.5e-3
    cut = np.zeros(n, bool)
    cut[8:13] = True
    gap = replace(sol, reachable=~cut, q=np.where(cut[:, None], np.nan, sol.q))
    for floor_z, clear in ((None, False), (floor, True)):
        run, q, gaps, src = split_unreachable(tr, gap, model, cell, clearance=0.02, floor_z=floor_z)
        assert len(gaps) == 1 and (src < 0).sum() == 2
        assert all(_clear_of_floor(model, cell, row, floor) for row in q[src < 0]) is clear
        # the retract and the approach's start are 20 mm from the pass, the pad off the surface
        lifted = run.position[src < 0]
        ends = tr.position[[7, 13]]
        np.testing.assert_allclose(np.linalg.norm(lifted - ends, axis=1), 0.02, atol=1e-6)
        assert np.all((lifted - ends) @ rot[:, 2] < -0.018)
