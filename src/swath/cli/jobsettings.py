"""The job's settings record, every setting declared once (:func:`swath.cli.schema.setting`).

Each field of :class:`JobSettings` states its SI default, what its value holds, the pipeline stage
that reads it, its help and its command-line option; the job-file schema
(:data:`swath.cli.settings.SCHEMA`), the options of ``swath plan`` / ``demo`` / ``rework`` and the
reference are derived from these declarations (see :mod:`swath.cli.schema` for adding one).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .schema import REQUIRED, Option, setting

#: Robot-realistic limits every trajectory is timed under unless the user turns them off ("none"):
#: tool angular speed (rad/s), centripetal and tangential acceleration (m/s²).
DEFAULT_LIMITS = {"max_angular": 1.0, "max_centripetal": 2.0, "max_accel": 1.0}


# the registries that hold the names of a setting's values (read when the schema is built)
def _planners() -> tuple:
    from ..plan import PLANNERS

    return tuple(PLANNERS)


def _orders() -> tuple:
    from ..order import ORDER_METHODS

    return tuple(ORDER_METHODS)


def _parameterizations() -> tuple:
    from ..scan.fit import PARAMETERIZATIONS

    return tuple(PARAMETERIZATIONS)


def _samplings() -> tuple:
    from ..simulate.removal import SAMPLINGS

    return tuple(SAMPLINGS)


def _force_programs() -> tuple:
    from ..robot.programs import FORCE_PROGRAMS

    return tuple(FORCE_PROGRAMS)


def _program_formats() -> tuple:
    from ..robot.programs import PROGRAM_FILES

    return tuple(PROGRAM_FILES)


def _robots() -> tuple:
    """The catalogue's robot names, each model once by its shortest name (``irb4600``, not also
    ``irb4600-60/2.05``)."""
    from ..robot.models import ROBOTS

    names = list(ROBOTS)
    return tuple(n for n in names if not any(o != n and n.startswith(o) for o in names))


@dataclass(frozen=True, kw_only=True)
class JobSettings:
    """Every setting of a job, SI units, each declared once with what it holds and its option.

    ``part`` is a mesh file path, ``example:NAME`` for a built-in part (``example:blade``), a
    B-spline patch saved by ``swath fit`` (``patch.json``), or, with ``fit``, a scan (point cloud
    or mesh) to fit a B-spline patch to first.  A patch is planned on its triangulation at
    ``surface_spacing`` (m; default its longest extent / 150, clipped to 2..5 mm).  The stages read
    their share through the records of :mod:`swath.cli.stage_settings`.
    """

    part: str = setting(REQUIRED, "str", stage="part", cli=False,
                        help="mesh file (STL, PLY, OBJ, STEP, IGES), patch.json from swath fit, example:NAME (a "
                             "built-in part), or with fit a scan (point cloud PLY/XYZ/PCD or mesh); the positional "
                             "PART of swath plan")
    units: str = setting("m", "str", stage="part", cli=Option(default="m", group="part"),
                         help="unit of a unitless mesh file: m, mm, cm or in (or their names, e.g. millimetres, inch)")
    side: str | None = setting(None, "str", stage="part", cli=Option(group="part"),
                               help="for a closed solid: the direction the tool comes from, e.g. +z, or all (finish "
                                    "it all round, in setups)")
    all_pieces: bool = setting(False, "bool", stage="part",
                               cli=Option(action="store_true", default=False, group="part"),
                               help="keep every piece of a multi-piece mesh")
    force_units: bool = setting(False, "bool", stage="part",
                                cli=Option(action="store_true", default=False, group="part"),
                                help="accept a part size outside 5 mm .. 20 m")
    fit: bool = setting(False, "bool", stage="part", cli=Option(action="store_true", default=False, group="part"),
                        help="PART is a scan (point cloud or mesh): fit a B-spline patch and plan on it")
    parameterization: str = setting("auto", "str", stage="part", choices=_parameterizations,
                                    cli=Option(group="part", choices=True),
                                    help="with --fit: how the scan is parameterised (default auto)")
    surface_spacing: float | None = setting(None, "length", stage="part", hi=0.1, bare_max=0.1, hint="mm, e.g. 3mm",
                                            positive=True, cli=Option(group="part"),
                                            help="triangle size of a fitted or saved patch to plan on, e.g. 3mm "
                                                 "(default: the patch's extent / 150, within 2..5 mm)")
    faces: str | None = setting(None, "str", stage="part", cli=Option(group="part"),
                                help="the area to finish: face ids, names or colours (3,5 / tube_outer / #0000ff) or "
                                     "box:xmin,ymin,zmin,xmax,ymax,zmax, polygon:FILE.csv or polygon:x,y x,y x,y (projected "
                                     "along +z; polygon[along=+x]:...), mask:FILE.stl (triangles within 1 mm of it "
                                     "or inside it); terms separated by ';' (default all)")
    keep_out: str | None = setting(None, "str", stage="part", cli=Option(group="part"),
                                   help="faces, boxes, polygons or masks the pad must not touch, as --faces")
    keep_out_margin: float = setting(0.002, "length", stage="part", lo=0.0, hi=1.0, bare_max=1.0, hint="mm, e.g. 2mm",
                                     cli=Option(group="part"),
                                     help="clearance beyond the pad radius from the keep-outs (default 2mm)")
    edge_margin: float = setting(0.0, "length", stage="part", lo=0.0, hi=1.0, bare_max=1.0, hint="mm, e.g. 5mm",
                                 cli=Option(group="part"),
                                 help="distance the pad centre keeps in from the area's open edges (default 0)")
    chordal_tol: float = setting(0.0001, "length", stage="part", hi=0.01, bare_max=0.01, hint="mm, e.g. 0.1mm",
                                 positive=True, cli=Option(group="part"),
                                 help="STEP/IGES tessellation: largest distance from the exact faces (default 0.1mm)")
    planner: str = setting("raster", "str", stage="plan", choices=_planners, cli=Option(default="raster"),
                           help="path planner: raster (plane slices, the baseline), uniform (contact-aware uniform "
                                "coverage), equidistant (geodesic-parallel passes) or wrap (a continuous helix round "
                                "a closed part's axis, for a rotary positioner)")
    pad_radius: float = setting(0.0381, "length", stage="tool", hi=1.0, bare_max=1.0, hint="mm, e.g. 38.1mm",
                                positive=True, cli=Option(default="38.1mm"),
                                help="pad radius, e.g. 38.1mm, within 5–150 mm (default: 3-inch pad)")
    force: float = setting(20.0, "force", stage="tool", hi=10000.0, bare_max=10000.0, positive=True,
                           cli=Option(default="20N"), help="normal force, e.g. 20N, within 1–500 N")
    depression: float | None = setting(None, "length", stage="tool", bare_max=0.1, hint="mm, e.g. 1mm", positive=True,
                                       cli=Option(exclusive="pad"),
                                       help="the pad's depression on a flat surface at a stated force, e.g. 1mm@20N; "
                                            "a bare 1mm is at 20 N, and the set --force then presses this pad deeper "
                                            "or shallower (default 1mm@20N)")
    stiffness: float | None = setting(None, "stiffness", stage="tool", positive=True, cli=Option(exclusive="pad"),
                                      help="pad foundation stiffness, e.g. 4.4MPa/m")
    motion: str | None = setting(None, "str", stage="tool", choices=("orbital", "rotary"), cli=Option(choices=True),
                                 help="pad motion (default orbital, or the motion the --calibration was measured "
                                      "with)")
    feed: float = setting(0.05, "speed", stage="trajectory", hi=5.0, bare_max=5.0, hint="mm/s, e.g. 50mm/s",
                          positive=True, cli=Option(default="50mm/s"),
                          help="feed along contact passes, e.g. 50mm/s, within 1–500 mm/s")
    spacing: float | None = setting(None, "length", stage="plan", bare_max=2.0, hint="mm, e.g. 60mm", positive=True,
                                    cli=True,
                                    help="pass spacing, e.g. 60mm (default: the least-ripple spacing within "
                                         "--length-budget, for even removal; with --constant-feed, full coverage "
                                         "from the contact model)")
    direction: float | None = setting(None, "angle", stage="plan", auto=True,
                                      cli=Option(flags=("--direction", "--angle"), default="auto"),
                                      help="pass direction: an angle from the part's principal axis, e.g. 30deg, or "
                                           "auto (default: each planner's own choice, e.g. the shortest "
                                           "full-coverage path)")
    point_spacing: float = setting(0.001, "length", stage="plan", hi=0.1, bare_max=0.1, hint="mm, e.g. 1mm",
                                   positive=True, cli=Option(default="1mm"), help="spacing of points along passes")
    clearance: float = setting(0.02, "length", stage="trajectory", hi=1.0, bare_max=1.0, hint="mm, e.g. 20mm",
                               positive=True, cli=Option(default="20mm"), help="lift off the surface for air moves")
    order: str | None = setting(None, "str", stage="order", auto=True, names=_orders, cli=True,
                                help="how passes are sequenced (default: the planner's own: snake for raster and "
                                     "equidistant, zigzag for uniform)")
    join_gap: float | None = setting(None, "length", stage="order", hi=1.0, bare_max=1.0, hint="mm, e.g. 76mm",
                                     off=True, positive=True, cli=True,
                                     help="make step-overs up to this long in contact where the pad can slide along "
                                          "the part, joining the passes (Wang's continuous paths; fewer air moves, "
                                          "more contact at the ends), e.g. 76mm; orders by gtsp unless --order is "
                                          "given")
    # Single passes by default: each pass picks its own direction, so a one-way sweep (return moves,
    # no 180-degree turns at 1 rad/s) can win over a region's snake (example:hub: 131 s vs 186 s).
    order_groups: str = setting("passes", "str", stage="order", choices=("regions", "passes"),
                                cli=Option(choices=True),
                                help="what the tour orders: single passes, each choosing its direction (default), or "
                                     "whole regions, each swept as a snake from one of its corners (Wang's path "
                                     "types)")
    # Link time by default: the shorter cycle (on example:hub 129 s against 212 s ordered by length
    # with contact step-overs).
    order_objective: str = setting("time", "str", stage="order", choices=("time", "length"), cli=Option(choices=True),
                                   help="what the tour minimises: link and step-over time, the shortest cycle "
                                        "(default), or air length (tool turns then may cost time)")
    overlap: float | None = setting(None, "fraction", stage="plan", lo=0.0, hi=0.9, cli=True,
                                    help="uniform planner: overlap of neighbouring swaths, e.g. 10%% (default: the "
                                         "least-ripple overlap within --length-budget, for even removal; 10%% with "
                                         "--constant-feed)")
    max_centripetal: float | None = setting(DEFAULT_LIMITS["max_centripetal"], "acceleration", stage="trajectory",
                                            off=True, positive=True, cli=True,
                                            help="limit on centripetal acceleration along passes (default 2m/s2; "
                                                 "'none' turns it off)")
    max_angular: float | None = setting(DEFAULT_LIMITS["max_angular"], "angular_speed", stage="trajectory", off=True,
                                        positive=True, cli=True,
                                        help="limit on the tool's angular speed (default 1rad/s; 'none' turns it off)")
    max_accel: float | None = setting(DEFAULT_LIMITS["max_accel"], "acceleration", stage="trajectory", off=True,
                                      positive=True, cli=True,
                                      help="limit on tangential acceleration along passes (default 1m/s2; 'none' "
                                           "turns it off)")
    out: str = setting(REQUIRED, "str", stage="job", cli=Option(required=True),
                       help="output directory (written atomically; an existing non-empty folder is refused unless it "
                            "is an earlier swath output or --overwrite)")
    overwrite: bool = setting(False, "bool", stage="job", cli=Option(action="store_true", default=False),
                              help="replace an existing non-empty output folder that swath did not write")
    # The lattice is 2-5x faster with a third of the samples on CAD parts with long slivers, same
    # metrics within 0.5 %; the depth picture is drawn on the part's own mesh, interpolated from the samples.
    removal_sampling: str = setting("lattice", "str", stage="simulate", choices=_samplings, cli=Option(choices=True),
                                    help="where removal is simulated: a lattice at the sample spacing on every "
                                         "triangle (default; much faster on CAD parts with long slivers) or the part "
                                         "subdivided to the sample spacing (mesh, the sampling of the feed "
                                         "optimiser's kernel)")
    memory_budget: float | None = setting(None, "str", stage="job", cli=True,
                                          help="refuse work estimated to need more memory than this, e.g. 8GiB "
                                               "(default: 3/4 of this machine's memory)")
    segment: str | None = setting(None, "str", stage="plan", choices=("none", "auto"), off=True, cli=True,
                                  help="auto: split the part into regions that parallel passes cross without breaks "
                                       "(Wang), plan each, visit them in the order with least air (gtsp); none")
    optimise_feed: bool = setting(False, "bool", stage="feed", cli=Option(action="store_true", group="even"),
                                  help="choose the feed along every pass so removal matches the target, never more "
                                       "than the target plus the tolerance (HiGHS; on by default, off with "
                                       "--constant-feed)")
    target_depth: float | None = setting(None, "length", stage="feed", bare_max=0.01, hint="um, e.g. 20um",
                                         positive=True, cli=Option(group="even"),
                                         help="uniform depth to remove, e.g. 20um (default: chosen so that the cycle "
                                              "time stays within --cycle-time-factor of the constant feed's)")
    target_map: str | None = setting(None, "path", stage="feed", cli=Option(group="even"),
                                     help="per-point depths to remove (CSV x,y,z,depth in m, or PLY with a vertex "
                                          "'depth')")
    depth_tolerance: float | None = setting(None, "length", stage="feed", lo=0.0, bare_max=0.01, hint="um, e.g. 5um",
                                            cli=Option(group="even"),
                                            help="allowed removal above the target, e.g. 2um "
                                                 "(default 10 %% of the target depth)")
    optimise_spacing: str | None = setting(None, "str", stage="feed", choices=("ripple", "greedy", "joint"), off=True,
                                           cli=Option(group="even"),
                                           help="raster pass spacing for even removal: ripple (the spacing whose "
                                                "summed pad cross-profiles are flattest, path within 1.5x the "
                                                "coverage bound; with --planner uniform its overlap), greedy (Wang's "
                                                "pattern search, pass by pass, against the target) or joint (equal "
                                                "spacing and feed together)")
    length_budget: float = setting(1.5, "fraction", stage="feed", lo=1.0, hi=4.0, cli=Option(group="even"),
                                   help="with the ripple spacing (the default): the contact length the spacing may "
                                        "use, in multiples of the coverage bound L*, e.g. 2 (default 1.5): closer passes, "
                                        "less ripple between them")
    # rad; None ("auto"): the angle at which half the pad presses on a flat part (Tool.half_pad_lead);
    # "default": auto in the even-removal job, else 0 (lead())
    lead_angle: float | str | None = setting("default", "angle", stage="trajectory", lo=-math.pi / 4, hi=math.pi / 4, auto=True,
                                       cli=Option(group="even"),
                                       help="tilt the pad about the axis across the feed in contact, its leading "
                                            "edge lifted, e.g. 7deg; auto: the angle at which half the pad presses "
                                            "on a flat part (7.0 deg for the default pad), which turns each pass's "
                                            "removal profile from a semicircle into a parabola and halves the ripple "
                                            "between passes (default: auto, and on a curved part the lead the passes "
                                            "simulate evenest at, among 0, auto, 11 and 15 deg; 0, z along minus the "
                                            "normal, with --constant-feed or --target-cov)")
    feed_simulate_check: bool = setting(True, "bool", stage="feed",
                                        cli=Option(action="boolean", group="even"),
                                        help="with --optimise-feed: simulate the optimised trajectory and tighten "
                                             "the feed where the simulator finds more than the target plus the "
                                             "tolerance (up to 6 rounds; default on)")
    target_cov: float | None = setting(None, "fraction", stage="job", hi=1.0, off=True, positive=True,
                                       cli=Option(group="even"),
                                       help="the interior removal CoV to reach, e.g. 6%%: swath plans, times and "
                                            "simulates a stated set of candidates (spacing, lead) and keeps the one "
                                            "with the shortest cycle time that reaches it, or refuses with the least "
                                            "reachable CoV and its cycle time")
    # the default job evens the removal (swath.cli.even_default); constant_feed: the plain plan
    constant_feed: bool = setting(False, "bool", stage="feed", cli=Option(action="store_true", group="even"),
                                  help="a plain plan: the planner's covering spacing, no lead, the feed given all "
                                       "along the passes (default: even removal: least-ripple spacing, half-pad "
                                       "lead, the feed optimised to a target depth)")
    # the default target depth keeps the cycle time within this factor of the constant-feed plan
    cycle_time_factor: float = setting(1.5, "fraction", stage="feed", lo=1.05, hi=10.0, cli=Option(group="even"),
                                       help="even removal without --target-depth: the target depth is chosen so "
                                            "that the cycle time stays within this factor of the same passes at "
                                            "constant feed (default 1.5)")
    robot: str | None = setting(None, "str", stage="robot", cli=Option(group="robot"), names=_robots,
                                help="robot model: {names}, or a URDF file (path/to/robot.urdf, with --tip)")
    base: str | None = setting(None, "str", stage="robot", cli=Option(group="robot"),
                               help="the part's pose in the robot base frame, x,y,z,rx,ry,rz (e.g. "
                                    "800mm,0,100mm,0,0,90deg)")
    tcp: str | None = setting(None, "str", stage="robot", cli=Option(group="robot"),
                              help="the tool (TCP) pose in the flange frame, x,y,z,rx,ry,rz (e.g. 0,0,150mm,0,0,0)")
    programs: tuple = setting((), "list", stage="robot", cli=Option(flags=("--program",), group="robot"),
                              names=_program_formats,
                              help="robot programs to write: {names} (comma-separated; default csv)")
    place: bool = setting(False, "bool", stage="robot", cli=Option(action="store_true", group="robot"),
                          help="search where to put the part so the whole job is reachable (x, y, yaw on the table)")
    table_z: float = setting(0.0, "length", stage="robot", bare_max=5.0, hint="mm, e.g. 700mm",
                             cli=Option(group="robot"),
                             help="with --place: height of the part's lowest point in the base frame, e.g. 0mm")
    cell: str | None = setting(None, "path", stage="robot", cli=Option(group="robot"),
                               help="cell file (TOML): robot, part2base, tool (tcp2flange and body), table, "
                                    "fixtures; the job's motion is checked for collisions in it (see "
                                    "docs/guide/cell.md)")
    allow_collisions: bool = setting(False, "bool", stage="robot", cli=Option(action="store_true", group="robot"),
                                     help="write the robot programs even when the collision check finds a collision "
                                          "(a warning then; default: refuse with exit status 2)")
    tip: str | None = setting(None, "str", stage="robot", cli=Option(group="robot"),
                              help="with --robot path/to/robot.urdf: the URDF frame the tool is mounted on (default "
                                   "tool0)")
    robot_keep_out: float | None = setting(None, "length", stage="robot", lo=0.0, hi=5.0, bare_max=5.0,
                                           hint="mm, e.g. 400mm", cli=Option(group="robot"),
                                           help="with --place: radius of the cylinder about the robot's base axis "
                                                "the part must stay out of, e.g. 400mm (default 0.2 m + 0.1 x reach)")
    force_program: str = setting("native", "str", stage="robot", choices=_force_programs,
                                 cli=Option(group="robot", choices=True),
                                 help="how the urscript/rapid/krl programs press the pad: native (the controller's "
                                      "force control along the tool axis: UR force_mode, ABB Force Control, "
                                      "KUKA.ForceTorqueControl; default) or position (position only, for a compliant "
                                      "tool; the program and a warning say so)")
    force_control: bool = setting(False, "bool", stage="simulate",
                                  cli=Option(action="store_true", default=False, group="force"),
                                  help="simulate hybrid position/force control along the trajectory: a force column, "
                                       "a force plot, removal from the simulated force")
    part_offset: tuple | None = setting(None, "offset", stage="simulate", cli=Option(group="force"),
                                        help="with --force-control: the real part's offset from the plan "
                                             "(registration error), dx,dy,dz,rx,ry,rz, e.g. 0.5mm,0,0,0.2deg,0,0")
    tool_mass: float = setting(0.0, "mass", stage="simulate", lo=0.0, hi=500.0, cli=Option(group="force"),
                               help="with --force-control: mass below the force sensor, e.g. 2kg (default 0)")
    tool_tilt: float = setting(0.0, "angle", stage="simulate", cli=Option(group="force"),
                               help="with --force-control: tilt of the cell from tool-down, e.g. 30deg (default 0)")
    gravity_compensation: bool = setting(True, "bool", stage="simulate",
                                         cli=Option(flags=("--no-gravity-compensation",), action="store_false",
                                                    group="force"),
                                         help="with --force-control: do not subtract the tool's weight from the "
                                              "measured force")
    calibration: str | None = setting(None, "path", stage="tool", cli=Option(group="force"),
                                      help="a Preston calibration file written by swath calibrate (sets k_p)")
    grit: str | None = setting(None, "str", stage="tool", cli=Option(group="force"),
                               help="with --calibration: which grit's fit to use (default: the only or first)")
    pad_thickness: float | None = setting(None, "length", stage="tool", hi=0.5, bare_max=0.5, hint="mm, e.g. 10mm",
                                          positive=True, cli=Option(group="process"),
                                          help="thickness of the pad's compliant layer, e.g. 10mm: refuses a force "
                                               "that presses through it")
    # rad/s (given as a frequency, e.g. 10000rpm, and turned into rad/s); None: 10 000 rpm or the calibration's
    spindle_speed: float | None = setting(None, "frequency", stage="tool", bare_max=0.0, hint="rpm, e.g. 10000rpm",
                                          positive=True, cli=Option(group="process"),
                                          help="pad (or orbit) speed, e.g. 10000rpm (default 10000rpm, or the "
                                               "calibration's)")
    # m; None: 2.5 mm or the calibration's
    orbit_radius: float | None = setting(None, "length", stage="tool", lo=0.0, hi=0.1, bare_max=0.1,
                                         hint="mm, e.g. 2.5mm", cli=Option(group="process"),
                                         help="orbit eccentricity of an orbital pad, e.g. 2.5mm (default 2.5mm, or "
                                              "the calibration's)")
    # 1/s; None: no wear, or the calibration's
    wear_rate: float | None = setting(None, "frequency", stage="process", lo=0.0, hint="1/s, e.g. 0.001/s",
                                      cli=Option(group="process"),
                                      help="pad wear: the removal rate falls as exp(-rate * time in contact), e.g. "
                                           "0.001/s (default 0, or the calibration's)")
    media_change: float | None = setting(None, "time", stage="process", hint="s, e.g. 300s", off=True, positive=True,
                                         cli=Option(group="process"),
                                         help="change the abrasive every this much time in contact, e.g. 300s: a "
                                              "pause for the operator in the programs, between passes")
    media_change_loss: float | None = setting(None, "fraction", stage="process", lo=0.01, hi=0.99, off=True,
                                              cli=Option(group="process"),
                                              help="change the abrasive when its removal rate has fallen by this "
                                                   "much, e.g. 20%% (needs a wear rate)")
    pad_damping: float = setting(0.0, "time", stage="tool", lo=0.0, hi=1.0, bare_max=1.0, hint="ms, e.g. 10ms",
                                 cli=Option(group="process"),
                                 help="the pad's viscous relaxation time, e.g. 10ms: with --force-control it resists "
                                      "the landing at every pass start and lets go late on the lift (default 0: "
                                      "elastic)")
    wear_compensation: bool = setting(True, "bool", stage="process",
                                      cli=Option(action="boolean", group="process"),
                                      help="slow the feed as the pad wears so that the removal stays as planned "
                                           "(default on when the pad wears)")
    allow_unusual_process: bool = setting(False, "bool", stage="job", cli=Option(action="store_true"),
                                          help="plan a feed, force or pad radius outside what a sanding robot does "
                                               "(feed 1–500 mm/s, force 1–500 N, pad radius 5–150 mm), with a "
                                               "warning instead of a refusal")
    sample_spacing: float | None = setting(None, "length", stage="simulate", hi=0.1, bare_max=0.1,
                                           hint="mm, e.g. 3mm", positive=True, cli=False,
                                           help="spacing of the removal samples, e.g. 3mm (default: from the pad "
                                                "radius and the part's size)")
    planner_options: dict = setting({}, "table", stage="plan", cli=False,
                                    help="options of the planner beyond the job's settings, a [planner_options] "
                                         "table (listed below)")
    target_floor: str = setting("none", "str", stage="feed", choices=("none", "fastest"), cli=False,
                                help="with optimise_feed: fastest raises the target to what the passes remove at the "
                                     "fastest feed (a tapering target map)")
    robot_strict: bool = setting(False, "bool", stage="robot", cli=False,
                                 help="refuse a job with any pose the robot cannot reach (default: a warning and the "
                                      "reachable part)")
    depression_force: float | None = setting(None, "force", stage="tool", hi=10000.0, bare_max=10000.0, positive=True,
                                             cli=False,
                                             help="the force the depression was measured at (default 20 N); "
                                                  "--depression 1mm@20N sets both")

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
        :data:`DEFAULT_LIMITS`); see :meth:`swath.cli.stage_settings.TrajectorySettings.constraints`."""
        from .stage_settings import TrajectorySettings

        return TrajectorySettings.of(self).constraints()

    def lead(self) -> float:
        """The lead angle (rad) the trajectory tilts the tool by in contact: ``lead_angle``, or for
        ``auto`` the angle at which half the pad presses on a flat part (``Tool.half_pad_lead``); for
        ``"default"`` auto in the even-removal job and 0 with ``constant_feed`` or ``target_cov``."""
        lead = self.lead_angle
        if lead == "default":
            lead = 0.0 if self.constant_feed or self.target_cov is not None or self.side == "all" else None
        return self.tool().half_pad_lead if lead is None else float(lead)

    def links(self):
        """How the tool moves between passes."""
        from .stage_settings import TrajectorySettings

        return TrajectorySettings.of(self).links()

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
        record.update(constant_feed=self.constant_feed)
        if self.optimise_feed or self.optimise_spacing:
            record.update(cycle_time_factor_ratio=self.cycle_time_factor, optimise_feed=self.optimise_feed, optimise_spacing=self.optimise_spacing,
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
