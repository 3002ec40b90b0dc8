"""Configurations, joint moves, force direction, re-timing to 20 ms, and programs a controller takes."""

import math

import numpy as np
import pytest

from swath.errors import InputError
from swath.robot import Cell, get_robot, run_robot_stage
from swath.robot.joint_moves import insert_joint_moves
from swath.robot.pose import matrix_to_quat, pose_error, poses_from_trajectory
from swath.robot.programs import (
    ProgramInput,
    abb_confdata,
    check_program_formats,
    commanded_force_angles,
    force_frame_samples,
    write_programs,
)
from swath.robot.readers import read_joint_csv, read_krl, read_rapid, read_ros_yaml, read_urscript
from swath.robot.retime import MAX_CONTACT_DT, joint_accel_ratio, joint_speed_ratio
from swath.robot.solve import JointSolution, align_turns
from swath.trajectory import Trajectory

CELLS = {"ur10e": Cell.from_text("0.55,-0.15,0,0,0,20", "0,0,120mm,0,0,0"),
         "irb4600": Cell.from_text("1.1,-0.15,0.3,0,0,0", "10mm,0,150mm,0,0,0"),
         "kr120": Cell.from_text("1.5,-0.15,0.4,0,0,-10", "0,0,150mm,0,0,0")}
VENDOR = {"ur10e": "urscript", "irb4600": "rapid", "kr120": "krl"}


#: Where the placement search (``--place``) puts the blade's first passes for each robot (150 mm TCP),
#: fixed here so the tests need not run the search.
BLADE_CELLS = {"ur10e": Cell.from_text("578.5687mm,132.6232mm,44.0028mm,0,0,0", "0,0,150mm,0,0,0"),
               "irb4600": Cell.from_text("2173.4636mm,448.2688mm,44.0028mm,0,0,112.5deg", "0,0,150mm,0,0,0")}


@pytest.fixture(scope="module")
def blade_trajectory():
    """The built-in blade's first two passes (the blade is twisted: the normal turns by up to 180°
    along a pass), planned and timed as a job does."""
    from dataclasses import replace

    from swath.cli.job import JobSettings, load_part_info, make_plan
    from swath.trajectory import time_path

    settings = JobSettings(part="example:blade", out="unused")
    surface, _ = load_part_info(settings)
    tr = time_path(make_plan(surface, settings), settings.constraints(), links=settings.links())
    end = int(np.flatnonzero(tr.pass_index == 2)[0])
    return replace(tr, t=tr.t[:end], position=tr.position[:end], quaternion=tr.quaternion[:end],
                   contact=tr.contact[:end], feed=tr.feed[:end], pass_index=tr.pass_index[:end],
                   extra={k: v[:end] for k, v in tr.extra.items()})


@pytest.fixture(scope="module")
def blade_runs(blade_trajectory, tmp_path_factory):
    out = {}
    for robot in ("ur10e", "irb4600"):
        d = tmp_path_factory.mktemp(f"blade_{robot}")
        res = run_robot_stage(blade_trajectory, robot=robot, cell=BLADE_CELLS[robot],
                              programs=[VENDOR[robot], "ros", "csv"], out_dir=d, warn=False)
        out[robot] = (res, d)
    return out


# --- whole turns ---------------------------------------------------------------------------------------------------
def test_align_turns_takes_the_way_round_that_needs_no_spin():
    """Two runs of one joint with ±360° limits: the first climbs from 40° to 352°, the second starts
    at 1° (8° further on, wrapped) and climbs to 80°.  Shifting the first run by a whole turn down
    (-320°..-8°) joins them with an 9° step; keeping it makes a 351° spin."""
    deg = np.radians
    q = np.zeros((8, 6))
    q[:4, 5] = deg([40, 150, 260, 352])
    q[4:, 5] = deg([1, 30, 60, 80])
    lo, hi = np.full(6, -2 * math.pi), np.full(6, 2 * math.pi)
    got = align_turns(q, lo, hi, np.zeros(8, bool))
    np.testing.assert_allclose(np.degrees(got[:, 5]), [-320, -210, -100, -8, 1, 30, 60, 80], atol=1e-9)
    # limits that leave no such choice: the spin stays (the run 40..352 cannot move down a turn)
    lo6 = np.full(6, -deg(100))
    got = align_turns(q, lo6, hi, np.zeros(8, bool))
    np.testing.assert_allclose(np.degrees(got[:4, 5]), [40, 150, 260, 352], atol=1e-9)
    assert np.degrees(got[4, 5]) == pytest.approx(1.0) or np.degrees(got[4, 5]) == pytest.approx(361.0)


# --- a configuration change as a joint move ----------------------------------------------------------------------
def _reconfiguration(model, cell, q_a_deg=(20.0, 10.0, 20.0, 0.0, 60.0, 30.0)):
    """A 4-sample air link: samples 0, 1 on one branch, 2, 3 on another (the same pose at 1 and 2)."""
    q_a = np.radians(q_a_deg)
    flange2base = model.fk(q_a[None])[0]
    sols = model.ik(flange2base[None])[0]
    a = int(np.argmin(np.abs(sols - q_a).max(axis=1)))
    b = next(k for k in range(8) if k != a and np.isfinite(sols[k, 0]) and (k ^ a) & 4)   # the shoulder turned over
    tcp2part = cell.tcp2part(flange2base[None])[0]
    pos = tcp2part[:3, 3] + np.array([[0, 0, 0], [0.01, 0, 0], [0.01, 0, 0], [0.02, 0, 0]])
    poses = np.repeat(tcp2part[None], 4, axis=0)
    poses[:, :3, 3] = pos
    flange = cell.flange2base(poses)
    all_q = model.ik(flange)
    q = np.array([all_q[0, a], all_q[1, a], all_q[2, b], all_q[3, b]])
    tr = Trajectory(t=np.array([0.0, 0.04, 0.08, 0.12]), position=pos, quaternion=matrix_to_quat(poses[:, :3, :3]),
                    contact=np.zeros(4, bool), feed=np.full(4, 0.25), pass_index=np.full(4, -1))
    sol = JointSolution(q=q, branch=np.array([a, a, b, b]), reachable=np.ones(4, bool),
                        joint_move=np.array([False, False, True, False]), branch_names=model.branch_names)
    return tr, sol


@pytest.mark.parametrize("robot", ["irb4600", "ur10e"])
def test_a_configuration_change_is_an_interpolated_joint_move(robot, tmp_path):
    model = get_robot(robot)
    cell = CELLS[robot]
    tr, sol = _reconfiguration(model, cell)
    tr2, sol2 = insert_joint_moves(tr, sol, model, cell)
    big = np.max(np.abs(sol.q[2] - sol.q[1]))
    assert big > 1.0                                            # the shoulder turns over: a real reconfiguration
    assert len(tr2) == 4 + math.ceil(big / math.radians(2.0)) - 1
    assert np.abs(np.diff(sol2.q[1:-1], axis=0)).max() <= math.radians(2.0) + 1e-12     # the move's own steps
    np.testing.assert_array_equal(sol2.joint_moves, [False, False] + [True] * (len(tr2) - 3) + [False])
    # every inserted row's pose is the FK of its joints (the swept arm is on the trajectory)
    dp, da = pose_error(cell.tcp2part(model.fk(sol2.q)), poses_from_trajectory(tr2))
    assert dp.max() < 1e-9 and da.max() < 1e-9
    # timed as a rest-to-rest move within the joint limits
    assert joint_speed_ratio(tr2.t[1:-1], sol2.q[1:-1], model.max_speed).max() <= 1.0
    assert joint_accel_ratio(tr2.t[1:-1], sol2.q[1:-1], model.max_accel).max() <= 1.05
    # the programs write it as a joint move to the new configuration
    data = ProgramInput(tr2, sol2, model, cell)
    fmt = VENDOR[robot]
    write_programs(data, tmp_path, [fmt])
    if fmt == "urscript":
        got = read_urscript(tmp_path / "swath_job.script")
        assert len(got["movej"]) == 2 and got["movej_after"][1] == 2        # after the two targets before it
        np.testing.assert_allclose(got["movej"][1], sol2.q[-2], atol=1e-8)
        assert "configuration change" in (tmp_path / "swath_job.script").read_text()
    else:
        got = read_rapid(tmp_path / "SwathJob.mod")
        (k_next, q_j), = got["joint_moves"]
        np.testing.assert_allclose(q_j, sol2.q[-2], atol=1e-8)
        conf = abb_confdata(model, sol2.q[[0, 1, -2, -1]])
        assert not np.array_equal(conf[1], conf[2])                # the confdata changes with the joint move
        text = (tmp_path / "SwathJob.mod").read_text()
        assert "ConfL\\On;" in text and "MoveAbsJ" in text


def test_kuka_reconfiguration_is_a_ptp_with_status_and_turn(tmp_path):
    model = get_robot("kr120")
    cell = CELLS["kr120"]
    tr, sol = _reconfiguration(model, cell, (20.0, -80.0, 100.0, 0.0, 60.0, 30.0))   # KUKA's zero: A2 -90°, A3 90°
    assert np.isfinite(sol.q).all()
    tr2, sol2 = insert_joint_moves(tr, sol, model, cell)
    write_programs(ProgramInput(tr2, sol2, model, cell), tmp_path, ["krl"])
    got = read_krl(tmp_path / "swath_job.src", tmp_path / "swath_job.dat")
    assert got["motion"] == ["PTP", "LIN", "PTP", "LIN"]
    assert got["status"][1] != got["status"][2]


# --- the stage on the blade: the promises, measured -----------------------------------------------------------------
@pytest.mark.parametrize("robot", ["ur10e", "irb4600"])
def test_blade_programs_keep_the_configuration_and_force_rules(blade_runs, robot):
    res, d = blade_runs[robot]
    tr, sol, m = res.trajectory, res.solution, res.metrics
    assert sol.reachable.all()
    same = (tr.contact[1:] & tr.contact[:-1] & (tr.pass_index[1:] == tr.pass_index[:-1]) & (tr.pass_index[1:] >= 0))
    b = sol.branch
    change = b[1:] != b[:-1]
    assert not (change & same).any() and m["branch_changes_in_contact"] == 0
    if change.any():                                # any change happens in the air, at least half the clearance up
        assert m["min_switch_clearance_m"] >= 0.01
    assert np.abs(np.diff(sol.q, axis=0))[same].max() <= 0.05
    assert np.diff(tr.t)[same].max() <= MAX_CONTACT_DT
    assert m["max_contact_dt_s"] == pytest.approx(np.diff(tr.t)[same].max())
    # FK of every written row on its pose within 0.01 mm / 0.01°
    want = poses_from_trajectory(tr)
    for rows in (read_joint_csv(d / "joints.csv"), read_ros_yaml(d / "joint_trajectory.yaml")):
        dp, da = pose_error(res.cell.tcp2part(res.model.fk(rows["q"])), want)
        assert dp.max() < 1e-5 and np.degrees(da.max()) < 0.01
    # commanded force within 5° of the pad axis (lead angle 0: minus the surface normal), although the
    # normal turns far within a pass on the blade
    ang = commanded_force_angles(ProgramInput(tr, sol, res.model, res.cell))
    on = tr.contact & (tr.pass_index >= 0)
    assert np.isfinite(ang[on]).all() and np.isnan(ang[~on]).all()
    assert np.degrees(ang[on].max()) <= 5.0
    z = tr.tool_z()
    turn = max(np.degrees(np.arccos(np.clip(z[tr.pass_index == p][0] @ z[tr.pass_index == p].T, -1, 1))).max()
               for p in np.unique(tr.pass_index[on]))
    assert turn > 30.0                              # a frame frozen at the pass start would be far off


def test_urscript_reissues_the_force_frame_along_the_pass(blade_runs):
    res, d = blade_runs["ur10e"]
    got = read_urscript(d / "swath_job.script")
    data = ProgramInput(res.trajectory, res.solution, res.model, res.cell)
    idx = data.kept()
    frame = force_frame_samples(data)
    tr = res.trajectory
    on = tr.contact[idx] & (tr.pass_index[idx] >= 0)
    np.testing.assert_array_equal(got["in_force"], on)
    # the frame in effect on the move to each contact target is the tool frame force_frame_samples names
    want = res.cell.part2base @ poses_from_trajectory(tr)[frame[idx[on]]]
    dp, da = pose_error(got["force_frame"][on], want)
    assert dp.max() < 1e-6 and da.max() < 1e-7
    assert len(got["force"]) > 3 * len(np.unique(tr.pass_index[tr.pass_index >= 0]))    # many per pass
    text = (d / "swath_job.script").read_text()
    assert "[0.005,0.005,0.1,0.0873,0.0873,0.0873]" in text        # 5 mm / 5° off the path at most


def test_ros2_yaml_starts_and_ends_at_rest(blade_runs):
    res, d = blade_runs["ur10e"]
    ros = read_ros_yaml(d / "joint_trajectory.yaml")
    assert all(set(x) == {"sec", "nanosec"} and isinstance(x["sec"], int) and 0 <= x["nanosec"] < 10 ** 9
               for x in ros["durations"])
    np.testing.assert_array_equal(ros["qd"][0], 0.0)
    np.testing.assert_array_equal(ros["qd"][-1], 0.0)
    assert ros["joint_names"][0] == "shoulder_pan_joint"
    # the first step from rest keeps the acceleration limit
    a0 = np.abs(ros["q"][1] - ros["q"][0]) * 2 / np.diff(ros["t"][:2]) ** 2
    assert np.all(a0 <= res.model.max_accel)


# --- re-timing ------------------------------------------------------------------------------------------------------
def test_contact_samples_are_at_most_20_ms_apart_after_retiming(plate_trajectory):
    """An IRB 4600 whose joints may only go at 1 % of their speed: the re-timing stretches the
    contact steps far past 20 ms, and the stage resamples them."""
    from swath.robot.retime import retime_trajectory
    from swath.robot.solve import solve_trajectory

    tr = plate_trajectory
    slow = get_robot("irb4600")
    slow = slow.with_limits(max_speed=0.01 * slow.max_speed)
    stretched, _ = retime_trajectory(tr, solve_trajectory(tr, slow, CELLS["irb4600"]), slow)
    same = tr.contact[1:] & tr.contact[:-1] & (tr.pass_index[1:] == tr.pass_index[:-1]) & (tr.pass_index[1:] >= 0)
    assert np.diff(tr.t)[same].max() <= MAX_CONTACT_DT < np.diff(stretched.t)[same].max()
    res = run_robot_stage(tr, robot=slow, cell=CELLS["irb4600"], programs=[])
    out, sol = res.trajectory, res.solution
    same = out.contact[1:] & out.contact[:-1] & (out.pass_index[1:] == out.pass_index[:-1]) & (out.pass_index[1:] >= 0)
    assert np.diff(out.t)[same].max() <= MAX_CONTACT_DT
    assert out.duration >= tr.duration
    dp, da = pose_error(res.cell.tcp2part(res.model.fk(sol.q)), poses_from_trajectory(out))
    assert dp.max() < 1e-9 and da.max() < 1e-9                  # the new rows are solved, not interpolated joints
    assert joint_speed_ratio(out.t, sol.q, res.model.max_speed).max() <= 1.0
    # the inserted contact samples stay on the plate (z = 0 plane, within 0.1 mm)
    assert np.abs(out.position[out.contact, 2]).max() < 1e-4


# --- programs a controller takes ------------------------------------------------------------------------------------
@pytest.mark.parametrize("robot,fmt,maker", [("ur10e", "rapid", "ABB"), ("ur10e", "krl", "KUKA"),
                                             ("irb4600", "urscript", "Universal Robots"), ("kr120", "rapid", "ABB"),
                                             ("irb4600", "krl", "KUKA")])
def test_vendor_programs_only_for_their_makers(robot, fmt, maker, plate_trajectory):
    with pytest.raises(InputError, match=f"cannot write {fmt} for .*only {maker} arms.*choose from"):
        check_program_formats(get_robot(robot), [fmt, "csv"])
    with pytest.raises(InputError, match=f"cannot write {fmt}"):
        run_robot_stage(plate_trajectory, robot=robot, cell=CELLS[robot], programs=[fmt])
    check_program_formats(get_robot(robot), [VENDOR[robot], "ros", "csv"])


def test_cli_refuses_rapid_for_a_ur_before_work(tmp_path, capsys):
    import time

    from swath.cli.main import main

    t0 = time.perf_counter()
    code = main(["plan", "--constant-feed", "example:plate", "--robot", "ur10e", "--program", "rapid", "--out", str(tmp_path / "o")])
    assert code != 0 and time.perf_counter() - t0 < 5.0
    assert "cannot write rapid for ur10e" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_position_only_programs_state_their_compliance_assumption(plate_trajectory, tmp_path):
    res = run_robot_stage(plate_trajectory, robot="irb4600", cell=CELLS["irb4600"], programs=["rapid"], out_dir=tmp_path,
                          force_program="position", warn=False)
    text = (tmp_path / "SwathJob.mod").read_text()
    assert "position only" in text and "compliant tool" in text and "FCPress" not in text
    assert any("position only" in w and "compliant tool" in w for w in res.warnings)
    native = run_robot_stage(plate_trajectory, robot="irb4600", cell=CELLS["irb4600"], programs=["rapid"],
                             out_dir=tmp_path / "n", warn=False)
    got = read_rapid(tmp_path / "n" / "SwathJob.mod")
    n_pass = len(np.unique(plate_trajectory.pass_index[plate_trajectory.pass_index >= 0]))
    assert got["instruction"].count("FCPress1LStart") == n_pass == got["instruction"].count("FCPressEnd")
    pressed = np.array([i.startswith("FCPress") and i != "FCPressEnd" for i in got["instruction"]])
    np.testing.assert_allclose(got["force"][pressed], 20.0)
    assert not any("position only" in w for w in native.warnings)
    with pytest.raises(InputError, match="force-program"):
        check_program_formats(get_robot("irb4600"), ["rapid"], "hybrid")


def test_krl_native_force_brackets_each_pass(plate_trajectory, tmp_path):
    res = run_robot_stage(plate_trajectory, robot="kr120", cell=CELLS["kr120"], programs=["krl"], out_dir=tmp_path)
    got = read_krl(tmp_path / "swath_job.src", tmp_path / "swath_job.dat")
    idx = ProgramInput(res.trajectory, res.solution, res.model, res.cell).kept()
    tr = res.trajectory
    on = tr.contact[idx] & (tr.pass_index[idx] >= 0)
    # every contact target is reached under force control; no air target is
    np.testing.assert_array_equal(got["force"][1:] > 0, on[1:])


def test_flange_tcp_is_warned(plate_trajectory):
    res = run_robot_stage(plate_trajectory, robot="ur10e", cell=Cell.from_text("0.55,-0.15,0.12,0,0,20"), programs=[],
                          warn=False)
    assert any("TCP is the flange" in w for w in res.warnings)
    res = run_robot_stage(plate_trajectory, robot="ur10e", cell=CELLS["ur10e"], programs=[], warn=False)
    assert not any("TCP is the flange" in w for w in res.warnings)


def test_no_needless_wrist_spin_between_passes(plate_trajectory):
    """The plate's raster turns the tool half a turn about its axis on every link; followed the
    nearest way each time, wrist 3 of a UR10e climbed past +360° on the fourth link and spun back a
    whole turn (351°) in the air.  Aligned by least joint travel, the job starts a turn lower and no
    joint moves more than the link's own rotation."""
    res = run_robot_stage(plate_trajectory, robot="ur10e", cell=CELLS["ur10e"], programs=[], warn=False)
    q, model = res.solution.q, res.model
    assert res.metrics["n_joint_moves"] == 0 and not res.solution.joint_moves.any()
    assert np.abs(np.diff(q, axis=0)).max() < math.radians(10.0)
    assert np.all(q >= model.lower) and np.all(q <= model.upper)
    assert np.ptp(q[:, 5]) > math.pi                 # the wrist does turn over the job, continuously


def test_force_frame_is_renewed_after_an_unreachable_gap(blade_trajectory):
    """The blade 0.3 m farther from a UR10e: stretches of both passes are out of reach, and the
    programs leave them out.  The pass resumes after a gap with a force frame of its own first
    sample, not the one from before the gap (on the IRB 4600 placed by the search that one was 92°
    off the normal)."""
    cell = Cell.from_text("878.5687mm,132.6232mm,44.0028mm,0,0,0", "0,0,150mm,0,0,0")
    # (unsplit: with split_gaps the robot stage lifts off at the gap and the pass resumes as a new approach)
    res = run_robot_stage(blade_trajectory, robot="ur10e", cell=cell, programs=[], warn=False, split_gaps=False)
    sol, tr = res.solution, res.trajectory
    resumes = [st.stop for st in sol.stretches
               if st.pass_index >= 0 and st.stop < len(tr) and tr.pass_index[st.stop] == st.pass_index
               and tr.contact[st.stop]]
    assert resumes                                          # a pass resumes after a gap
    frame = force_frame_samples(ProgramInput(tr, sol, res.model, res.cell))
    np.testing.assert_array_equal(frame[resumes], resumes)
    ang = commanded_force_angles(ProgramInput(tr, sol, res.model, res.cell))
    on = tr.contact & (tr.pass_index >= 0)
    assert np.isnan(ang[~sol.reachable]).all()
    assert np.isfinite(ang[on & sol.reachable]).all()
    assert np.degrees(np.nanmax(ang)) <= 5.0
