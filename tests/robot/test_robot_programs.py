"""Robot programs: each format is written, parsed back by its reader and compared with the trajectory/joints."""

import itertools
import math

import numpy as np
import pytest

from swath.robot import Cell, get_robot, run_robot_stage
from swath.robot.pose import pose_error, poses_from_trajectory
from swath.robot.programs import (
    FLANGE2KUKA_FLANGE,
    ProgramInput,
    abb_confdata,
    decimate,
    kuka_status_turn,
)
from swath.robot.readers import (
    read_joint_csv,
    read_krl,
    read_rapid,
    read_ros_yaml,
    read_urscript,
)

CELLS = {"ur10e": Cell.from_text("0.55,-0.15,0,0,0,20", "0,0,120mm,0,0,0"),
         "irb4600": Cell.from_text("1.1,-0.15,0.3,0,0,0", "10mm,0,150mm,0,0,0"),
         "kr120": Cell.from_text("1.5,-0.15,0.4,0,0,-10", "0,0,150mm,0,0,0")}
#: Each maker's own program beside the joint-space files.
VENDOR = {"ur10e": "urscript", "irb4600": "rapid", "kr120": "krl"}


@pytest.fixture(scope="module")
def written(plate_trajectory, tmp_path_factory):
    out = {}
    for robot, cell in CELLS.items():
        d = tmp_path_factory.mktemp(robot.replace("/", "_"))
        res = run_robot_stage(plate_trajectory, robot=robot, cell=cell, programs=[VENDOR[robot], "ros", "csv"],
                              out_dir=d)
        out[robot] = (res, d)
    return out


def _kept(res):
    return ProgramInput(res.trajectory, res.solution, res.model, res.cell).kept()


def test_decimation_keeps_pass_ends_and_tolerance(plate_trajectory):
    tr = plate_trajectory
    idx = decimate(tr, np.ones(len(tr), bool), tol_position=1e-4)
    assert len(idx) < len(tr) / 3
    for p in np.unique(tr.pass_index[tr.pass_index >= 0]):
        members = np.flatnonzero((tr.pass_index == p) & tr.contact)
        assert members[0] in idx and members[-1] in idx
    # every dropped sample lies within 0.1 mm of the chord between its kept neighbours
    for a, b in itertools.pairwise(idx):
        if b - a < 2:
            continue
        u = tr.position[b] - tr.position[a]
        mid = tr.position[a + 1:b] - tr.position[a]
        w = np.clip(mid @ u / (u @ u), 0, 1) if u @ u > 0 else np.zeros(len(mid))
        assert np.linalg.norm(mid - w[:, None] * u, axis=1).max() <= 1e-4 + 1e-12


def test_urscript_round_trip(written, plate_trajectory):
    res, d = written["ur10e"]
    got = read_urscript(d / "swath_job.script")
    idx = _kept(res)
    np.testing.assert_allclose(got["tcp"], res.cell.tcp2flange, atol=1e-7)
    want = res.cell.part2base @ poses_from_trajectory(res.trajectory)[idx]
    dp, da = pose_error(got["tcp2base"], want)
    assert dp.max() < 1e-6 and da.max() < 1e-7
    # force_mode brackets exactly the contact samples; blend 0 at pass ends
    tr = res.trajectory
    np.testing.assert_array_equal(got["in_force"], tr.contact[idx] & (tr.pass_index[idx] >= 0))
    assert got["force"] and all(f == pytest.approx(20.0) for f in got["force"])
    np.testing.assert_allclose(got["movej"][0], res.solution.q[idx[0]], atol=1e-8)
    starts = [k for k, i in enumerate(idx) if tr.contact[i] and (i == 0 or tr.pass_index[i - 1] != tr.pass_index[i])]
    assert all(got["blend"][k] == 0 for k in starts)
    np.testing.assert_allclose(got["speed"], np.maximum(res.trajectory.feed[idx], 1e-3), rtol=1e-4, atol=1e-5)


def test_rapid_round_trip(written, plate_trajectory):
    res, d = written["irb4600"]
    got = read_rapid(d / "SwathJob.mod")
    idx = _kept(res)
    np.testing.assert_allclose(got["tool"], res.cell.tcp2flange, atol=1e-7)
    np.testing.assert_allclose(got["wobj"], res.cell.part2base, atol=1e-7)
    dp, da = pose_error(got["targets"], poses_from_trajectory(res.trajectory)[idx])
    assert dp.max() < 1e-7 and da.max() < 1e-8
    np.testing.assert_array_equal(got["conf"], abb_confdata(res.model, res.solution.q[idx]))
    # the robot reaching each robtarget with its confdata lands on the written joint values:
    # quadrants of axes 1, 4, 6 agree with them
    q = res.solution.q[idx]
    np.testing.assert_array_equal(got["conf"][:, :3], np.floor(q[:, [0, 3, 5]] / (math.pi / 2)))
    assert got["zone"][0] == "fine" and got["zone"][-1] == "fine"


def test_abb_confdata_cfx_matches_branch():
    model = get_robot("irb4600")
    q = np.radians([[10, 20, -30, 40, 50, 60], [10, 20, -30, 40, -50, 60]])
    conf = abb_confdata(model, q)
    np.testing.assert_array_equal(conf[:, :3], [[0, 0, 0], [0, 0, 0]])
    assert conf[0, 3] == 0 and conf[1, 3] == 1        # wrist centre in front of axis 1 and the lower arm; axis 5 sign


def test_krl_round_trip(written, plate_trajectory):
    res, d = written["kr120"]
    got = read_krl(d / "swath_job.src", d / "swath_job.dat")
    idx = _kept(res)
    np.testing.assert_allclose(got["base"], res.cell.part2base, atol=1e-7)
    np.testing.assert_allclose(FLANGE2KUKA_FLANGE @ got["tool"], res.cell.tcp2flange, atol=1e-7)
    dp, da = pose_error(got["targets"], poses_from_trajectory(res.trajectory)[idx])
    assert dp.max() < 1e-7 and da.max() < 1e-7
    status, turn = kuka_status_turn(res.model, res.solution.q[idx])
    np.testing.assert_array_equal(got["status"], status)
    np.testing.assert_array_equal(got["turn"], turn)
    lin = ~np.isnan(got["speed"])
    np.testing.assert_allclose(got["speed"][lin], np.maximum(res.trajectory.feed[idx][lin], 1e-3), atol=1e-5)


@pytest.mark.parametrize("robot", list(CELLS))
def test_joint_files_round_trip_through_forward_kinematics(written, plate_trajectory, robot):
    res, d = written[robot]
    csv = read_joint_csv(d / "joints.csv")
    ros = read_ros_yaml(d / "joint_trajectory.yaml")
    idx = np.flatnonzero(res.solution.reachable)
    for q in (csv["q"], ros["q"]):
        got = res.cell.tcp2part(res.model.fk(q))
        dp, da = pose_error(got, poses_from_trajectory(res.trajectory)[idx])
        assert dp.max() < 1e-8 and da.max() < 1e-8        # 0.01 µm, far inside the 0.01 mm / 0.01° asked
    np.testing.assert_allclose(csv["t"], res.trajectory.t[idx], atol=1e-9)
    np.testing.assert_allclose(ros["t"], res.trajectory.t[idx] - res.trajectory.t[idx[0]], atol=2e-9)
    # joint speeds by finite differences on the written rows stay within the limits
    for t, q in ((csv["t"], csv["q"]), (ros["t"], ros["q"])):
        v = np.abs(np.diff(q, axis=0)) / np.diff(t)[:, None]
        assert np.all(v <= res.model.max_speed * (1 + 1e-6))
    assert ros["joint_names"][0] in ("shoulder_pan_joint", "joint_1", "joint_a1")
    np.testing.assert_array_equal(csv["pass_index"], res.trajectory.pass_index[idx])
