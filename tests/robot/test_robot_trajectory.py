"""IK along a trajectory: one branch, switches only on links, unreachable reports, re-timing, placement."""

import math

import numpy as np
import pytest

from swath.errors import InputError, UnreachableError
from swath.robot import (
    Cell,
    Margins,
    flips_inside_passes,
    get_robot,
    parse_pose,
    run_robot_stage,
    solve_trajectory,
)
from swath.robot.retime import joint_accel_ratio, joint_speed_ratio, retime_joints
from swath.robot.solve import choose_branches


def test_parse_pose_units_and_defaults():
    t = parse_pose("800mm, 0.1, 20mm, 0, 0, 90deg")
    np.testing.assert_allclose(t[:3, 3], [0.8, 0.1, 0.02])
    np.testing.assert_allclose(t[:3, :3] @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(parse_pose("0,0,0,0,0,90")[:3, :3], t[:3, :3])       # bare angles are degrees
    np.testing.assert_allclose(parse_pose("0,0,0,0,0,1.5707963267948966rad")[:3, :3], t[:3, :3], atol=1e-15)
    with pytest.raises(InputError, match="six values"):
        parse_pose("1,2,3")
    with pytest.raises(InputError, match="unit"):
        parse_pose("1furlong,0,0,0,0,0")


@pytest.mark.parametrize("robot,base", [("ur10e", "0.55,-0.15,0,0,0,0"), ("irb4600", "1.1,-0.15,0.3,0,0,0"),
                                        ("kr120", "1.5,-0.15,0.4,0,0,0")])
def test_whole_trajectory_on_one_branch_within_limits(plate_trajectory, robot, base):
    tr = plate_trajectory
    model = get_robot(robot)
    result = run_robot_stage(tr, robot=model, cell=Cell.from_text(base, "0,0,120mm,0,0,0"), programs=[])
    sol = result.solution
    assert sol.reachable.all()
    tr_out = result.trajectory               # the re-timed samples the solution is on (resampled to <= 20 ms)
    assert flips_inside_passes(sol, tr_out) == 0
    assert len(np.unique(sol.branch)) == 1
    assert result.metrics["max_fk_position_error_m"] < 1e-9
    assert result.metrics["max_fk_angle_error_rad"] < 1e-9
    q = sol.q
    assert np.all(q >= model.lower) and np.all(q <= model.upper)
    t = result.trajectory.t
    assert joint_speed_ratio(t, q, model.max_speed).max() <= 1.0
    assert joint_accel_ratio(t, q, model.max_accel).max() <= 1.0
    assert result.trajectory.duration >= tr.duration
    # within a pass no joint jumps more than the margin allows
    same = (tr_out.pass_index[1:] == tr_out.pass_index[:-1]) & (tr_out.pass_index[1:] >= 0)
    assert np.abs(np.diff(q, axis=0))[same].max() < Margins().max_step


def test_unreachable_stretch_is_reported_with_pass_and_position(plate_trajectory):
    tr = plate_trajectory
    far = Cell.from_text("1.2,-0.15,0,0,0,0")          # plate from x = 1.2 m to 1.6 m: beyond a UR10e's 1.3 m
    sol = solve_trajectory(tr, get_robot("ur10e"), far)
    assert 0 < sol.reachable_fraction < 1
    s = sol.stretches[0]
    assert s.pass_index == tr.pass_index[s.start]
    np.testing.assert_allclose(s.position, tr.position[s.start])
    assert np.all(np.isnan(sol.q[s.start:s.stop]))
    assert "out of reach" in " ".join(x.reason for x in sol.stretches)
    with pytest.raises(UnreachableError, match="pass|link"):
        solve_trajectory(tr, get_robot("ur10e"), far, strict=True)


def test_unreachable_poses_are_one_warning_the_caller_can_keep_quiet(plate_trajectory, caplog):
    """The solution carries the sentence either way; it is logged only when asked, and the robot
    stage hands it (with what the programs do about it) to its caller as ``warnings``."""
    tr = plate_trajectory
    far = Cell.from_text("1.2,-0.15,0,0,0,0")
    with caplog.at_level("WARNING"):
        quiet = solve_trajectory(tr, get_robot("ur10e"), far, warn=False)
    assert not caplog.records
    n_bad = int((~quiet.reachable).sum())
    assert quiet.warning.startswith(f"{n_bad} of {len(tr)} poses are unreachable for ur10e")
    assert f"pass {quiet.stretches[0].pass_index}" in quiet.warning
    with caplog.at_level("WARNING"):
        loud = solve_trajectory(tr, get_robot("ur10e"), far)
    # (a CLI run earlier in this process may have installed the filter that appends the "[W-...]" code)
    assert [r.getMessage().split(" [W-")[0] for r in caplog.records] == [loud.warning]
    caplog.clear()
    with caplog.at_level("WARNING"):
        result = run_robot_stage(tr, robot="ur10e", cell=far, programs=[], warn=False)
    assert not caplog.records
    unreachable = [w for w in result.warnings if "unreachable" in w]
    assert len(unreachable) == 1
    assert quiet.warning in unreachable[0] and "split there with a retract and an approach" in unreachable[0]
    near = Cell.from_text("0.55,-0.15,0,0,0,0", "0,0,120mm,0,0,0")
    ok = run_robot_stage(tr, robot="ur10e", cell=near, programs=[])
    assert ok.solution.warning is None and not [w for w in ok.warnings if "unreachable" in w]


def test_a_cell_where_no_pose_is_reachable_is_refused_even_when_not_strict(plate_trajectory):
    """Nothing to program (the program writers used to fail on an empty pose list): the error names
    the robot, how far the nearest pose is against its reach, and what to change."""
    tr = plate_trajectory
    away = Cell.from_text("5,0,0,0,0,0")               # the plate 5 m from a UR3e's base
    with pytest.raises(UnreachableError, match=r"none of the \d+ poses is reachable for ur3e .* nearest lies "
                                               r"5\.\d\d m from the robot base, its reach is about 0\.\d\d m.*--place"):
        solve_trajectory(tr, get_robot("ur3e"), away)


def test_branch_switches_only_on_links():
    # 3 branches; pass A (samples 2..5) only on branch 0, pass B (8..11) only on branch 2
    feasible = np.zeros((12, 3), bool)
    feasible[0:7, 0] = True
    feasible[6:12, 2] = True
    segs = [(0, 2, False), (2, 6, True), (6, 8, False), (8, 12, True)]
    # the link 5 -> 8 has two candidate steps (5 -> 6 and 6 -> 7: branch 0 ends at 6, branch 2 serves
    # from 6 on); the switch goes on the one whose samples are farthest from the part
    clearance = np.array([20, 10, 0, 0, 0, 0, 10, 20, 0, 0, 0, 0]) * 1e-3
    branch = choose_branches(feasible, segs, clearance)
    np.testing.assert_array_equal(branch, [0, 0, 0, 0, 0, 0, 0, 2, 2, 2, 2, 2])
    clearance[6], clearance[7] = 20e-3, 1e-3       # now the step 5 -> 6 (min 0) vs 6 -> 7 (min 1 mm)
    np.testing.assert_array_equal(choose_branches(feasible, segs, clearance), [0, 0, 0, 0, 0, 0, 0, 2, 2, 2, 2, 2])
    clearance[5] = 30e-3                            # 5 -> 6 now 20 mm from the part: chosen
    np.testing.assert_array_equal(choose_branches(feasible, segs, clearance), [0, 0, 0, 0, 0, 0, 2, 2, 2, 2, 2, 2])


def test_retime_stretches_only_where_a_joint_is_too_fast():
    t = np.linspace(0, 1, 11)
    q = np.zeros((11, 6))
    q[:, 0] = np.linspace(0, 1.0, 11)              # 1 rad/s on joint 1
    q[6:, 0] = q[5, 0] + np.linspace(0.3, 1.5, 5)  # then 3 rad/s
    rt = retime_joints(t, q, np.full(6, 2.0), np.full(6, 1e6))
    assert joint_speed_ratio(rt.t, q, np.full(6, 2.0)).max() <= 1.0
    np.testing.assert_allclose(np.diff(rt.t)[:5], 0.1)       # slow part untouched
    np.testing.assert_allclose(np.diff(rt.t)[6:], 0.3 / 2.0 / 0.999)


def test_placement_search_finds_a_reachable_placement(plate_trajectory):
    from swath.robot import search_placement

    model = get_robot("ur10e")
    best = search_placement(plate_trajectory, model, Cell(tcp2flange=parse_pose("0,0,100mm,0,0,0")), n_xy=4,
                            yaws=(0.0, math.pi / 2), n_sample=40, n_refine=2)
    assert best.reachable_fraction == 1.0
    assert best.z == pytest.approx(-plate_trajectory.position[:, 2].min())
    assert np.hypot(best.x, best.y) < model.reach


def test_placement_search_keeps_solving_cells_until_one_reaches_every_pose():
    """bezier_dac_cad's default raster on a UR5e: the four best cells by the sampled score each
    miss a pose (one between the 150 scored ones), so the search solves further cells in score
    order, within its budget of 8 (then the tool rotations), and stops at the first that reaches
    every pose."""
    from conftest import SHARED_MESH_UNITS, shared_mesh
    from swath.cli.job import make_plan
    from swath.cli.settings import settings_from_mapping
    from swath.io.mesh import load_mesh
    from swath.robot import search_placement
    from swath.trajectory import time_path

    name = "bezier_dac_cad.ply"
    surface = load_mesh(shared_mesh(name), units=SHARED_MESH_UNITS[name])
    settings = settings_from_mapping({"part": name, "out": "unused"})
    trajectory = time_path(make_plan(surface, settings), settings.constraints(), links=settings.links())
    model = get_robot("ur5e")
    first_four = search_placement(trajectory, model, n_refine=4, max_refine=4, tool_rotations=(0.0,))
    assert first_four.solved == 4 and 0.999 < first_four.reachable_fraction < 1.0
    best = search_placement(trajectory, model, n_refine=4)
    assert best.reachable_fraction == 1.0
    assert 4 < best.solved <= 8 + 3
    assert best.as_record()["placements_solved"] == best.solved


def test_a_configuration_flip_inside_a_pass_is_a_warning():
    from swath.robot.solve import JointSolution
    from swath.robot.stage import robot_warnings

    clean = JointSolution(q=np.zeros((3, 6)), branch=np.zeros(3, int), reachable=np.ones(3, bool))
    assert robot_warnings(clean, {"configuration_flips_in_passes": 0, "robot": "ur10e"}) == []
    (w,) = robot_warnings(clean, {"configuration_flips_in_passes": 2, "robot": "ur10e"})
    assert w.startswith("robot: the arm changes configuration 2 time(s) inside a contact pass (ur10e)")


def test_placement_trials_do_not_warn(plate_trajectory, caplog, monkeypatch):
    """The search solves its best few cells on the whole trajectory; cells it does not choose
    may leave poses unreachable, and those are not the user's concern (they were logged as
    warnings, one per trial, before the job's own)."""
    import swath.robot.placement as placement

    trials = []
    real = placement.solve_trajectory

    def spy(*args, **kwargs):
        sol = real(*args, **kwargs)
        trials.append(sol)
        return sol

    monkeypatch.setattr(placement, "solve_trajectory", spy)
    with caplog.at_level("WARNING"):
        best = placement.search_placement(plate_trajectory, get_robot("ur3e"), Cell(), n_xy=4,
                                          yaws=(0.0, math.pi / 2), n_sample=40, n_refine=4, keep_out=0.2,
                                          max_refine=6)
    assert any(t.warning for t in trials)              # some trial cell missed poses ...
    assert not [r for r in caplog.records if r.levelname == "WARNING"]     # ... and said nothing
    assert best.reachable_fraction == max(t.reachable_fraction for t in trials)


def test_singularity_margin_rejects_a_straight_wrist():
    from swath.robot.solve import branch_table

    model = get_robot("irb4600")
    q = np.radians([[10, 20, -10, 30, 2.0, 40], [10, 20, -10, 30, 30.0, 40]])   # wrist at 2° and 30°
    qs, feasible, reason = branch_table(model.fk(q), model, same_pass=np.zeros(2, bool))
    slot = np.argmin(np.abs(qs[0] - q[0]).max(axis=1))
    assert not feasible[0, slot] and reason[0, slot] == 3
    assert feasible[1, slot]
    m = model.singularity_measures(q)
    np.testing.assert_allclose(m["wrist"], np.abs(np.sin(np.radians([2.0, 30.0]))))


def test_robot_options_from_cli_text():
    from swath.robot import robot_options_from_mapping

    opts = robot_options_from_mapping({"robot": "irb4600", "base": "1200mm,0,300mm,0,0,90deg", "tcp": "0,0,0.15,0,0,0",
                                       "program": "rapid, csv", "place": "auto", "table-z": "700mm"})
    assert opts["robot"] == "irb4600" and opts["programs"] == ["rapid", "csv"] and opts["place"] is True
    assert opts["table_z"] == pytest.approx(0.7)
    np.testing.assert_allclose(opts["cell"].part2base[:3, 3], [1.2, 0, 0.3])
    np.testing.assert_allclose(opts["cell"].tcp2flange[:3, 3], [0, 0, 0.15])
    with pytest.raises(InputError, match="unknown robot setting"):
        robot_options_from_mapping({"robto": "ur5e"})
    with pytest.raises(InputError, match="auto"):
        robot_options_from_mapping({"place": "yes"})
