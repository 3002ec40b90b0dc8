"""A whole finishing job: part → plan → trajectory → removal → report, from one settings record.

:class:`JobSettings` holds every setting in SI units; the CLI and TOML job files fill it from text
with unit suffixes (``"38.1mm"``).  :func:`run_job` runs the stages and writes the output directory
atomically: it appears complete, or not at all.
"""

from __future__ import annotations

import difflib
import json
import logging
import math
import time
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, ClassVar

from ..errors import InputError
from . import jobwrap
from .settings import JobSettings, load_job_toml, settings_from_mapping  # noqa: F401  (the job's inputs)

if TYPE_CHECKING:                   # the trajectory stage is imported only when a job times a path
    from ..trajectory.links import LinkSettings

log = logging.getLogger(__name__)

def load_part(settings: JobSettings):
    """The job's part as a Surface (built-in example, mesh file, saved patch, or fitted scan)."""
    return load_part_info(settings)[0]


def load_part_info(settings: JobSettings, *, progress=None):
    """The job's part as ``(Surface, info)``.

    A STEP/IGES file is read as a :class:`~swath.io.part.Part` (:func:`swath.io.step.load_step`);
    with ``faces``/``keep_out``/``edge_margin`` set (any part), ``info["part"]`` holds the part
    with its selection and the Surface returned is the area to finish
    (:func:`swath.segment.select.work_surface`).

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
    selecting = settings.faces is not None or settings.keep_out is not None or settings.edge_margin > 0
    if PurePath(part).suffix.lower() in (".step", ".stp", ".iges", ".igs") or (selecting and not settings.fit):
        return _selected_part(settings, say)
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


def _selected_part(settings: JobSettings, say):
    """``(work surface, {"part": Part})`` of a CAD file, or of a mesh / example with a selection."""
    from pathlib import PurePath

    from ..io.part import Part
    from ..segment.select import select, work_surface

    name = settings.part
    if PurePath(name).suffix.lower() in (".step", ".stp", ".iges", ".igs"):
        from ..io.step import load_step

        part = load_step(name, chordal_tolerance=settings.chordal_tol, force_units=settings.force_units)
        say(f"read {len(part.faces)} CAD faces, tessellated to {settings.chordal_tol * 1e3:.3g} mm", 0, 1)
        faces = settings.faces
        if faces is None and part.closed:
            if settings.side is None:
                raise InputError(f"{PurePath(name).name} is a closed solid; pick the area to finish with --faces "
                                 "(ids, names or colours) or pass --side +z to finish the faces facing that side")
            faces = None if settings.side == "all" else _facing(part, settings.side)   # all: on a positioner
    else:
        from dataclasses import replace

        surface = load_part_info(replace(settings, faces=None, keep_out=None, edge_margin=0.0))[0]
        part = Part.from_surface(surface, source=name)
        faces = settings.faces
    part = select(part, faces=faces, keep_out=settings.keep_out, keep_out_margin=settings.keep_out_margin,
                  edge_margin=settings.edge_margin, units=settings.units)
    metrics = {"n_part_faces": len(part.faces), "selected_faces": sorted({int(i) for i in
                                                                         part.face_ids[part.work_triangles]})}
    if part.chordal_tolerance is not None:
        metrics["chordal_tolerance_m"] = part.chordal_tolerance
    return work_surface(part, settings.pad_radius), {"part": part, "metrics": metrics}


def _facing(part, side) -> str:
    """The ids (as a --faces text) of the faces of a closed CAD part whose mean normal faces ``side``."""
    import numpy as np

    from ..io.mesh import SIDE_DOT, parse_side

    direction = parse_side(side)
    s = part.surface
    weighted = np.zeros((max(f.id for f in part.faces) + 1, 3))
    np.add.at(weighted, part.face_ids, s.face_normals * s.face_areas[:, None])
    facing = [f.id for f in part.faces if weighted[f.id] @ direction > SIDE_DOT * np.linalg.norm(weighted[f.id])]
    if not facing:
        raise InputError(f"no face of the part faces --side {side}; pick faces with --faces")
    return ",".join(str(i) for i in facing)


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

    def bounded(self, toolpath, bar: float) -> tuple[float | None, str]:
        """``self(toolpath)``, or ``(None, why)`` without routing and timing the links when the
        candidate certainly costs more than ``bar`` (s): its passes' contact time plus a lower bound
        of its links' time (:func:`swath.trajectory.links_duration_bound`) exceeds it, so a cheaper
        candidate is already known.  Otherwise the very value of ``self(toolpath)`` (the passes are
        timed once)."""
        from ..order import order_toolpath
        from ..trajectory import contact_duration, links_duration_bound, time_passes, time_path

        names = ", ".join(type(c).__name__ for c in self.constraints)
        ordered = order_toolpath(toolpath, method=self.order)
        timed = time_passes(ordered, list(self.constraints))
        turning = [c.omega_max for c in self.constraints if type(c).__name__ == "AngularSpeedLimit"]
        least = contact_duration(timed) + links_duration_bound(ordered, timed, self.links,
                                                               omega_max=turning[0] if turning else None)
        if least > bar:
            return None, f"at least {least:.4g} s, more than the best cycle time {bar:.4g} s"
        return time_path(ordered, list(self.constraints), links=self.links, timed=timed).duration, \
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
        spec = PLANNER_OPTION_SCHEMA.get(k) or SCHEMA.get(k)   # a planner's own option first (edge_margin)
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
    if "axis" in takes:                       # the wrap planner turns about the cell's positioner axis
        from .positioner_job import positioner_axis

        context["axis"] = positioner_axis(settings)
    options = {k: v for k, v in {**context, **given}.items() if k in takes and v is not None}
    options.update(own)
    return options


def make_plan(surface, settings: JobSettings, *, progress=None, tool=None, part=None, choose_lead: bool = False,
              timings: dict | None = None, ridge: bool = False):
    """Run the job's planner on ``surface`` and order its passes; returns a ToolPath.
    ``progress(stage, done, total)`` hears about long planning steps; ``tool`` is the job's tool
    (default :func:`swath.cli.stages.job_tool`, built from the settings and the calibration).  With a
    ``part`` (its selection set), the passes are cut where the pad would touch a keep-out or cross
    the edge margin (:func:`swath.segment.select.keep_clear`) before they are ordered.  ``choose_lead``:
    the least-ripple spacing may choose the lead too (:func:`swath.cli.curved_spacing.curved_spacing_plan`;
    the plan's ``metadata["ripple_lead_rad"]``).  ``timings`` (a dict): with a spacing search
    (``settings.optimise_spacing``), ``timings["spacing_s"]`` is set to the time (s) the search took
    besides the planner call whose passes the job keeps (the plans at the spacings tried, the
    curvature read from them, the ripple models).  ``ridge``: a raster may turn to the uniform planner
    where its feed is held round a ridge (:mod:`swath.cli.ridge_turn`; ``metadata["ridge_planner"]``)."""
    from ..order import order_toolpath, route_links
    from ..plan import get_planner, planner_options
    from . import stages

    tool = stages.job_tool(settings) if tool is None else tool
    planner = get_planner(settings.planner)
    arguments = planner_arguments(settings, progress=progress)
    if part is not None and "around" in planner_options(settings.planner):
        arguments["around"] = part.surface     # the wrap planner keeps the pad clear of the whole part
    if settings.optimise_spacing:
        from .stages import spacing_plan

        if progress is not None:
            progress(f"choosing the spacing ({settings.optimise_spacing})", 0, 1)
        calls: list[float] = []
        t0 = time.perf_counter()
        toolpath = spacing_plan(surface, tool, jobwrap.timed(planner, calls), settings, arguments, choose_lead=choose_lead,
                                ridge=ridge, progress=progress)
        if timings is not None:
            # the last plan is the one kept (a search ends with the plan at the spacing chosen)
            timings["spacing_s"] = time.perf_counter() - t0 - (calls[-1] if calls else 0.0)
    elif settings.segment == "auto":
        from .stages import segmented_plan

        toolpath = segmented_plan(surface, tool, planner, settings, arguments)
    else:
        toolpath = planner(surface, tool, **arguments)
    toolpath = stages.kept_clear(toolpath, surface, part, settings)     # keep-outs, edge margin, folds at the rim
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
    from ..report.warncodes import tagged
    from ..simulate import simulate_removal
    from ..simulate.compliance import softer_pad_study, worth_a_study
    from ..trajectory import time_path
    from ..trajectory.timing import describe_lead
    from . import even_default, even_spacing, process_stage, ridge_turn, stages
    from .guard import check_budget

    if settings.side == "all":
        from .positioner_job import all_round_settings, job_positioner
        from .setups import run_setups

        if job_positioner(settings) is None:
            return run_setups(settings, progress=progress)
        settings = all_round_settings(settings)           # all round on the positioner, in one program
    say = progress or (lambda stage, done, total: None)
    timings = {}
    check_output_dir(settings.out, overwrite=settings.overwrite)
    plain = even_default.plain_alternative(settings)  # the plain plan the default job is compared with
    settings = even_default.resolve(settings)        # the default job: spacing, lead and feed for even removal
    tool = stages.job_tool(settings)
    if settings.target_cov is not None:
        from .target_cov import check_target_cov

        check_target_cov(settings)            # below the plane's floor: refused before the part is loaded

    from ..io.facing import facing_warning

    t0 = time.perf_counter()
    jobwrap.first_run_notice(say)                   # a fresh install compiles the kernels as it goes
    say("loading part", 0, 1)
    surface, part_info = load_part_info(settings, progress=say)
    log.info("part %s", surface)
    check_budget(surface, settings)
    from ..contact.tessellation import warn_if_coarse

    tessellation = warn_if_coarse(surface, tool)      # before planning: facets that kink more than the pad sinks
    if settings.robot and settings.place:
        stages.robot_fit_check(surface, settings)       # a part too big for the reach is refused before planning
    timings["load_s"] = time.perf_counter() - t0

    # a raster plans in this process alone (no workers): the plain plan is made beside it from the start
    early = even_default.plain_beside(surface, tool, plain, part=part_info.get("part")) if plain is not None and \
        settings.optimise_feed and even_default.is_even(settings) and settings.planner == "raster" else None
    searched, target_cov, ridge, constant_run = None, settings.target_cov, [], None   # constant_run: the lead check's
    settings_target = target_cov or 0.0
    if target_cov is not None:
        from .target_cov import search_target_cov

        t0 = time.perf_counter()
        searched = search_target_cov(surface, tool, settings, progress=say,
                                     plan_options={"tool": tool, "part": part_info.get("part")})
        surface.forget()                                  # the candidates' shared planning models
        settings = searched.chosen.settings               # the job goes on with the chosen candidate
        toolpath, trajectory = searched.chosen.toolpath, searched.chosen.trajectory
        timings["target_cov_search_s"] = time.perf_counter() - t0
    else:
        t0 = time.perf_counter()
        say(f"planning ({settings.planner})", 0, 1)
        searched_spacing: dict = {}
        toolpath = make_plan(surface, settings, progress=say, tool=tool, part=part_info.get("part"),
                             choose_lead=plain is not None,       # the default job chose the lead: on a curved part, again
                             timings=searched_spacing, ridge=plain is not None)
        ridge = ridge_turn.ridge_warnings(toolpath.metadata, settings)   # the raster's feed held round a ridge
        if toolpath.metadata.get("ridge_planner"):
            settings = replace(settings, planner=toolpath.metadata["ridge_planner"])
        if plain is not None:
            t1 = time.perf_counter()                                  # part of the even default's search
            even_default.settle_plan_lead(toolpath, surface, tool)    # ... for the spacing the plan has
            toolpath, constant_run = even_spacing.evener_passes(      # equidistant where the planes spread,
                toolpath, surface, tool, settings, part=part_info.get("part"), progress=say)  # the lead simulated
            searched_spacing["spacing_s"] = searched_spacing.get("spacing_s", 0.0) + time.perf_counter() - t1
        lead = toolpath.metadata.get("ripple_lead_rad")
        if plain is not None and lead is not None and lead != settings.lead():
            settings = replace(settings, lead_angle=lead)
        # the spacing search, when the job ran one, is its own stage: plan_s is the plan kept and its order
        timings.update(searched_spacing)
        timings["plan_s"] = time.perf_counter() - t0 - searched_spacing.get("spacing_s", 0.0)
        log.info("%d passes, %.3f m in contact", len(toolpath.passes), toolpath.contact_length)

        t0 = time.perf_counter()
        say("timing trajectory", 0, 1)
        trajectory = constant_run[0] if constant_run is not None else time_path(
            toolpath, settings.constraints(), links=settings.links(), lead_angle=settings.lead())
        timings["trajectory_s"] = time.perf_counter() - t0
        if plain is None or not settings.optimise_feed:
            surface.forget()                # no plan follows: the planners' shared models are released

    extra_metrics, figures, force, robot, feed = {}, {}, None, None, None
    even: dict | None = {} if settings.optimise_feed and even_default.is_even(settings) else None
    if settings.optimise_feed:
        t0 = time.perf_counter()
        # the plain plan is made beside the job (in a child process where one can be forked)
        plain_run = early or (None if plain is None or even is None else (
            even_default.plain_beside(surface, tool, plain, part=part_info.get("part"))))
        settings, trajectory, feed, feed_metrics = stages.even_feed_stage(
            toolpath, tool, settings, trajectory, surface, even, progress=say, plain=plain_run,
            constant=None if constant_run is None else constant_run[1])
        if even is not None and even.get("plain_plan_kept"):      # the plain plan's passes are written ...
            (toolpath, trajectory, plain_removal), settings = even.pop("_plain"), replace(plain, constant_feed=False)
            # ... with the feed optimised along them: where the curvature changes the contact width along a
            # pass, the feed follows it (blade: interior CoV 0.66 -> 0.57 at 1.4x the cycle time)
            settings = replace(settings, optimise_feed=True, target_floor="fastest")
            settings, trajectory, feed, feed_metrics = stages.even_feed_stage(
                toolpath, tool, settings, trajectory, surface, even, progress=say, constant=plain_removal)
        extra_metrics.update(feed_metrics)
        timings["feed_s"] = time.perf_counter() - t0
        surface.forget()
    if process_stage.wants_wear_stage(tool, settings):
        t0 = time.perf_counter()
        say("pad wear and media changes", 0, 1)
        trajectory, _, wear_metrics = process_stage.wear_stage(trajectory, tool, settings)
        extra_metrics.update(wear_metrics)
        timings["wear_s"] = time.perf_counter() - t0
    if settings.robot or settings.cell:
        t0 = time.perf_counter()
        say(f"robot: inverse kinematics for {settings.robot or 'the cell file robot'}", 0, 1)
        # the simulation below runs on the robot's trajectory: unreachable stretches are air there
        trajectory, robot, robot_metrics = stages.robot_stage(trajectory, surface, settings, progress=say)
        extra_metrics.update(robot_metrics)
        timings["robot_s"] = time.perf_counter() - t0
    if settings.force_control:
        t0 = time.perf_counter()
        say("simulating force control", 0, 1)
        trajectory, force, force_metrics = stages.force_stage(trajectory, surface, tool, settings)
        extra_metrics.update(force_metrics)
        timings["force_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    wear_and_holds = {"rate_scale": process_stage.removal_rate_scale(trajectory, tool, settings),
                      "holds": None if force is None else force.holds}
    simulated = (searched.chosen.trajectory, searched.chosen.removal) if searched is not None else \
        (even or {}).pop("_simulated", (None, None))      # the feed stage kept the constant feed it simulated
    if trajectory is simulated[0] and force is None and wear_and_holds["rate_scale"] is None:
        removal = simulated[1]                      # this very trajectory was simulated already
    else:
        removal = simulate_removal(trajectory, surface, tool, sample_spacing=settings.sample_spacing,
                                   sampling=settings.removal_sampling, force=None if force is None else force.force,
                                   progress=lambda d, n: say("simulating removal", d, n), **wear_and_holds)
    timings["simulate_s"] = time.perf_counter() - t0
    if even is not None and "_constant" in even and force is None and robot is None \
            and wear_and_holds["rate_scale"] is None:
        trajectory, removal, feed = even_default.keep_evener(trajectory, removal, feed, even)
        if even.get("plain_plan_kept") and feed is not None:
            even["plain_feed_optimised"] = True
        if "_plain" in even:
            kept = even_default.plain_if_evener(even.pop("_plain"), removal, even)
            if kept is not None:
                (toolpath, trajectory, removal), feed, settings = kept, None, replace(plain, constant_feed=False)
    if even is not None:
        even.pop("_plain", None)                 # the comparisons not made (a robot, force or wear stage re-timed)
        even.pop("_constant", None)
        if feed is None:                              # the feed figures describe a trajectory not written
            extra_metrics = {k: v for k, v in extra_metrics.items() if not k.startswith("feed_")}
    if force is not None and len(force.holds.get("dwell", ())):
        # the marks the landings and lifts leave, each on its own
        extra_metrics.update(process_stage.transient_metrics(trajectory, surface, tool, force, settings, removal))
    if worth_a_study(removal.metrics):
        # Uneven removal: would a softer pad, running the same programme, have removed more evenly?
        t0 = time.perf_counter()
        say("comparing with a softer pad", 0, 1)
        study = softer_pad_study(trajectory, surface, tool, removal, sampling=settings.removal_sampling,
                                 force=None if force is None else force.force, **wear_and_holds)
        if study is not None:
            extra_metrics.update(study)
        timings["pad_study_s"] = time.perf_counter() - t0

    metrics = dict(removal.metrics)
    if robot is not None and extra_metrics.get("robot_n_gaps"):
        metrics.update(stages.efficiency_after_gaps(metrics, int(extra_metrics["robot_n_gaps"]), tool.pad_radius))
    if even is not None:
        extra_metrics.update(even_default.even_metrics(settings, removal, trajectory,
                                                       {k: v for k, v in even.items() if k != "warnings"},
                                                       tool))
    if part_info.get("part") is not None:
        extra_metrics.update(_judge_on_part(part_info["part"], trajectory, tool, settings, force, say))
    warnings: list[str] = list(ridge)              # the job's own warnings (the others come from plan_warnings)
    if even is not None:
        warnings += even.pop("warnings", [])
    if searched is not None:
        metrics.update(searched.metrics(settings_target))
        if not metrics["interior_removal_cov"] <= settings_target:      # a later stage (robot, force) changed it
            warnings.append(
                f"--target-cov: the chosen plan reached {float(searched.chosen.interior_removal_cov or 0.0) * 100:.1f} %, but the "
                f"job's final trajectory removes with an interior CoV of {metrics['interior_removal_cov'] * 100:.1f} % "
                f"(> {settings_target * 100:.1f} %): the robot or force stage changed the timing [W-TARGET-COV-MISSED]")
    from ..simulate.ripple import removal_ripple

    metrics.update(removal_ripple(removal, trajectory, tool))      # the mid-spatial ripple across the passes
    from ..simulate.evenness import evenness_metrics
    from ..simulate.hot_spots import hot_spot_metrics
    metrics.update(evenness_metrics(removal, trajectory, tool))    # where the interior CoV comes from
    if settings.target_map is None:        # (a target map varies the depth on purpose: rework says its own residual)
        metrics.update(hot_spot_metrics(removal, trajectory, tool))    # where it runs deepest, and why
    metrics.update(jobwrap.plan_figures(toolpath.metadata, metrics))     # the plan's own figures
    metrics.update(timings)
    metrics.update(part_info.get("metrics", {}))
    metrics.update(extra_metrics)
    if settings.calibration:
        metrics["preston_coefficient_per_Pa"] = tool.preston
    metrics.update(tool_motion=tool.motion, spindle_speed_rpm=tool.spindle_speed * 60 / (2 * math.pi),
                   orbit_radius_m=tool.orbit_radius if tool.motion == "orbital" else 0.0,
                   pad_depression_on_flat_m=tool.flat_depression)
    # FORMATS.md: a deliberate tilt of the tool is stated in the job's metadata
    ramp = float(trajectory.metadata.get("lead_end_ramp_m", 0.0))       # the lead laid flat at each pass end
    metrics.update(lead_angle_rad=settings.lead(), lead_end_ramp_m=ramp, tool_tilt=describe_lead(settings.lead(), ramp))
    metrics["warnings"] = plan_warnings(surface, toolpath, trajectory, metrics, settings.feed, tool.pad_radius)
    facing = facing_warning(surface, side=settings.side)      # a part planned from underneath
    if facing is not None:
        metrics["warnings"].insert(0, facing)
    if robot is not None:
        metrics["warnings"] += robot.warnings
    if "keep_out_warning" in metrics:
        metrics["warnings"].append(metrics.pop("keep_out_warning"))
    metrics["warnings"] += warnings
    metrics["warnings"] = [tagged(w) for w in metrics["warnings"]]        # "... [W-CODE]", docs: Warnings
    for w in metrics["warnings"]:
        log.warning("%s", w)
    # logged before planning, listed with the job's warnings
    metrics["warnings"] += [tagged(w) for w in tessellation.warnings(surface.name)]
    metrics.update(tessellation.metrics())
    record = settings.as_record()
    record.update(motion=tool.motion, spindle_speed_rad_per_s=tool.spindle_speed, orbit_radius_m=tool.orbit_radius,
                  preston_coefficient_per_Pa=tool.preston, wear_rate_per_s=tool.wear_rate)
    record["plan"] = dict(toolpath.metadata)
    if target_cov is not None:
        record["target_cov"] = target_cov

    say("writing report", 0, 1)
    with atomic_directory(settings.out, overwrite=settings.overwrite) as tmp:
        trajectory.write_csv(tmp / "trajectory.csv")
        if robot is not None:
            figures.update(stages.write_robot_outputs(robot, surface, settings, tmp / "robot"))
        if part_info.get("patch") is not None:
            from ..io.patch_files import save_patch

            save_patch(part_info["patch"], tmp / "patch.json", part_info.get("footprint"))
        feed_plots = None
        if feed is not None:
            from ..core.beside import Beside
            from ..report.feed_plots import write_feed_plots

            # drawn by a forked child while this process draws the report's own figures (the same files)
            feed_plots = Beside(write_feed_plots, tmp, feed)
            figures[jobwrap.FEED_PLOTS] = None                  # their place among the figures
        if searched is not None:
            from ..report.target_cov_plot import write_target_cov_plot

            figures.update(write_target_cov_plot(tmp, metrics["target_cov_candidates"], settings_target))
        if force is not None:
            from ..report.force_plots import write_force_plots

            figures.update(write_force_plots(tmp, trace=force))
        traces = None
        if robot is not None:
            from ..report.robot_plots import robot_traces

            traces = robot_traces(robot)          # the arm, its reach and the stretches it skips
        write_report(tmp, surface=surface, toolpath=toolpath, trajectory=trajectory, removal=removal,
                     metrics=metrics, settings=_jsonable(record), title=f"swath plan — {surface.name}",
                     extra_figures=figures if feed_plots is None else (
                         lambda: jobwrap.in_place(figures, feed_plots.result)),
                     scene_traces=None if robot is None else stages.cell_scene(robot, metrics, surface) + (traces or []))
    say("done", 1, 1)
    return metrics


def _judge_on_part(part, trajectory, tool, settings, force, say) -> dict:
    """The removal of the job's trajectory simulated on the whole part (every face, not only the
    area planned on), judged by :func:`swath.segment.select.area_metrics`; a warning when a
    keep-out receives removal."""
    from ..segment.select import area_metrics
    from ..simulate import simulate_removal

    whole = simulate_removal(trajectory, part.surface, tool, sample_spacing=settings.sample_spacing,
                             sampling=settings.removal_sampling, force=None if force is None else force.force,
                             progress=lambda d, n: say("simulating removal on the whole part", d, n))
    metrics = area_metrics(part, whole.surface.vertices, whole.surface.vertex_areas, whole.depth)
    metrics["part_faces"] = part.faces_table()
    if metrics["keep_out_max_removal_m"] > 0:
        metrics["keep_out_warning"] = (f"the pad removes material on the keep-outs: up to "
                                       f"{metrics['keep_out_max_removal_m'] * 1e6:.3g} um over "
                                       f"{metrics['keep_out_touched_area_m2'] * 1e4:.3g} cm²; raise --keep-out-margin")
    return metrics


def _jsonable(d: dict) -> dict:
    return json.loads(json.dumps(d, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o)))
