"""Job settings: the :class:`JobSettings` record (SI units) and the schema that fills it from text.

The CLI flags and TOML job files use the same keys (``pad_radius`` or ``pad-radius``).  Every key
has one entry in :data:`SCHEMA` saying what it holds; :func:`settings_from_mapping` checks every
value against it before any work — types (a quoted ``"false"`` is not a boolean), units, ranges —
and names the key in every refusal.
"""

from __future__ import annotations

import difflib
import logging
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import InputError
from ..units import canonical_length_unit, parse_quantity

log = logging.getLogger(__name__)

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
    motion: str | None = None                  # None: orbital, or the motion the calibration was measured with
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
    # "fastest": raise the target to what the passes remove at the fastest feed (a tapering target map)
    target_floor: str = "none"
    # the contact length a spacing optimisation may use, in multiples of the coverage bound L*
    length_budget: float = 1.5
    # the interior removal CoV asked for (a fraction): the shortest candidate plan that reaches it
    target_cov: float | None = None
    # robot stage
    robot: str | None = None
    base: str | None = None
    tcp: str | None = None
    programs: tuple = ()
    place: bool = False
    table_z: float = 0.0
    robot_strict: bool = False
    cell: str | None = None
    allow_collisions: bool = False
    tip: str | None = None
    robot_keep_out: float | None = None
    # process model: the pad as a shop knows it (depression at a stated force, thickness), its
    # kinematics, wear and media changes (swath.process)
    depression_force: float | None = None      # the force `depression` was measured at (None: 20 N)
    pad_thickness: float | None = None
    spindle_speed: float | None = None         # rad/s; None: 10 000 rpm or the calibration's
    orbit_radius: float | None = None          # m; None: 2.5 mm or the calibration's
    wear_rate: float | None = None             # 1/s; None: no wear, or the calibration's
    media_change: float | None = None          # s of contact per media
    media_change_loss: float | None = None     # change when the removal rate has fallen by this fraction
    wear_compensation: bool = True
    pad_damping: float = 0.0                   # the pad's viscous relaxation time, s (force-control landings)
    faces: str | None = None
    keep_out: str | None = None
    keep_out_margin: float = 2e-3
    edge_margin: float = 0.0
    chordal_tol: float = 1e-4
    # plan with a feed, force, pad or spindle speed outside PROCESS_RANGES
    allow_unusual_process: bool = False
    force_program: str = "native"

    def tool(self):
        """The job's tool from the settings alone (no calibration: see :func:`swath.cli.stages.job_tool`).

        A bare ``depression`` is the pad's depression at the reference force 20 N (or at
        ``depression_force``); the set ``force`` then presses that pad deeper or shallower."""
        from ..contact import Tool

        kw = {}
        if self.spindle_speed is not None:
            kw["spindle_speed"] = self.spindle_speed
        if self.orbit_radius is not None:
            kw["orbit_radius"] = self.orbit_radius
        return Tool(pad_radius=self.pad_radius, force=self.force, depression=self.depression,
                    stiffness=self.stiffness, motion=self.motion or "orbital",
                    reference_force=20.0 if self.depression_force is None else self.depression_force,
                    pad_thickness=self.pad_thickness, wear_rate=self.wear_rate or 0.0,
                    damping_time=self.pad_damping, **kw)

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
            "pad_depression_m": tool.depression_at(tool.reference_force),
            "pad_depression_reference_force_N": tool.reference_force, "pad_thickness_m": self.pad_thickness,
            "spindle_speed_rad_per_s": tool.spindle_speed, "orbit_radius_m": tool.orbit_radius,
            "motion": tool.motion, "feed_m_per_s": self.feed, "spacing_m": self.spacing,
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
        if self.wear_rate or self.media_change or self.media_change_loss:
            record.update(wear_rate_per_s=self.wear_rate, media_change_s=self.media_change,
                          media_change_loss_fraction=self.media_change_loss, wear_compensation=self.wear_compensation)
        if self.robot:
            record.update(robot=self.robot, base=self.base, tcp=self.tcp, programs=list(self.programs),
                          place=self.place, table_z_m=self.table_z, cell=self.cell,
                          allow_collisions=self.allow_collisions,
                          force_program=self.force_program)
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
    "feed_simulate_check": Key("bool"), "target_floor": Key("str", choices=("none", "fastest")),
    "length_budget": Key("fraction", lo=1.0, hi=4.0),
    "target_cov": Key("fraction", positive=True, hi=1.0, off=True),
    "robot": Key("str"), "base": Key("str"), "tcp": Key("str"), "programs": Key("list"), "place": Key("bool"),
    "table_z": Key("length", bare_max=5.0, hint="mm, e.g. 700mm"), "robot_strict": Key("bool"),
    "cell": Key("path"), "allow_collisions": Key("bool"),
    "tip": Key("str"), "robot_keep_out": Key("length", lo=0.0, hi=5.0, bare_max=5.0, hint="mm, e.g. 400mm"),
    "depression_force": Key("force", positive=True, hi=1e4, bare_max=1e4),
    "pad_thickness": Key("length", positive=True, hi=0.5, bare_max=0.5, hint="mm, e.g. 10mm"),
    "spindle_speed": Key("frequency", positive=True, bare_max=0.0, hint="rpm, e.g. 10000rpm"),
    "orbit_radius": Key("length", lo=0.0, hi=0.1, bare_max=0.1, hint="mm, e.g. 2.5mm"),
    "wear_rate": Key("frequency", lo=0.0, hint="1/s, e.g. 0.001/s"),
    "media_change": Key("time", positive=True, off=True, hint="s, e.g. 300s"),
    "media_change_loss": Key("fraction", lo=0.01, hi=0.99, off=True),
    "wear_compensation": Key("bool"),
    "pad_damping": Key("time", lo=0.0, hi=1.0, bare_max=1.0, hint="ms, e.g. 10ms"),
    "faces": Key("str"), "keep_out": Key("str"),
    "keep_out_margin": Key("length", lo=0.0, hi=1.0, bare_max=1.0, hint="mm, e.g. 2mm"),
    "edge_margin": Key("length", lo=0.0, hi=1.0, bare_max=1.0, hint="mm, e.g. 5mm"),
    "chordal_tol": Key("length", positive=True, hi=1e-2, bare_max=1e-2, hint="mm, e.g. 0.1mm"),
    "allow_unusual_process": Key("bool"),
    "force_program": Key("str", choices=("native", "position")),
}


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
        if name == "depression" and isinstance(value, str) and "@" in value:
            # "1mm@20N": the pad's depression on flat at a stated force
            value, _, at = value.partition("@")
            if "depression_force" in values or "depression-force" in values:
                raise InputError(f"{key} states its force after '@' and depression_force is given too; give it once")
            kwargs["depression_force"] = parse_value(f"{key} (the force after '@')", at.strip(), SCHEMA["depression_force"])
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
    if settings.target_cov is not None:
        given = [flag for flag, on in (("--optimise-spacing", settings.optimise_spacing is not None),
                                       ("--spacing", settings.spacing is not None),
                                       ("--overlap", settings.overlap is not None),
                                       ("--optimise-feed", settings.optimise_feed),
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
