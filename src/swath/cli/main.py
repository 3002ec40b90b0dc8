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

Errors caused by the input exit with status 2 and one line on stderr; no half-written output is
left behind.
"""

from __future__ import annotations

import argparse
import logging
import math
import sys
import time

from ..errors import InputError, SwathError

log = logging.getLogger("swath")

#: Scan parameterisations of ``--parameterization`` (as :data:`swath.surface.fit.PARAMETERIZATIONS`).
PARAMETERIZATIONS = ("auto", "projection", "lscm", "rows")


def _add_plan_options(p: argparse.ArgumentParser, *, with_part_options: bool = True) -> None:
    if with_part_options:
        p.add_argument("--units", default="m", help="unit of a unitless mesh file: m, mm, cm or in (or their names, "
                                                    "e.g. millimetres, inch)")
        p.add_argument("--side", help="for a closed solid: the direction the tool comes from, e.g. +z")
        p.add_argument("--all-pieces", action="store_true", help="keep every piece of a multi-piece mesh")
        p.add_argument("--force-units", action="store_true", help="accept a part size outside 5 mm .. 20 m")
        p.add_argument("--fit", action="store_true",
                       help="PART is a scan (point cloud or mesh): fit a B-spline patch and plan on it")
        p.add_argument("--parameterization", choices=PARAMETERIZATIONS,
                       help="with --fit: how the scan is parameterised (default auto)")
        p.add_argument("--surface-spacing",
                       help="triangle size of a fitted or saved patch to plan on, e.g. 3mm "
                            "(default: the patch's extent / 150, within 2..5 mm)")
    p.add_argument("--planner", default="raster",
                   help="path planner: raster (plane slices, the baseline), uniform (contact-aware uniform coverage) "
                        "or equidistant (geodesic-parallel passes)")
    p.add_argument("--pad-radius", default="38.1mm", help="pad radius, e.g. 38.1mm (default: 3-inch pad)")
    p.add_argument("--force", default="20N", help="normal force, e.g. 20N")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--depression", help="pad depression on a flat surface at the set force (default 1mm)")
    g.add_argument("--stiffness", help="pad foundation stiffness, e.g. 4.4MPa/m")
    p.add_argument("--motion", default="orbital", choices=["orbital", "rotary"], help="pad motion")
    p.add_argument("--feed", default="50mm/s", help="feed along contact passes, e.g. 50mm/s")
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
    e = p.add_argument_group("even removal (Wang §2): feed (dwell) optimisation to a target depth")
    e.add_argument("--optimise-feed", action="store_true", default=None,
                   help="choose the feed along every pass so removal matches the target, never more than the "
                        "target plus the tolerance (HiGHS)")
    e.add_argument("--target-depth", help="with --optimise-feed: uniform depth to remove, e.g. 20um")
    e.add_argument("--target-map", help="with --optimise-feed: per-point depths (CSV x,y,z,depth in m, or PLY with a "
                                        "vertex 'depth')")
    e.add_argument("--depth-tolerance", help="with --optimise-feed: allowed removal above the target, e.g. 2um "
                                             "(default 10 %% of the target depth)")
    e.add_argument("--optimise-spacing",
                   help="raster pass spacing for even removal: ripple (the spacing whose summed pad "
                        "cross-profiles are flattest, path within 1.5x the coverage bound; with --planner uniform its overlap), greedy (Wang's pattern "
                        "search, pass by pass, against the target) or joint (equal spacing and feed together)")
    e.add_argument("--lead-angle",
                   help="tilt the pad about the axis across the feed in contact, its leading edge lifted, e.g. "
                        "7deg; auto: the angle at which half the pad presses on a flat part (7.0 deg for the "
                        "default pad), which turns each pass's removal profile from a semicircle into a "
                        "parabola and halves the ripple between passes (default 0: z along minus the normal)")
    e.add_argument("--feed-simulate-check", action=argparse.BooleanOptionalAction, default=None,
                   help="with --optimise-feed: simulate the optimised trajectory and tighten the feed where the "
                        "simulator finds more than the target plus the tolerance (up to 6 rounds; default on)")
    r = p.add_argument_group("robot (kinematics, reachability, programs)")
    r.add_argument("--robot", help="robot model: ur3e, ur5e, ur10e, ur16e, irb4600, kr120")
    r.add_argument("--base", help="the part's pose in the robot base frame, x,y,z,rx,ry,rz (e.g. 800mm,0,100mm,0,0,90deg)")
    r.add_argument("--tcp", help="the tool (TCP) pose in the flange frame, x,y,z,rx,ry,rz (e.g. 0,0,150mm,0,0,0)")
    r.add_argument("--program", dest="programs",
                   help="robot programs to write: urscript, rapid, krl, ros, csv (comma-separated; default csv)")
    r.add_argument("--place", action="store_true", default=None,
                   help="search where to put the part so the whole job is reachable (x, y, yaw on the table)")
    r.add_argument("--table-z", help="with --place: height of the part's lowest point in the base frame, e.g. 0mm")
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
    p.add_argument("part", help="mesh file (STL, PLY, OBJ), patch.json from swath fit, example:NAME (blade, "
                                "plate, panel), or with --fit a scan (point cloud PLY/XYZ/PCD or mesh)")
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
    g.add_argument("--table-normal", default="+z", help="with --table: the table normal, e.g. +z or 0,0,1")
    g.add_argument("--all-pieces", action="store_true",
                   help="keep every piece of a multi-piece CAD mesh (default the largest)")
    g.add_argument("--side", help="for a closed CAD solid: the direction the tool comes from, e.g. +z")
    g.add_argument("--trim", default="0.9",
                   help="fraction of correspondences kept each ICP step, 0.2..1 (lower for partial overlap)")
    g.add_argument("--max-iterations", default="100", help="ICP steps per stage (default 100)")
    g.add_argument("--force-units", action="store_true", help="accept sizes outside 5 mm .. 20 m")
    g.add_argument("--out", required=True, help="output directory (written atomically)")
    g.add_argument("--overwrite", action="store_true", help="replace an existing non-empty folder swath did not write")

    d = add_parser("demo", help="plan the built-in helicopter-blade section with the uniform planner")
    d.add_argument("--part", default="example:blade", help="built-in part (example:blade, example:plate, example:panel)")
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


class _Progress:
    """Progress lines on stderr: a line per stage, percentages for long steps."""

    def __init__(self, quiet: bool):
        self.quiet = quiet
        self.stage: str | None = None
        self.t0 = time.perf_counter()
        self.last = 0.0

    def __call__(self, stage: str, done: int, total: int) -> None:
        if self.quiet:
            return
        now = time.perf_counter()
        if stage != self.stage:
            self.stage = stage
            self.last = now
            print(f"[{now - self.t0:6.1f} s] {stage}", file=sys.stderr, flush=True)
        elif total > 1 and (now - self.last > 2.0 or done == total):
            self.last = now
            print(f"[{now - self.t0:6.1f} s]   {stage}: {100.0 * done / total:5.1f} %", file=sys.stderr, flush=True)


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
    args = parser.parse_args(argv)
    level = logging.ERROR if args.quiet else (logging.DEBUG if args.verbose else logging.WARNING)
    logging.basicConfig(level=level, format="swath: %(levelname)s: %(message)s")
    try:
        progress = _Progress(args.quiet)
        if args.command == "batch":
            from .batch import run_from_args

            return run_from_args(args, quiet=args.quiet)
        if args.command == "fit":
            from .fitjob import run_fit

            settings = _fit_settings_from_args(args)
            doc = run_fit(settings, progress=progress)
            if not args.quiet:
                print(_fit_summary(settings, doc))
            return 0
        if args.command == "register":
            from .registerjob import run_register

            settings = _register_settings_from_args(args)
            doc = run_register(settings, progress=progress)
            if not args.quiet:
                print(_register_summary(settings, doc))
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


def _fit_summary(settings, doc: dict) -> str:
    f = doc["figures"]
    dropped = f" ({f['n_dropped']} stray points dropped)" if f["n_dropped"] else ""
    return (
        f"wrote {settings.out}/patch.json, surface.ply, fit.json, fit.html\n"
        f"  {doc['parameterization']} parameterisation, control net {f['n_ctrl_u']}x{f['n_ctrl_v']}; "
        f"rms {f['rms_m'] * 1e3:.3g} mm, max {f['max_error_m'] * 1e3:.3g} mm over {f['n_points']} points{dropped}; "
        f"surface {doc['surface']['n_vertices']} vertices at {doc['surface']['spacing_m'] * 1e3:.3g} mm"
    )


def _register_summary(settings, doc: dict) -> str:
    import numpy as np

    m = np.asarray(doc["cad2scan"])
    q = doc["quality"]
    return (f"cad2scan ({doc['method']}): rotation {q['rotation_deg']:.3f} deg, translation "
            f"{np.round(m[:3, 3] * 1e3, 2).tolist()} mm; rms {doc['rms_m'] * 1e3:.3g} mm, inliers "
            f"{100 * doc['inlier_fraction']:.1f} %, {doc['iterations']} iterations, "
            f"{'converged' if doc['converged'] else 'NOT converged'} -> {settings.out}/transform.json")


def _summary(settings, m: dict) -> str:
    inner = m.get("interior_removal_cov")
    # the CoV away from the edge band, where the pad hangs over (what --optimise-feed evens out)
    inside = f" ({inner:.3f} a pad radius in from the edges)" if inner is not None and math.isfinite(inner) else ""
    return (
        f"wrote {settings.out}/trajectory.csv, metrics.json, report.html\n"
        f"  passes {m.get('n_passes')}, contact path {m['contact_length_m']:.3f} m, air {m['air_length_m']:.3f} m, "
        f"cycle time {m['cycle_time_s']:.1f} s\n"
        f"  coverage {100 * m['coverage_fraction']:.2f} %, removal CoV {m['removal_cov']:.3f}{inside}, "
        f"L* {m['coverage_lower_bound_m']:.3f} m, efficiency {m['efficiency']:.3f}"
    )


if __name__ == "__main__":
    sys.exit(main())
