"""Collision checking of a solved job: planted collisions found with their pass and time, a clean
cell passing, the job refusing (exit 2) unless --allow-collisions."""

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from swath.cell import Body, Box, Cell, Table, default_sander, format_pose, parse_pose
from swath.robot import get_robot, run_robot_stage
from swath.robot.collision import check_job_collisions, interpolate_joints, link_bodies

PART2BASE = "0.55,-0.15,0,0,0,20"
SPINDLE = (0.035, 0.030, 0.125)        # radius, lowest and highest height above the TCP (m)


@pytest.fixture(scope="module")
def plate():
    from swath.examples import example_part

    return example_part("plate")


@pytest.fixture(scope="module")
def solved(plate_trajectory):
    tool = default_sander()
    cell = replace(Cell.from_text(PART2BASE), tool=tool, tcp2flange=tool.tcp2flange)
    res = run_robot_stage(plate_trajectory, robot="ur10e", cell=cell, warn=False)
    assert res.solution.reachable.all()
    # the plate is flat: every sample's tool z is minus the part's z, so the tool body stands
    # straight up from the TCP and the expected collisions follow from the TCP positions alone
    from swath.robot.pose import poses_from_trajectory

    z_tool = poses_from_trajectory(res.trajectory)[:, :3, 2]
    np.testing.assert_allclose(z_tool, np.tile([0, 0, -1.0], (len(z_tool), 1)), atol=1e-9)
    return res


def _with_fixture(res, name, size, centre_part):
    body2part = np.eye(4)
    body2part[:3, 3] = centre_part
    return replace(res.cell, fixtures=(Body(f"fixture {name}", Box(size), res.cell.part2base @ body2part),))


def _cylinder_touches_box(tcp, part, size, centre, radius, z_lo, z_hi):
    """A vertical cylinder (axis through ``tcp`` xy, heights tcp z + [z_lo, z_hi]) against an
    axis-aligned box: whether they overlap (analytic)."""
    half = np.asarray(size) / 2
    lo, hi = np.asarray(centre) - half, np.asarray(centre) + half
    z_ok = (tcp[:, 2] + z_lo < hi[2]) & (tcp[:, 2] + z_hi > lo[2])
    dxy = np.linalg.norm(np.maximum(np.maximum(lo[:2] - tcp[:, :2], tcp[:, :2] - hi[:2]), 0.0), axis=1)
    return z_ok & (dxy < radius)


def test_interpolated_joint_steps_stay_under_two_degrees():
    q = np.array([[0, 0, 0, 0, 0, 0], [0.5, 0, 0, 0, 0, 0], [0.5, 0.01, 0, 0, 0, -0.2]])
    fine, src = interpolate_joints(q)
    assert np.abs(np.diff(fine, axis=0)).max() <= math.radians(2) + 1e-12
    np.testing.assert_allclose(fine[[0, -1]], q[[0, -1]])
    assert len(fine) == math.ceil(0.5 / math.radians(2)) + math.ceil(0.2 / math.radians(2)) + 1
    assert np.all(np.diff(src) > 0) and src[-1] == 2


def test_link_capsules_follow_the_kinematic_chain():
    """UR10e: the upper arm and forearm capsules are as long as the DH a2, a3 (612.7, 571.55 mm) and
    their ends sit on the joint frames' origins at any pose."""
    model = get_robot("ur10e")
    links = link_bodies(model)
    lengths = {b.body.name: b.body.shape.length for b in links}
    assert lengths["robot link 2"] == pytest.approx(0.6127) and lengths["robot link 3"] == pytest.approx(0.57155)
    q = np.array([[0.3, -1.1, 1.4, -0.8, 1.2, 0.4]])
    frames = model.chain.frames(q)[0]
    for b in links:
        end = frames[b.link] @ b.body.body2frame @ [0, 0, b.body.shape.length / 2, 1]
        np.testing.assert_allclose(end[:3], frames[b.link + 1][:3, 3], atol=1e-12)


def test_a_clean_cell_passes(solved, plate):
    rep = check_job_collisions(solved.trajectory, solved.solution, solved.model, solved.cell,
                               part_vertices=plate.vertices, part_faces=plate.faces)
    assert rep.events == []
    assert rep.cell.table is not None and rep.cell.table.assumed and rep.cell.table.top_z == pytest.approx(0, abs=1e-12)
    assert rep.n_poses >= len(solved.trajectory)
    # joint steps between checked poses <= 2 deg: more poses than samples where the arm moves far
    dq = np.abs(np.diff(solved.solution.q, axis=0)).max(axis=1)
    assert rep.n_poses == len(solved.trajectory) + int(np.sum(np.maximum(np.ceil(dq / math.radians(2)), 1) - 1))


def test_a_fixture_post_through_a_pass_is_found_with_its_pass_and_time(solved, plate):
    """A 30 x 30 x 120 mm post standing on the plate at (200, 150) mm: the spindle (Ø70 mm, 30 to
    125 mm above the pad face) hits it first where the analytic cylinder-box test says so."""
    size, centre = (0.03, 0.03, 0.12), (0.2, 0.16, 0.06)
    cell = _with_fixture(solved, "post", size, centre)
    rep = check_job_collisions(solved.trajectory, solved.solution, solved.model, cell,
                               part_vertices=plate.vertices, part_faces=plate.faces)
    tr = solved.trajectory
    hit = _cylinder_touches_box(tr.position, None, size, centre, SPINDLE[0], SPINDLE[1], SPINDLE[2])
    assert hit.any()
    first = int(np.argmax(hit))
    # grazing contact is a matter of tolerance: the first hit lies between the first samples
    # within the spindle radius plus and minus 1 mm (one sample either way: poses between samples)
    early = int(np.argmax(_cylinder_touches_box(tr.position, None, size, centre, SPINDLE[0] + 1e-3, *SPINDLE[1:])))
    late = int(np.argmax(_cylinder_touches_box(tr.position, None, size, centre, SPINDLE[0] - 1e-3, *SPINDLE[1:])))
    ev = rep.events[0]
    assert (ev.body_a, ev.body_b) == ("tool spindle", "fixture post")
    assert early - 1 <= ev.sample <= late + 1
    assert ev.pass_index == tr.pass_index[first] or ev.pass_index == -1 and tr.pass_index[first] == -1
    assert abs(ev.t_start - tr.t[first]) <= tr.t[first + 1] - tr.t[first - 1]
    spindle_events = [e for e in rep.events if e.body_a == "tool spindle"]
    # one event per run of touching samples (runs split by pass changes)
    runs = np.flatnonzero(np.diff(hit.astype(int)) == 1).size + int(hit[0])
    assert len(spindle_events) >= runs
    assert {e.body_b for e in rep.events} == {"fixture post"}
    # where: within a spindle radius of the post's footprint, in the part frame
    assert np.all(np.abs(ev.point_part[:2] - centre[:2]) <= 0.015 + 1e-3)
    assert "pass" in ev.sentence() and "tool spindle hits fixture post" in ev.sentence()


def test_the_tool_body_against_a_wall_is_found(solved, plate):
    """A 120 mm wall beside the plate, its face 30 mm beyond the furthest TCP in x: the spindle
    (Ø70 mm, from 30 mm above the pad face) reaches it; the holder and the last link, from 125 mm
    up, pass over it."""
    tr = solved.trajectory
    x_face = tr.position[:, 0].max() + 0.03
    size, centre = (0.05, 1.0, 0.12), (x_face + 0.025, 0.15, 0.06)
    cell = _with_fixture(solved, "wall", size, centre)
    rep = check_job_collisions(tr, solved.solution, solved.model, cell,
                               part_vertices=plate.vertices, part_faces=plate.faces)
    want = _cylinder_touches_box(tr.position, None, size, centre, *SPINDLE)
    assert want.any()
    assert {(e.body_a, e.body_b) for e in rep.events} == {("tool spindle", "fixture wall")}
    first = int(np.argmax(want))
    early = int(np.argmax(_cylinder_touches_box(tr.position, None, size, centre, SPINDLE[0] + 1e-3, *SPINDLE[1:])))
    late = int(np.argmax(_cylinder_touches_box(tr.position, None, size, centre, SPINDLE[0] - 1e-3, *SPINDLE[1:])))
    assert early - 1 <= rep.events[0].sample <= late + 1
    assert rep.events[0].pass_index == tr.pass_index[first]


def test_a_table_above_the_plate_is_hit_by_the_tool(solved, plate):
    """A table top 50 mm above the plate (a user's cell file mistake): the spindle, from 30 mm
    above the pad face, is in it from the first sample; the holder, from 125 mm up, is not; the
    robot's first link stands on the table by design and is not reported; the TCP is in it on the
    air moves (20 mm above the plate), and where the pad is on the plate it is not reported."""
    cell = replace(solved.cell, table=Table(top_z=0.05, centre_xy=(0.0, 0.0), size_xy=(3.0, 3.0)))
    rep = check_job_collisions(solved.trajectory, solved.solution, solved.model, cell,
                               part_vertices=plate.vertices, part_faces=plate.faces)
    assert rep.events and rep.events[0].sample == 0
    assert {e.body_b for e in rep.events} == {"table"}
    assert {e.body_a for e in rep.events} == {"tool spindle", "tool centre point"}
    tcp = [e for e in rep.events if e.body_a == "tool centre point"]
    assert not any(e.contact for e in tcp) and all(e.pass_index == -1 for e in tcp)


def _cell_file(tmp_path, size, centre_part):
    body2base = parse_pose(PART2BASE) @ parse_pose([*centre_part, 0, 0, 0])
    rows = ", ".join("[" + ", ".join(f"{v:.12g}" for v in r) + "]" for r in body2base)
    text = (f'robot = "ur10e"\npart2base = "{PART2BASE}"\n\n[[fixture]]\nname = "post"\nshape = "box"\n'
            f'size = [{", ".join(repr(f"{1e3 * s:g}mm") for s in size)}]\npose = [{rows}]\n')
    path = tmp_path / "cell.toml"
    path.write_text(text.replace("'", '"'))
    return path


@pytest.mark.slow
def test_the_job_refuses_a_colliding_plan_unless_allowed(tmp_path, capsys):
    from swath.cli import main

    cell = _cell_file(tmp_path, (0.03, 0.03, 0.12), (0.2, 0.16, 0.06))
    base = ["plan", "--constant-feed", "example:plate", "--spacing", "100mm", "--cell", str(cell), "--program", "urscript"]
    code = main([*base, "--out", str(tmp_path / "refused")])
    err = capsys.readouterr().err
    assert code == 2
    assert "tool spindle hits fixture post in " in err and " pass " in err and "t = " in err
    assert "--allow-collisions" in err
    assert not (tmp_path / "refused").exists()
    code = main([*base, "--allow-collisions", "--out", str(tmp_path / "allowed")])
    assert code == 0
    metrics = json.loads((tmp_path / "allowed" / "metrics.json").read_text())["metrics"]
    assert metrics["collision_count"] >= 1
    # the spindle and, where the pad runs into the post, the TCP
    assert {(c["body_a"], c["body_b"]) for c in metrics["collisions"]} == {("tool spindle", "fixture post"),
                                                                          ("tool centre point", "fixture post")}
    assert any(c["pass"] >= 0 and c["contact"] for c in metrics["collisions"])
    assert any("--allow-collisions" in w for w in metrics["warnings"])
    assert any("3-inch random-orbital sander" in w for w in metrics["warnings"])
    assert (tmp_path / "allowed" / "robot").is_dir()
    html = (tmp_path / "allowed" / "report.html").read_text(encoding="utf-8")
    assert "fixture post" in html and "tool spindle hits fixture post" in html and "table (assumed)" in html
    assert format_pose(parse_pose(metrics["robot_part2base"])) == metrics["robot_part2base"]


def test_self_collisions_culled_match_coal_on_every_pair(rng):
    """Random UR10e configurations: the arm's links and the tool against links three or more joints
    away, culled, find exactly what coal finds when asked about every pair at every pose."""
    import coal

    from swath.robot.collision import job_scene

    model = get_robot("ur10e")
    tool = default_sander()
    scene, _ = job_scene(model, Cell(tool=tool, tcp2flange=tool.tcp2flange, auto_table=False))
    q = rng.uniform(-math.pi, math.pi, (400, 6))
    frames = model.chain.frames(q)
    hits = scene.check(frames)
    want = set()
    for i, j in scene.self_pairs:
        a, b = scene.moving[i], scene.moving[j]
        for k in range(len(q)):
            ta = frames[k, a.link] @ a.body.body2frame
            tb = frames[k, b.link] @ b.body.body2frame
            res = coal.CollisionResult()
            if coal.collide(a.body.shape.coal(), coal.Transform3s(ta[:3, :3].copy(), ta[:3, 3].copy()),
                            b.body.shape.coal(), coal.Transform3s(tb[:3, :3].copy(), tb[:3, 3].copy()),
                            coal.CollisionRequest(), res):
                want.add((k, a.body.name, b.body.name))
    got = {(int(k), a, b) for k, a, b in zip(hits.pose, hits.body_a, hits.body_b)}
    assert got == want
    assert len({k for k, _, _ in want}) > 10            # random configurations do fold onto themselves
    assert len({(a, b) for _, a, b in want}) >= 2       # and more than one pair of bodies meets
    # adjacent links and the tool on the last wrist links are never pairs
    names = {(scene.moving[i].body.name, scene.moving[j].body.name) for i, j in scene.self_pairs}
    assert ("robot link 5", "tool holder") not in names and ("robot link 2", "robot link 3") not in names


def test_an_arm_through_the_table_is_refused_with_the_link_named(tmp_path, plate_trajectory, plate):
    """A table slab 360 to 400 mm above the plate (a cell file whose table top is wrong): the tool,
    up to 175 mm, passes under it, the wrist links do not; the job refuses, naming a robot link and
    the table, and says the arm passes through the table."""
    from swath.cli.job import JobSettings
    from swath.cli.stages import robot_stage
    from swath.robot.collision import CollisionError

    cell = tmp_path / "cell.toml"
    cell.write_text(f'robot = "ur10e"\npart2base = "{PART2BASE}"\n[table]\ntop_z = "400mm"\nthickness = "40mm"\n'
                    'centre = ["550mm", "-150mm"]\nsize = ["1.0", "1.0"]\n')
    settings = JobSettings(part="example:plate", out=str(tmp_path / "out"), cell=str(cell))
    with pytest.raises(CollisionError) as err:
        robot_stage(plate_trajectory, plate, settings)
    text = str(err.value)
    assert "robot link" in text and "hits table" in text and "The arm passes through the table" in text
    assert "tool" not in text.split("no program written")[0]
