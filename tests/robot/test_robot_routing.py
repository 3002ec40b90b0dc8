"""A joint move that no straight joint path clears is routed through via-points found in joint space."""

import math
from dataclasses import replace

import numpy as np
import pytest

from swath.cell import Body, Box
from swath.examples import example_part
from swath.robot import Cell, get_robot
from swath.robot.collision import interpolate_joints
from swath.robot.routing import route_joint_move
from swath.robot.sweep import SweepCheck

TWO_DEG = math.radians(2.0)


@pytest.fixture(scope="module")
def post_scene():
    """A UR10e over the plate (part frame at (0.6, −0.15, 0) in the base frame, 150 mm TCP) with a
    40 x 40 x 600 mm fixture post standing on the plate's centre line, and two elbow-up
    configurations with the tool pointing down 100 mm above the plate either side of the post."""
    plate = example_part("plate")
    model = get_robot("ur10e")
    post = np.eye(4)
    post[:3, 3] = [0.8, 0.0, 0.3]
    cell = replace(Cell.from_text("0.6,-0.15,0,0,0,0", "0,0,150mm,0,0,0"),
                   fixtures=(Body("fixture post", Box((0.04, 0.04, 0.6)), post),))
    ends = []
    for y in (0.02, 0.28):
        tcp2part = np.eye(4)
        tcp2part[:3, :3] = np.diag([1.0, -1.0, -1.0])
        tcp2part[:3, 3] = [0.2, y, 0.1]
        slot = model.branch_names.index("shoulder1-elbow1-wrist0")
        ends.append(model.ik(cell.flange2base(tcp2part[None]))[0, slot])
    return model, cell, SweepCheck(model, cell, plate.vertices, plate.faces), np.array(ends)


def test_a_post_across_the_straight_move_is_passed_by_routed_via_points(post_scene):
    """The straight joint move between the two ends drives the wrist and the TCP through the post;
    the routing finds via-points whose path, followed at ≤ 2° joint steps, touches nothing and keeps
    20 mm from the plate; the path starts and ends exactly at the move's ends and stays inside the
    joint limits; the same seed gives the same via-points."""
    model, cell, check, (q0, q1) = post_scene
    straight = check.sweep(np.array([q0, q1]))
    assert ("tool centre point", "fixture post") in straight.hits
    assert check.sweep(np.array([q0, q0])).ok(0.02) and check.sweep(np.array([q1, q1])).ok(0.02)
    vias = route_joint_move(check, q0, q1, required=0.02)
    assert vias is not None and len(vias) >= 1
    path = np.vstack([q0, vias, q1])
    assert np.all(path >= model.lower) and np.all(path <= model.upper)
    fine, _ = interpolate_joints(path, max_step=TWO_DEG)
    assert np.abs(np.diff(fine, axis=0)).max() <= TWO_DEG + 1e-12
    frames = model.chain.frames(fine)
    assert len(check.scene.check(frames)) == 0          # nothing touches anywhere along the path
    d, _ = check.scene.distances(frames, "the part", cap=0.3)
    assert d.min() >= 0.02
    assert check.sweep(path).ok(0.02)
    np.testing.assert_array_equal(route_joint_move(check, q0, q1, required=0.02), vias)


def test_a_clean_straight_move_gets_no_via_point(post_scene):
    """Ends on the same side of the post: the straight move is clean and no via-point is added."""
    model, cell, check, (q0, _) = post_scene
    q1 = q0.copy()
    q1[5] += 0.5                                         # a turn of wrist 3 in place
    assert route_joint_move(check, q0, q1, required=0.02).shape == (0, 6)


def test_a_ur_elbow_is_kept_within_half_a_turn():
    """A UR10e's elbow is limited to ±180°: across a configuration change from a run ending with the
    elbow at −162.6° to one at +140.6°, the turns are aligned to +140.6° (the arm unfolds through the
    stretched elbow), not to −219.4° (the 2π-equivalent nearest the last, through the folded arm: the
    joint move that swept the wrist into the base column on snp_part_scan), while wrist 3 still takes
    the equivalent nearest the last run."""
    from swath.robot.solve import align_turns

    model = get_robot("ur10e")
    assert model.lower[2] == pytest.approx(-math.pi) and model.upper[2] == pytest.approx(math.pi)
    assert np.all(np.delete(model.upper, 2) == pytest.approx(2 * math.pi))
    q0 = np.radians([8.0, -82.8, -162.6, 12.7, 36.2, 86.9])
    q1 = np.radians([117.1, -104.7, 140.6, -7.4, 84.3, 209.1 - 360.0])
    out = align_turns(np.array([q0, q1]), model.lower, model.upper, np.array([True, True]))
    assert math.degrees(out[1, 2]) == pytest.approx(140.6, abs=1e-9)
    assert math.degrees(out[1, 5]) == pytest.approx(209.1, abs=1e-9)       # −150.9° + 360°: nearer 86.9°
    # with the elbow allowed ±360° the same alignment folds the arm
    folded = align_turns(np.array([q0, q1]), np.full(6, -2 * math.pi), np.full(6, 2 * math.pi), np.array([True, True]))
    assert math.degrees(folded[1, 2]) == pytest.approx(140.6 - 360.0, abs=1e-9)
