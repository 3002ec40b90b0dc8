"""The arm kept out of the part: the capsule test, the branch choice and the placement search."""

import math

import numpy as np
import pytest

from swath.robot import get_robot
from swath.robot.arm_part import ArmPartCheck
from swath.robot.collision import link_bodies
from swath.robot.solve import Margins, branch_table


def _square(centre, half: float = 0.05):
    """A horizontal square plate of side 2·half (m) centred on ``centre`` (3,), as 2 triangles."""
    c = np.asarray(centre, dtype=float)
    v = c + np.array([[-half, -half, 0], [half, -half, 0], [half, half, 0], [-half, half, 0.0]])
    return v, np.array([[0, 1, 2], [0, 2, 3]])


def _capsule_axis(model, q, link_name):
    """Centre and axis (3,) of a link capsule at ``q``, base frame."""
    mb = next(m for m in link_bodies(model) if m.body.name == link_name)
    t = model.chain.frames(q[None])[0, mb.link] @ mb.body.body2frame
    return t[:3, 3], t[:3, 2], mb.body.shape


def test_a_plate_through_the_forearm_is_a_hit_and_one_away_from_it_is_not():
    model = get_robot("ur10e")
    q = np.array([0.0, -1.2, 1.4, -1.8, -1.57, 0.0])
    centre, axis, cap = _capsule_axis(model, q, "robot link 3")
    check = ArmPartCheck(model, *_square(centre), spacing=0.01)
    assert check.hits(q[None], np.eye(4)).tolist() == [True]
    # moved off the axis by the capsule radius + 20 mm, across the axis: clear
    off = np.cross(axis, [0, 0, 1.0]) if abs(axis[2]) < 0.9 else np.array([1.0, 0, 0])
    off /= np.linalg.norm(off)
    far = ArmPartCheck(model, *_square(centre + (cap.radius + 0.03 + 0.05 * math.sqrt(2)) * off, half=0.05),
                       spacing=0.01)
    assert far.hits(q[None], np.eye(4)).tolist() == [False]
    # the part's placement counts: the same plate in the part frame, shifted back by part2base
    part2base = np.eye(4)
    part2base[:3, 3] = [0.3, -0.2, 0.1]
    placed = ArmPartCheck(model, *_square(centre - part2base[:3, 3]), spacing=0.01)
    assert placed.hits(q[None], part2base).tolist() == [True]
    assert placed.hits(q[None], np.eye(4)).tolist() == [False]


def test_a_branch_that_puts_the_arm_in_the_part_is_not_feasible():
    """Two branches reach the same flange pose; a plate on one's elbow makes only that one infeasible
    (reason 6), the other stays feasible."""
    model = get_robot("ur10e")
    q_up = np.array([0.3, -1.3, 1.5, -1.8, -1.57, 0.2])
    flange = model.fk(q_up[None])
    q_all, feas, _ = branch_table(flange, model, Margins())
    ok = np.flatnonzero(feas[0])
    assert len(ok) >= 2
    which = int(np.argmin(np.abs(q_all[0, ok] - q_up).max(axis=1)))
    mine = ok[which]
    centre, _, _ = _capsule_axis(model, q_all[0, mine], "robot link 3")
    check = ArmPartCheck(model, *_square(centre, half=0.02), spacing=0.005)
    others = [b for b in ok if b != mine and not check.hits(q_all[0, b][None], np.eye(4))[0]]
    assert others, "the planted plate should leave another branch clear"
    _, feas2, reason2 = branch_table(flange, model, Margins(arm_part=check))
    assert not feas2[0, mine] and reason2[0, mine] == 6
    assert all(feas2[0, b] for b in others)


def _two_strokes():
    """Two 50 mm strokes on the plate (z = 0, tool z down) joined by an air link only 5 mm up."""
    from swath.trajectory import Trajectory

    x = np.r_[np.linspace(0.10, 0.15, 11), 0.15, 0.16, np.linspace(0.16, 0.21, 11)]
    z = np.r_[np.zeros(11), 0.005, 0.005, np.zeros(11)]
    n = len(x)
    pass_index = np.r_[np.zeros(11), -1, -1, np.ones(11)].astype(int)
    return Trajectory(t=np.arange(n) * 0.1, position=np.column_stack([x, np.full(n, 0.15), z]),
                      quaternion=np.tile([0.0, 1.0, 0.0, 0.0], (n, 1)), contact=z == 0, feed=np.full(n, 0.05),
                      pass_index=pass_index)


def test_an_air_link_through_a_fixture_is_taken_over_it():
    """A 14 x 20 x 4 mm block planted on the 5 mm air link between two strokes (its bottom 3 mm above
    the plate): as planned the TCP runs through it; the robot stage turns the link into a gap (retract,
    joint move, approach at the 20 mm clearance), keeps every contact sample, and the job's collision
    check finds nothing."""
    from swath.cell import Body, Box, default_sander
    from swath.examples import example_part
    from swath.robot import Cell, run_robot_stage, solve_trajectory
    from swath.robot.collision import check_job_collisions
    from swath.robot.sweep import SweepCheck

    plate = example_part("plate")
    tool = default_sander()
    part2base = Cell.from_text("0.55,-0.15,0,0,0,20").part2base
    block_part = np.eye(4)
    block_part[:3, 3] = [0.155, 0.15, 0.005]
    block = Body("fixture block", Box((0.014, 0.02, 0.004)), part2base @ block_part)
    cell = Cell(part2base=part2base, tcp2flange=tool.tcp2flange, fixtures=(block,))
    model = get_robot("ur10e")
    tr = _two_strokes()
    sol = solve_trajectory(tr, model, cell, warn=False)
    assert sol.reachable.all()
    check = SweepCheck(model, cell, plate.vertices, plate.faces)
    planned = check.scene.check(model.chain.frames(sol.q))
    real = planned.pose[np.array(planned.body_b) != "table"]         # the TCP grazing the table top is allowed
    assert "fixture block" in set(planned.body_b) and set(real.tolist()) == {11, 12}
    res = run_robot_stage(tr, robot=model, cell=cell, surface=plate, clearance=0.02, warn=False)
    m = res.metrics
    assert m["n_air_collision_gaps"] == 1 and m["n_gaps"] == 1
    assert m["gaps"][0]["pass"] == -1 and m["gaps"][0]["contact_length_m"] == 0.0
    rt = res.trajectory
    both = rt.contact[1:] & rt.contact[:-1] & (rt.pass_index[1:] == rt.pass_index[:-1])
    run = np.linalg.norm(np.diff(rt.position, axis=0), axis=1)[both].sum()
    assert run == pytest.approx(0.10, abs=1e-6)                     # both 50 mm strokes still run
    rep = check_job_collisions(res.trajectory, res.solution, res.model, res.cell, part_vertices=plate.vertices,
                               part_faces=plate.faces)
    assert len(rep.events) == 0
    # the air rows that replace the link are at least the clearance above the plate (z = 0) at their ends
    air = ~res.trajectory.contact
    assert res.trajectory.position[air, 2].max() >= 0.02 - 1e-6


def test_a_change_where_the_old_configuration_cannot_retract_moves_into_a_gap():
    """A wrist flip planted right where the pad leaves the first stroke, on a UR10e whose joint 4 may
    not rise more than 0.06 rad above its value at the stroke's end (retracting 50 mm turns it by about
    0.077 rad): the stroke's last samples, from which the old configuration cannot rise, are given up
    back to the first one it can rise from; the change then happens in the gap's joint move, at least
    the 20 mm clearance from the plate over its whole sweep."""
    from dataclasses import replace

    from swath.cell import default_sander
    from swath.examples import example_part
    from swath.robot import Cell, solve_trajectory
    from swath.robot.gaps import _retracts, air_splits, solution_after_split, split_unreachable
    from swath.robot.pose import poses_from_trajectory
    from swath.robot.sweep import SweepCheck, clear_joint_moves

    plate = example_part("plate")
    tool = default_sander()
    cell = Cell(part2base=Cell.from_text("0.55,-0.15,0,0,0,20").part2base, tcp2flange=tool.tcp2flange, tool=tool)
    tr = _two_strokes()
    sol = solve_trajectory(tr, get_robot("ur10e"), cell, warn=False)
    upper = get_robot("ur10e").upper.copy()
    upper[3] = sol.q[10, 3] + 0.06
    model = replace(get_robot("ur10e"), upper=upper)
    q_all, feasible, _ = branch_table(cell.flange2base(poses_from_trajectory(tr)), model)
    b0 = int(sol.branch[0])
    b1 = b0 ^ 1                                        # the same shoulder and elbow, the other wrist
    assert feasible[11:, b1].all()
    q, branch = sol.q.copy(), sol.branch.copy()
    q[11:], branch[11:] = q_all[11:, b1], b1
    jm = np.zeros(len(tr), bool)
    jm[11] = True
    planted = replace(sol, q=q, branch=branch, joint_move=jm)
    check = SweepCheck(model, cell, plate.vertices, plate.faces)
    drop, low, air = air_splits(tr, planted, model, cell, check, clearance=0.02)
    assert (low, air) == (1, 0)
    gone = np.flatnonzero(drop)
    poses = poses_from_trajectory(tr)
    assert gone.max() == 10 and 0 < gone.min() < 10 and np.all(np.diff(gone) == 1)
    assert all(not _retracts(model, cell, poses[i], q[i], 0.02) for i in gone)
    assert _retracts(model, cell, poses[gone.min() - 1], q[gone.min() - 1], 0.02)
    cut = replace(planted, reachable=~drop, q=np.where(drop[:, None], np.nan, q), branch=np.where(drop, -1, branch))
    tr2, q2, gaps, src = split_unreachable(tr, cut, model, cell, clearance=0.02)
    assert len(gaps) == 1 and gaps[0].pass_index == 0 and gaps[0].contact_length > 0
    sol2 = solution_after_split(cut, tr2, q2, src, model)
    _, _, sweeps = clear_joint_moves(tr2, sol2, model, cell, check, clearance=0.02)
    changes = [s for s in sweeps if s.branch_change]
    assert len(changes) == 1 and changes[0].ok and changes[0].final.min_distance >= 0.02


@pytest.mark.parametrize("robot", ["ur10e", "irb4600"])
def test_the_raised_via_point_lifts_the_wrist_above_both_ends(robot):
    """The via-point a shoulder or elbow change may pass through: joints 1, 4 and 6 half-way, the wrist
    centre higher than at either end of the move, clear of the elbow singularity, inside the limits,
    and a configuration the inverse kinematics gives back (its branch slot is the one written)."""
    from swath.robot import Cell
    from swath.robot.sweep import _raised_via

    model = get_robot(robot)
    rng = np.random.default_rng(3)
    cell = Cell()
    done = 0
    for _ in range(20):
        q0, q1 = rng.uniform(0.6 * model.lower, 0.6 * model.upper, size=(2, 6))
        got = _raised_via(model, cell, q0, q1)
        if got is None:
            continue
        (q, slot), = got[0]
        assert np.allclose(q[[0, 3, 5]], 0.5 * (q0 + q1)[[0, 3, 5]], atol=1e-6)
        z = model.chain.frames(np.array([q0, q1, q]))[:, 4, 2, 3]
        bent = model.singularity_measures(np.array([q0, q1]))["elbow"] >= 0.3
        # within the 50 mm band and the 5° grid's step (under 0.07 m at these reaches) of the highest
        assert z[2] > max([z[k] for k in (0, 1) if bent[k]], default=-np.inf) - 0.12
        assert z[2] > 0.5 * model.reach
        assert model.singularity_measures(q[None])["elbow"][0] >= 0.3
        assert np.all(q >= model.lower) and np.all(q <= model.upper)
        back = model.ik(model.fk(q[None]))[0, slot]
        assert np.allclose(np.cos(back), np.cos(q), atol=1e-6) and np.allclose(np.sin(back), np.sin(q), atol=1e-6)
        done += 1
    assert done >= 15
