"""The optional stages a job runs after timing: a calibrated tool, force-control simulation.

Each takes the job's settings and the records of the stages before it and returns new records
and its metrics (units in the keys); :func:`swath.cli.job.run_job` calls them in pipeline order.
"""

from __future__ import annotations

import logging

import numpy as np

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


def robot_options(settings) -> dict:
    """Keyword arguments of :func:`swath.robot.run_robot_stage` from the job's settings (checked:
    a known robot, parseable base and tcp poses, known program formats)."""
    from ..errors import InputError
    from ..robot import get_robot
    from ..robot.programs import PROGRAM_FILES
    from ..robot.stage import robot_options_from_mapping

    if not settings.robot:
        raise InputError("programs and placement need a robot: add --robot (e.g. ur10e, irb4600, kr120)")
    get_robot(settings.robot)
    unknown = set(settings.programs) - set(PROGRAM_FILES)
    if unknown:
        raise InputError(f"unknown program format(s) {', '.join(sorted(unknown))}; choose from "
                         f"{', '.join(PROGRAM_FILES)}")
    values = {"robot": settings.robot, "program": ",".join(settings.programs or ("csv",)),
              "place": "auto" if settings.place else "", "table_z": settings.table_z,
              "robot_strict": settings.robot_strict, "force_program": settings.force_program}
    if settings.base:
        values["base"] = settings.base
    if settings.tcp:
        values["tcp"] = settings.tcp
    return robot_options_from_mapping(values)


def robot_stage(trajectory, surface, settings):
    """Inverse kinematics along the trajectory for the job's robot, re-timed where a joint limit
    binds; returns the re-timed trajectory, the :class:`RobotResult` and its metrics (nothing is
    written: see :func:`write_robot_outputs`)."""
    from ..robot import run_robot_stage

    result = run_robot_stage(trajectory, **robot_options(settings), out_dir=None, surface=surface,
                             force=settings.force, warn=False)      # the job reports result.warnings
    metrics = {k if k.startswith("robot") else f"robot_{k}": v for k, v in result.metrics.items()}
    return result.trajectory, result, metrics


def write_robot_outputs(result, surface, settings, out_dir) -> dict:
    """The robot programs and figures (joint plots, reachability map) into ``out_dir``; returns
    the figures by name."""
    from ..report.robot_plots import write_robot_plots
    from ..robot.programs import ProgramInput, write_programs

    out_dir.mkdir(parents=True, exist_ok=True)
    write_programs(ProgramInput(result.trajectory, result.solution, result.model, result.cell, force=settings.force,
                                force_program=settings.force_program), out_dir, list(settings.programs or ("csv",)))
    return write_robot_plots(out_dir, result=result, surface=surface, reach_map=result.reach_map)


def segmented_plan(surface, tool, planner, settings, arguments: dict):
    """Split the part into regions that sweep lines cross without breaks (Wang §1) and plan each;
    a planner with a spacing gets the whole part's default spacing, so neighbouring regions meet,
    and what the regions' passes leave untouched on the whole part gets fill passes
    (:func:`swath.plan.regions.plan_regions`, ``fill_whole_part``)."""
    from ..plan.regions import plan_regions
    from ..segment import segment

    regions = segment(surface)
    log.info("segmented %s into %d regions", surface.name, len(regions))
    options = dict(arguments)
    if settings.planner == "raster":
        if "spacing" not in options:
            options["spacing"] = planner(surface, tool, **arguments).metadata["spacing_m"]
        options["fill_gaps"] = False      # a region's edge is its neighbour's: judged on the whole part only
    return plan_regions(surface, tool, planner, regions, fill_whole_part=True, **options)


def job_target(settings):
    """The job's target depth (a :class:`TargetMap`) and over-removal tolerance (m): the given
    tolerance, else 10 % of a uniform target depth."""
    from ..feed import read_target_map, uniform_target

    if settings.target_map:
        target = read_target_map(settings.target_map, units=settings.units)
        depth = None
    else:
        depth = settings.target_depth
        target = uniform_target(depth)
    tolerance = settings.depth_tolerance if settings.depth_tolerance is not None else 0.1 * (depth or 0.0)
    return target, tolerance


def spacing_plan(surface, tool, planner, settings, arguments: dict):
    """Raster passes placed by ``settings.optimise_spacing``: ``ripple`` plans the raster at the
    spacing whose summed pad cross-profiles are flattest with the path within 1.5x the coverage
    bound (:func:`swath.feed.ripple_spacing`, for the pad at the job's lead angle), or the uniform planner at the overlap that gives that
    spacing over the local swath width (:func:`swath.feed.ripple_overlap`); ``greedy`` and ``joint`` place the planes against the
    job's target depth (:func:`swath.feed.greedy_offsets`, :func:`swath.feed.joint_spacing`) in the
    raster's direction (its automatic choice when none is given).  The feed stage then optimises
    the feed along these passes."""
    from ..feed import greedy_offsets, joint_spacing, ripple_overlap, ripple_spacing

    method = settings.optimise_spacing
    if method == "ripple" and settings.planner == "uniform":
        # the uniform planner spaces passes by overlap of the local swath width: keep d / w at the
        # ratio the ripple analysis chose (on a plane w = 2R and the spacing is ripple_spacing's)
        overlap = ripple_overlap(tool, lead_angle=settings.lead())
        log.info("ripple overlap %.3f of the swath width", overlap)
        return planner(surface, tool, **{**arguments, "overlap": overlap})
    if method == "ripple":
        spacing, cov = ripple_spacing(tool, lead_angle=settings.lead())
        log.info("ripple spacing %.1f mm (pad cross-profile ripple CoV %.3f on a plane)", spacing * 1e3, cov)
        return planner(surface, tool, **{**arguments, "spacing": spacing})
    direction = arguments.get("direction")
    if direction is None:
        direction = planner(surface, tool, **arguments).metadata["angle_rad"]
    place = {"angle": float(direction)} if np.ndim(direction) == 0 else {"direction": direction}
    target, tolerance = job_target(settings)
    constraints = settings.constraints()
    if method == "greedy":
        result = greedy_offsets(surface, tool, constraints, target=target, **place)
    else:
        result = joint_spacing(surface, tool, constraints, target=target, tolerance=tolerance, **place)
    log.info("%s spacing: %d planes, mean step %.1f mm, %.1f s", method, len(result.offsets),
             float(np.mean(np.diff(result.offsets))) * 1e3 if len(result.offsets) > 1 else float("nan"),
             result.metrics.get("solve_time_s", float("nan")))
    return result.toolpath


def feed_stage(toolpath, tool, settings, trajectory, surface=None, progress=None):
    """Optimise the feed along the passes to the job's target depth (Wang §2) and re-time the
    path with it; returns the new trajectory, the :class:`FeedResult` and its metrics.

    With ``settings.feed_simulate_check`` (and the ``surface`` the job simulates on), each optimised
    trajectory is run through the job's own removal simulation and the feed is tightened where the
    simulator finds more than the target plus the tolerance.  ``progress(stage, done, total)`` hears
    about the kernel's batches, each HiGHS solve, each simulated check and each trim round (a line
    for each: the programme takes up to a minute on a large part)."""
    from ..feed import optimise_feed
    from ..simulate import simulate_removal
    from ..trajectory import time_path

    target, tolerance = job_target(settings)
    constraints = settings.constraints()
    simulate = None
    if settings.feed_simulate_check and surface is not None:
        def simulate(timed):
            return simulate_removal(timed, surface, tool, sample_spacing=settings.sample_spacing,
                                    sampling=settings.removal_sampling)
    say = progress or (lambda stage, done, total: None)

    def report(stage, done, total):
        if stage == "kernel":
            say("optimising the feed: removal kernel", done, total)
        elif stage == "solve":
            say(f"optimising the feed: dwell programme, HiGHS solve {done + 1}", 0, 1)
        elif stage == "simulate":
            say(f"optimising the feed: simulated check {done + 1}", 0, 1)
        elif stage == "trim":
            say(f"optimising the feed: speeding up where the simulation is over, round {done + 1}", 0, 1)
        else:
            say(f"optimising the feed: {stage}", done, total)

    result = optimise_feed(toolpath, tool, constraints, target=target, tolerance=tolerance, trajectory=trajectory,
                           simulate=simulate, progress=report, lead_angle=settings.lead())
    timed = time_path(toolpath, constraints + [result.profile], links=settings.links(), lead_angle=settings.lead())
    metrics = {k if k.startswith("feed") else f"feed_{k}": v for k, v in result.metrics.items()
               if isinstance(v, (int, float, str, bool))}
    return timed, result, metrics
