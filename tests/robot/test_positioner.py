"""A rotary positioner in the cell: the file's [positioner] table, the axis kinematics, the wrap
planner's continuous helix, and the STEP tube with a flange finished all round in one program."""

from __future__ import annotations

import math

import numpy as np
import pytest

from swath.cell import Positioner, cell_from_mapping, default_sander
from swath.contact.tool import Tool
from swath.errors import InputError
from swath.robot.pose import poses_from_trajectory
from swath.robot.positioner import facing_angles, to_base_frame, to_part_frame

AXIS_X, AXIS_Z = 1.2, 0.7         # a horizontal axis along base y, 1.2 m in front of an IRB 4600, 0.7 m up


def _cell(**extra):
    table = {"axis_point": [f"{AXIS_X}", "-100mm", f"{AXIS_Z}"], "axis_direction": [0, 1, 0], **extra}
    return cell_from_mapping({"robot": "irb4600", "positioner": table})


# --- the cell file ---------------------------------------------------------------------------------------------
def test_cell_file_reads_the_positioner_with_units():
    cell = _cell(limits=["-2turn".replace("2turn", "720deg"), "1.5rad"], max_speed="90deg/s", max_accel="6rad/s2",
                 part2faceplate="0,0,20mm,0,0,90deg", name="IRBP")
    p = cell.positioner
    assert p.name == "IRBP"
    assert np.allclose(p.axis_point, [1.2, -0.1, 0.7])
    assert p.limits == pytest.approx((-4 * math.pi, 1.5))
    assert p.max_speed == pytest.approx(math.pi / 2)
    assert p.max_accel == pytest.approx(6.0)
    assert np.allclose(p.part2faceplate[:3, 3], [0, 0, 0.02])
    assert not cell.auto_table                 # no table assumed under a part held in the air
    assert cell.as_record()["positioner"]["max_speed_rad_per_s"] == pytest.approx(math.pi / 2)


@pytest.mark.parametrize("table, words", [
    ({"axis_point": [0, 0, 0]}, "axis_direction"),
    ({"axis_point": [0, 0], "axis_direction": [0, 0, 1]}, "three lengths"),
    ({"axis_point": [0, 0, 0], "axis_direction": [0, 0, 0]}, "non-zero direction"),
    ({"axis_point": [0, 0, 0], "axis_direction": [0, 0, 1], "limits": ["10deg", "-10deg"]}, "lower < upper"),
    ({"axis_point": [0, 0, 0], "axis_direction": [0, 0, 1], "max_speed": "-1deg/s"}, "positive"),
    ({"axis_point": [0, 0, 0], "axis_direction": [0, 0, 1], "max_accel": "fast"}, "720deg/s2"),
    ({"axis_point": [0, 0, 0], "axis_direction": [0, 0, 1], "spin": 1}, "unknown key"),
    ({"axis_point": [0, 0, 0], "axis_direction": [0, 0, 1], "part2faceplate": "1,2,3"}, "six values"),
])
def test_bad_positioner_tables_are_refused_naming_the_key(table, words):
    with pytest.raises(InputError, match=words):
        cell_from_mapping({"positioner": table})


def test_part2base_and_positioner_together_are_refused():
    with pytest.raises(InputError, match="either part2base"):
        cell_from_mapping({"part2base": "1,0,0,0,0,0", "positioner": {"axis_point": [0, 0, 0],
                                                                        "axis_direction": [0, 0, 1]}})


# --- the axis kinematics ---------------------------------------------------------------------------------------
def test_axis_turns_points_about_its_line():
    p = Positioner(axis_point=np.array([1.0, 0.5, 0.2]), axis_direction=np.array([0.0, 2.0, 0.0]))
    on_axis = np.array([0.0, 0.0, 0.3, 1.0])           # faceplate z is the axis: this point stays put
    theta = np.array([0.0, 0.7, -2.0])
    got = p.part2base(theta) @ on_axis
    assert np.allclose(got[:, :3], [1.0, 0.8, 0.2])
    off = np.array([0.1, 0.0, 0.0, 1.0])              # a point 0.1 m off the axis turns on a circle
    pts = (p.part2base(np.linspace(0, 2 * math.pi, 9)) @ off)[:, :3]
    centre = np.array([1.0, 0.5, 0.2])
    assert np.allclose(np.linalg.norm(pts - centre, axis=1), 0.1)
    assert np.allclose(pts[:, 1], 0.5)                 # in the plane normal to the axis
    # a quarter turn is right-handed about +y: x0 (base +z) goes to z × ... = +x
    x0 = p.faceplate_zero2base[:3, 0]
    assert np.allclose(x0, [0, 0, 1])
    assert np.allclose(p.faceplate2base([math.pi / 2])[0, :3, 0], [1, 0, 0])
    assert np.allclose(p.base2part(theta) @ p.part2base(theta), np.eye(4))


def test_slow_for_axis_keeps_the_axis_within_its_speed_and_acceleration():
    from swath.robot.positioner import axis_speed_accel, slow_for_axis
    from swath.trajectory import Trajectory

    # 2 s at rest, then the axis asked to turn at 3 rad/s at once, 10 ms steps; limits 2 rad/s, 5 rad/s²
    n = 600
    t = 0.01 * np.arange(n)
    theta = np.where(t < 2.0, 0.0, 3.0 * (t - 2.0))
    tr = Trajectory(t=t, position=np.zeros((n, 3)), quaternion=np.tile([1.0, 0, 0, 0], (n, 1)),
                    contact=np.ones(n, bool), feed=np.full(n, 0.05), pass_index=np.zeros(n, int))
    slow = slow_for_axis(tr, theta, 2.0, 5.0, safety=1.0)
    w, a = axis_speed_accel(slow.t, theta)
    assert w.max() == pytest.approx(2.0, rel=1e-6)       # the speed limit binds on the long stretch
    assert a.max() <= 5.0 * (1 + 1e-9)
    # from rest to 2 rad/s at 5 rad/s² takes 0.4 s and 0.4 rad, and as long to stop at the end (the job
    # ends at rest); the rest of the turn at full speed
    turn_time = slow.t[-1] - 2.0
    assert turn_time == pytest.approx(0.4 + 0.4 + (theta[-1] - 0.8) / 2.0, abs=0.02)
    assert np.all(np.diff(slow.t) >= np.diff(t) - 1e-12)   # only ever slower
    assert slow.feed.min() < 0.05 and slow.feed[:150].min() == pytest.approx(0.05)


# --- a small tube with a flange, written as STEP by the test --------------------------------------------------
LENGTH, RADIUS, WALL, FLANGE_R, FLANGE_T = 0.16, 0.025, 0.004, 0.045, 0.008


@pytest.fixture(scope="module")
def tube(tmp_path_factory):
    pytest.importorskip("OCP")
    from swath.examples import cad
    from swath.io.step import load_step

    shape = cad.tube_with_flange(length=LENGTH, radius=RADIUS, wall=WALL, flange_radius=FLANGE_R,
                                 flange_thickness=FLANGE_T)
    names = cad.tube_face_names(shape, length=LENGTH, radius=RADIUS, wall=WALL, flange_thickness=FLANGE_T)
    path = tmp_path_factory.mktemp("positioner") / "tube.step"
    cad.write_step(shape, path, names=names)
    return load_step(path)


def _faces_named(part, name):
    ids = [f.id for f in part.faces if f.name == name]
    return part.surface.sub_surface(np.flatnonzero(np.isin(part.face_ids, ids)))


@pytest.fixture(scope="module")
def helix(tube):
    from swath.plan import wrap

    cell = _cell()
    return wrap(tube.surface, Tool(), axis=cell.positioner.axis_in_part())


def test_wrap_is_one_continuous_helix_on_the_outer_cylinder(tube, helix):
    tool = Tool()
    assert len(helix.passes) == 1                       # no seam, no restart
    pts = helix.passes[0].points
    r = np.hypot(pts[:, 0], pts[:, 1])
    assert np.allclose(r, RADIUS, atol=1e-4)           # on the tube's outer skin (within the chordal tolerance)
    nrm = helix.passes[0].normals
    radial = np.column_stack([pts[:, :2] / r[:, None], np.zeros(len(r))])
    angle = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", nrm, radial), -1, 1)))
    assert angle.max() < 0.1                           # the exact faces' normals, interpolated on a facet
    step = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    assert step.max() < 1.1e-3                         # the point spacing, all round, no jump
    # the pad centre stays one pad radius from the flange top, and runs to near the open end
    assert FLANGE_T + tool.pad_radius < pts[:, 2].min() < FLANGE_T + tool.pad_radius + 2e-4
    assert LENGTH - 0.02 < pts[:, 2].max() < LENGTH
    # the angle about the axis only grows: a helix, turning n_turns times
    phi = np.unwrap(np.arctan2(pts[:, 1], pts[:, 0]))
    assert np.all(np.diff(phi) > 0)
    assert (phi[-1] - phi[0]) / (2 * math.pi) == pytest.approx(helix.metadata["n_turns"], abs=0.01)
    # pitch no larger than the spacing chosen from the contact width
    assert helix.metadata["spacing_m"] <= 2 * tool.pad_radius


def test_wrap_rings_alternate_direction(tube):
    from swath.plan import wrap

    rings = wrap(tube.surface, Tool(), axis=_cell().positioner.axis_in_part(), mode="rings", spacing=0.02)
    assert len(rings.passes) >= 2
    turn = [np.unwrap(np.arctan2(p.points[:, 1], p.points[:, 0])) for p in rings.passes]
    signs = [np.sign(t[-1] - t[0]) for t in turn]
    assert all(a == -b for a, b in zip(signs, signs[1:]))
    assert all(abs(t[-1] - t[0]) == pytest.approx(2 * math.pi, abs=0.02) for t in turn)
    z = [float(np.ptp(p.points[:, 2])) for p in rings.passes]
    assert max(z) < 1e-3                                # each ring at one station


def test_wrap_refuses_an_axis_across_the_tube(tube):
    from swath.plan import wrap

    with pytest.raises(InputError, match="no axial station"):
        wrap(tube.surface, Tool(), axis=((0, 0, 0.06), (1, 0, 0)))


def test_wrap_goes_round_a_rounded_box_like_a_handle(tmp_path):
    """A box with rounded edges (200 x 100 x 60 mm, 10 mm fillets) round its long axis: one helix, on the
    skin, normals within 60° of the direction away from the axis, the long sides all covered."""
    pytest.importorskip("OCP")
    from swath.examples import cad
    from swath.io.step import load_step
    from swath.plan import wrap
    from swath.simulate import simulate_removal
    from swath.trajectory import time_path

    part = load_step(cad.write_step(cad.rounded_box(), tmp_path / "box.step"), chordal_tolerance=2e-4)
    axis = ((0.0, 0.05, 0.03), (1.0, 0.0, 0.0))
    tp = wrap(part.surface, Tool(), axis=axis)
    assert len(tp.passes) == 1
    p, n = tp.passes[0].points, tp.passes[0].normals
    radial = p - np.array([p[:, 0] * 0, np.full(len(p), 0.05), np.full(len(p), 0.03)]).T
    radial[:, 0] = 0.0
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    assert np.einsum("ij,ij->i", n, radial).min() >= 0.5
    _, dist, _ = part.surface.closest_points(p)
    assert dist.max() < 1e-6                                   # on the tessellation
    c = part.surface.vertices[part.surface.faces].mean(axis=1)
    sides = np.flatnonzero(np.abs(part.surface.face_normals[:, 0]) < 1e-3)   # the four long sides and their fillets
    removal = simulate_removal(time_path(tp), part.surface.sub_surface(sides), Tool())
    assert removal.metrics["coverage_fraction"] >= 0.99
    assert c[sides, 0].min() < 0.02 and c[sides, 0].max() > 0.18      # the sides run the whole length


def test_facing_angles_turn_each_contact_point_to_the_robot(helix):
    from swath.trajectory import time_path

    cell = _cell()
    tr = time_path(helix)
    theta = facing_angles(tr, cell.positioner, elevation=0.0)
    base = to_base_frame(tr, cell.positioner, theta)
    on = tr.contact
    # every contact point's outward normal (minus tool z) faces the robot base (-x) in the base frame
    out = -base.tool_z()[on]
    assert np.allclose(out, [-1, 0, 0], atol=2e-3)
    # and the round trip back to the part frame gives the planned poses
    back = to_part_frame(base, cell.positioner)
    assert np.allclose(poses_from_trajectory(back), poses_from_trajectory(tr), atol=1e-12)
    lo, hi = cell.positioner.limits
    assert lo <= theta.min() and theta.max() <= hi
    # too few turns allowed: refused before any work
    tight = Positioner(axis_point=cell.positioner.axis_point, axis_direction=cell.positioner.axis_direction,
                       limits=(-math.pi, math.pi))
    with pytest.raises(InputError, match="limits allow 360 deg"):
        facing_angles(tr, tight)


def test_tube_all_round_in_one_program_with_the_positioner(tube, helix, tmp_path):
    """Must show (issue 38): the STEP tube with a flange finished all round in ONE program with the
    positioner: coverage of the outer cylinder >= 99 % on the tessellation, FK checks with the axis
    angle, no configuration change in contact, no collision with the turning part, the axis in RAPID
    and joints.csv."""
    from dataclasses import replace

    from swath.robot.positioner import check_positioner_collisions, run_positioner_stage
    from swath.simulate import simulate_removal
    from swath.trajectory import time_path

    sander = default_sander()
    cell = replace(_cell(), tool=sander, tcp2flange=sander.tcp2flange)
    tr = time_path(helix)
    res = run_positioner_stage(tr, cell=cell, robot="irb4600", programs=("rapid", "csv"), out_dir=tmp_path,
                               warn=False)
    m = res.metrics
    assert m["reachable_fraction"] == 1.0
    assert m["branch_changes_in_contact"] == 0 and m["configuration_flips_in_passes"] == 0
    assert m["n_branch_switches"] == 0
    assert m["max_fk_position_error_m"] < 1e-5 and m["max_fk_angle_error_rad"] < math.radians(0.01)
    assert m["max_contact_dt_s"] <= 0.02
    assert m["positioner_max_speed_ratio"] <= 1.0 and m["positioner_max_accel_ratio"] <= 1.0
    assert m["positioner_range_rad"] / (2 * math.pi) == pytest.approx(helix.metadata["n_turns"], abs=0.05)
    # the FK check done here independently: joints.csv rows + their axis angle against trajectory rows
    rows = np.loadtxt(tmp_path / "joints.csv", delimiter=",", skiprows=1)
    header = (tmp_path / "joints.csv").read_text().splitlines()[0].split(",")
    assert header[:8] == ["t", "q1", "q2", "q3", "q4", "q5", "q6", "positioner"]
    got = cell.positioner.base2part(rows[:, 7]) @ res.model.fk(rows[:, 1:7]) @ cell.tcp2flange
    want = poses_from_trajectory(res.trajectory)[np.flatnonzero(res.solution.reachable)]
    assert np.abs(got[:, :3, 3] - want[:, :3, 3]).max() < 1e-5
    # one program: one RAPID module, every robtarget with eax_a, one force-controlled pass
    rapid = (tmp_path / "swath_job.mod").read_text() if (tmp_path / "swath_job.mod").exists() else \
        next(tmp_path.glob("*.mod")).read_text()
    targets = [ln for ln in rapid.splitlines() if "CONST robtarget" in ln]
    assert targets and all(",9E9,9E9,9E9,9E9,9E9]];" in ln and "[9E9,9E9" not in ln for ln in targets)
    assert rapid.count("FCPress1LStart p") == 1 and rapid.count("FCPressEnd p") == 1
    # the trajectory the robot runs stays in the part frame: contact samples on the tube's skin
    on = res.trajectory.contact
    r = np.hypot(*res.trajectory.position[on, :2].T)
    assert np.abs(r - RADIUS).max() < 1e-4
    inward = -res.trajectory.position[on].copy()
    inward[:, 2] = 0.0
    inward /= np.linalg.norm(inward, axis=1, keepdims=True)
    cos = np.einsum("ij,ij->i", res.trajectory.tool_z()[on], inward)
    assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 0.5     # tool z along minus the normal
    # no collision of the arm or the tool with the turning part, the cell or itself
    report = check_positioner_collisions(res.program_view[0], res.solution, res.model, cell,
                                         part_vertices=tube.surface.vertices, part_faces=tube.surface.faces)
    assert not report.events, report.message()
    # coverage of the outer cylinder judged on the tessellation; the flange never touched
    tool = Tool()
    outer = simulate_removal(res.trajectory, _faces_named(tube, "tube_outer"), tool)
    assert outer.metrics["coverage_fraction"] >= 0.99
    flange = simulate_removal(res.trajectory, _faces_named(tube, "flange_top"), tool)
    assert flange.metrics["coverage_fraction"] == 0.0


def test_krl_carries_the_axis_in_e1(helix, tmp_path):
    from dataclasses import replace

    from swath.robot.positioner import run_positioner_stage
    from swath.trajectory import time_path

    sander = default_sander()
    cell = cell_from_mapping({"positioner": {"axis_point": ["1.3", "-100mm", "0.8"], "axis_direction": [0, 1, 0]}})
    cell = replace(cell, tool=sander, tcp2flange=sander.tcp2flange)
    res = run_positioner_stage(time_path(helix), cell=cell, robot="kr120", programs=("krl", "csv"), out_dir=tmp_path,
                               warn=False)
    dat = next(tmp_path.glob("*.dat")).read_text()
    e1 = np.array([float(ln.split("E1 ")[1].split(",")[0]) for ln in dat.splitlines() if "DECL E6POS" in ln])
    rows = np.loadtxt(tmp_path / "joints.csv", delimiter=",", skiprows=1)
    assert len(e1) == len(rows)                                 # every sample a target: nothing thinned
    assert np.allclose(e1, np.degrees(rows[:, 7]), atol=1e-5)
    assert np.ptp(e1) == pytest.approx(np.degrees(res.metrics["positioner_range_rad"]), rel=1e-9)
    src = next(tmp_path.glob("*.src")).read_text()
    assert "positioner" in src and "$BASE is the robot base" in src


def test_urscript_and_place_are_refused_with_a_positioner(helix):
    from swath.robot.positioner import run_positioner_stage
    from swath.trajectory import time_path

    tr = time_path(helix)
    with pytest.raises(InputError, match="URScript has no standard external axis"):
        run_positioner_stage(tr, cell=_cell(), robot="ur10e", programs=("urscript",))
    with pytest.raises(InputError, match="--place"):
        run_positioner_stage(tr, cell=_cell(), robot="ur10e", programs=("csv",), place=True)
