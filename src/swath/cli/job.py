"""A whole finishing job: part → plan → trajectory → removal → report, from one settings record.

:class:`JobSettings` holds every setting in SI units; the CLI and TOML job files fill it from text
with unit suffixes (``"38.1mm"``).  :func:`run_job` runs the stages and writes the output directory
atomically: it appears complete, or not at all.
"""

from __future__ import annotations

import json
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import InputError
from ..units import parse_quantity

log = logging.getLogger(__name__)

#: Robot-realistic limits every trajectory is timed under unless the user turns them off ("none"):
#: tool angular speed (rad/s), centripetal and tangential acceleration (m/s²).
DEFAULT_LIMITS = {"max_angular": 1.0, "max_centripetal": 2.0, "max_accel": 1.0}

#: Sentinel text that turns a default limit off.
OFF_WORDS = ("none", "off", "no")


@dataclass(frozen=True)
class JobSettings:
    """Every setting of a job, SI units.

    ``part`` is a mesh file path, ``example:NAME`` for a built-in part (``example:blade``), a
    B-spline patch saved by ``swath fit`` (``patch.json``), or, with ``fit``, a scan (point cloud
    or mesh) to fit a B-spline patch to first.  A patch is planned on its triangulation at
    ``surface_spacing`` (m; default its longest extent / 150, clipped to 2..5 mm).
    """

    part: str
    out: str
    units: str = "m"
    side: str | None = None
    all_pieces: bool = False
    force_units: bool = False
    planner: str = "raster"
    order: str | None = None
    pad_radius: float = 0.0381
    force: float = 20.0
    depression: float | None = None
    stiffness: float | None = None
    motion: str = "orbital"
    feed: float = 0.05
    spacing: float | None = None
    direction: float | None = None
    point_spacing: float = 1e-3
    clearance: float = 0.02
    max_centripetal: float | None = DEFAULT_LIMITS["max_centripetal"]
    max_angular: float | None = DEFAULT_LIMITS["max_angular"]
    max_accel: float | None = DEFAULT_LIMITS["max_accel"]
    overlap: float | None = None
    sample_spacing: float | None = None
    planner_options: dict = field(default_factory=dict)
    fit: bool = False
    parameterization: str = "auto"
    surface_spacing: float | None = None

    def tool(self):
        from ..contact import Tool

        return Tool(pad_radius=self.pad_radius, force=self.force, depression=self.depression,
                    stiffness=self.stiffness, motion=self.motion)

    def constraints(self) -> list:
        """The trajectory constraints: the feed and whichever limits are on (by default all three of
        :data:`DEFAULT_LIMITS`)."""
        from ..trajectory import AngularSpeedLimit, CentripetalLimit, FeedLimit, TangentialAccelLimit

        out = [FeedLimit(self.feed)]
        if self.max_centripetal is not None:
            out.append(CentripetalLimit(self.max_centripetal))
        if self.max_angular is not None:
            out.append(AngularSpeedLimit(self.max_angular))
        if self.max_accel is not None:
            out.append(TangentialAccelLimit(self.max_accel))
        return out

    def links(self):
        """How the tool moves between passes."""
        from ..trajectory import LinkSettings

        return LinkSettings(clearance=self.clearance)

    def as_record(self) -> dict:
        """Settings with units in the key names, for metrics.json and the report."""
        tool = self.tool()
        return {
            "part": self.part, "units": self.units, "planner": self.planner,
            "pad_radius_m": self.pad_radius, "force_N": self.force,
            "depression_on_flat_m": tool.flat_depression, "stiffness_Pa_per_m": tool.k,
            "motion": self.motion, "feed_m_per_s": self.feed, "spacing_m": self.spacing,
            "direction_rad": self.direction, "order": self.order, "point_spacing_m": self.point_spacing, "clearance_m": self.clearance,
            "max_centripetal_m_per_s2": self.max_centripetal, "max_angular_rad_per_s": self.max_angular,
            "max_accel_m_per_s2": self.max_accel,
            "fit": self.fit, "fit_parameterization": self.parameterization,
            "surface_spacing_m": self.surface_spacing,
            **{f"planner_{k}": v for k, v in self.planner_options.items()},
        }


# Text keys (CLI flags and TOML keys) -> (field, quantity kind or None for plain values).
_QUANTITY_FIELDS = {
    "pad_radius": "length", "pad-radius": "length",
    "force": "force",
    "depression": "length",
    "stiffness": "stiffness",
    "feed": "speed",
    "spacing": "length",
    "angle": "angle",
    "direction": "angle",
    "point_spacing": "length", "point-spacing": "length",
    "clearance": "length",
    "sample_spacing": "length", "sample-spacing": "length",
    "surface_spacing": "length", "surface-spacing": "length",
    "max_centripetal": "acceleration", "max-centripetal": "acceleration",
    "max_angular": "angular_speed", "max-angular": "angular_speed",
    "max_accel": "acceleration", "max-accel": "acceleration",
    "overlap": "fraction",
}
_PLAIN_FIELDS = {"part", "out", "units", "side", "all_pieces", "all-pieces", "force_units", "force-units",
                 "planner", "order", "motion", "fit", "parameterization"}


def settings_from_mapping(values: dict, *, base_dir: Path | None = None) -> JobSettings:
    """Build :class:`JobSettings` from text values (a TOML table or parsed CLI flags).

    Quantities accept unit suffixes; bare numbers are SI (``pad_radius = 0.0381``) except angles,
    which default to degrees.  Unknown keys are refused by name.
    """
    kwargs = {}
    for key, value in values.items():
        if value is None:
            continue
        name = key.replace("-", "_")
        if name == "angle":              # the raster planner's word for the pass direction
            name = "direction"
        if key in _QUANTITY_FIELDS:
            kind = _QUANTITY_FIELDS[key]
            if kind == "angle" and str(value).strip().lower() == "auto":
                kwargs[name] = None
                continue
            if name in DEFAULT_LIMITS and str(value).strip().lower() in OFF_WORDS:
                kwargs[name] = None      # the user turned a default limit off
                continue
            kwargs[name] = parse_quantity(value, kind, default_unit="deg" if kind == "angle" else None)
        elif key in _PLAIN_FIELDS:
            kwargs[name] = value
        elif key == "planner_options" and isinstance(value, dict):
            kwargs[name] = dict(value)
        else:
            known = sorted({k.replace("-", "_") for k in list(_QUANTITY_FIELDS) + list(_PLAIN_FIELDS)})
            raise InputError(f"unknown job setting {key!r}; known settings: {', '.join(known)}")
    if "part" not in kwargs or "out" not in kwargs:
        raise InputError("a job needs 'part' (a mesh file or example:NAME) and 'out' (the output directory)")
    if base_dir is not None:
        for k in ("part", "out"):
            p = str(kwargs[k])
            if not p.startswith("example:") and not Path(p).is_absolute():
                kwargs[k] = str(base_dir / p)
    from ..order import ORDER_METHODS
    from ..plan import get_planner

    get_planner(kwargs.get("planner", "raster"))          # refuses an unknown planner by name
    if kwargs.get("order") is not None and kwargs["order"] not in ORDER_METHODS:
        raise InputError(f"unknown order {kwargs['order']!r}; choose one of {', '.join(ORDER_METHODS)}")
    if "parameterization" in kwargs:
        from ..surface.fit import PARAMETERIZATIONS

        if kwargs["parameterization"] not in PARAMETERIZATIONS:
            raise InputError(f"unknown parameterization {kwargs['parameterization']!r}; choose one of "
                             f"{', '.join(PARAMETERIZATIONS)}")
    if kwargs.get("surface_spacing") is not None and not kwargs["surface_spacing"] > 0:
        raise InputError(f"surface_spacing must be a positive length, got {kwargs['surface_spacing']!r} m")
    return JobSettings(**kwargs)


def load_job_toml(path) -> JobSettings:
    """Read a TOML job file: top-level keys as in :class:`JobSettings`, quantities with units."""
    import tomllib

    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"job file {path} not found") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"job file {path} is not valid TOML: {exc}") from None
    table = data.get("job", data)
    return settings_from_mapping(table, base_dir=path.parent)


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

    from . import fitjob

    say = progress or (lambda stage, done, total: None)
    part = settings.part
    if part.startswith("example:"):
        from ..examples import example_part

        surface = example_part(part.split(":", 1)[1])
        if not settings.fit:
            return surface, {}
        scan = fitjob.scan_from_surface(surface)
    elif PurePath(part).suffix.lower() == ".json":
        if settings.fit:
            raise InputError(f"{PurePath(part).name} is already a fitted patch; drop --fit to plan on it")
        patch, footprint = fitjob.load_patch(part)
        surface, spacing = fitjob.patch_surface(patch, spacing=settings.surface_spacing, name=PurePath(part).stem,
                                                footprint=footprint)
        say(f"triangulated the patch at {spacing * 1e3:.3g} mm"
            + ("" if footprint is None else ", trimmed to the scanned area"), 0, 1)
        return surface, {"patch": patch, "footprint": footprint, "metrics": {"surface_spacing_m": spacing}}
    elif settings.fit:
        scan = fitjob.load_scan(part, units=settings.units, side=settings.side, force_units=settings.force_units)
    else:
        if fitjob.is_point_cloud_file(part):
            raise InputError(f"{PurePath(part).name} is a point cloud, not a mesh; add --fit to plan on a B-spline "
                             "patch fitted to it (or run `swath fit` and plan its patch.json)")
        from ..io.mesh import load_mesh

        return load_mesh(part, units=settings.units, side=settings.side, all_pieces=settings.all_pieces,
                         force_units=settings.force_units), {}
    say(f"fitting a B-spline patch to {len(scan.points)} points ({settings.parameterization} parameterisation)", 0, 1)
    patch, report = fitjob.fit_scan(scan, parameterization=settings.parameterization, side=settings.side)
    u, v, _ = patch.project(scan.points)
    footprint = fitjob.scan_footprint(patch, scan.points, u, v, faces=scan.faces, rms=report.rms)
    surface, spacing = fitjob.patch_surface(patch, spacing=settings.surface_spacing, name=scan.name,
                                            footprint=footprint)
    say(f"fit rms {report.rms * 1e3:.3g} mm; triangulated the patch at {spacing * 1e3:.3g} mm, trimmed to the scan"
        + ("" if settings.surface_spacing is not None else " (default: extent / 150 in 2..5 mm)"), 0, 1)
    metrics = {"fit_rms_m": report.rms, "fit_max_error_m": report.max_error, "n_fit_points": report.n_points,
               "n_fit_dropped": report.n_dropped, "fit_time_s": report.time, "surface_spacing_m": spacing}
    return surface, {"patch": patch, "footprint": footprint, "metrics": metrics}


def cycle_time_cost(constraints, links, order: str | None = None):
    """A cost function for planners that compare candidates: the cycle time (s) of a candidate
    tool path ordered by ``order`` (None: the planner's hint) and timed under exactly the
    ``constraints`` and ``links`` the job's trajectory will use."""
    from ..order import order_toolpath
    from ..trajectory import time_path

    names = ", ".join(type(c).__name__ for c in constraints)

    def cost(toolpath) -> tuple[float, str]:
        ordered = order_toolpath(toolpath, method=order)
        return time_path(ordered, constraints, links=links).duration, f"predicted cycle time (s) under {names}"

    return cost


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

    takes = planner_options(settings.planner)
    given = {"spacing": settings.spacing, "direction": settings.direction, "overlap": settings.overlap}
    for key, value in {**given, **settings.planner_options}.items():
        if value is not None and key not in takes:
            others = planners_taking(key)
            raise InputError(f"the {settings.planner} planner does not take {key!r}"
                             + (f"; planners that do: {', '.join(others)}" if others else
                                f"; it takes: {', '.join(sorted(takes - {'progress', 'cost'}))}"))
    context = {"point_spacing": settings.point_spacing, "feed": settings.feed, "progress": progress,
               "cost": cycle_time_cost(settings.constraints(), settings.links(), settings.order)}
    if settings.max_angular is not None:
        context["max_angular"] = settings.max_angular
    options = {k: v for k, v in {**context, **given}.items() if k in takes and v is not None}
    options.update(settings.planner_options)
    return options


def make_plan(surface, settings: JobSettings, *, progress=None):
    """Run the job's planner on ``surface`` and order its passes; returns a ToolPath.
    ``progress(stage, done, total)`` hears about long planning steps."""
    from ..order import order_toolpath
    from ..plan import get_planner

    planner = get_planner(settings.planner)
    toolpath = planner(surface, settings.tool(), **planner_arguments(settings, progress=progress))
    return order_toolpath(toolpath, method=settings.order)


def run_job(settings: JobSettings, *, progress=None) -> dict:
    """Run a whole job and write ``trajectory.csv``, ``metrics.json``, ``report.html`` and PNGs.

    Parameters
    ----------
    settings : JobSettings
    progress : callable, optional
        ``progress(stage: str, done: int, total: int)`` for long steps.

    Returns
    -------
    dict
        The metrics (keys with units).
    """
    from ..io.atomic import atomic_directory
    from ..report import write_report
    from ..simulate import simulate_removal
    from ..trajectory import time_path

    say = progress or (lambda stage, done, total: None)
    timings = {}

    t0 = time.perf_counter()
    say("loading part", 0, 1)
    surface, part_info = load_part_info(settings, progress=say)
    log.info("part %s", surface)
    timings["load_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    say(f"planning ({settings.planner})", 0, 1)
    planner_arguments(settings)                      # option errors before loading, not after planning
    toolpath = make_plan(surface, settings, progress=say)
    timings["plan_s"] = time.perf_counter() - t0
    log.info("%d passes, %.3f m in contact", len(toolpath.passes), toolpath.contact_length)

    t0 = time.perf_counter()
    say("timing trajectory", 0, 1)
    trajectory = time_path(toolpath, settings.constraints(), links=settings.links())
    timings["trajectory_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    tool = settings.tool()
    removal = simulate_removal(trajectory, surface, tool, sample_spacing=settings.sample_spacing,
                               progress=lambda d, n: say("simulating removal", d, n))
    timings["simulate_s"] = time.perf_counter() - t0

    metrics = dict(removal.metrics)
    metrics.update({k: float(v) for k, v in toolpath.metadata.items() if isinstance(v, (int, float)) and not isinstance(v, bool)
                    and k.endswith(("_m", "_rad", "_s")) and k not in metrics})
    metrics.update(timings)
    metrics.update(part_info.get("metrics", {}))
    record = settings.as_record()
    record["plan"] = dict(toolpath.metadata)

    say("writing report", 0, 1)
    with atomic_directory(settings.out) as tmp:
        trajectory.write_csv(tmp / "trajectory.csv")
        if part_info.get("patch") is not None:
            from .fitjob import save_patch

            save_patch(part_info["patch"], tmp / "patch.json", part_info.get("footprint"))
        write_report(tmp, surface=surface, toolpath=toolpath, trajectory=trajectory, removal=removal,
                     metrics=metrics, settings=_jsonable(record), title=f"swath plan — {surface.name}")
    say("done", 1, 1)
    return metrics


def _jsonable(d: dict) -> dict:
    return json.loads(json.dumps(d, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o)))
