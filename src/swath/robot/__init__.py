"""The ``robot`` stage: kinematic models, IK along a trajectory, placement, robot programs.

``run_robot_stage(trajectory, robot="ur10e", cell=Cell.from_text("x,y,z,rx,ry,rz"), programs=[...], out_dir=...)``
(:mod:`.stage`) is the entry point; the parts are :mod:`.models` (catalogue, limits), :mod:`.opw`
(closed-form IK), :mod:`.cell` (placement and tool), :mod:`.solve` (branch-continuous IK),
:mod:`.retime` (joint limits), :mod:`.placement` (placement search), :mod:`.reach` (reachability map),
:mod:`.gaps` (unreachable stretches flown in air), :mod:`.urdf` (URDF robots through pinocchio),
:mod:`.programs` / :mod:`.readers` (URScript, RAPID, KRL, ROS YAML, CSV).
"""

from ..cell import Cell, format_pose, parse_pose
from .models import ROBOTS, RobotModel, dh_robot, get_robot
from .retime import retime_joints, retime_trajectory
from .solve import (
           JointSolution,
           Margins,
           UnreachableStretch,
           flips_inside_passes,
           solve_trajectory,
)

__all__ = [
           "ROBOTS",
           "Cell",
           "JointSolution",
           "Margins",
           "RobotModel",
           "UnreachableStretch",
           "dh_robot",
           "flips_inside_passes",
           "format_pose",
           "get_robot",
           "parse_pose",
           "retime_joints",
           "retime_trajectory",
           "solve_trajectory",
]

from .placement import Placement, search_placement
from .reach import ReachMap, reachability_map
from .stage import RobotResult, robot_options_from_mapping, run_robot_stage
from .urdf import urdf_robot

__all__ += ["Placement", "ReachMap", "RobotResult", "reachability_map", "robot_options_from_mapping",
            "run_robot_stage", "search_placement", "urdf_robot"]
