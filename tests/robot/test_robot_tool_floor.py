"""The tool's bodies kept out of the table: a pose is refused on every branch when they dip below."""

import math

import numpy as np
import pytest

from swath.cell.tool import SANDER_3IN, default_sander
from swath.robot.tool_floor import tool_below


def flange_pose(tilt_deg: float, tcp_z: float) -> np.ndarray:
    """The flange pose whose TCP (the default sander's, on its z axis) sits at height ``tcp_z`` with
    the tool axis tilted ``tilt_deg`` from pointing straight down."""
    tool = default_sander()
    t = math.radians(tilt_deg)
    # tool z (into the part) tilted from -z towards +x
    z = np.array([math.sin(t), 0.0, -math.cos(t)])
    x = np.array([math.cos(t), 0.0, math.sin(t)])
    tcp2base = np.eye(4)
    tcp2base[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    tcp2base[:3, 3] = [0.0, 0.0, tcp_z]
    return tcp2base @ np.linalg.inv(tool.tcp2flange)


def lowest_spindle_z(tilt_deg: float, tcp_z: float) -> float:
    """The spindle's lowest point, worked out by hand: its centre lies on the tool axis
    pad_stack + spindle_length / 2 behind the TCP."""
    s, t = SANDER_3IN, math.radians(tilt_deg)
    behind = s["pad_stack"] + s["spindle_length"] / 2
    centre_z = tcp_z + behind * math.cos(t)
    return centre_z - 0.5 * s["spindle_length"] * math.cos(t) - s["spindle_radius"] * math.sin(t)


def test_a_tool_pointing_down_is_above_the_table_and_a_horizontal_one_at_the_edge_is_not():
    tool = default_sander()
    down = flange_pose(0.0, 0.001)
    assert not tool_below(tool, down[None], 0.0)[0]
    # horizontal at 20 mm above the table: the Ø70 spindle and the Ø90 holder reach 35 / 45 mm down
    side = flange_pose(90.0, 0.020)
    assert tool_below(tool, side[None], 0.0)[0]
    assert not tool_below(tool, flange_pose(90.0, 0.046)[None], 0.0)[0]


@pytest.mark.parametrize("tilt", [30.0, 60.0, 80.0])
def test_the_spindle_threshold_is_the_hand_worked_lowest_point(tilt):
    tool = default_sander()
    # the holder sits further back and higher than the spindle for these tilts, so the spindle decides
    tcp_z = 0.01
    low = lowest_spindle_z(tilt, tcp_z)
    poses = np.stack([flange_pose(tilt, tcp_z)] * 2)
    assert list(tool_below(tool, poses, low - 1e-4)) == [False, False]
    assert list(tool_below(tool, poses, low + 1e-4)) == [True, True]
