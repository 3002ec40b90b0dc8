"""The pad in the swept distance: a disc of the pad's radius at the TCP, normal to the tool axis,
whose rim comes nearer a surface than the TCP when the tool is tilted."""

import math

import numpy as np
import pytest

from swath.examples import example_part
from swath.robot import Cell, get_robot
from swath.robot.sweep import SweepCheck, ik_near

PAD_R = 0.0381


@pytest.fixture(scope="module")
def plate():
    return example_part("plate")


def _tilted(x: float, height: float, tilt: float) -> np.ndarray:
    """TCP pose (4, 4) in the plate's frame at (x, 150 mm, ``height``) m, its z axis (into the part)
    tilted ``tilt`` rad from straight down about the part's y axis."""
    c, s = math.cos(tilt), math.sin(tilt)
    z = np.array([s, 0.0, -c])
    y = np.array([0.0, 1.0, 0.0])
    pose = np.eye(4)
    pose[:3, :3] = np.column_stack([np.cross(y, z), y, z])
    pose[:3, 3] = [x, 0.15, height]
    return pose


def test_the_pad_rim_not_its_centre_comes_within_the_clearance(plate):
    """A 60 mm joint move of a UR10e with the tool tilted 60° and the TCP 45 mm above the plate
    (z = 0): the TCP keeps 44 mm (its 1 mm body), but the pad's lowest rim point is 45 − 38.1·sin 60°
    = 12.0 mm above the plate; the sweep measures the pad there and the 20 mm clearance fails,
    while without the pad it passes."""
    model = get_robot("ur10e")
    cell = Cell(part2base=Cell.from_text("0.55,-0.15,0,0,0,20").part2base,
                tcp2flange=Cell.from_text(None, "0,0,150mm,0,0,0").tcp2flange)
    tilt, height = math.radians(60.0), 0.045
    seed = np.radians([0.0, -90.0, 90.0, -90.0, -90.0, 0.0])
    q = []
    for x in (0.12, 0.18):
        got = ik_near(model, cell, _tilted(x, height, tilt), seed if not q else q[-1], max_change=2 * math.pi)
        assert got is not None
        q.append(got[0])
    nodes = np.array(q)
    # both ends are the poses asked for
    tcp = cell.tcp2part(model.fk(nodes))
    np.testing.assert_allclose(tcp[:, 2, 3], height, atol=1e-9)
    with_pad = SweepCheck(model, cell, plate.vertices, plate.faces).sweep(nodes)
    without = SweepCheck(model, cell, plate.vertices, plate.faces, pad_radius=None).sweep(nodes)
    rim = height - PAD_R * math.sin(tilt)
    assert rim == pytest.approx(0.0120, abs=1e-4)
    assert with_pad.nearest == "tool pad"
    # the joint-space line sags below the straight TCP line by well under a millimetre over 60 mm
    assert with_pad.min_distance == pytest.approx(rim, abs=1e-3)
    assert without.nearest != "tool pad" and without.min_distance > 0.04
    assert not with_pad.ok(0.02) and without.ok(0.02)
    assert not with_pad.hits and not without.hits


def test_the_smallest_distance_over_a_sweep_matches_every_pose_measured(plate):
    """:meth:`CollisionScene.min_distance` (exact queries in the order of the lower bounds, stopping at
    the first bound not below the best) gives the minimum of the per-pose :meth:`distances`, its body
    and pose, on 300 seeded random UR10e configurations within 0.05 rad of one 120 mm above the plate."""
    model = get_robot("ur10e")
    cell = Cell(part2base=Cell.from_text("0.55,-0.15,0,0,0,20").part2base,
                tcp2flange=Cell.from_text(None, "0,0,150mm,0,0,0").tcp2flange)
    check = SweepCheck(model, cell, plate.vertices, plate.faces)
    rng = np.random.default_rng(7)
    branches = model.ik(cell.flange2base(_tilted(0.15, 0.12, 0.0)[None]))[0]
    branches = branches[np.isfinite(branches[:, 0])]
    # the branch farthest from the plate (elbow up)
    centre = branches[np.argmax(check.scene.distances(model.chain.frames(branches), "the part", cap=1.0)[0])]
    q = centre + rng.uniform(-0.05, 0.05, (300, 6))
    frames = model.chain.frames(q)
    found = {}
    for cap in (0.3, 0.02):
        per_pose, who = check.scene.distances(frames, "the part", cap=cap)
        d, body, k = check.scene.min_distance(frames, "the part", cap=cap)
        assert d == pytest.approx(per_pose.min(), abs=1e-12)
        assert per_pose[k] == pytest.approx(d, abs=1e-12) and who[k] == body
        found[cap] = d
    # measured: the pad's rim comes 64 mm from the plate; with a 20 mm cap nothing is nearer than the cap,
    # and the figure is the lower bound (at or above the cap, below the exact distance)
    assert 0.03 < found[0.3] < 0.12
    assert 0.02 <= found[0.02] <= found[0.3]
