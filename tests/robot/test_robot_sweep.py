"""Joint moves checked along their sweep: a configuration change lifted to the clearance, a gap
crossing taken over a wall through a via-point, and a wall no lift clears routed around."""

import math
from dataclasses import replace

import numpy as np
import pytest

from swath.cell import Body, Box, default_sander
from swath.examples import example_part
from swath.robot import Cell, get_robot, run_robot_stage, solve_trajectory
from swath.robot.collision import check_job_collisions
from swath.robot.joint_moves import insert_joint_moves
from swath.robot.pose import pose_error, poses_from_trajectory
from swath.robot.readers import read_urscript
from swath.robot.solve import branch_table
from swath.robot.sweep import SweepCheck, clear_joint_moves
from swath.trajectory import Trajectory

TWO_DEG = math.radians(2.0)


@pytest.fixture(scope="module")
def plate():
    return example_part("plate")


def _two_strokes():
    """Two 50 mm strokes on the plate (z = 0, tool z down) joined by an air link only 5 mm up."""
    x = np.r_[np.linspace(0.10, 0.15, 11), 0.15, 0.16, np.linspace(0.16, 0.21, 11)]
    z = np.r_[np.zeros(11), 0.005, 0.005, np.zeros(11)]
    n = len(x)
    contact = z == 0
    pass_index = np.r_[np.zeros(11), -1, -1, np.ones(11)].astype(int)
    return Trajectory(t=np.arange(n) * 0.1, position=np.column_stack([x, np.full(n, 0.15), z]),
                      quaternion=np.tile([0.0, 1.0, 0.0, 0.0], (n, 1)), contact=contact, feed=np.full(n, 0.05),
                      pass_index=pass_index)


def test_a_low_configuration_change_is_lifted_to_the_clearance(plate):
    """A wrist flip planted on the 5 mm air link of two strokes (UR10e, 3-inch sander): as planned its
    sweep drives the TCP through the plate; lifted, every swept TCP and flange position stays at
    least the 20 mm clearance above the plate (z, the plate being the plane z = 0), the change is a
    joint move, and every added row is FK of its joints."""
    tool = default_sander()
    cell = Cell(part2base=Cell.from_text("0.55,-0.15,0,0,0,20").part2base, tcp2flange=tool.tcp2flange, tool=tool)
    model = get_robot("ur10e")
    tr = _two_strokes()
    sol = solve_trajectory(tr, model, cell, warn=False)
    assert sol.reachable.all() and len(set(sol.branch)) == 1
    q_all, feasible, _ = branch_table(cell.flange2base(poses_from_trajectory(tr)), model)
    b0 = int(sol.branch[0])
    b1 = b0 ^ 1                                       # the same shoulder and elbow, the other wrist
    assert feasible[12:, b1].all()
    q = sol.q.copy()
    q[12:] = q_all[12:, b1]
    branch = sol.branch.copy()
    branch[12:] = b1
    jm = np.zeros(len(tr), bool)
    jm[12] = True
    planted = replace(sol, q=q, branch=branch, joint_move=jm)
    check = SweepCheck(model, cell, plate.vertices, plate.faces)
    tr2, sol2, sweeps = clear_joint_moves(tr, planted, model, cell, check, clearance=0.02)
    assert len(sweeps) == 1
    s = sweeps[0]
    assert s.branch_change and s.required_m == 0.02
    assert s.planned.min_distance < 0.005                 # as planted: low
    assert s.ok and s.lift_m > 0 and s.final.min_distance >= 0.02 and not s.final.hits
    assert s.after_pass == 0 and s.pass_after == 1
    # the added rows are consistent: FK of their joints is their pose
    dp, da = pose_error(cell.tcp2part(model.fk(sol2.q)), poses_from_trajectory(tr2))
    assert dp.max() < 1e-9 and da.max() < 1e-9
    assert np.all(np.diff(tr2.t) > 0)
    # the swept path as the controller drives it (joint moves interpolated ≤ 2°): the branch changes
    # on a joint move, and every swept TCP and flange position is at least the clearance above z = 0
    tr3, sol3 = insert_joint_moves(tr2, sol2, model, cell)
    moving = sol3.joint_moves
    change = np.flatnonzero(np.diff(sol3.branch)) + 1
    assert len(change) == 1 and moving[change[0]]
    swept = moving | np.r_[moving[1:], False]           # each joint-move row and the row it leaves from
    tcp = cell.tcp2part(model.fk(sol3.q[swept]))[:, :3, 3]
    flange = (cell.base2part @ model.fk(sol3.q[swept]))[:, :3, 3]
    assert tcp[:, 2].min() >= 0.02 - 1e-9 and flange[:, 2].min() >= 0.02
    assert np.abs(np.diff(sol3.q[swept], axis=0)).max() <= TWO_DEG + 1e-9


def _wall_cell(height: float) -> Cell:
    """The far plate's cell (the plate's far end out of a UR10e's reach) with a 10 mm wall
    ``height`` tall standing on the plate between the passes at y = 5 mm and y = 100 mm, across
    x = 255–355 mm (part frame), where the joint move across the unreachable end runs."""
    wall = np.eye(4)
    wall[:3, 3] = [1.305, -0.075, height / 2]           # base frame: the part is at (1.0, -0.15, 0)
    return replace(Cell.from_text("1.0,-0.15,0,0,0,0", "0,0,150mm,0,0,0"),
                   fixtures=(Body("fixture wall", Box((0.1, 0.01, height)), wall),))


def _inside_wall(p_part, height: float, margin: float = 0.0):
    lo = np.array([0.255, 0.07, 0.0]) - margin
    hi = np.array([0.355, 0.08, height]) + margin
    return np.all((p_part >= lo) & (p_part <= hi), axis=1)


def test_a_gap_crossing_through_a_wall_goes_over_it_by_a_via_point(plate_trajectory, plate, tmp_path):
    """The joint move across the unreachable end between passes 1 and 2 sweeps the TCP through a
    40 mm wall; the robot stage adds a raised via-point, the job's collision check then finds
    nothing, no swept TCP position lies in the wall, and the URScript's movej targets are exactly the
    joint-move targets checked (the via-point among them)."""
    height = 0.04
    cell = _wall_cell(height)
    r = run_robot_stage(plate_trajectory, robot="ur10e", cell=cell, programs=["urscript"], out_dir=tmp_path,
                        warn=False, surface=plate)
    moves = {s["after_pass"]: s for s in r.metrics["joint_move_sweeps"]}
    wall = moves[1]
    assert ["tool centre point", "fixture wall"] in wall["planned_collisions"]        # as planned: through it
    assert wall["ok"] and wall["vias"] >= 1 and wall["collisions"] == []
    assert r.metrics["n_lifted_joint_moves"] >= 1 and r.metrics["n_joint_moves_not_clear"] == 0
    rep = check_job_collisions(r.trajectory, r.solution, r.model, r.cell, part_vertices=plate.vertices,
                               part_faces=plate.faces)
    assert rep.events == []
    sol = r.solution
    tcp = r.cell.tcp2part(r.model.fk(sol.q))[:, :3, 3]
    assert not _inside_wall(tcp, height).any()
    jm, via = sol.joint_moves, sol.vias
    assert via.sum() == wall["vias"]
    nxt = np.r_[jm[1:], False]
    targets = np.flatnonzero(jm & (~nxt | via))
    written = read_urscript(tmp_path / "swath_job.script")["movej"]
    np.testing.assert_allclose(np.array(written[1:]), sol.q[targets], atol=1e-7)


def test_a_wall_no_lift_clears_is_routed_around(plate_trajectory, plate):
    """A 400 mm wall: no lift of up to 200 mm nor a raised via-point clears the TCP over it; the move
    after pass 1 is routed through via-points found in joint space and the job's collision check finds
    the TCP nowhere in the wall.  The wall is tall enough to reach the wrist in pass 0 itself, which
    no joint move can change: the check still names those hits (the job refuses them)."""
    cell = _wall_cell(0.4)
    r = run_robot_stage(plate_trajectory, robot="ur10e", cell=cell, programs=[], warn=False, surface=plate)
    rec = next(s for s in r.metrics["joint_move_sweeps"] if s["after_pass"] == 1)
    assert ["tool centre point", "fixture wall"] in rec["planned_collisions"]
    assert rec["ok"] and "routed" in rec["lift_direction"] and rec["vias"] >= 1 and rec["collisions"] == []
    rep = check_job_collisions(r.trajectory, r.solution, r.model, r.cell, part_vertices=plate.vertices,
                               part_faces=plate.faces)
    assert not [e for e in rep.events if e.body_a == "tool centre point"]
    wrist = [e for e in rep.events if e.body_a in ("robot link 5", "robot link 6") and e.body_b == "fixture wall"]
    assert wrist and wrist[0].where() == "pass 0" and wrist[0].contact


@pytest.mark.parametrize("robot", ["ur10e", "irb4600"])
def test_the_arm_below_the_table_top_is_what_coal_finds_in_a_deep_table(robot):
    """``arm_below`` (the floor of :class:`Margins`) agrees with coal on 400 seeded random
    configurations: the link capsules dip below a table top at 0.1 m exactly where they touch a
    table 4 m deep and 8 m wide (so below the top is inside it); the base column is not counted."""
    from swath.cell import Cell, Table
    from swath.robot.collision import job_scene
    from swath.robot.solve import arm_below

    model = get_robot(robot)
    rng = np.random.default_rng(7)
    q = rng.uniform(np.maximum(model.lower, -math.pi), np.minimum(model.upper, math.pi), size=(400, 6))
    table = Table(top_z=0.1, size_xy=(8.0, 8.0), thickness=4.0)
    scene, _ = job_scene(model, Cell(table=table, auto_table=False))
    hits = scene.check(model.chain.frames(q))
    touching = np.zeros(len(q), bool)
    touching[[p for p, b in zip(hits.pose, hits.body_b) if b == "table"]] = True
    below = arm_below(model, q, 0.1)
    assert 0.2 < below.mean() < 0.9                       # both kinds are among the samples
    np.testing.assert_array_equal(below, touching)


def test_a_change_forced_at_a_pass_end_moves_to_the_link_before_the_pass():
    """Branch 0 serves everything up to the end of the first pass and nothing after; branch 1 serves
    from sample 2 on.  The change cannot wait for the link after the pass (the pad would leave the
    part on a change), so it is put on the link before the pass, at its highest sample."""
    from swath.robot.solve import choose_branches

    n = 20
    segs = [(0, 5, False), (5, 10, True), (10, 15, False), (15, 20, True)]
    feasible = np.zeros((n, 2), bool)
    feasible[:10, 0] = True
    feasible[2:, 1] = True
    clearance = np.r_[[0.02, 0.03, 0.05, 0.04, 0.01], np.zeros(5), np.full(5, 0.02), np.zeros(5)]
    branch = choose_branches(feasible, segs, clearance)
    # the step 2 -> 3 has both samples highest (0.05, 0.04) among the steps inside the link
    np.testing.assert_array_equal(branch, np.r_[[0, 0, 0], np.ones(17, int)])
    # without distances the change stays where the old branch stops
    np.testing.assert_array_equal(choose_branches(feasible, segs), np.r_[np.zeros(10, int), np.ones(10, int)])
