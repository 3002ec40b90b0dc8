"""URDF robots through pinocchio: a UR10e written from its DH table agrees with ur-analytic-ik."""

import math

import numpy as np
import pytest

pytest.importorskip("pinocchio")

from swath.errors import InputError  # noqa: E402
from swath.robot import Cell, flips_inside_passes, get_robot  # noqa: E402
from swath.robot.pose import pose_error  # noqa: E402
from swath.robot.urdf import urdf_robot  # noqa: E402

UR10E_D = (0.1807, 0, 0, 0.17415, 0.11985, 0.11655)
UR10E_A = (0, -0.6127, -0.57155, 0, 0, 0)
UR10E_ALPHA = (math.pi / 2, 0, 0, math.pi / 2, -math.pi / 2, 0)


def write_dh_urdf(path, d, a, alpha, *, limit=2 * math.pi, extra_finger=False):
    """A URDF whose joint i turns about z after the standard DH transform of link i-1."""
    links = ["base_link"] + [f"link{i}" for i in range(1, 7)] + ["tool0"]
    out = ['<?xml version="1.0"?>', '<robot name="dh_ur10e">']
    out += [f'  <link name="{n}"/>' for n in links]
    origins = [(0.0, 0.0, 0.0, 0.0)] + [(a[i], 0.0, d[i], alpha[i]) for i in range(6)]
    for i in range(6):
        x, y, z, roll = origins[i]
        out.append(f'  <joint name="joint{i + 1}" type="revolute"><parent link="{links[i]}"/>'
                   f'<child link="{links[i + 1]}"/><origin xyz="{x!r} {y!r} {z!r}" rpy="{roll!r} 0 0"/>'
                   f'<axis xyz="0 0 1"/><limit lower="{-limit!r}" upper="{limit!r}" effort="100" velocity="2.0"/>'
                   '</joint>')
    x, y, z, roll = origins[6]
    out.append(f'  <joint name="flange" type="fixed"><parent link="link6"/><child link="tool0"/>'
               f'<origin xyz="{x!r} {y!r} {z!r}" rpy="{roll!r} 0 0"/></joint>')
    if extra_finger:   # a joint off the base-to-tip path: locked by the loader
        out.append('  <link name="finger"/><joint name="finger_joint" type="prismatic"><parent link="tool0"/>'
                   '<child link="finger"/><axis xyz="1 0 0"/><limit lower="0" upper="0.04" effort="1" '
                   'velocity="0.1"/></joint>')
    out.append("</robot>")
    path.write_text("\n".join(out))
    return path


@pytest.fixture(scope="module")
def ur10e_urdf(tmp_path_factory):
    path = tmp_path_factory.mktemp("urdf") / "ur10e_dh.urdf"
    return write_dh_urdf(path, UR10E_D, UR10E_A, UR10E_ALPHA, extra_finger=True)


def test_urdf_fk_matches_ur_analytic_ik(ur10e_urdf):
    import ur_analytic_ik

    robot = urdf_robot(ur10e_urdf, tip="tool0")
    assert robot.kind == "numeric" and robot.chain.n_joints == 6
    np.testing.assert_allclose(robot.lower, -2 * math.pi)
    np.testing.assert_allclose(robot.max_speed, 2.0)
    qs = np.random.default_rng(7).uniform(-math.pi, math.pi, size=(200, 6))
    got = robot.fk(qs)
    want = np.array([ur_analytic_ik.ur10e.forward_kinematics(*q) for q in qs])
    assert np.max(np.abs(got[:, :3, 3] - want[:, :3, 3])) < 1e-9          # metres
    assert np.max(np.abs(got[:, :3, :3] - want[:, :3, :3])) < 1e-9
    # the stretched arm from the shoulder: |a2| + |a3| along, d4..d6 offsets across, about 1.3 m
    assert 1.25 < robot.reach < 1.40


def test_urdf_jacobian_and_wrist_measure_match_the_catalogue_ur10e(ur10e_urdf):
    robot = urdf_robot(ur10e_urdf)
    cat = get_robot("ur10e")
    qs = np.random.default_rng(3).uniform(-math.pi, math.pi, size=(20, 6))
    np.testing.assert_allclose(robot.jacobian(qs), cat.jacobian(qs), atol=1e-9)
    # sin of the angle between axes 4 and 6 is |sin q5| on a UR
    np.testing.assert_allclose(robot.singularity_measures(qs)["wrist"], np.abs(np.sin(qs[:, 4])), atol=1e-9)


def test_urdf_ik_along_a_path_stays_on_one_branch(ur10e_urdf):
    """A 10 cm line with the tool pointing down: every pose solved to 1e-9 m, small joint steps, and
    every solution is one of the analytic solver's eight (mod 2 pi), the same branch throughout."""
    import ur_analytic_ik

    robot = urdf_robot(ur10e_urdf)
    down = np.diag([1.0, -1.0, -1.0])
    poses = np.repeat(np.eye(4)[None], 41, axis=0)
    poses[:, :3, :3] = down
    poses[:, :3, 3] = np.c_[np.full(41, 0.6), np.linspace(-0.05, 0.05, 41), np.full(41, 0.2)]
    q = robot.ik(poses, seed=[0, -1.5, 1.5, -1.5, -1.5, 0])[:, 0]
    assert np.all(np.isfinite(q))
    dp, da = pose_error(robot.fk(q), poses)
    assert dp.max() < 1e-9 and da.max() < 1e-9
    assert np.max(np.abs(np.diff(q, axis=0))) < 0.05                     # rad per 2.5 mm step
    slots = []
    for qi, pose in zip(q, poses):
        sols = np.array(ur_analytic_ik.ur10e.inverse_kinematics(np.ascontiguousarray(pose)))
        d = np.abs(np.angle(np.exp(1j * (sols - qi)))).max(axis=1)
        assert d.min() < 1e-7
        slots.append(int(np.argmin(d)))
    # one analytic solution followed all along (the analytic solver orders its solutions by branch)
    assert len(set(slots)) == 1


def test_urdf_robot_runs_the_robot_stage_like_the_catalogue_model(plate_trajectory, ur10e_urdf):
    """The plate job on the URDF UR10e: every pose reached on one branch, FK on every row within 1e-9 m,
    joint steps in a pass as small as the analytic model's."""
    from swath.robot import run_robot_stage

    tr = plate_trajectory
    cell = Cell.from_text("0.55,-0.15,0,0,0,0", "0,0,120mm,0,0,0")
    urdf = run_robot_stage(tr, robot=get_robot(str(ur10e_urdf), tip="tool0"), cell=cell, programs=[])
    cat = run_robot_stage(tr, robot="ur10e", cell=cell, programs=[])
    assert urdf.solution.reachable.all() and cat.solution.reachable.all()
    assert urdf.metrics["max_fk_position_error_m"] < 1e-9
    assert urdf.metrics["max_fk_angle_error_rad"] < 1e-9

    def largest_step_in_a_pass(result):       # on the robot stage's own (re-sampled) samples
        run = result.trajectory
        same = (run.pass_index[1:] == run.pass_index[:-1]) & (run.pass_index[1:] >= 0)
        return np.abs(np.diff(result.solution.q, axis=0))[same].max()

    step_urdf, step_cat = largest_step_in_a_pass(urdf), largest_step_in_a_pass(cat)
    assert step_urdf < 0.05 and step_urdf < 2 * step_cat + 1e-3
    assert flips_inside_passes(urdf.solution, urdf.trajectory) == 0


def test_urdf_refusals(tmp_path, ur10e_urdf):
    with pytest.raises(InputError, match="no frame 'flange_x'"):
        urdf_robot(ur10e_urdf, tip="flange_x")
    with pytest.raises(InputError, match="not found"):
        urdf_robot(tmp_path / "missing.urdf")
    with pytest.raises(InputError, match="six revolute joints"):
        urdf_robot(ur10e_urdf, tip="link4")
    with pytest.raises(InputError, match="catalogue robot"):
        get_robot("ur10e", tip="tool0")
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'/>")
    with pytest.raises(InputError, match="could not read URDF"):
        urdf_robot(bad)


def test_urdf_robot_from_job_settings(ur10e_urdf):
    from swath.cli.settings import settings_from_mapping
    from swath.cli.stages import robot_options

    s = settings_from_mapping({"part": "example:plate", "out": "unused", "robot": str(ur10e_urdf), "tip": "tool0",
                               "robot_keep_out": "400mm"})
    opts = robot_options(s)
    assert opts["robot"].kind == "numeric" and opts["robot"].extra["tip"] == "tool0"
    assert opts["keep_out"] == pytest.approx(0.4)
    with pytest.raises(InputError, match="no frame 'nope'"):      # refused with the settings, before any work
        settings_from_mapping({"part": "example:plate", "out": "unused", "robot": str(ur10e_urdf), "tip": "nope"})


def test_relative_urdf_paths_are_read_from_the_job_and_cell_files_folders(tmp_path, ur10e_urdf, monkeypatch):
    """``robot = "arms/ur10e.urdf"`` in a TOML job and in a cell file names the URDF beside that file,
    wherever swath is run from; a URDF that is not there is refused naming the folder it looked in."""
    from swath.cell import read_cell_file
    from swath.cli.settings import load_job_toml
    from swath.cli.stages import robot_options

    job_dir = tmp_path / "jobs"
    (job_dir / "arms").mkdir(parents=True)
    (job_dir / "arms" / "ur10e.urdf").write_text(ur10e_urdf.read_text())
    job = job_dir / "job.toml"
    job.write_text('part = "example:plate"\nout = "out"\nrobot = "arms/ur10e.urdf"\ntip = "tool0"\n')
    cell_file = job_dir / "cell.toml"
    cell_file.write_text('robot = "arms/ur10e.urdf"\npart2base = "0.55,-0.15,0,0,0,0"\n')
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")
    s = load_job_toml(job)
    assert s.robot == str(job_dir / "arms" / "ur10e.urdf")
    model = robot_options(s)["robot"]
    assert model.kind == "numeric" and model.extra["tip"] == "tool0"
    cell = read_cell_file(cell_file)
    assert cell.robot == str(job_dir / "arms" / "ur10e.urdf")
    # a job naming only the cell file takes the cell's URDF robot
    job.write_text('part = "example:plate"\nout = "out"\ncell = "cell.toml"\n')
    opts = robot_options(load_job_toml(job))
    assert opts["robot"].kind == "numeric"
    np.testing.assert_allclose(opts["cell"].part2base[:3, 3], [0.55, -0.15, 0.0])
    # a catalogue name is no file
    job.write_text('part = "example:plate"\nout = "out"\nrobot = "ur10e"\n')
    assert load_job_toml(job).robot == "ur10e"
    cell_file.write_text('robot = "arms/missing.urdf"\n')
    with pytest.raises(InputError, match="missing.urdf not found .*cell file's folder"):
        read_cell_file(cell_file)
