"""``swath`` command line: one subcommand per job kind.

    swath plan PART [--units mm] [--planner raster] [--pad-radius 38.1mm] [--force 20N]
               [--depression 1mm] [--feed 50mm/s] [--spacing 60mm] [--direction 0deg] --out DIR
    swath plan SCAN --fit [--parameterization auto] [--surface-spacing 3mm] ... --out DIR
    swath plan patch.json ... --out DIR   # a patch written by swath fit
    swath demo --out DIR              # the same on the built-in helicopter-blade section
    swath run job.toml                # settings from a TOML file
    swath batch sweep.toml [--workers 2]   # a grid of jobs on Ray, one results table
    swath fit SCAN [--units mm] [--parameterization auto|projection|lscm|rows] [--spacing 2mm] --out DIR
    swath register CAD SCAN [--units mm] [--scan-units mm] [--table] --out DIR
    swath rework CAD SCAN [--units mm] [--placement register] [--min-excess 2um] ... --out DIR

Errors caused by the input exit with status 2 and one line on stderr; no half-written output is
left behind.
"""

from __future__ import annotations

import argparse
import difflib
import logging
import math
import sys
import time
from pathlib import Path

from ..errors import InputError, SwathError

log = logging.getLogger("swath")

#: Scan parameterisations of ``--parameterization`` (as :data:`swath.scan.fit.PARAMETERIZATIONS`).
PARAMETERIZATIONS = ("auto", "projection", "lscm", "rows")


def _add_plan_options(p: argparse.ArgumentParser, *, with_part_options: bool = True) -> None:
    if with_part_options:
        p.add_argument("--units", default="m", help="unit of a unitless mesh file: m, mm, cm or in (or their names, "
                                                    "e.g. millimetres, inch)")
        p.add_argument("--side", help="for a closed solid: the direction the tool comes from, e.g. +z, or all "
                                      "(finish it all round, in setups)")
        p.add_argument("--all-pieces", action="store_true", help="keep every piece of a multi-piece mesh")
        p.add_argument("--force-units", action="store_true", help="accept a part size outside 5 mm .. 20 m")
        p.add_argument("--fit", action="store_true",
                       help="PART is a scan (point cloud or mesh): fit a B-spline patch and plan on it")
        p.add_argument("--parameterization", choices=PARAMETERIZATIONS,
                       help="with --fit: how the scan is parameterised (default auto)")
        p.add_argument("--surface-spacing",
                       help="triangle size of a fitted or saved patch to plan on, e.g. 3mm "
                            "(default: the patch's extent / 150, within 2..5 mm)")
        p.add_argument("--faces", help="the area to finish: face ids, names or colours (3,5 / tube_outer / #0000ff) "
                                       "or box:xmin,ymin,zmin,xmax,ymax,zmax; terms separated by ';' (default all)")
        p.add_argument("--keep-out", help="faces or boxes the pad must not touch, as --faces")
        p.add_argument("--keep-out-margin", help="clearance beyond the pad radius from the keep-outs (default 2mm)")
        p.add_argument("--edge-margin", help="distance the pad centre keeps in from the area's open edges (default 0)")
        p.add_argument("--chordal-tol", help="STEP/IGES tessellation: largest distance from the exact faces "
                                             "(default 0.1mm)")
    p.add_argument("--planner", default="raster",
                   help="path planner: raster (plane slices, the baseline), uniform (contact-aware uniform coverage) "
                        "or equidistant (geodesic-parallel passes)")
    p.add_argument("--pad-radius", default="38.1mm",
                   help="pad radius, e.g. 38.1mm, within 5–150 mm (default: 3-inch pad)")
    p.add_argument("--force", default="20N", help="normal force, e.g. 20N, within 1–500 N")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--depression", help="the pad's depression on a flat surface at a stated force, e.g. 1mm@20N; a "
                                        "bare 1mm is at 20 N, and the set --force then presses this pad deeper or "
                                        "shallower (default 1mm@20N)")
    g.add_argument("--stiffness", help="pad foundation stiffness, e.g. 4.4MPa/m")
    p.add_argument("--motion", choices=["orbital", "rotary"],
                   help="pad motion (default orbital, or the motion the --calibration was measured with)")
    p.add_argument("--feed", default="50mm/s", help="feed along contact passes, e.g. 50mm/s, within 1–500 mm/s")
    p.add_argument("--spacing", help="pass spacing, e.g. 60mm (default: full coverage from the contact model)")
    p.add_argument("--direction", "--angle", dest="direction", default="auto",
                   help="pass direction: an angle from the part's principal axis, e.g. 30deg, or auto (default: "
                        "each planner's own choice, e.g. the shortest full-coverage path)")
    p.add_argument("--point-spacing", default="1mm", help="spacing of points along passes")
    p.add_argument("--clearance", default="20mm", help="lift off the surface for air moves")
    p.add_argument("--order",
                   help="how passes are sequenced (default: the planner's own: snake for raster and equidistant, "
                        "zigzag for uniform)")
    p.add_argument("--join-gap", help="make step-overs up to this long in contact where the pad can slide along the "
                                      "part, joining the passes (Wang's continuous paths; fewer air moves, more "
                                      "contact at the ends), e.g. 76mm; orders by gtsp unless --order is given")
    p.add_argument("--order-groups", choices=("regions", "passes"),
                   help="what the tour orders: single passes, each choosing its direction (default), or whole "
                        "regions, each swept as a snake from one of its corners (Wang's path types)")
    p.add_argument("--order-objective", choices=("time", "length"),
                   help="what the tour minimises: link and step-over time, the shortest cycle (default), or air "
                        "length (tool turns then may cost time)")
    p.add_argument("--overlap", help="uniform planner: overlap of neighbouring swaths, e.g. 10%% (default 10%%)")
    p.add_argument("--max-centripetal", help="limit on centripetal acceleration along passes (default 2m/s2; "
                                             "'none' turns it off)")
    p.add_argument("--max-angular", help="limit on the tool's angular speed (default 1rad/s; 'none' turns it off)")
    p.add_argument("--max-accel", help="limit on tangential acceleration along passes (default 1m/s2; 'none' "
                                       "turns it off)")
    p.add_argument("--out", required=True, help="output directory (written atomically; an existing non-empty folder "
                                                "is refused unless it is an earlier swath output or --overwrite)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an existing non-empty output folder that swath did not write")
    p.add_argument("--removal-sampling", choices=("lattice", "mesh"),
                   help="where removal is simulated: a lattice at the sample spacing on every triangle (default; "
                        "much faster on CAD parts with long slivers) or the part subdivided to the sample spacing "
                        "(mesh, the sampling of the feed optimiser's kernel)")
    p.add_argument("--memory-budget", help="refuse work estimated to need more memory than this, e.g. 8GiB "
                                           "(default: 3/4 of this machine's memory)")
    p.add_argument("--segment", help="auto: split the part into regions that parallel passes cross without breaks "
                                      "(Wang), plan each, visit them in the order with least air (gtsp); none")
    e = p.add_argument_group("even removal (the default; Wang §2): spacing, lead and feed (dwell) to a target depth")
    e.add_argument("--optimise-feed", action="store_true", default=None,
                   help="choose the feed along every pass so removal matches the target, never more than the "
                        "target plus the tolerance (HiGHS; on by default, off with --constant-feed)")
    e.add_argument("--target-depth", help="uniform depth to remove, e.g. 20um (default: chosen so that the cycle time stays "
                                             "within --cycle-time-factor of the constant feed's)")
    e.add_argument("--target-map", help="per-point depths to remove (CSV x,y,z,depth in m, or PLY with a "
                                        "vertex 'depth')")
    e.add_argument("--depth-tolerance", help="allowed removal above the target, e.g. 2um "
                                             "(default 10 %% of the target depth)")
    e.add_argument("--optimise-spacing",
                   help="raster pass spacing for even removal: ripple (the spacing whose summed pad "
                        "cross-profiles are flattest, path within 1.5x the coverage bound; with --planner uniform its overlap), greedy (Wang's pattern "
                        "search, pass by pass, against the target) or joint (equal spacing and feed together)")
    e.add_argument("--length-budget",
                   help="with the ripple spacing (the default): the contact length the spacing may use, in multiples of the "
                        "coverage bound L*, e.g. 2 (default 1.5): closer passes, less ripple between them")
    e.add_argument("--lead-angle",
                   help="tilt the pad about the axis across the feed in contact, its leading edge lifted, e.g. "
                        "7deg; auto: the angle at which half the pad presses on a flat part (7.0 deg for the "
                        "default pad), which turns each pass's removal profile from a semicircle into a "
                        "parabola and halves the ripple between passes (default: auto; 0, z along minus the normal, "
                        "with --constant-feed or --target-cov)")
    e.add_argument("--feed-simulate-check", action=argparse.BooleanOptionalAction, default=None,
                   help="with --optimise-feed: simulate the optimised trajectory and tighten the feed where the "
                        "simulator finds more than the target plus the tolerance (up to 6 rounds; default on)")
    e.add_argument("--target-cov",
                   help="the interior removal CoV to reach, e.g. 6%%: swath plans, times and simulates a stated set "
                        "of candidates (spacing, lead) and keeps the one with the shortest cycle time that reaches "
                        "it, or refuses with the least reachable CoV and its cycle time")
    e.add_argument("--constant-feed", action="store_true", default=None,
                   help="a plain plan: the planner's covering spacing, no lead, the feed given all along the passes "
                        "(default: even removal: least-ripple spacing, half-pad lead, the feed optimised to a "
                        "target depth)")
    e.add_argument("--cycle-time-factor",
                   help="even removal without --target-depth: the target depth is chosen so that the cycle time "
                        "stays within this factor of the same passes at constant feed (default 1.5)")
    r = p.add_argument_group("robot (kinematics, reachability, programs)")
    r.add_argument("--robot", help="robot model: ur3e, ur5e, ur10e, ur16e, irb4600, kr120, or a URDF file "
                                   "(path/to/robot.urdf, with --tip)")
    r.add_argument("--base", help="the part's pose in the robot base frame, x,y,z,rx,ry,rz (e.g. 800mm,0,100mm,0,0,90deg)")
    r.add_argument("--tcp", help="the tool (TCP) pose in the flange frame, x,y,z,rx,ry,rz (e.g. 0,0,150mm,0,0,0)")
    r.add_argument("--program", dest="programs",
                   help="robot programs to write: urscript, rapid, krl, ros, csv (comma-separated; default csv)")
    r.add_argument("--place", action="store_true", default=None,
                   help="search where to put the part so the whole job is reachable (x, y, yaw on the table)")
    r.add_argument("--table-z", help="with --place: height of the part's lowest point in the base frame, e.g. 0mm")
    r.add_argument("--cell", help="cell file (TOML): robot, part2base, tool (tcp2flange and body), table, fixtures; "
                                  "the job's motion is checked for collisions in it (see docs/guide/cell.md)")
    r.add_argument("--allow-collisions", action="store_true", default=None,
                   help="write the robot programs even when the collision check finds a collision (a warning "
                        "then; default: refuse with exit status 2)")
    r.add_argument("--tip", help="with --robot path/to/robot.urdf: the URDF frame the tool is mounted on (default tool0)")
    r.add_argument("--robot-keep-out", help="with --place: radius of the cylinder about the robot's base axis the part "
                                      "must stay out of, e.g. 400mm (default 0.2 m + 0.1 x reach)")
    r.add_argument("--force-program", choices=("native", "position"),
                   help="how the urscript/rapid/krl programs press the pad: native (the controller's force control "
                        "along the tool axis: UR force_mode, ABB Force Control, KUKA.ForceTorqueControl; default) or "
                        "position (position only, for a compliant tool; the program and a warning say so)")
    f = p.add_argument_group("force control and calibration (Jaeger ch. 5, 6)")
    f.add_argument("--force-control", action="store_true",
                   help="simulate hybrid position/force control along the trajectory: a force column, a force plot, "
                        "removal from the simulated force")
    f.add_argument("--part-offset", help="with --force-control: the real part's offset from the plan (registration "
                                         "error), dx,dy,dz,rx,ry,rz, e.g. 0.5mm,0,0,0.2deg,0,0")
    f.add_argument("--tool-mass", help="with --force-control: mass below the force sensor, e.g. 2kg (default 0)")
    f.add_argument("--tool-tilt", help="with --force-control: tilt of the cell from tool-down, e.g. 30deg (default 0)")
    f.add_argument("--no-gravity-compensation", dest="gravity_compensation", action="store_false", default=None,
                   help="with --force-control: do not subtract the tool's weight from the measured force")
    f.add_argument("--calibration", help="a Preston calibration file written by swath calibrate (sets k_p)")
    f.add_argument("--grit", help="with --calibration: which grit's fit to use (default: the only or first)")
    w = p.add_argument_group("process: pad, kinematics, wear and media changes")
    w.add_argument("--pad-thickness", help="thickness of the pad's compliant layer, e.g. 10mm: refuses a force that "
                                           "presses through it")
    w.add_argument("--spindle-speed", help="pad (or orbit) speed, e.g. 10000rpm (default 10000rpm, or the "
                                           "calibration's)")
    w.add_argument("--orbit-radius", help="orbit eccentricity of an orbital pad, e.g. 2.5mm (default 2.5mm, or the "
                                          "calibration's)")
    w.add_argument("--wear-rate", help="pad wear: the removal rate falls as exp(-rate * time in contact), e.g. "
                                       "0.001/s (default 0, or the calibration's)")
    w.add_argument("--media-change", help="change the abrasive every this much time in contact, e.g. 300s: a pause "
                                          "for the operator in the programs, between passes")
    w.add_argument("--media-change-loss", help="change the abrasive when its removal rate has fallen by this much, "
                                               "e.g. 20%% (needs a wear rate)")
    w.add_argument("--pad-damping", help="the pad's viscous relaxation time, e.g. 10ms: with --force-control it "
                                         "resists the landing at every pass start and lets go late on the lift "
                                         "(default 0: elastic)")
    w.add_argument("--wear-compensation", action=argparse.BooleanOptionalAction, default=None,
                   help="slow the feed as the pad wears so that the removal stays as planned (default on when the "
                        "pad wears)")
    p.add_argument("--allow-unusual-process", action="store_true", default=None,
                   help="plan a feed, force or pad radius outside what a sanding robot does (feed 1–500 mm/s, "
                        "force 1–500 N, pad radius 5–150 mm), with a warning instead of a refusal")


class _DefaultsFormatter(argparse.HelpFormatter):
    """Help that states each option's default where it has a real one (not None, False or a
    default the help text already names)."""

    def _get_help_string(self, action):
        text = action.help or ""
        default = action.default
        if default in (None, False, argparse.SUPPRESS) or "default" in text or not action.option_strings:
            return text
        # argparse %-formats help strings: a literal % in the default (say "90%") must be doubled.
        return f"{text} (default: {str(default).replace('%', '%%')})"


def build_parser() -> argparse.ArgumentParser:
    from .. import __version__

    parser = argparse.ArgumentParser(prog="swath", description="Plan robotic surface finishing on free-form parts.")
    parser.add_argument("--version", action="version", version=f"swath {__version__}")
    parser.add_argument("-q", "--quiet", action="store_true", help="only errors")
    parser.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    sub = parser.add_subparsers(dest="command", required=True)

    def add_parser(name: str, **kw) -> argparse.ArgumentParser:     # every --help shows its defaults
        return sub.add_parser(name, formatter_class=_DefaultsFormatter, **kw)

    p = add_parser("plan", help="plan a part: trajectory.csv, metrics.json, report.html")
    from ..examples import PARTS

    examples = ", ".join(PARTS)                     # the registry's names, so a new example is listed
    p.add_argument("part", help=f"mesh file (STL, PLY, OBJ), patch.json from swath fit, example:NAME ({examples}), "
                                "or with --fit a scan (point cloud PLY/XYZ/PCD or mesh)")
    _add_plan_options(p)

    f = add_parser("fit", help="fit a B-spline patch to a scan: patch.json, surface.ply, fit.json, fit.html")
    f.add_argument("scan", help="point cloud (XYZ/TXT/CSV/PTS, PCD, PLY without faces) or mesh (STL, OBJ, PLY)")
    f.add_argument("--units", default="m", help="unit of the scan file: m, mm, cm or in (default m)")
    f.add_argument("--parameterization", default="auto", choices=PARAMETERIZATIONS,
                   help="auto (projection if it does not fold, else LSCM on a mesh), projection, lscm (mesh "
                        "scans; patches that wrap), rows (a cloud in scan order; rows split at jumps and turns)")
    f.add_argument("--spacing", "--surface-spacing", dest="spacing",
                   help="triangle size of surface.ply, e.g. 2mm (default: extent / 150, within 2..5 mm)")
    f.add_argument("--side", help="direction the tool comes from, e.g. +z: the patch normal faces it "
                                  "(default: the scan's normals or winding, else the convex side)")
    f.add_argument("--force-units", action="store_true", help="accept a scan size outside 5 mm .. 20 m")
    f.add_argument("--out", required=True, help="output directory (written atomically)")
    f.add_argument("--overwrite", action="store_true", help="replace an existing non-empty folder swath did not write")

    g = add_parser("register", help="register a CAD mesh onto a scan: transform.json (cad2scan), residuals.csv")
    g.add_argument("cad", help="nominal CAD surface: mesh (STL, PLY, OBJ) or patch.json")
    g.add_argument("scan", help="the measured scan: mesh (all its pieces are used) or point cloud")
    g.add_argument("--units", default="m", help="unit of the CAD file (default m)")
    g.add_argument("--scan-units", help="unit of the scan file (default: --units)")
    g.add_argument("--table", action="store_true",
                   help="the part rests on a table in both frames: solve the turn about the table normal and "
                        "the shift along the table and in height, perimeter weighted")
    g.add_argument("--keep-height", action="store_true",
                   help="with --table: the table is at the same height in both frames (3 DOF)")
    g.add_argument("--table-normal", default="+z", help="the table normal, e.g. +z or 0,0,1 (without --table: the direction the outlines are compared along)")
    g.add_argument("--all-pieces", action="store_true",
                   help="keep every piece of a multi-piece CAD mesh (default the largest)")
    g.add_argument("--side", help="for a closed CAD solid: the direction the tool comes from, e.g. +z")
    g.add_argument("--trim", default="0.9",
                   help="fraction of correspondences kept each ICP step, 0.2..1 (lower for partial overlap)")
    g.add_argument("--max-iterations", default="100", help="ICP steps per stage (default 100)")
    g.add_argument("--force-units", action="store_true", help="accept sizes outside 5 mm .. 20 m")
    g.add_argument("--out", required=True, help="output directory (written atomically)")
    g.add_argument("--overwrite", action="store_true", help="replace an existing non-empty folder swath did not write")

    w = add_parser("rework", help="plan again only where a scan after a run shows material left: the feed set to "
                                  "remove the measured excess; rework.json, rework.png, plan/")
    w.add_argument("cad", help="nominal CAD surface: mesh (STL, PLY, OBJ)")
    w.add_argument("scan", help="the part measured after the run: point cloud or mesh")
    w.add_argument("--units", default="m", help="unit of the CAD file: m, mm, cm or in")
    w.add_argument("--scan-units", help="unit of the scan file (default: --units)")
    w.add_argument("--side", help="for a closed CAD solid: the direction the tool comes from, e.g. +z")
    w.add_argument("--force-units", action="store_true", help="accept sizes outside 5 mm .. 20 m")
    w.add_argument("--placement", default="register",
                   help="how the CAD is placed on the scan: register (global search, then refined on the areas at "
                        "the nominal surface), as-measured (the scan is in the CAD frame), or a transform.json "
                        "written by swath register (then refined)")
    w.add_argument("--excess-radius", default="10mm",
                   help="scan points within this distance of a CAD vertex are averaged into its excess")
    w.add_argument("--min-excess", help="excess under which nothing is reworked, e.g. 2um (default: three times "
                                        "the excess map's noise, at least 1um)")
    _add_plan_options(w, with_part_options=False)
    # the least ripple between passes the contact model allows (3.7 % on a plane, at 2 L*): a rework
    # run removes a few micrometres, so the ripple is the residual's largest part
    w.set_defaults(lead_angle="15deg", optimise_spacing="ripple", length_budget="2")

    d = add_parser("demo", help="plan the built-in helicopter-blade section with the uniform planner")
    d.add_argument("--part", default="example:blade",
                   help=f"built-in part ({', '.join('example:' + name for name in PARTS)})")
    _add_plan_options(d, with_part_options=False)
    d.set_defaults(planner="uniform")

    r = add_parser("run", help="run a TOML job file")
    r.add_argument("job", help="job file (TOML)")

    from .calibrate_cmd import add_calibrate_arguments, add_doe_arguments

    add_calibrate_arguments(add_parser("calibrate", help="fit the Preston coefficient from trials: "
                                                             "calibration.json, calibration.png"))
    add_doe_arguments(add_parser("doe", help="write a trials template (full or fractional factorial design)"))

    from .batch import add_arguments as add_batch_arguments

    b = add_parser("batch", help="run a sweep of jobs (parts x settings) in parallel on Ray; one results table")
    add_batch_arguments(b)
    return parser


#: A step running longer than this (s) gets an estimate of its time left on its percentage lines.
ESTIMATE_AFTER_S = 5.0


def _time_left(elapsed: float, done: int, total: int) -> str:
    """``", about 12 s left"``: the rest of a step at the rate of its first ``done`` of ``total``
    units (``elapsed`` s); ``""`` before the first unit, once done, or before :data:`ESTIMATE_AFTER_S`."""
    if done <= 0 or done >= total or elapsed < ESTIMATE_AFTER_S:
        return ""
    left = elapsed * (total - done) / done
    return f", about {left:.0f} s left" if left < 120 else f", about {left / 60:.0f} min left"


class _Progress:
    """Progress lines on stderr: a line per stage, percentages for long steps, and for a step
    running over :data:`ESTIMATE_AFTER_S` an estimate of its time left."""

    def __init__(self, quiet: bool, *, clock=time.perf_counter):
        self.quiet = quiet
        self.clock = clock
        self.stage: str | None = None
        self.t0 = clock()
        self.last = 0.0
        self.stage_t0 = self.t0

    def __call__(self, stage: str, done: int, total: int) -> None:
        if self.quiet:
            return
        now = self.clock()
        if stage != self.stage:
            self.stage = stage
            self.last = self.stage_t0 = now
            print(f"[{now - self.t0:6.1f} s] {stage}", file=sys.stderr, flush=True)
        elif total > 1 and (now - self.last > 2.0 or done == total):
            self.last = now
            left = _time_left(now - self.stage_t0, done, total)
            print(f"[{now - self.t0:6.1f} s]   {stage}: {100.0 * done / total:5.1f} %{left}", file=sys.stderr,
                  flush=True)


def _settings_from_args(args):
    from .settings import SCHEMA, settings_from_mapping

    values = {k: v for k, v in vars(args).items() if k in SCHEMA and v is not None}
    return settings_from_mapping(values)


def _join_negative_values(argv: list[str]) -> list[str]:
    """``--feed -5mm/s`` as ``--feed=-5mm/s``: argparse takes a value that starts with a minus sign
    and a digit for an option and says "expected one argument"; joined, the value reaches the
    settings check, which says what is wrong with it."""
    out: list[str] = []
    for tok in argv:
        if out and out[-1].startswith("--") and "=" not in out[-1] and len(tok) > 1 and tok[0] == "-" \
                and (tok[1].isdigit() or tok[1] == "."):
            out[-1] = f"{out[-1]}={tok}"
        else:
            out.append(tok)
    return out


def _check_option_names(parser: argparse.ArgumentParser, argv: list[str]) -> None:
    """Refuse a mistyped ``--option`` before argparse does, naming the nearest option of the
    subcommand it was given to: argparse alone prints the top-level usage and "unrecognized
    arguments" (or a missing required option, when the typo was in that option's name)."""
    subcommands = next((a.choices for a in parser._actions if isinstance(a, argparse._SubParsersAction)), {})
    current = parser
    for tok in argv:
        if tok == "--":
            break
        if current is parser and not tok.startswith("-") and tok in subcommands:
            current = subcommands[tok]
            continue
        if not tok.startswith("--") or tok == "--":
            continue
        name = tok.split("=", 1)[0]
        known = [o for o in current._option_string_actions if o.startswith("--")]
        if name in known or (current.allow_abbrev and any(o.startswith(name) for o in known)):
            continue                        # an option or a prefix of some (argparse handles ambiguity)
        if current is not parser and name in parser._option_string_actions:
            current.error(f"{name} is an option of swath itself: give it before the subcommand "
                          f"(swath {name} {current.prog.split()[-1]} ...)")
        close = difflib.get_close_matches(name, known, n=1, cutoff=0.6)
        current.error(f"unknown option {name}; " + (f"did you mean {close[0]}?" if close else
                                                     f"{current.prog} --help lists the options"))


def _exit_on_sigterm(signum, frame):
    """SIGTERM (a job killed by a scheduler, ``kill``) unwinds like an interrupt, so the output
    folder being built is removed on the way out."""
    raise SystemExit(128 + signum)


def main(argv=None) -> int:
    import signal

    if hasattr(signal, "SIGTERM"):
        try:
            signal.signal(signal.SIGTERM, _exit_on_sigterm)
        except ValueError:                 # not the main thread (e.g. a worker): leave the default
            pass
    parser = build_parser()
    argv = _join_negative_values(list(sys.argv[1:] if argv is None else argv))
    _check_option_names(parser, argv)
    args = parser.parse_args(argv)
    level = logging.ERROR if args.quiet else (logging.DEBUG if args.verbose else logging.WARNING)
    logging.basicConfig(level=level, format="swath: %(levelname)s: %(message)s")
    from ..report.warncodes import install_warning_codes

    install_warning_codes()                # each warning ends with its code, e.g. [W-COVERAGE-LOW]
    try:
        progress = _Progress(args.quiet)
        if args.command == "batch":
            from .batch import run_from_args

            return run_from_args(args, quiet=args.quiet)
        if args.command in ("fit", "register", "rework"):
            run, settings_of, summary = _document_job(args.command)
            settings = settings_of(args)
            doc = run(settings, progress=progress)
            if not args.quiet:
                print(summary(settings, doc))
            return 0
        if args.command in ("calibrate", "doe"):
            from .calibrate_cmd import run_calibrate, run_doe

            return (run_calibrate if args.command == "calibrate" else run_doe)(args)
        from .job import run_job
        from .settings import load_job_toml

        settings = load_job_toml(args.job) if args.command == "run" else _settings_from_args(args)
        metrics = run_job(settings, progress=progress)
        if not args.quiet:
            print(_summary(settings, metrics))
        return 0
    except SwathError as exc:
        print(f"swath: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("swath: interrupted; no output was written", file=sys.stderr)
        return 130


def _document_job(command: str):
    """``(run, settings_from_args, summary)`` of a subcommand that writes one document: fit, register or rework."""
    if command == "fit":
        from .fitjob import run_fit

        return run_fit, _fit_settings_from_args, _fit_summary
    if command == "register":
        from .registerjob import run_register

        return run_register, _register_settings_from_args, _register_summary
    from .reworkjob import run_rework

    return run_rework, _rework_settings_from_args, _rework_summary


def _no_example(path, command: str, what: str) -> None:
    """Refuse a built-in part where ``command`` reads ``what`` from a file; say where they work."""
    if str(path).startswith("example:"):
        raise InputError(f"swath {command} reads {what}; built-in parts such as {path} are for `swath plan` and "
                         "`swath demo`")


def _fit_settings_from_args(args):
    from ..units import length_unit_factor, parse_quantity
    from .fitjob import FitSettings
    from .settings import check_side

    _no_example(args.scan, "fit", "the scan from a file (a point cloud PLY, XYZ or PCD, or a mesh)")
    check_side(args.side, "--side")
    length_unit_factor(args.units)                 # refuses an unknown unit by name
    spacing = None
    if args.spacing is not None:
        spacing = parse_quantity(args.spacing, "length")
        if not spacing > 0:
            raise InputError(f"--spacing must be a positive length, got {args.spacing!r}")
    return FitSettings(scan=args.scan, out=args.out, units=args.units, parameterization=args.parameterization,
                       spacing=spacing, side=args.side, force_units=args.force_units,
                       overwrite=args.overwrite)


def _register_settings_from_args(args):
    from ..units import length_unit_factor
    from .registerjob import RegisterSettings
    from .settings import check_side

    _no_example(args.cad, "register", "the CAD from a file (STL, PLY, OBJ or a patch.json)")
    _no_example(args.scan, "register", "the scan from a file (a point cloud PLY, XYZ or PCD, or a mesh)")
    check_side(args.side, "--side")
    for unit in (args.units, args.scan_units):
        if unit is not None:
            length_unit_factor(unit)
    try:
        trim = float(args.trim)
    except ValueError:
        raise InputError(f"--trim must be a number in 0.2..1, got {args.trim!r}") from None
    try:
        max_iterations = int(args.max_iterations)
    except ValueError:
        raise InputError(f"--max-iterations must be a whole number, got {args.max_iterations!r}") from None
    return RegisterSettings(cad=args.cad, scan=args.scan, out=args.out, units=args.units,
                            scan_units=args.scan_units, table=args.table, keep_height=args.keep_height,
                            table_normal=args.table_normal, all_pieces=args.all_pieces, side=args.side,
                            trim=trim, max_iterations=max_iterations, force_units=args.force_units,
                            overwrite=args.overwrite)


def _in_folder(folder, name: str) -> str:
    """``folder/name`` as the user typed the folder, without a doubled separator (``out/`` + name)."""
    return str(Path(folder) / name)


def _fit_summary(settings, doc: dict) -> str:
    f = doc["figures"]
    dropped = f" ({f['n_dropped']} stray points dropped)" if f["n_dropped"] else ""
    return (
        f"wrote {_in_folder(settings.out, 'patch.json')}, surface.ply, fit.json, fit.html\n"
        f"  {doc['parameterization']} parameterisation, control net {f['n_ctrl_u']}x{f['n_ctrl_v']}; "
        f"rms {f['rms_m'] * 1e3:.3g} mm, max {f['max_error_m'] * 1e3:.3g} mm over {f['n_points']} points{dropped}; "
        f"surface {doc['surface']['n_vertices']} vertices at {doc['surface']['spacing_m'] * 1e3:.3g} mm"
    )


def _rework_settings_from_args(args):
    import dataclasses

    from ..units import parse_quantity
    from .reworkjob import ReworkSettings
    from .settings import SCHEMA, settings_from_mapping

    values = {k: v for k, v in vars(args).items() if k in SCHEMA and v is not None}
    tolerance = values.pop("depth_tolerance", None)
    for key in ("target_depth", "target_map", "optimise_feed"):
        if values.pop(key, None) is not None:
            raise InputError(f"swath rework sets the target from the scan; drop --{key.replace('_', '-')}")
    values["part"] = args.cad
    plan = settings_from_mapping(values)
    if tolerance is not None:
        plan = dataclasses.replace(plan, depth_tolerance=parse_quantity(tolerance, "length"))
    radius = parse_quantity(args.excess_radius, "length")
    min_excess = None if args.min_excess is None else parse_quantity(args.min_excess, "length")
    if min_excess is not None and min_excess < 0:
        raise InputError(f"--min-excess must be >= 0, got {args.min_excess}")
    return ReworkSettings(cad=args.cad, scan=args.scan, out=args.out, plan=plan, scan_units=args.scan_units,
                          placement=args.placement, radius=radius, min_excess=min_excess, overwrite=args.overwrite)


def _rework_summary(settings, doc: dict) -> str:
    if "message" in doc:
        return f"{doc['message']} -> {settings.out}/rework.json"
    return (f"wrote {settings.out}/rework.json, rework.png, plan/ (trajectory.csv in the CAD frame)\n"
            f"  excess rms {doc['excess_rms_m'] * 1e6:.3g} um (max {doc['excess_max_m'] * 1e6:.3g} um) over "
            f"{doc['rework_area_m2']:.3g} m2 -> predicted residual rms {doc['residual_rms_m'] * 1e6:.3g} um "
            f"({100 * doc['residual_rms_fraction']:.1f} %), most left {doc['residual_max_m'] * 1e6:.3g} um, most "
            f"below nominal {doc['over_removal_max_m'] * 1e6:.3g} um; {doc['n_passes']} passes, cycle "
            f"{doc['cycle_time_s']:.1f} s")


def _register_summary(settings, doc: dict) -> str:
    import numpy as np

    m = np.asarray(doc["cad2scan"])
    q = doc["quality"]
    return (f"cad2scan ({doc['method']}): rotation {q['rotation_deg']:.3f} deg, translation "
            f"{np.round(m[:3, 3] * 1e3, 2).tolist()} mm; rms {doc['rms_m'] * 1e3:.3g} mm, inliers "
            f"{100 * doc['inlier_fraction']:.1f} %, {doc['iterations']} iterations, "
            f"{'converged' if doc['converged'] else 'NOT converged'} -> {_in_folder(settings.out, 'transform.json')}")


def _summary(settings, m: dict) -> str:
    from .even_default import summary_line

    if "n_setups" in m:
        return (f"wrote {settings.out}/metrics.json and setup_1..{m['n_setups']}/trajectory.csv, report.html\n"
                f"  {m['n_setups']} setups, passes {m['n_passes']}, contact path {m['contact_length_m']:.3f} m, "
                f"cycle time {m['cycle_time_s']:.1f} s\n"
                f"  coverage of the whole outer surface {100 * m['coverage_fraction']:.2f} %, removal CoV "
                f"{m['removal_cov']:.3f}")
    inner = m.get("interior_removal_cov")
    # the CoV away from the edge band, where the pad hangs over (what --optimise-feed evens out)
    inside = f" ({inner:.3f} a pad radius in from the edges)" if inner is not None and math.isfinite(inner) else ""
    return (
        f"wrote {_in_folder(settings.out, 'trajectory.csv')}, metrics.json, report.html\n"
        f"  passes {m.get('n_passes')}, contact path {m['contact_length_m']:.3f} m, air {m['air_length_m']:.3f} m, "
        f"cycle time {m['cycle_time_s']:.1f} s\n"
        f"  coverage {100 * m['coverage_fraction']:.2f} %, removal CoV {m['removal_cov']:.3f}{inside}, "
        f"L* {m['coverage_lower_bound_m']:.3f} m, efficiency {m['efficiency']:.3f}"
    ) + ("\n" + even if (even := summary_line(m)) else "")


if __name__ == "__main__":
    sys.exit(main())
