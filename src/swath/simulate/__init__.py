"""The ``simulate`` stage: predicted material removal, the plan's metrics, the force control, and
the Preston calibration from trials."""

from .calibrate import Calibration, PrestonFit, calibrate, load_calibration, read_trials, write_calibration
from .calibrated import calibrated_tool, predict_depth, predict_job_depth, tool_with_calibration
from .force import Disturbance, ForceController, ForceTrace, gravity_for_tilt, simulate_force, trajectory_with_force
from .preston_doe import factorial_design, write_doe
from .removal import RemovalMap, coverage_lower_bound, plan_metrics, simulate_removal
from .samples import RemovalSamples, count_removal_samples, removal_samples

__all__ = ["Calibration", "Disturbance", "ForceController", "ForceTrace", "PrestonFit", "RemovalMap",
           "RemovalSamples", "calibrate", "calibrated_tool", "count_removal_samples", "coverage_lower_bound", "factorial_design", "gravity_for_tilt", "load_calibration", "plan_metrics",
           "predict_depth", "predict_job_depth", "read_trials", "removal_samples", "simulate_force", "simulate_removal",
           "tool_with_calibration", "trajectory_with_force", "write_calibration", "write_doe"]
