"""A whole finishing job: part → plan → trajectory → removal → report, from one settings record.

:class:`JobSettings` holds every setting in SI units; the CLI and TOML job files fill it from text
with unit suffixes (``"38.1mm"``).  :func:`run_job` runs the stages and writes the output directory
atomically: it appears complete, or not at all.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

from .errors import InputError
from .units import parse_quantity

log = logging.getLogger(__name__)

#: Planner name -> "module:function"; every planner has the call shape f(surface, tool, **options).
PLANNERS = {
    "raster": "swath.plan.raster:raster",
}


@dataclass(frozen=True)
class JobSettings:
    """Every setting of a job, SI units.

    ``part`` is a mesh file path or ``example:NAME`` for a built-in part (``example:blade``).
    """

    part: str
    out: str
    units: str = "m"
    side: str | None = None
    all_pieces: bool = False
    force_units: bool = False
    planner: str = "raster"
    pad_radius: float = 0.0381
    force: float = 20.0
    depression: float | None = None
    stiffness: float | None = None
    motion: str = "orbital"
    feed: float = 0.05
    spacing: float | None = None
    angle: float | None = None
    point_spacing: float = 1e-3
    clearance: float = 0.02
    max_centripetal: float | None = None
    max_angular: float | None = None
    max_accel: float | None = None
    sample_spacing: float | None = None
    planner_options: dict = field(default_factory=dict)

    def tool(self):
        from .contact import Tool

        return Tool(pad_radius=self.pad_radius, force=self.force, depression=self.depression,
                    stiffness=self.stiffness, motion=self.motion)

    def constraints(self) -> list:
        """The trajectory constraints: the feed and whichever limits are set."""
        from .trajectory import AngularSpeedLimit, CentripetalLimit, FeedLimit, TangentialAccelLimit

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
        from .trajectory import LinkSettings

        return LinkSettings(clearance=self.clearance)

    def as_record(self) -> dict:
        """Settings with units in the key names, for metrics.json and the report."""
        tool = self.tool()
        return {
            "part": self.part, "units": self.units, "planner": self.planner,
            "pad_radius_m": self.pad_radius, "force_N": self.force,
            "depression_on_flat_m": tool.flat_depression, "stiffness_Pa_per_m": tool.k,
            "motion": self.motion, "feed_m_per_s": self.feed, "spacing_m": self.spacing,
            "angle_rad": self.angle, "point_spacing_m": self.point_spacing, "clearance_m": self.clearance,
            "max_centripetal_m_per_s2": self.max_centripetal, "max_angular_rad_per_s": self.max_angular,
            "max_accel_m_per_s2": self.max_accel,
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
    "point_spacing": "length", "point-spacing": "length",
    "clearance": "length",
    "sample_spacing": "length", "sample-spacing": "length",
    "max_centripetal": "acceleration", "max-centripetal": "acceleration",
    "max_angular": "angular_speed", "max-angular": "angular_speed",
    "max_accel": "acceleration", "max-accel": "acceleration",
}
_PLAIN_FIELDS = {"part", "out", "units", "side", "all_pieces", "all-pieces", "force_units", "force-units",
                 "planner", "motion"}


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
        if key in _QUANTITY_FIELDS:
            kind = _QUANTITY_FIELDS[key]
            if kind == "angle" and str(value).strip().lower() == "auto":
                kwargs[name] = None
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
    if kwargs.get("planner", "raster") not in PLANNERS:
        raise InputError(f"unknown planner {kwargs['planner']!r}; choose one of {', '.join(PLANNERS)}")
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
    """The job's part as a Surface (built-in example or a mesh file)."""
    from .examples import example_part

    if settings.part.startswith("example:"):
        return example_part(settings.part.split(":", 1)[1])
    from .io.mesh import load_mesh

    return load_mesh(settings.part, units=settings.units, side=settings.side, all_pieces=settings.all_pieces,
                     force_units=settings.force_units)


def make_plan(surface, settings: JobSettings):
    """Run the job's planner on ``surface``; returns a ToolPath."""
    import importlib

    module, func = PLANNERS[settings.planner].split(":")
    planner = getattr(importlib.import_module(module), func)
    options = dict(settings.planner_options)
    if settings.planner == "raster":
        options.update(spacing=settings.spacing, angle=settings.angle, point_spacing=settings.point_spacing)
    return planner(surface, settings.tool(), **options)


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
    from .io.atomic import atomic_directory
    from .report import write_report
    from .simulate import simulate_removal
    from .trajectory import time_path

    say = progress or (lambda stage, done, total: None)
    timings = {}

    t0 = time.perf_counter()
    say("loading part", 0, 1)
    surface = load_part(settings)
    log.info("part %s", surface)
    timings["load_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    say(f"planning ({settings.planner})", 0, 1)
    toolpath = make_plan(surface, settings)
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
    record = settings.as_record()
    record.update({f"plan_{k}": v for k, v in toolpath.metadata.items()})

    say("writing report", 0, 1)
    with atomic_directory(settings.out) as tmp:
        trajectory.write_csv(tmp / "trajectory.csv")
        write_report(tmp, surface=surface, toolpath=toolpath, trajectory=trajectory, removal=removal,
                     metrics=metrics, settings=_jsonable(record), title=f"swath plan — {surface.name}")
    say("done", 1, 1)
    return metrics


def _jsonable(d: dict) -> dict:
    return json.loads(json.dumps(d, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o)))
