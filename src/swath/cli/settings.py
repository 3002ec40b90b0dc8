"""Job settings: the :class:`JobSettings` record (SI units) and the schema that fills it from text.

The CLI flags and TOML job files use the same keys (``pad_radius`` or ``pad-radius``).  Every key
has one entry in :data:`SCHEMA` saying what it holds; :func:`settings_from_mapping` checks every
value against it before any work — types (a quoted ``"false"`` is not a boolean), units, ranges —
and names the key in every refusal.
"""

from __future__ import annotations

import difflib
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import InputError
from ..units import canonical_length_unit, parse_quantity

#: Robot-realistic limits every trajectory is timed under unless the user turns them off ("none"):
#: tool angular speed (rad/s), centripetal and tangential acceleration (m/s²).
DEFAULT_LIMITS = {"max_angular": 1.0, "max_centripetal": 2.0, "max_accel": 1.0}

#: Words that turn a default limit off.
OFF_WORDS = ("none", "off", "no")


@dataclass(frozen=True)
class JobSettings:
    """Every setting of a job, SI units.

    ``part`` is a mesh file path, ``example:NAME`` for a built-in part (``example:blade``), a
    B-spline patch saved by ``swath fit`` (``patch.json``), or, with ``fit``, a scan (point cloud
    or mesh) to fit a B-spline patch to first.  A patch is planned on its triangulation at
    ``surface_spacing`` (m; default its longest extent / 150, clipped to 2..5 mm).  The keys and
    what each holds are listed in :data:`SCHEMA`.
    """

    part: str
    out: str
    units: str = "m"
    side: str | None = None
    all_pieces: bool = False
    force_units: bool = False
    overwrite: bool = False
    planner: str = "raster"
    order: str | None = None
    segment: str | None = None
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
    # tilt of the pad about the axis across the feed in contact, rad; None ("auto"): half the pad
    # presses on a flat part (Tool.half_pad_lead)
    lead_angle: float | None = 0.0
    join_gap: float | None = None
    # Single passes by default: each pass picks its own direction, so a one-way sweep (return moves,
    # no 180-degree turns at 1 rad/s) can win over a region's snake (example:hub: 131 s vs 186 s).
    order_groups: str = "passes"
    # What the tour methods minimise: link time (default: the shorter cycle; on example:hub 129 s
    # against 212 s ordered by length with contact step-overs) or air length.
    order_objective: str = "time"
    sample_spacing: float | None = None
    # Removal samples: a lattice at the sample spacing on every triangle (default: 2-5x faster and a
    # third of the samples on CAD parts with long slivers, same metrics within 0.5 %; the depth
    # picture is drawn on the part's own mesh, interpolated from the samples), or the part
    # subdivided to the sample spacing ("mesh", the feed kernel's own sampling).
    removal_sampling: str = "lattice"
    planner_options: dict = field(default_factory=dict)
    fit: bool = False
    parameterization: str = "auto"
    surface_spacing: float | None = None
    memory_budget: float | None = None
    # force control and calibration (simulate stage)
    force_control: bool = False
    part_offset: tuple | None = None
    tool_mass: float = 0.0
    tool_tilt: float = 0.0
    gravity_compensation: bool = True
    calibration: str | None = None
    grit: str | None = None
    # feed optimisation
    optimise_feed: bool = False
    target_depth: float | None = None
    target_map: str | None = None
    depth_tolerance: float | None = None
    optimise_spacing: str | None = None
    # the optimised feed is checked in the removal simulator and corrected where it over-removes
    feed_simulate_check: bool = True
    # robot stage
    robot: str | None = None
    base: str | None = None
    tcp: str | None = None
    programs: tuple = ()
    place: bool = False
    table_z: float = 0.0
    robot_strict: bool = False
    force_program: str = "native"

    def tool(self):
        from ..contact import Tool

        return Tool(pad_radius=self.pad_radius, force=self.force, depression=self.depression,
                    stiffness=self.stiffness, motion=self.motion)

    def constraints(self) -> list:
        """The trajectory constraints: the feed and whichever limits are on (by default all three of
        :data:`DEFAULT_LIMITS`)."""
        from ..trajectory import AngularSpeedLimit, CentripetalLimit, FeedLimit, TangentialAccelLimit

        out: list = [FeedLimit(self.feed)]
        if self.max_centripetal is not None:
            out.append(CentripetalLimit(self.max_centripetal))
        if self.max_angular is not None:
            out.append(AngularSpeedLimit(self.max_angular))
        if self.max_accel is not None:
            out.append(TangentialAccelLimit(self.max_accel))
        return out

    def lead(self) -> float:
        """The lead angle (rad) the trajectory tilts the tool by in contact: ``lead_angle``, or for
        ``auto`` the angle at which half the pad presses on a flat part (``Tool.half_pad_lead``)."""
        return self.tool().half_pad_lead if self.lead_angle is None else float(self.lead_angle)

    def links(self):
        """How the tool moves between passes."""
        from ..trajectory import LinkSettings

        return LinkSettings(clearance=self.clearance)

    def as_record(self) -> dict:
        """Settings with units in the key names, for metrics.json and the report."""
        tool = self.tool()
        record = {
            "part": self.part, "units": self.units, "planner": self.planner, "order": self.order,
            "join_gap_m": self.join_gap, "order_groups": self.order_groups, "order_objective": self.order_objective,
            "segment": self.segment, "removal_sampling": self.removal_sampling,
            "pad_radius_m": self.pad_radius, "force_N": self.force,
            "depression_on_flat_m": tool.flat_depression, "stiffness_Pa_per_m": tool.k,
            "motion": self.motion, "feed_m_per_s": self.feed, "spacing_m": self.spacing,
            "direction_rad": self.direction, "point_spacing_m": self.point_spacing, "clearance_m": self.clearance,
            "max_centripetal_m_per_s2": self.max_centripetal, "max_angular_rad_per_s": self.max_angular,
            "max_accel_m_per_s2": self.max_accel, "overlap_fraction": self.overlap,
            "lead_angle_rad": self.lead(),
            "fit": self.fit, "fit_parameterization": self.parameterization,
            "surface_spacing_m": self.surface_spacing,
            **{f"planner_{k}": v for k, v in self.planner_options.items()},
        }
        if self.force_control:
            record.update(force_control=True, part_offset_m_rad=self.part_offset, tool_mass_kg=self.tool_mass,
                          tool_tilt_rad=self.tool_tilt, gravity_compensation=self.gravity_compensation)
        if self.calibration:
            record.update(calibration=self.calibration, grit=self.grit)
        if self.optimise_feed or self.optimise_spacing:
            record.update(optimise_feed=self.optimise_feed, optimise_spacing=self.optimise_spacing,
                          target_depth_m=self.target_depth, target_map=self.target_map,
                          depth_tolerance_m=self.depth_tolerance, feed_simulate_check=self.feed_simulate_check)
        if self.robot:
            record.update(robot=self.robot, base=self.base, tcp=self.tcp, programs=list(self.programs),
                          place=self.place, table_z_m=self.table_z, force_program=self.force_program)
        return record


# ----------------------------------------------------------------------------------------------
# the schema
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Key:
    """What one settings key holds.

    kind : a quantity kind of :func:`swath.units.parse_quantity`, or ``"bool"``, ``"str"``,
        ``"path"``, ``"table"``, ``"list"``, ``"offset"``, ``"count"`` (a whole number).
    choices : allowed strings (``"str"`` keys).
    lo, hi : allowed range in SI (inclusive), None for open.
    bare_max : a number given without a unit must not exceed this (SI); catches ``feed = 50``.
    hint : the unit the user likely meant, for that message.
    off : the key may be turned off with ``none``/``off``.
    auto : the key may be ``auto`` (None).
    positive : the value must be > 0.
    infinite : the value may be ``inf`` (a TOML float or the text), returned as ``math.inf``.
    """

    kind: str
    choices: tuple = ()
    lo: float | None = None
    hi: float | None = None
    bare_max: float | None = None
    hint: str = ""
    off: bool = False
    auto: bool = False
    positive: bool = False
    infinite: bool = False


def _planners() -> tuple:
    from ..plan import PLANNERS

    return tuple(PLANNERS)


def _orders() -> tuple:
    from ..order import ORDER_METHODS

    return tuple(ORDER_METHODS)


#: Every settings key -> what it holds (the CLI's ``--pad-radius`` is ``pad_radius``).
SCHEMA: dict[str, Key] = {
    "part": Key("str"), "out": Key("str"), "units": Key("str"), "side": Key("str"),
    "all_pieces": Key("bool"), "force_units": Key("bool"), "overwrite": Key("bool"),
    "planner": Key("str", choices=("raster", "uniform", "equidistant")), "order": Key("str", auto=True),
    "segment": Key("str", choices=("none", "auto"), off=True),
    "pad_radius": Key("length", positive=True, hi=1.0, bare_max=1.0, hint="mm, e.g. 38.1mm"),
    "force": Key("force", positive=True, hi=1e4, bare_max=1e4),
    "depression": Key("length", positive=True, bare_max=0.1, hint="mm, e.g. 1mm"),
    "stiffness": Key("stiffness", positive=True),
    "motion": Key("str", choices=("orbital", "rotary")),
    "feed": Key("speed", positive=True, hi=5.0, bare_max=5.0, hint="mm/s, e.g. 50mm/s"),
    "spacing": Key("length", positive=True, bare_max=2.0, hint="mm, e.g. 60mm"),
    "direction": Key("angle", auto=True),
    "point_spacing": Key("length", positive=True, hi=0.1, bare_max=0.1, hint="mm, e.g. 1mm"),
    "clearance": Key("length", positive=True, hi=1.0, bare_max=1.0, hint="mm, e.g. 20mm"),
    "order_groups": Key("str", choices=("regions", "passes")),
    "order_objective": Key("str", choices=("length", "time")),
    "join_gap": Key("length", positive=True, hi=1.0, bare_max=1.0, hint="mm, e.g. 76mm", off=True),
    "sample_spacing": Key("length", positive=True, hi=0.1, bare_max=0.1, hint="mm, e.g. 3mm"),
    "removal_sampling": Key("str", choices=("lattice", "mesh")),
    "surface_spacing": Key("length", positive=True, hi=0.1, bare_max=0.1, hint="mm, e.g. 3mm"),
    "max_centripetal": Key("acceleration", positive=True, off=True),
    "max_angular": Key("angular_speed", positive=True, off=True),
    "max_accel": Key("acceleration", positive=True, off=True),
    "overlap": Key("fraction", lo=0.0, hi=0.9),
    "lead_angle": Key("angle", auto=True, lo=-math.pi / 4, hi=math.pi / 4),
    "planner_options": Key("table"),
    "fit": Key("bool"), "parameterization": Key("str", choices=("auto", "projection", "lscm", "rows")),
    "memory_budget": Key("str"),
    "force_control": Key("bool"), "part_offset": Key("offset"), "tool_mass": Key("mass", lo=0.0, hi=500.0),
    "tool_tilt": Key("angle"), "gravity_compensation": Key("bool"), "calibration": Key("path"), "grit": Key("str"),
    "optimise_feed": Key("bool"), "target_depth": Key("length", positive=True, bare_max=1e-2, hint="um, e.g. 20um"),
    "target_map": Key("path"), "depth_tolerance": Key("length", lo=0.0, bare_max=1e-2, hint="um, e.g. 5um"),
    "optimise_spacing": Key("str", choices=("ripple", "greedy", "joint"), off=True),
    "feed_simulate_check": Key("bool"),
    "robot": Key("str"), "base": Key("str"), "tcp": Key("str"), "programs": Key("list"), "place": Key("bool"),
    "table_z": Key("length", bare_max=5.0, hint="mm, e.g. 700mm"), "robot_strict": Key("bool"),
    "force_program": Key("str", choices=("native", "position")),
}

#: Planner options (``[planner_options]``) that are not job settings: what each holds.  The job
#: sets ``cost`` and ``progress`` itself; ``cross_direction`` is for the library only.
PLANNER_OPTION_SCHEMA: dict[str, Key] = {
    "min_pass_length": Key("length", positive=True, hi=1.0, bare_max=1.0, hint="mm, e.g. 10mm"),
    "edge_margin": Key("length", lo=0.0, hi=1.0, bare_max=1.0, hint="mm, e.g. 5mm", infinite=True),
    "work_spacing": Key("length", positive=True, hi=0.1, bare_max=0.1, hint="mm, e.g. 2mm"),
    "max_edge": Key("length", positive=True, hi=0.1, bare_max=0.1, hint="mm, e.g. 3mm"),
    "max_passes": Key("count", positive=True), "workers": Key("count", positive=True),
    "fill_gaps": Key("bool"), "distance": Key("str", choices=("fmm", "heat")), "seed": Key("str"),
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
        bounds = (f"[{spec.lo:g}, {spec.hi:g}]" if spec.lo is not None and spec.hi is not None else
                  f"at most {spec.hi:g}" if spec.hi is not None else f"at least {spec.lo:g}")
        raise InputError(f"{key} = {value!r} is out of range: {bounds} (SI units)")
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
        spec = SCHEMA.get(name)
        if spec is None:
            close = difflib.get_close_matches(name, list(SCHEMA) + list(ALIASES), n=1)
            hint = f"did you mean {ALIASES.get(close[0], close[0])!r}? " if close else ""
            raise InputError(f"unknown job setting {key!r}; {hint}known settings: {', '.join(sorted(SCHEMA))}")
        kwargs[name] = parse_value(str(key), value, spec)
    if not kwargs.get("part") or not kwargs.get("out"):
        raise InputError("a job needs 'part' (a mesh file or example:NAME) and 'out' (the output directory)")
    if base_dir is not None:
        for k in ("part", "out", "calibration", "target_map"):
            p = kwargs.get(k)
            if p and not str(p).startswith("example:") and not Path(p).is_absolute():
                kwargs[k] = str(base_dir / p)
    if "units" in kwargs:
        kwargs["units"] = canonical_length_unit(kwargs["units"])
    if kwargs.get("order") is not None and kwargs["order"] not in _orders():
        raise InputError(f"unknown order {kwargs['order']!r}; choose one of {', '.join(_orders())}")
    if kwargs.get("join_gap") is not None and kwargs.get("order") in ("snake", "zigzag", "index"):
        raise InputError(f"join_gap makes step-overs in contact while a tour is chosen; the {kwargs['order']} order "
                         "keeps the planner's sequence: use order = gtsp (the default with join_gap) or greedy")
    if kwargs.get("planner", "raster") not in _planners():
        raise InputError(f"unknown planner {kwargs['planner']!r}; choose one of {', '.join(_planners())}")
    if kwargs.get("memory_budget") is not None:
        kwargs["memory_budget"] = parse_bytes(kwargs["memory_budget"], "memory_budget")
    settings = JobSettings(**kwargs)
    check_settings(settings)
    return settings


def check_side(side, key: str) -> None:
    """Refuse a tool side (``--side``) that is no direction, naming ``key``; None passes."""
    if side is not None:
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
    if settings.robot or settings.programs or settings.place:
        from .stages import robot_options

        robot_options(settings)                     # robot name, base and tcp poses, program formats
    if settings.optimise_feed and not (settings.target_depth or settings.target_map):
        raise InputError("--optimise-feed needs a target: --target-depth (e.g. 20um) or --target-map FILE")
    if (settings.target_depth or settings.target_map or settings.depth_tolerance) and not settings.optimise_feed:
        raise InputError("--target-depth, --target-map and --depth-tolerance apply with --optimise-feed; add it")
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
        if settings.optimise_spacing in ("greedy", "joint") and not settings.optimise_feed:
            raise InputError(f"--optimise-spacing {settings.optimise_spacing} scores spacings against the target "
                             "depth: add --optimise-feed and --target-depth or --target-map (or use "
                             "--optimise-spacing ripple, which needs no target)")
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
