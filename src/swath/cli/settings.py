"""Job settings: the :class:`JobSettings` record (SI units) and the schema that fills it from text.

The CLI flags and TOML job files use the same keys (``pad_radius`` or ``pad-radius``).  Every key
is one field of :class:`JobSettings` (:mod:`swath.cli.jobsettings`), declared once with what it
holds; :data:`SCHEMA` is derived from those declarations, and :func:`settings_from_mapping` checks
every value against it before any work — types (a quoted ``"false"`` is not a boolean), units,
ranges — and names the key in every refusal.
"""

from __future__ import annotations

import difflib
import logging
import math
import re
from dataclasses import dataclass
from pathlib import Path

from ..errors import InputError
from ..units import canonical_length_unit, display_unit, parse_quantity
from .jobsettings import DEFAULT_LIMITS, JobSettings, _orders, _planners  # noqa: F401  (DEFAULT_LIMITS, Key: re-exported)
from .schema import Key, schema

log = logging.getLogger(__name__)

#: Words that turn a default limit off.
OFF_WORDS = ("none", "off", "no")


#: Every settings key -> what it holds (the CLI's ``--pad-radius`` is ``pad_radius``), derived from
#: the declarations of :class:`JobSettings` (:func:`swath.cli.schema.schema`).
SCHEMA: dict[str, Key] = schema(JobSettings)


@dataclass(frozen=True)
class ProcessRange:
    """What a sanding or polishing robot does with one process setting: the range (SI) a job is
    refused outside unless ``allow_unusual_process`` is set, shown in ``unit`` (SI value × ``scale``)."""

    lo: float
    hi: float
    unit: str
    scale: float
    why: str

    def text(self) -> str:
        """The range in the user's unit, e.g. ``1–500 mm/s``."""
        return f"{self.lo * self.scale:g}–{self.hi * self.scale:g} {self.unit}"


#: Plausible ranges of the process settings (SI), checked before any work. Robotic sanding and
#: polishing feeds run at 5–200 mm/s: below 1 mm/s a pass is a dwell (minutes per metre), above
#: 0.5 m/s the arm cannot hold a contact path; normal forces of sanding and polishing heads are
#: 5–150 N, grinding up to a few hundred, and below 1 N a pad does not stay in contact; pads are
#: 10–300 mm across; orbital sanders and polishers turn at 1 000–12 000 rpm, grinders up to about
#: 20 000, and under 60 rpm the pad barely turns.
PROCESS_RANGES: dict[str, ProcessRange] = {
    "feed": ProcessRange(1e-3, 0.5, "mm/s", 1e3, "the feed of a sanding robot"),
    "force": ProcessRange(1.0, 500.0, "N", 1.0, "the normal force of a sanding or polishing head"),
    "pad_radius": ProcessRange(5e-3, 0.15, "mm", 1e3, "the radius of a sanding or polishing pad"),
    "spindle_speed": ProcessRange(2 * math.pi, 20000 * 2 * math.pi / 60, "rpm", 60 / (2 * math.pi),
                                  "the speed of a sanding or polishing spindle"),
}


def check_process_ranges(values: dict, *, allow: bool) -> list[str]:
    """Check the process settings in ``values`` (key -> SI value) against :data:`PROCESS_RANGES`.

    Returns the messages of the values outside their range when ``allow`` (to warn about);
    otherwise refuses the first one.

    Raises
    ------
    InputError
        Naming the key, the value in the range's unit, the range and the way out (a unit, or
        ``--allow-unusual-process``), when a value is out of range and ``allow`` is False.
    """
    out = []
    for key, rng in PROCESS_RANGES.items():
        value = values.get(key)
        if value is None or rng.lo <= value <= rng.hi:
            continue
        message = (f"{key} = {value * rng.scale:.4g} {rng.unit} is outside {rng.why} ({rng.text()})")
        if not allow:
            raise InputError(f"{message}; check the value and its unit, or add --allow-unusual-process (allow_unusual_process "
                             "= true in a job file) to plan it anyway")
        out.append(message)
    return out

#: Planner options (``[planner_options]``) that are not job settings: what each holds.  The job
#: sets ``cost`` and ``progress`` itself; ``cross_direction`` is for the library only.
PLANNER_OPTION_SCHEMA: dict[str, Key] = {
    "min_pass_length": Key("length", positive=True, hi=1.0, bare_max=1.0, hint="mm, e.g. 10mm"),
    "edge_margin": Key("length", lo=0.0, hi=1.0, bare_max=1.0, hint="mm, e.g. 5mm", infinite=True),
    "work_spacing": Key("length", positive=True, hi=0.1, bare_max=0.1, hint="mm, e.g. 2mm"),
    "max_edge": Key("length", positive=True, hi=0.1, bare_max=0.1, hint="mm, e.g. 3mm"),
    "max_passes": Key("count", positive=True), "workers": Key("count", positive=True),
    "fill_gaps": Key("bool"), "distance": Key("str", choices=("fmm", "heat")), "seed": Key("str"),
    "mode": Key("str", choices=("helix", "rings")), "spacing_on": Key("str", choices=("surface", "projection", "swath")),
}

#: Other spellings of keys.
ALIASES = {"angle": "direction", "program": "programs"}

_BARE_NUMBER = re.compile(r"^\s*[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?\s*$")


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def parse_value(key: str, value, spec: Key):
    """One value checked against its schema entry; returns the SI / typed value (None = automatic
    or off).  Raises :class:`InputError` naming ``key``."""
    if spec.kind == "bool":
        if isinstance(value, bool):
            return value
        raise InputError(f"{key} must be true or false (a TOML boolean, unquoted), got {value!r}")
    if spec.kind in ("str", "path"):
        if not isinstance(value, str):
            raise InputError(f"{key} must be text, got {type(value).__name__} {value!r}")
        if spec.auto and value.strip().lower() == "auto":
            return None
        if spec.off and value.strip().lower() in OFF_WORDS:
            return None
        if spec.choices and value not in spec.choices:
            raise InputError(f"{key} must be one of {', '.join(spec.choices)}, got {value!r}")
        return value
    if spec.kind == "count":
        if not (isinstance(value, int) and not isinstance(value, bool)) or (spec.positive and value < 1):
            raise InputError(f"{key} must be a whole number{' >= 1' if spec.positive else ''} (unquoted), "
                             f"got {value!r}")
        return int(value)
    if spec.kind == "table":
        if not isinstance(value, dict):
            raise InputError(f"{key} must be a table ([{key}] in TOML), got {type(value).__name__}")
        return dict(value)
    if spec.kind == "list":
        if isinstance(value, str):
            value = [v.strip() for v in value.split(",") if v.strip()]
        if not (isinstance(value, (list, tuple)) and all(isinstance(v, str) for v in value)):
            raise InputError(f"{key} must be a list of names (e.g. urscript,rapid), got {value!r}")
        return tuple(value)
    if spec.kind == "offset":
        from ..simulate.force import parse_part_offset

        try:
            return parse_part_offset(value if isinstance(value, str) else ",".join(map(str, value)))
        except InputError as exc:
            raise InputError(f"{key}: {exc}") from None
    # a quantity
    if not (isinstance(value, str) or _is_number(value)):
        raise InputError(f"{key} must be a number with a unit (e.g. {spec.hint or 'see --help'}), "
                         f"got {type(value).__name__} {value!r}")
    text = str(value).strip()
    if spec.auto and text.lower() == "auto":
        return None
    if spec.off and text.lower() in OFF_WORDS:
        return None
    if spec.infinite and text.lower() in ("inf", "+inf", "infinity"):
        return math.inf
    try:
        si = parse_quantity(value, spec.kind, default_unit="deg" if spec.kind == "angle" else None)
    except InputError as exc:
        raise InputError(f"{key}: {exc}") from None
    bare = _is_number(value) or bool(_BARE_NUMBER.match(text))
    if bare and spec.bare_max is not None and abs(si) > spec.bare_max:
        raise InputError(f"{key} = {value} has no unit, so it is read in SI units, which is not plausible here; "
                         f"give the unit{f' ({spec.hint})' if spec.hint else ''}")
    if spec.positive and not si > 0:
        raise InputError(f"{key} must be positive, got {value!r}")
    if spec.lo is not None and si < spec.lo or spec.hi is not None and si > spec.hi:
        # the bounds in the unit the value was given in (a lead typed in degrees is not refused in radians)
        unit, per = display_unit(text, spec.kind)
        lo, hi = (None if b is None else float(f"{b / per:.6g}") for b in (spec.lo, spec.hi))
        bounds = (f"[{lo:g}, {hi:g}]" if lo is not None and hi is not None else
                  f"at most {hi:g}" if hi is not None else f"at least {lo:g}")
        raise InputError(f"{key} = {value!r} is out of range: {bounds}{' ' + unit if unit else ''}")
    return si


def settings_from_mapping(values: dict, *, base_dir: Path | None = None) -> JobSettings:
    """Build :class:`JobSettings` from text values (a TOML table or parsed CLI flags).

    Every key is checked against :data:`SCHEMA` (types, units, ranges), and the settings that
    depend only on each other — the tool, the trajectory limits, the planner's options, the order
    method — are checked too, all before any part is loaded.  Quantities accept unit suffixes;
    bare numbers are SI except angles (degrees).  Unknown keys are refused by name.
    """
    if not isinstance(values, dict):
        raise InputError(f"a job is a table of settings, got {type(values).__name__}")
    kwargs: dict = {}
    for key, value in values.items():
        if value is None:
            continue
        name = str(key).replace("-", "_")
        name = ALIASES.get(name, name)
        if name == "depression" and isinstance(value, str) and "@" in value:
            # "1mm@20N": the pad's depression on flat at a stated force
            value, _, at = value.partition("@")
            if "depression_force" in values or "depression-force" in values:
                raise InputError(f"{key} states its force after '@' and depression_force is given too; give it once")
            kwargs["depression_force"] = parse_value(f"{key} (the force after '@')", at.strip(), SCHEMA["depression_force"])
        if name in ("faces", "keep_out") and not isinstance(value, str):
            from ..segment.regions import selection_text_from_table

            value = selection_text_from_table(value, str(key))      # a job file's region table
        spec = SCHEMA.get(name)
        if spec is None:
            close = difflib.get_close_matches(name, list(SCHEMA) + list(ALIASES), n=1)
            hint = f"did you mean {ALIASES.get(close[0], close[0])!r}? " if close else ""
            raise InputError(f"unknown job setting {key!r}; {hint}known settings: {', '.join(sorted(SCHEMA))}")
        kwargs[name] = parse_value(str(key), value, spec)
    if not kwargs.get("part") or not kwargs.get("out"):
        raise InputError("a job needs 'part' (a mesh file or example:NAME) and 'out' (the output directory)")
    if base_dir is not None:
        for k in ("part", "out", "calibration", "target_map", "cell", "robot"):
            p = kwargs.get(k)
            if k == "robot" and not str(p or "").strip().lower().endswith(".urdf"):
                continue                            # a catalogue name, not a file
            if p and not str(p).startswith("example:") and not Path(p).is_absolute():
                kwargs[k] = str(base_dir / p)
        for k in ("faces", "keep_out"):
            if kwargs.get(k):
                from ..segment.regions import resolve_region_paths

                kwargs[k] = resolve_region_paths(kwargs[k], base_dir)
    if "units" in kwargs:
        kwargs["units"] = canonical_length_unit(kwargs["units"])
    if kwargs.get("spindle_speed") is not None:
        kwargs["spindle_speed"] *= 2.0 * math.pi          # revolutions per second -> rad/s
    if kwargs.get("order") is not None and kwargs["order"] not in _orders():
        raise InputError(f"unknown order {kwargs['order']!r}; choose one of {', '.join(_orders())}")
    if kwargs.get("join_gap") is not None and kwargs.get("order") in ("snake", "zigzag", "index"):
        raise InputError(f"join_gap makes step-overs in contact while a tour is chosen; the {kwargs['order']} order "
                         "keeps the planner's sequence: use order = gtsp (the default with join_gap) or greedy")
    if kwargs.get("planner", "raster") not in _planners():
        raise InputError(f"unknown planner {kwargs['planner']!r}; choose one of {', '.join(_planners())}")
    if kwargs.get("memory_budget") is not None:
        kwargs["memory_budget"] = parse_bytes(kwargs["memory_budget"], "memory_budget")
    for message in check_process_ranges(kwargs, allow=bool(kwargs.get("allow_unusual_process"))):
        log.warning("%s; planning it as asked (--allow-unusual-process)", message)
    settings = JobSettings(**kwargs)
    check_settings(settings)
    return settings


def check_side(side, key: str) -> None:
    """Refuse a tool side (``--side``) that is no direction, naming ``key``; None passes."""
    if side is not None and side != "all":      # "all": a closed part all round, in setups
        from ..io.mesh import parse_side

        try:
            parse_side(side)
        except InputError as exc:
            raise InputError(f"{key}: {exc}") from None


def check_settings(settings: JobSettings) -> None:
    """Refuse settings that cannot work together, before any work: the tool, the limits, the links,
    the planner's options."""
    from .job import planner_arguments

    settings.tool()
    settings.constraints()
    settings.links()
    planner_arguments(settings)
    check_side(settings.side, "side")                # refused even where the part turns out open
    if settings.fit and str(settings.part).lower().endswith(".json"):
        raise InputError(f"{Path(settings.part).name} is already a fitted patch; drop --fit to plan on it")
    if settings.robot or settings.programs or settings.place or settings.cell:
        from .stages import robot_options

        robot_options(settings)                     # robot name, cell file, base and tcp poses, program formats
    if settings.constant_feed:
        given = [flag for flag, on in (("--optimise-feed", settings.optimise_feed),
                                       ("--target-depth", settings.target_depth is not None),
                                       ("--target-map", settings.target_map is not None),
                                       ("--depth-tolerance", settings.depth_tolerance is not None)) if on]
        if given:
            raise InputError(f"--constant-feed runs the feed given (--feed) all along the passes: drop "
                             f"{', '.join(given)}, or drop --constant-feed to optimise the feed to a target depth")
    if settings.optimise_spacing:
        uniform_ripple = settings.planner == "uniform" and settings.optimise_spacing == "ripple"
        if uniform_ripple and settings.overlap is not None:
            raise InputError("--optimise-spacing ripple sets the uniform planner's overlap itself (the least-ripple "
                             "spacing over the swath width): drop --overlap, or drop --optimise-spacing")
        if (settings.planner != "raster" and not uniform_ripple) or settings.segment == "auto" \
                or settings.spacing is not None:
            raise InputError(f"--optimise-spacing {settings.optimise_spacing} places raster passes itself: use it "
                             "with the raster planner (ripple also with uniform), without --spacing and without "
                             "--segment auto")
        if settings.optimise_spacing in ("greedy", "joint") and not (settings.target_depth or settings.target_map):
            raise InputError(f"--optimise-spacing {settings.optimise_spacing} scores spacings against the target "
                             "depth: add --target-depth or --target-map (or use --optimise-spacing ripple, which "
                             "needs no target)")
    if not settings.force_control:
        given = [flag for flag, on in (("--part-offset", settings.part_offset is not None),
                                       ("--tool-mass", settings.tool_mass != 0.0),
                                       ("--tool-tilt", settings.tool_tilt != 0.0),
                                       ("--no-gravity-compensation", not settings.gravity_compensation)) if on]
        if given:
            raise InputError(f"{', '.join(given)} appl{'ies' if len(given) == 1 else 'y'} with --force-control (the "
                             "force-controlled run it simulates); add --force-control")
    if settings.grit is not None and not settings.calibration:
        raise InputError("--grit picks a grit from a calibration file: add --calibration FILE (from `swath calibrate`)")
    if settings.target_cov is not None:
        given = [flag for flag, on in (("--optimise-spacing", settings.optimise_spacing is not None),
                                       ("--spacing", settings.spacing is not None),
                                       ("--overlap", settings.overlap is not None),
                                       ("--optimise-feed", settings.optimise_feed),
                                       ("--target-depth", settings.target_depth is not None),
                                       ("--target-map", settings.target_map is not None),
                                       ("--segment auto", settings.segment == "auto")) if on]
        if given:
            raise InputError(f"--target-cov chooses the spacing, lead and feed itself: drop {', '.join(given)}")
        if settings.planner not in ("raster", "uniform"):
            raise InputError(f"--target-cov searches raster or uniform plans, not {settings.planner}: use "
                             "--planner raster (default) or --planner uniform")
    if settings.target_map and settings.target_depth:
        raise InputError("give either target_depth (a uniform depth) or target_map (a depth per vertex), not both")


_BYTE_UNITS = {"": 1, "b": 1, "kb": 1e3, "mb": 1e6, "gb": 1e9, "kib": 2**10, "mib": 2**20, "gib": 2**30}


def parse_bytes(text, key: str = "memory") -> float:
    """``"4GiB"``, ``"500MB"`` or a number of bytes -> bytes."""
    m = re.fullmatch(r"\s*(\d+\.?\d*|\.\d+)\s*([a-zA-Z]*)\s*", str(text))
    if not m or m.group(2).lower() not in _BYTE_UNITS:
        raise InputError(f"{key} must be an amount of memory such as 4GiB or 500MB, got {text!r}")
    value = float(m.group(1)) * _BYTE_UNITS[m.group(2).lower()]
    if not (math.isfinite(value) and value > 0):
        raise InputError(f"{key} must be positive, got {text!r}")
    return value


def read_toml(path, what: str = "job file") -> dict:
    """The table of a TOML file; :class:`InputError` naming ``what`` for a directory, a missing file
    or invalid TOML."""
    import tomllib

    path = Path(path)
    if path.is_dir():
        raise InputError(f"{path} is a directory; give the {what} (a .toml) inside it")
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"{what} {path} not found") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{what} {path} is not valid TOML: {exc}") from None


def load_job_toml(path) -> JobSettings:
    """Read a TOML job file: top-level keys as in :data:`SCHEMA` (or a ``[job]`` table)."""
    path = Path(path)
    data = read_toml(path)
    table = data.get("job", data)
    if not isinstance(table, dict):
        raise InputError(f"job file {path}: 'job' must be a table ([job]), got {type(table).__name__}")
    return settings_from_mapping(table, base_dir=path.parent)
