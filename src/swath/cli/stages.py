"""The optional stages a job runs after timing: a calibrated tool, force-control simulation.

Each takes the job's settings and the records of the stages before it and returns new records
and its metrics (units in the keys); :func:`swath.cli.job.run_job` calls them in pipeline order.
"""

from __future__ import annotations

import logging
import math
import time

import numpy as np

log = logging.getLogger(__name__)


def job_tool(settings):
    """The job's Tool, built once: the pad and force of the settings, with the Preston coefficient,
    wear rate and the kinematics (motion, spindle speed, orbit) of ``settings.calibration`` where
    the user did not give them (:func:`swath.simulate.calibrated.calibrated_tool`)."""
    from ..errors import InputError

    tool = settings.tool()
    if settings.calibration:
        from ..simulate.calibrated import calibrated_tool

        tool = calibrated_tool(tool, settings.calibration, grit=settings.grit, motion=settings.motion,
                               spindle_speed=settings.spindle_speed, orbit_radius=settings.orbit_radius,
                               wear_rate=settings.wear_rate)
    if settings.media_change_loss is not None and not tool.wear_rate > 0:
        raise InputError("--media-change-loss needs a pad that wears: give --wear-rate, or a --calibration fitted "
                         "from trials with pad_age_s")
    return tool


def force_stage(trajectory, surface, tool, settings):
    """Hybrid position/force control along ``trajectory`` (Jaeger ch. 5) with the job's
    disturbances; returns the trajectory with a ``force`` column, the :class:`ForceTrace` and
    its metrics."""
    from ..simulate.force import Disturbance, ForceController, gravity_for_tilt, simulate_force, trajectory_with_force
    from .stage_settings import SimulateSettings

    settings = SimulateSettings.of(settings)          # the stage's own record
    disturbance = Disturbance(part_offset=settings.part_offset or (0.0,) * 6, tool_mass=settings.tool_mass,
                              gravity=gravity_for_tilt(settings.tool_tilt))
    controller = ForceController(gravity_compensation=settings.gravity_compensation)
    trace = simulate_force(trajectory, surface, tool, controller=controller, disturbance=disturbance)
    return trajectory_with_force(trajectory, trace), trace, dict(trace.metrics)


def job_cell(settings):
    """The job's robot cell: the cell file (``--cell``) if any, ``--base`` (part2base) and ``--tcp``
    (tcp2flange) over it, and the default 3-inch sander when no tool is given (said in the cell's
    ``notes``)."""
    from dataclasses import replace

    from ..cell import Cell, default_sander, parse_pose, read_cell_file

    cell = read_cell_file(settings.cell) if settings.cell else Cell()
    warnings = list(cell.notes)
    if settings.base:
        cell = replace(cell, part2base=parse_pose(settings.base, name="--base (part2base)"))
    if settings.tcp:
        cell = replace(cell, tcp2flange=parse_pose(settings.tcp, name="--tcp (tcp2flange)"))
        if cell.tool is None:
            warnings.append("cell: --tcp gives the TCP but not the tool's body, so only the robot's links are checked "
                            "for collisions; describe the tool in a cell file ([tool] with [[tool.body]] entries) [W-CELL-NO-TOOL-BODY]")
    elif cell.tool is None:
        tool = default_sander()
        cell = replace(cell, tool=tool, tcp2flange=tool.tcp2flange)
        warnings.append(f"cell: no tool given (--tcp or a cell file's [tool]), so a {tool.description} is assumed "
                        "for the TCP and the collision check; give your tool's TCP and body in a cell file "
                        "[W-CELL-DEFAULT-TOOL]")
    return replace(cell, notes=tuple(warnings))


def robot_options(settings) -> dict:
    """Keyword arguments of :func:`swath.robot.run_robot_stage` from the job's settings (checked:
    a known robot, a readable cell file, parseable base and tcp poses, known program formats)."""
    from ..errors import InputError
    from ..robot import get_robot
    from ..robot.programs import PROGRAM_FILES
    from ..robot.stage import robot_options_from_mapping
    from .stage_settings import RobotSettings

    settings = RobotSettings.of(settings)             # the stage's own record
    cell = job_cell(settings)
    robot = settings.robot or cell.robot
    if not robot:
        raise InputError("programs, placement and a cell need a robot: add --robot (e.g. ur10e, irb4600, kr120, "
                         "or a URDF file with --tip) or `robot = ...` in the cell file")
    get_robot(robot, tip=settings.tip)
    unknown = set(settings.programs) - set(PROGRAM_FILES)
    if unknown:
        raise InputError(f"unknown program format(s) {', '.join(sorted(unknown))}; choose from "
                         f"{', '.join(PROGRAM_FILES)}")
    table_z = settings.table_z
    if settings.place and cell.table is not None and not settings.table_z:
        table_z = cell.table.top_z
    values = {"robot": robot, "program": ",".join(settings.programs or ("csv",)),
              "place": "auto" if settings.place else "", "table_z": table_z,
              "robot_strict": settings.robot_strict,
              "force_program": settings.force_program}
    if settings.tip:
        values["tip"] = settings.tip
    if settings.robot_keep_out is not None:
        values["keep_out"] = settings.robot_keep_out
    options = robot_options_from_mapping(values)
    options["cell"] = cell
    return options


def robot_fit_check(surface, settings) -> None:
    """With ``--place``: refuse before planning a part whose footprint cannot lie within the robot's
    reach outside the keep-out cylinder (:func:`swath.robot.placement.check_fits_reach`)."""
    from ..robot import get_robot
    from ..robot.placement import check_fits_reach, default_keep_out

    options = robot_options(settings)
    model = options["robot"] if not isinstance(options["robot"], str) else get_robot(options["robot"])
    keep = options.get("keep_out")
    check_fits_reach(surface.vertices, model, options["cell"], keep_out=default_keep_out(model) if keep is None else keep)


def robot_stage(trajectory, surface, settings, *, progress=None):
    """Inverse kinematics along the trajectory for the job's robot, re-timed where a joint limit
    binds, then the collision check of the whole joint path in the cell; returns the re-timed
    trajectory, the :class:`RobotResult` (its cell with the table assumed, if any) and its metrics
    (nothing is written: see :func:`write_robot_outputs`).

    Raises
    ------
    CollisionError
        When a body of the robot or tool hits the part, the cell or the robot, unless
        ``settings.allow_collisions`` (then a warning).
    """
    from dataclasses import replace

    from ..robot import run_robot_stage
    from ..robot.collision import CollisionError, check_job_collisions

    options = robot_options(settings)
    if options["cell"].positioner is not None:          # the part turns on a positioner (cli.positioner_job)
        from .positioner_job import positioner_robot_stage

        return positioner_robot_stage(trajectory, surface, settings, options, progress=progress)
    result = run_robot_stage(trajectory, **options, out_dir=None, surface=surface,
                             force=settings.force, warn=False,      # the job reports result.warnings
                             clearance=settings.clearance, pad_radius=settings.pad_radius,
                             progress=None if progress is None else (lambda m, d, n: progress(m, d, n)))
    metrics = {k if k.startswith("robot") else f"robot_{k}": v for k, v in result.metrics.items()}
    report = check_job_collisions(result.trajectory, result.solution, result.model, result.cell,
                                  part_vertices=surface.vertices, part_faces=surface.faces)
    metrics.update(report.metrics())
    metrics["robot_table"] = report.cell.table.as_record() if report.cell.table is not None else None
    warnings = list(result.warnings) + list(report.cell.notes)
    table = report.cell.table
    if table is not None and table.assumed:
        warnings.append(f"cell: no table given, so the part is assumed to stand on a table whose top is its lowest "
                        f"point (z = {table.top_z * 1e3:.0f} mm in the base frame), {table.size_xy[0]:.1f} x "
                        f"{table.size_xy[1]:.1f} m under the robot's whole reach; the arm and the tool are checked "
                        "against it (a cell file's [table], or `table = false`, says otherwise) [W-CELL-DEFAULT-TABLE]")
    if report.events:
        arm_in_table = any(e.body_a.startswith("robot link") and e.body_b == "table" for e in report.events)
        hint = (" The arm passes through the table: raise the part or bring it nearer the robot so that the elbow "
                "stays above the table top." if arm_in_table else "")
        if not settings.allow_collisions:
            raise CollisionError(f"collision check: {report.message()}; no program written.{hint} Move the part "
                                 "(--base, --place) or the fixture, change the tool or the path, or pass "
                                 "--allow-collisions to write the programs anyway")
        warnings.append(f"cell: {report.message()}; the programs are written anyway (--allow-collisions) "
                        "[W-CELL-COLLISION]")
    result = replace(result, cell=report.cell, warnings=warnings)
    return result.trajectory, result, metrics


def cell_scene(result, metrics, surface) -> list:
    """The robot cell (table, fixtures) and the collisions found, as 3D-view traces in the part frame."""
    from ..report.cell_view import cell_traces

    return cell_traces(result.cell, metrics.get("collisions", ()), part_vertices=surface.vertices)


def write_robot_outputs(result, surface, settings, out_dir) -> dict:
    """The robot programs and figures (joint plots, reachability map) into ``out_dir``; returns
    the figures by name."""
    from ..report.robot_plots import write_robot_plots
    from ..robot.programs import ProgramInput, write_programs

    out_dir.mkdir(parents=True, exist_ok=True)
    trajectory, cell = result.program_view or (result.trajectory, result.cell)     # a positioner: the base frame
    write_programs(ProgramInput(trajectory, result.solution, result.model, cell, force=settings.force,
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


def spacing_plan(surface, tool, planner, settings, arguments: dict, *, choose_lead: bool = False, ridge: bool = False,
                 progress=None):
    """Raster passes placed by ``settings.optimise_spacing``: ``ripple`` plans the raster at the
    spacing whose summed pad cross-profiles, on the part's representative curvature and at the
    job's lead, are flattest within the length budget, or the uniform planner at the overlap that
    gives it (:func:`swath.cli.curved_spacing.curved_spacing_plan`; ``choose_lead``: the lead too, on a
    curved part; ``ridge``: the uniform planner where the raster's feed is held round a ridge);
    ``greedy`` and ``joint`` place the planes against the
    job's target depth (:func:`swath.feed.greedy_offsets`, :func:`swath.feed.joint_spacing`) in the
    raster's direction (its automatic choice when none is given).  The feed stage then optimises
    the feed along these passes.  ``progress(stage, done, total)`` hears the uniform planner's
    steps where a raster turns to it round a ridge."""
    from ..feed import greedy_offsets, joint_spacing

    method = settings.optimise_spacing
    if method == "ripple":
        from .curved_spacing import curved_spacing_plan

        return curved_spacing_plan(surface, tool, planner, settings, arguments, choose_lead=choose_lead, ridge=ridge,
                                   progress=progress)
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


#: The simulated checks and trim rounds of the feed programme when the even-removal default chose
#: the target depth (the programme's own defaults, 6 and 8, when the job gives it): each round is a
#: HiGHS solve and a simulation, the largest part of the default job's time.  The default job runs
#: none: its final simulation, compared with the constant feed and the plain plan, is the check
#: (on crs_part_5 31 s of CPU instead of 45 s, interior CoV 0.232 instead of 0.242; the plate alike).
DEFAULT_JOB_FEED_ROUNDS: dict = {"simulate_rounds": 0, "trim_rounds": 0}


#: A HiGHS solve line gives the time the solve before it took once that was at least this long (s).
SOLVE_ESTIMATE_AFTER_S = 1.0


class FeedProgress:
    """The job's progress lines for :func:`swath.feed.optimise_feed`'s ``progress(stage, done, total)``.

    The kernel's batches are a step with percentages.  The HiGHS solves, the simulated checks and
    the trim rounds are a line each: how many of them a programme needs is not known in advance
    (the cap rows and the simulation decide), so no percentage of the whole is given.  A solve's
    line instead gives the time the solve before it took (the same programme with a few more cap
    rows, so about as long): "HiGHS solve 3, about 4 s as solve 2".  A solve ends at the next
    line of any kind.  ``say`` is the job's ``progress``; ``clock`` returns seconds."""

    def __init__(self, say, *, clock=None):
        import time

        self.say = say
        self.clock = clock or time.perf_counter
        self.solve_started: float | None = None
        self.last_solve: tuple[int, float] | None = None       # (number, duration s) of the latest solve

    def __call__(self, stage: str, done: int, total: int) -> None:
        now = self.clock()
        if self.solve_started is not None:
            self.last_solve = (self.last_solve[0] + 1 if self.last_solve else 1, now - self.solve_started)
            self.solve_started = None
        if stage == "kernel":
            self.say("optimising the feed: removal kernel", done, total)
        elif stage == "solve":
            self.solve_started = now
            line = f"optimising the feed: dwell programme, HiGHS solve {done + 1}"
            if self.last_solve is not None and self.last_solve[1] >= SOLVE_ESTIMATE_AFTER_S:
                line += f", about {self.last_solve[1]:.0f} s as solve {self.last_solve[0]}"
            self.say(line, 0, 1)
        elif stage == "simulate":
            self.say(f"optimising the feed: simulated check {done + 1}", 0, 1)
        elif stage == "trim":
            self.say(f"optimising the feed: speeding up where the simulation is over, round {done + 1}", 0, 1)
        else:
            self.say(f"optimising the feed: {stage}", done, total)


def feed_stage(toolpath, tool, settings, trajectory, surface=None, progress=None, rounds: dict | None = None):
    """Optimise the feed along the passes to the job's target depth (Wang §2) and re-time the
    path with it; returns the new trajectory, the :class:`FeedResult` and its metrics.

    With ``settings.feed_simulate_check`` (and the ``surface`` the job simulates on), each optimised
    trajectory is run through the job's own removal simulation and the feed is tightened where the
    simulator finds more than the target plus the tolerance.  ``progress(stage, done, total)`` hears
    about the kernel's batches, each HiGHS solve, each simulated check and each trim round (a line
    for each: the programme takes up to a minute on a large part).  ``rounds`` overrides
    :func:`swath.feed.optimise_feed`'s ``simulate_rounds`` and ``trim_rounds``."""
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
    report = FeedProgress(progress or (lambda stage, done, total: None))
    result = optimise_feed(toolpath, tool, constraints, target=target, tolerance=tolerance, trajectory=trajectory,
                           simulate=simulate, progress=report, lead_angle=settings.lead(),
                           target_floor=settings.target_floor, **(rounds or {}))
    timed = time_path(toolpath, constraints + [result.profile], links=settings.links(), lead_angle=settings.lead())
    metrics = {k if k.startswith("feed") else f"feed_{k}": v for k, v in result.metrics.items()
               if isinstance(v, (int, float, str, bool))}
    return timed, result, metrics


def even_feed_stage(toolpath, tool, settings, trajectory, surface, even: dict | None, progress=None, plain=None,
                    constant=None):
    """The job's feed stage (:func:`feed_stage`), choosing the target depth first when the job
    leaves it to the even-removal default (:mod:`swath.cli.even_default`).

    The passes at the constant feed (``trajectory``) are simulated, the target is chosen from
    their interior depth and cycle time (:func:`~swath.cli.even_default.choose_target_depth`) and
    the feed optimised to it; when the cycle time comes out over ``settings.cycle_time_factor``
    times the constant feed's, the feed is optimised once more to a lower target
    (:func:`~swath.cli.even_default.lower_target`).  The figures of the choice go into ``even``
    (a dict, filled in here; None: not the default job).

    ``plain`` (a callable returning the plain plan's ``(toolpath, trajectory, removal)``,
    :func:`~swath.cli.even_default.plain_run`, or the answer of one planning it beside this process,
    :func:`~swath.cli.even_default.plain_beside`) is asked for before the feed is optimised (one
    still being made beside, once the feed is chosen, with the same outcome): when the
    plain plan already removes more evenly than these passes at constant feed, these passes are
    dropped (``even["plain_plan_kept"]``; measured on the panel, the blade and the scans, their
    optimised feed never caught up with it) and the job optimises the feed on the plain plan's
    passes instead; else it is kept in ``even["_plain"]`` for the job's comparison after the final
    simulation.  A plain plan made beside this process is planned while these passes are timed and
    simulated here.
    ``constant``: the removal of ``trajectory``, when already simulated.

    Returns
    -------
    tuple
        ``(settings with the target depth, trajectory, FeedResult, metrics)``.
    """
    from ..simulate import simulate_removal
    from . import even_default

    say = progress or (lambda stage, done, total: None)
    if even is None or not even_default.wants_target_depth(settings):
        say("optimising the feed (dwell) to the target depth", 0, 1)
        return (settings, *feed_stage(toolpath, tool, settings, trajectory, surface, progress=say))
    factor = settings.cycle_time_factor
    if constant is None:
        say("simulating the passes at constant feed (to choose the target depth)", 0, 1)
        constant = simulate_removal(trajectory, surface, tool, sample_spacing=settings.sample_spacing,
                                    sampling=settings.removal_sampling)
    depth, figures = even_default.choose_target_depth(constant, trajectory.duration, factor, tool.pad_radius)
    even.update(figures)
    if plain is not None and getattr(plain, "ready", lambda: True)():
        # asked for before the feed is optimised: where the plain plan wins (four of the seven shared
        # meshes), optimising these passes' feed first cost 5-40 s for nothing
        if _plain_wins(plain, constant, even, say):
            return settings, trajectory, None, {}        # the feed is optimised on the plain plan's passes
        plain = None
    # A plain plan still being made beside (the uniform planner's: started after the job's plan) is
    # asked for once this feed is chosen, so the two run at once; where it wins, the same answer as
    # asking first (the feed chosen here is dropped, and so are the figures of choosing it).
    before = {k: list(v) if isinstance(v, list) else v for k, v in even.items()}
    chosen = _feed_for_even(toolpath, tool, settings, trajectory, surface, even, constant, depth, figures, say)
    if plain is not None and _plain_wins(plain, constant, even, say, undo=before):
        return settings, trajectory, None, {}
    return chosen


#: Progress steps of the plain plan a job waits for, and how often (s) it reads how far it is.
PLAIN_STEPS, PLAIN_POLL_S = 1000, 0.25


def _plain_wins(plain, constant, even: dict, say, undo: dict | None = None) -> bool:
    """Ask ``plain`` for the plain plan's run and judge it against the passes' ``constant`` removal
    (:func:`swath.cli.even_default.plain_if_evener`, the figures into ``even``, the run kept in
    ``even["_plain"]``); True where it removes more evenly.  ``undo``: where it wins, ``even`` is
    first set back to these entries (what it held before the feed was chosen).  While a plain plan
    made beside is not ready, ``say`` hears how much of it is made (its ``share()``) every
    :data:`PLAIN_POLL_S`: on crs_part_5 with the uniform planner the job waits 6-8 s for it."""
    from . import even_default

    stage = "the plain plan (covering spacing, flat pad, constant feed) to compare"
    share = getattr(plain, "share", None)       # made beside: how much of it is made (0 to 1)
    say(stage, 0 if share is None else int(PLAIN_STEPS * share()), 1 if share is None else PLAIN_STEPS)
    while share is not None and not plain.ready():
        time.sleep(PLAIN_POLL_S)
        say(stage, int(PLAIN_STEPS * share()), PLAIN_STEPS)
    run = plain()
    wins = even_default.plain_if_evener(run, constant, {}, feed_follows=True) is not None   # the verdict alone
    if wins and undo is not None:
        even.clear()
        even.update(undo)
    even["_plain"] = run
    even_default.plain_if_evener(run, constant, even, feed_follows=True)
    return wins


def _feed_for_even(toolpath, tool, settings, trajectory, surface, even: dict, constant, depth: float, figures: dict,
                   say):
    """The default job's feed for ``toolpath`` to the target ``depth`` (m) (:func:`even_feed_stage`,
    after the plain plan's comparison): skipped where it cannot help, the constant feed where the
    programme has no solution."""
    from dataclasses import replace

    from ..errors import InfeasibleError
    from .feed_reach import FEED_REACH_MIN, feed_cannot_help, feed_reach

    reach = feed_reach(constant, trajectory, tool)
    even.update(reach)
    if feed_cannot_help(reach):
        # the variance lies across the passes: no feed along them evens it (crs_part_5: 15 s for a worse CoV)
        even.setdefault("warnings", []).append(
            f"even removal: the feed is not optimised: {100 * reach['feed_reachable_variance_fraction']:.0f} % of the "
            f"interior removal variance at constant feed (CoV {reach['feed_reach_interior_cov']:.3f}) lies between "
            f"and along the passes, where a feed along them reaches, under the {100 * FEED_REACH_MIN:.3g} % it needs; "
            "the rest is the ripple across them, and the constant feed is written (--target-depth runs the feed "
            "programme all the same) [W-EVEN-FEED-SKIPPED]")
        even.update(constant_feed_kept=True, feed_optimisation_skipped=True, _simulated=(trajectory, constant))
        return replace(settings, target_depth=depth), trajectory, None, {}
    optimised, first = _default_target_feed(toolpath, tool, replace(settings, target_depth=depth), trajectory,
                                            surface, figures, say)
    if isinstance(optimised, InfeasibleError):   # the default's own target: the plain plan, said, rather than no plan
        message = (f"even removal: the feed could not be optimised to the default target {depth * 1e6:.3g} um "
                   f"({optimised}); the same passes are written at constant feed [W-EVEN-FEED-WORSE]")
        even.setdefault("warnings", []).append(message)
        even["constant_feed_kept"] = True
        return replace(settings, target_depth=depth), trajectory, None, {}
    even.update(first)
    even["_constant"] = (trajectory, constant)          # the fallback when the feed does not even the removal
    return optimised


def _default_target_feed(toolpath, tool, settings, trajectory, surface, figures: dict, say):
    """The feed optimised to the default target ``settings.target_depth`` (m), and once more to a
    lower target when the cycle time comes out over ``settings.cycle_time_factor`` times the
    constant feed's ``trajectory`` (:func:`even_feed_stage`).  Returns ``((settings, trajectory,
    FeedResult, metrics), first)`` (``first``: the first target's figures when a second was
    needed, else empty), or ``(InfeasibleError, {})`` when the programme has no solution."""
    from dataclasses import replace

    from ..errors import InfeasibleError
    from . import even_default

    depth, factor = settings.target_depth, settings.cycle_time_factor
    say(f"optimising the feed to the default target depth {depth * 1e6:.3g} um (cycle time within {factor:g}x "
        "the constant feed's)", 0, 1)
    try:
        timed, result, metrics = feed_stage(toolpath, tool, replace(settings, feed_simulate_check=False), trajectory,
                                            surface, progress=say, rounds=DEFAULT_JOB_FEED_ROUNDS)
    except InfeasibleError as exc:
        return exc, {}
    first: dict = {}
    reached = timed.duration / trajectory.duration
    if reached > factor * 1.01:
        lower = even_default.lower_target(depth, figures["constant_feed_interior_removal_mean_m"], factor, reached)
        if 0 < lower < depth:
            log.info("target %.3g um: cycle time %.2fx the constant feed's (over %.2gx); again at %.3g um",
                     depth * 1e6, reached, factor, lower * 1e6)
            first = {"first_target_depth_m": depth, "first_cycle_time_ratio": reached}
            settings = replace(settings, target_depth=lower)
            say(f"optimising the feed again to {lower * 1e6:.3g} um (the cycle time was {reached:.2f}x)", 0, 1)
            timed, result, metrics = feed_stage(toolpath, tool, replace(settings, feed_simulate_check=False),
                                                trajectory, surface, progress=say, rounds=DEFAULT_JOB_FEED_ROUNDS)
    return (settings, timed, result, metrics), first


def efficiency_after_gaps(metrics: dict, n_gaps: int, pad_radius: float) -> dict:
    """The efficiency of a trajectory whose passes the robot stage cut at ``n_gaps`` unreachable
    stretches, bounded again for the ends the cuts add.

    ``covered_lower_bound_m`` integrates ``dA / w_max`` over all the pad touched, and beyond the
    end of a contact stretch the pad touches a half patch that no path length pays for: a half
    ellipse of semi-axes ``a <= R`` along the feed and ``b`` across, area ``π a b / 2``, over a
    widest swath of at least ``2 b``, so at most ``π R / 4`` of bound per end.  A gap adds at most
    two ends on the part (a cut inside a pass), so the bound the path is compared with is lowered by
    ``2 · n_gaps · π R / 4``; without it a job cut into many stretches could report an efficiency
    over 1, which no path can reach.  Returns the metrics to update: ``efficiency``,
    ``covered_lower_bound_m`` and ``gap_end_allowance_m``.
    """
    allowance = 2 * n_gaps * math.pi * pad_radius / 4
    bound = max(float(metrics["covered_lower_bound_m"]) - allowance, 0.0)
    length = float(metrics["contact_length_m"])
    return {"covered_lower_bound_m": bound, "gap_end_allowance_m": allowance,
            "efficiency": bound / length if length > 0 else float("nan")}


def kept_clear(toolpath, surface, part, settings):
    """The planner's ``toolpath`` cut where the pad would touch a keep-out or cross the edge margin of
    ``part`` (its selection, or None: :func:`swath.segment.select.keep_clear`), and where its passes
    would crawl over a fold at the rim of ``surface`` under the job's angular speed limit
    (:func:`swath.plan.folds.cut_rim_folds`)."""
    from ..plan.folds import cut_rim_folds

    if part is not None and (part.keep_out.any() or part.edge_margin > 0):
        from ..segment.select import keep_clear

        toolpath = keep_clear(toolpath, part, settings.pad_radius)
    return cut_rim_folds(toolpath, surface, feed=settings.feed, omega_max=settings.max_angular,
                         pad_radius=settings.pad_radius)
