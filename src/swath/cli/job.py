"""A whole finishing job: part → plan → trajectory → removal → report, from one settings record.

:class:`JobSettings` holds every setting in SI units; the CLI and TOML job files fill it from text
with unit suffixes (``"38.1mm"``).  :func:`run_job` runs the stages and writes the output directory
atomically: it appears complete, or not at all.
"""

from __future__ import annotations

import difflib
import json
import logging
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

from ..errors import InputError
from .settings import JobSettings, load_job_toml, settings_from_mapping  # noqa: F401  (the job's inputs)

if TYPE_CHECKING:                   # the trajectory stage is imported only when a job times a path
    from ..trajectory.links import LinkSettings

log = logging.getLogger(__name__)

def load_part(settings: JobSettings):
    """The job's part as a Surface (built-in example, mesh file, saved patch, or fitted scan)."""
    return load_part_info(settings)[0]


def load_part_info(settings: JobSettings, *, progress=None):
    """The job's part as ``(Surface, info)``.

    ``info`` is empty for a mesh or an example; for a patch (``patch.json``, or a scan fitted
    with ``settings.fit``) it holds ``"patch"`` (the BSplinePatch), ``"footprint"`` (the scanned
    area the surface is trimmed to, or None) and ``"metrics"`` (fit figures and the triangulation
    spacing, units in the key names).
    """
    from pathlib import PurePath

    from ..io.patch_files import load_patch
    from ..io.scan import is_point_cloud_file, load_scan, scan_from_surface
    from ..surface.footprint import patch_surface, scan_footprint
    from . import fitjob

    say = progress or (lambda stage, done, total: None)
    part = settings.part
    if part.startswith("example:"):
        from ..examples import example_part

        surface = example_part(part.split(":", 1)[1])
        if not settings.fit:
            return surface, {}
        scan = scan_from_surface(surface)
    elif PurePath(part).suffix.lower() == ".json":
        if settings.fit:
            raise InputError(f"{PurePath(part).name} is already a fitted patch; drop --fit to plan on it")
        patch, footprint = load_patch(part)
        surface, spacing = patch_surface(patch, spacing=settings.surface_spacing, name=PurePath(part).stem,
                                                footprint=footprint)
        say(f"triangulated the patch at {spacing * 1e3:.3g} mm"
            + ("" if footprint is None else ", trimmed to the scanned area"), 0, 1)
        return surface, {"patch": patch, "footprint": footprint, "metrics": {"surface_spacing_m": spacing}}
    elif settings.fit:
        scan = load_scan(part, units=settings.units, side=settings.side, force_units=settings.force_units)
    else:
        if is_point_cloud_file(part):
            raise InputError(f"{PurePath(part).name} is a point cloud, not a mesh; add --fit to plan on a B-spline "
                             "patch fitted to it (or run `swath fit` and plan its patch.json)")
        from ..io.mesh import load_mesh

        return load_mesh(part, units=settings.units, side=settings.side, all_pieces=settings.all_pieces,
                         force_units=settings.force_units), {}
    say(f"fitting a B-spline patch to {len(scan.points)} points ({settings.parameterization} parameterisation)", 0, 1)
    patch, report = fitjob.fit_scan(scan, parameterization=settings.parameterization, side=settings.side)
    u, v, _ = patch.project(scan.points)
    footprint = scan_footprint(patch, scan.points, u, v, faces=scan.faces, rms=report.rms)
    surface, spacing = patch_surface(patch, spacing=settings.surface_spacing, name=scan.name,
                                            footprint=footprint)
    say(f"fit rms {report.rms * 1e3:.3g} mm; triangulated the patch at {spacing * 1e3:.3g} mm, trimmed to the scan"
        + ("" if settings.surface_spacing is not None else " (default: extent / 150 in 2..5 mm)"), 0, 1)
    metrics = {"fit_rms_m": report.rms, "fit_max_error_m": report.max_error, "n_fit_points": report.n_points,
               "n_fit_dropped": report.n_dropped, "fit_time_s": report.time, "surface_spacing_m": spacing}
    return surface, {"patch": patch, "footprint": footprint, "metrics": metrics}


@dataclass(frozen=True)
class CycleTimeCost:
    """A cost function for planners that compare candidates: the cycle time (s) of a candidate
    tool path ordered by ``order`` (None: the planner's hint) and timed under exactly the
    ``constraints`` and ``links`` the job's trajectory will use.

    A plain record with ``__call__`` (not a closure), so it pickles: a planner may rank its
    candidates in worker processes.

    Attributes
    ----------
    constraints : tuple of constraint records
        The job's trajectory limits (:mod:`swath.trajectory`).
    links : LinkSettings
        The job's air moves between passes.
    order : str or None
        Order-stage method applied before timing (None: the tool path's ``order_hint``).
    """

    constraints: tuple
    links: LinkSettings | None
    order: str | None = None
    #: The cost reads the passes and the order metadata only (the uniform planner then ranks
    #: candidate directions that lay the same passes once).
    passes_only: ClassVar[bool] = True

    def prepare(self) -> None:
        """Import what :meth:`__call__` needs (the order and trajectory stages, toppra) now: a planner
        that forks worker processes calls this first, so the workers inherit the imports instead of
        each repeating them (about 0.3 s of CPU per worker)."""
        from .. import order, trajectory  # noqa: F401

        try:
            import toppra  # noqa: F401
        except ImportError:                # pragma: no cover - toppra is a dependency; timing falls back
            pass

    def __call__(self, toolpath) -> tuple[float, str]:
        from ..order import order_toolpath
        from ..trajectory import time_path

        names = ", ".join(type(c).__name__ for c in self.constraints)
        ordered = order_toolpath(toolpath, method=self.order)
        return time_path(ordered, list(self.constraints), links=self.links).duration, \
            f"predicted cycle time (s) under {names}"


def cycle_time_cost(constraints, links, order: str | None = None) -> CycleTimeCost:
    """The :class:`CycleTimeCost` of a job's ``constraints`` (sequence), ``links`` and ``order``."""
    return CycleTimeCost(tuple(constraints), links, order)


def planner_arguments(settings: JobSettings, *, progress=None) -> dict:
    """The keyword options the job passes to its planner: those the planner takes, from the job's
    settings and ``planner_options``; the planner's own default where a setting is None.

    Raises
    ------
    InputError
        When a setting or planner option is given that the chosen planner does not take, naming the
        planners that do.
    """
    from ..plan import planner_options, planners_taking
    from .settings import PLANNER_OPTION_SCHEMA, SCHEMA, parse_value

    takes = planner_options(settings.planner)
    given = {"spacing": settings.spacing, "direction": settings.direction, "overlap": settings.overlap}
    own = {}
    for k, v in settings.planner_options.items():
        spec = SCHEMA.get(k) or PLANNER_OPTION_SCHEMA.get(k)
        if spec is None and k in takes:
            # a library-only option (the job's cost and progress, a direction vector): no text form
            raise InputError(f"planner_options.{k} cannot be set from a job; the options a job may give the "
                             f"{settings.planner} planner: "
                             f"{', '.join(sorted(o for o in takes if o in SCHEMA or o in PLANNER_OPTION_SCHEMA))}")
        own[k] = parse_value(f"planner_options.{k}", v, spec) if spec is not None else v
    for key, value in {**given, **own}.items():
        if value is not None and key not in takes:
            others = planners_taking(key)
            close = difflib.get_close_matches(key, sorted(takes - {"progress", "cost"}), n=1)
            if close and not others:
                raise InputError(f"the {settings.planner} planner does not take {key!r}; did you mean {close[0]!r}?")
            raise InputError(f"the {settings.planner} planner does not take {key!r}"
                             + (f"; planners that do: {', '.join(others)}" if others else
                                f"; it takes: {', '.join(sorted(takes - {'progress', 'cost'}))}"))
    context = {"point_spacing": settings.point_spacing, "feed": settings.feed, "progress": progress,
               "cost": cycle_time_cost(settings.constraints(), settings.links(), settings.order)}
    if settings.max_angular is not None:
        context["max_angular"] = settings.max_angular
    options = {k: v for k, v in {**context, **given}.items() if k in takes and v is not None}
    options.update(own)
    return options


def make_plan(surface, settings: JobSettings, *, progress=None):
    """Run the job's planner on ``surface`` and order its passes; returns a ToolPath.
    ``progress(stage, done, total)`` hears about long planning steps."""
    from ..order import order_toolpath, route_links
    from ..plan import get_planner

    planner = get_planner(settings.planner)
    arguments = planner_arguments(settings, progress=progress)
    if settings.optimise_spacing:
        from .stages import spacing_plan

        toolpath = spacing_plan(surface, settings.tool(), planner, settings, arguments)
    elif settings.segment == "auto":
        from .stages import segmented_plan

        toolpath = segmented_plan(surface, settings.tool(), planner, settings, arguments)
    else:
        toolpath = planner(surface, settings.tool(), **arguments)
    ordered = order_toolpath(toolpath, method=order_method(toolpath, settings), **order_options(toolpath, settings))
    return route_links(ordered, clearance=settings.clearance, pad_radius=settings.pad_radius, units=settings.units)


def order_options(toolpath, settings) -> dict:
    """Options for the tour methods of the order stage: links routed as the trajectory flies them
    and costed by time under the job's own link speed and angular-speed limit (a snake's 180-degree
    turn costs seconds, not millimetres), or with ``order_objective = "length"`` by air length."""
    from ..order import ORDER_METHODS, sequence

    method = order_method(toolpath, settings)
    if ORDER_METHODS.get(method) in (sequence.snake, sequence.zigzag):
        return {}
    links = settings.links()
    options = {"clearance": links.clearance, "pad_radius": settings.pad_radius}
    if settings.order_objective == "time":
        options.update(link_speed=links.speed, link_acceleration=links.acceleration, omega_max=settings.max_angular,
                       feed=settings.feed)
    if settings.join_gap is not None:
        options["join_gap"] = settings.join_gap
    if settings.order_groups == "passes":
        # Every pass its own group: order and direction chosen pass by pass, regions may interleave.
        options["groups"] = [[i] for i in range(len(toolpath.passes))]
    return options


def order_method(toolpath, settings) -> str:
    """The order-stage method of a job: the one asked for, gtsp when step-overs may be joined in
    contact (``join_gap``), else the planner's ``order_hint``."""
    if settings.order:
        return settings.order
    if settings.join_gap is not None:
        return "gtsp"
    return toolpath.metadata.get("order_hint", "snake")


def run_job(settings: JobSettings, *, progress=None) -> dict:
    """Run a whole job and write ``trajectory.csv``, ``metrics.json``, ``report.html`` and PNGs.

    Everything that can be refused from the settings alone (the output folder, units, values, the
    planner's options) is refused before the part is loaded; the work the part needs is estimated
    and refused over the memory budget before planning (:func:`swath.cli.guard.check_budget`).

    Parameters
    ----------
    settings : JobSettings
    progress : callable, optional
        ``progress(stage: str, done: int, total: int)`` for long steps.

    Returns
    -------
    dict
        The metrics (keys with units), with ``warnings`` (list of str).
    """
    from ..io.atomic import atomic_directory, check_output_dir
    from ..report import plan_warnings, write_report
    from ..simulate import simulate_removal
    from ..simulate.compliance import softer_pad_study, worth_a_study
    from ..trajectory import time_path
    from ..trajectory.timing import describe_lead
    from . import stages
    from .guard import check_budget

    say = progress or (lambda stage, done, total: None)
    timings = {}
    check_output_dir(settings.out, overwrite=settings.overwrite)
    tool = stages.job_tool(settings)

    t0 = time.perf_counter()
    say("loading part", 0, 1)
    surface, part_info = load_part_info(settings, progress=say)
    log.info("part %s", surface)
    check_budget(surface, settings)
    timings["load_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    say(f"planning ({settings.planner})", 0, 1)
    toolpath = make_plan(surface, settings, progress=say)
    timings["plan_s"] = time.perf_counter() - t0
    log.info("%d passes, %.3f m in contact", len(toolpath.passes), toolpath.contact_length)

    t0 = time.perf_counter()
    say("timing trajectory", 0, 1)
    trajectory = time_path(toolpath, settings.constraints(), links=settings.links(), lead_angle=settings.lead())
    timings["trajectory_s"] = time.perf_counter() - t0

    extra_metrics, figures, force, robot, feed = {}, {}, None, None, None
    if settings.optimise_feed:
        t0 = time.perf_counter()
        say("optimising the feed (dwell) to the target depth", 0, 1)
        trajectory, feed, feed_metrics = stages.feed_stage(toolpath, tool, settings, trajectory, surface, progress=say)
        extra_metrics.update(feed_metrics)
        timings["feed_s"] = time.perf_counter() - t0
    if settings.robot:
        t0 = time.perf_counter()
        say(f"robot: inverse kinematics for {settings.robot}", 0, 1)
        trajectory, robot, robot_metrics = stages.robot_stage(trajectory, surface, settings)
        extra_metrics.update(robot_metrics)
        timings["robot_s"] = time.perf_counter() - t0
    if settings.force_control:
        t0 = time.perf_counter()
        say("simulating force control", 0, 1)
        trajectory, force, force_metrics = stages.force_stage(trajectory, surface, tool, settings)
        extra_metrics.update(force_metrics)
        timings["force_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    removal = simulate_removal(trajectory, surface, tool, sample_spacing=settings.sample_spacing,
                               sampling=settings.removal_sampling, force=None if force is None else force.force,
                               progress=lambda d, n: say("simulating removal", d, n))
    timings["simulate_s"] = time.perf_counter() - t0
    if worth_a_study(removal.metrics):
        # Uneven removal: would a softer pad, running the same programme, have removed more evenly?
        t0 = time.perf_counter()
        say("comparing with a softer pad", 0, 1)
        study = softer_pad_study(trajectory, surface, tool, removal, sampling=settings.removal_sampling,
                                 force=None if force is None else force.force)
        if study is not None:
            extra_metrics.update(study)
        timings["pad_study_s"] = time.perf_counter() - t0

    metrics = dict(removal.metrics)
    metrics.update({k: float(v) for k, v in toolpath.metadata.items() if isinstance(v, (int, float))
                    and not isinstance(v, bool) and k.endswith(("_m", "_rad", "_s")) and k not in metrics})
    metrics.update(timings)
    metrics.update(part_info.get("metrics", {}))
    metrics.update(extra_metrics)
    if settings.calibration:
        metrics["preston_coefficient_per_Pa"] = tool.preston
    # FORMATS.md: a deliberate tilt of the tool is stated in the job's metadata
    metrics["lead_angle_rad"] = settings.lead()
    metrics["tool_tilt"] = describe_lead(settings.lead())
    metrics["warnings"] = plan_warnings(surface, toolpath, trajectory, metrics, settings.feed, tool.pad_radius)
    if robot is not None:
        metrics["warnings"] += robot.warnings
    for w in metrics["warnings"]:
        log.warning("%s", w)
    record = settings.as_record()
    record["plan"] = dict(toolpath.metadata)

    say("writing report", 0, 1)
    with atomic_directory(settings.out, overwrite=settings.overwrite) as tmp:
        trajectory.write_csv(tmp / "trajectory.csv")
        if robot is not None:
            figures.update(stages.write_robot_outputs(robot, surface, settings, tmp / "robot"))
        if part_info.get("patch") is not None:
            from ..io.patch_files import save_patch

            save_patch(part_info["patch"], tmp / "patch.json", part_info.get("footprint"))
        if feed is not None:
            from ..report.feed_plots import write_feed_plots

            figures.update(write_feed_plots(tmp, feed))
        if force is not None:
            from ..report.force_plots import write_force_plots

            figures.update(write_force_plots(tmp, trace=force))
        write_report(tmp, surface=surface, toolpath=toolpath, trajectory=trajectory, removal=removal,
                     metrics=metrics, settings=_jsonable(record), title=f"swath plan — {surface.name}",
                     extra_figures=figures)
    say("done", 1, 1)
    return metrics


def _jsonable(d: dict) -> dict:
    return json.loads(json.dumps(d, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o)))
