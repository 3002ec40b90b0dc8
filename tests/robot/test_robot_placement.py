"""Placement: the size-against-reach refusal, the keep-out cylinder, the tool-axis rotation, the warnings."""

import math
import time

import numpy as np
import pytest

from swath.errors import InfeasibleError
from swath.robot import Cell, get_robot, run_robot_stage, search_placement
from swath.robot.placement import check_fits_reach, default_keep_out, footprint_need
from swath.robot.solve import JointSolution
from swath.robot.stage import WARN_JOINT_LIMIT_MARGIN, WARN_MANIPULABILITY, WARN_WRIST_SIN, robot_warnings


def test_footprint_need_of_a_rectangle():
    """A 1.0 m x 0.4 m rectangle outside a 0.3 m keep-out disc: best seen narrow side first, its far
    side 0.3 + 0.4 m away; its corners hypot(0.3, 0.5) = 0.58 m are nearer."""
    xy = np.array([[0, 0], [1.0, 0], [1.0, 0.4], [0, 0.4], [0.5, 0.2]])
    need, theta, width, length = footprint_need(xy, 0.3)
    assert need == pytest.approx(0.7, abs=1e-12)
    assert width == pytest.approx(0.4) and length == pytest.approx(1.0)
    assert abs(math.sin(theta)) == pytest.approx(1.0)              # looking along y
    # a square 1 m x 1 m with no keep-out: its far side is 1 m away
    sq = np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])
    assert footprint_need(sq, 0.0)[0] == pytest.approx(1.0)


def test_crs_part_5_is_refused_for_a_ur10e_in_under_two_seconds():
    from conftest import SHARED_MESH_UNITS, shared_mesh
    from swath.io.mesh import load_mesh

    name = "crs_part_5.stl"
    surface = load_mesh(shared_mesh(name), units=SHARED_MESH_UNITS.get(name, "m"))
    ur10e = get_robot("ur10e")
    cell = Cell.from_text(None, "0,0,120mm,0,0,0")
    t0 = time.perf_counter()
    with pytest.raises(InfeasibleError) as err:
        check_fits_reach(surface.vertices, ur10e, cell, keep_out=default_keep_out(ur10e))
    assert time.perf_counter() - t0 < 2.0
    msg = str(err.value)
    assert "does not fit the reach of ur10e" in msg and "keep-out" in msg
    assert "irb4600" in msg and "setups" in msg and "positioner" in msg
    # the figures: the footprint is 1.5 m deep at best, and 0.33 m keep-out + 1.5 m is beyond 1.42 m
    irb = get_robot("irb4600")
    info = check_fits_reach(surface.vertices, irb, cell, keep_out=default_keep_out(irb))
    assert 1.4 < info["width_m"] < 1.7 and info["need_m"] <= info["reach_m"]


def test_placement_keeps_the_part_outside_the_keep_out_cylinder(plate_trajectory):
    model = get_robot("ur10e")
    keep = 0.45
    best = search_placement(plate_trajectory, model, Cell(tcp2flange=np.diag([1.0, 1, 1, 1])), n_xy=5,
                            yaws=(0.0, math.pi / 2), n_sample=40, n_refine=2, keep_out=keep)
    assert best.keep_out == keep and best.clearance >= keep
    p_base = plate_trajectory.position @ best.cell.part2base[:3, :3].T + best.cell.part2base[:3, 3]
    assert np.hypot(p_base[:, 0], p_base[:, 1]).min() >= keep - 1e-9
    assert best.reachable_fraction == 1.0
    assert best.tool_rotation in (0.0, math.pi / 2, -math.pi / 2, math.pi)
    # the placed cell's TCP includes the rotation about the tool axis: z is unchanged
    np.testing.assert_allclose(best.cell.tcp2flange[:3, 2], [0, 0, 1], atol=1e-12)


def test_a_keep_out_wider_than_the_reach_is_refused(plate_trajectory):
    with pytest.raises(InfeasibleError, match="does not fit the reach"):
        search_placement(plate_trajectory, get_robot("ur5e"), keep_out=1.0)


def test_placed_job_runs_on_the_rotated_tool(plate_trajectory):
    """The stage's placement: FK of every row with the cell's TCP (turned about z) is the pose."""
    r = run_robot_stage(plate_trajectory, robot="ur10e", cell=Cell.from_text(None, "0,0,120mm,0,0,0"), place=True,
                        programs=[])
    assert r.metrics["max_fk_position_error_m"] < 1e-9 and r.metrics["max_fk_angle_error_rad"] < 1e-9
    assert r.metrics["keep_out_m"] == pytest.approx(default_keep_out(r.model))
    assert r.metrics["part_clearance_from_base_axis_m"] >= r.metrics["keep_out_m"]
    assert r.metrics["placement_search_s"] < 60


def test_margin_warnings_name_the_measure_and_threshold():
    clean = JointSolution(q=np.zeros((3, 6)), branch=np.zeros(3, int), reachable=np.ones(3, bool))
    good = {"robot": "ur10e", "min_manipulability": 0.05, "min_wrist_sin": 0.5, "min_joint_limit_margin_rad": 0.5}
    assert robot_warnings(clean, good) == []
    bad = {"robot": "ur10e", "min_manipulability": 0.00018, "min_wrist_sin": 0.14,
           "min_joint_limit_margin_rad": math.radians(0.06)}
    w = robot_warnings(clean, bad)
    assert len(w) == 3
    assert "manipulability falls to 0.00018" in w[0] and f"{WARN_MANIPULABILITY:g}" in w[0]
    assert "sin of the wrist angle falls to 0.14 (8.0 deg" in w[1]
    assert "within 0.06 deg of its limit" in w[2]
    assert WARN_WRIST_SIN == pytest.approx(math.sin(math.radians(10))) and WARN_JOINT_LIMIT_MARGIN == pytest.approx(
        math.radians(5))
