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


def _add_plan_options(p: argparse.ArgumentParser, *, with_part_options: bool = True) -> None:
    """The options of every job setting that has one (declared once on
    :class:`~swath.cli.jobsettings.JobSettings`; see :mod:`swath.cli.schema`)."""
    from .jobsettings import JobSettings
    from .schema import add_setting_options

    add_setting_options(p, JobSettings, with_part_options=with_part_options)


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
    from .jobsettings import _parameterizations  # the scan fitter's registry (swath.scan.fit)

    f.add_argument("--parameterization", default="auto", choices=_parameterizations(),
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

    from .bigpart import add_arguments as add_big_arguments

    big = add_parser("big", help="plan a part too big for one process: span-wise regions on Ray, stitched at the seams")
    big.add_argument("part", help="mesh file (STL, PLY, OBJ, or .npz with vertices and faces arrays) or example:NAME")
    _add_plan_options(big)
    add_big_arguments(big)
    return parser


#: A step that runs longer than this (s), or is on its way to (its rate so far says so), gets an
#: estimate of its time left on its percentage lines.
ESTIMATE_AFTER_S = 5.0


def _time_left(elapsed: float, done: int, total: int) -> str:
    """``", about 12 s left"``: the rest of a step at the rate of its first ``done`` of ``total``
    units (``elapsed`` s); ``""`` before the first unit, once done, or for a step whose length at
    that rate stays under :data:`ESTIMATE_AFTER_S`.  A step of few units (four candidate
    directions) may pass 5 s between two of its lines: it is judged by where its rate leads, not
    by the time it has run."""
    if done <= 0 or done >= total or elapsed * total / done < ESTIMATE_AFTER_S:
        return ""
    left = elapsed * (total - done) / done
    if left < 0.5:
        return ", under a second left"          # not "about 0 s"
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
        self.done = self.done0 = 0

    def __call__(self, stage: str, done: int, total: int) -> None:
        if self.quiet:
            return
        now = self.clock()
        if stage != self.stage:
            self.stage = stage
            self.last = self.stage_t0 = now
            self.done = self.done0 = done
            print(f"[{now - self.t0:6.1f} s] {stage}", file=sys.stderr, flush=True)
            return
        if done < self.done:
            # the same step run again (the spacing search plans at several spacings): its rate from here
            self.stage_t0, self.done0 = now, done
        self.done = done
        if total > 1 and (done > self.done0 or done == total) and (now - self.last > 2.0 or done == total):
            self.last = now
            left = _time_left(now - self.stage_t0, done - self.done0, total - self.done0)
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
        if args.command == "big":
            from .bigpart import run_from_args as run_big

            return run_big(args, _settings_from_args(args), progress=progress, quiet=args.quiet)
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


def console() -> None:
    """The ``swath`` command: :func:`main` on ``sys.argv``, then a quick exit.

    Python's own exit frees every object and module one by one, 0.2-0.6 s after a job (longer than
    some jobs take to write their files).  By then every file is written and closed, so the command
    runs the exit handlers (temporary folders, child processes, Ray), flushes its output and leaves
    at once.  Where a thread that is not a daemon still runs, the normal exit waits for it as
    always.
    """
    import atexit
    import os
    import threading

    code = main()
    if any(t.is_alive() and not t.daemon for t in threading.enumerate() if t is not threading.main_thread()):
        sys.exit(code)
    atexit._run_exitfuncs()
    logging.shutdown()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):      # a closed pipe (``swath ... | head``): nothing left to say
            pass
    os._exit(code)


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

    _no_example(args.cad, "rework", "the CAD from a file (STL, PLY or OBJ)")
    _no_example(args.scan, "rework", "the scan after the run from a file (a point cloud PLY, XYZ or PCD, or a mesh)")
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
    from ..simulate.edge_band import band_line
    from ..simulate.evenness import split_line
    from .even_default import summary_line
    from .target_cov import summary_line as target_line

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
    ) + ("\n" + even if (even := summary_line(m)) else "") + ("\n" + target if (target := target_line(m)) else "") + (
        "\n" + split if (split := split_line(m)) else "") + (
        "\n" + band if (band := band_line(m)) else "")


if __name__ == "__main__":
    sys.exit(main())
