"""The optional stages a job runs after timing: a calibrated tool, force-control simulation.

Each takes the job's settings and the records of the stages before it and returns new records
and its metrics (units in the keys); :func:`swath.cli.job.run_job` calls them in pipeline order.
"""

from __future__ import annotations

import logging

log = logging.getLogger(__name__)


def job_tool(settings):
    """The job's Tool, with the Preston coefficient of ``settings.calibration`` when one is given."""
    tool = settings.tool()
    if settings.calibration:
        from ..simulate.calibrate import tool_with_calibration

        tool = tool_with_calibration(tool, settings.calibration, grit=settings.grit)
    return tool


def force_stage(trajectory, surface, tool, settings):
    """Hybrid position/force control along ``trajectory`` (Jaeger ch. 5) with the job's
    disturbances; returns the trajectory with a ``force`` column, the :class:`ForceTrace` and
    its metrics."""
    from ..simulate.force import Disturbance, ForceController, gravity_for_tilt, simulate_force, trajectory_with_force

    disturbance = Disturbance(part_offset=settings.part_offset or (0.0,) * 6, tool_mass=settings.tool_mass,
                              gravity=gravity_for_tilt(settings.tool_tilt))
    controller = ForceController(gravity_compensation=settings.gravity_compensation)
    trace = simulate_force(trajectory, surface, tool, controller=controller, disturbance=disturbance)
    return trajectory_with_force(trajectory, trace), trace, dict(trace.metrics)
