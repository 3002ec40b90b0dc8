"""The ``simulate`` stage: predicted material removal, the plan's metrics, and the force control."""

from .force import (Disturbance, ForceController, ForceTrace, gravity_for_tilt, simulate_force,
                    trajectory_with_force)
from .removal import RemovalMap, coverage_lower_bound, plan_metrics, simulate_removal

__all__ = ["Disturbance", "ForceController", "ForceTrace", "RemovalMap", "coverage_lower_bound", "gravity_for_tilt",
           "plan_metrics", "simulate_force", "simulate_removal", "trajectory_with_force"]
