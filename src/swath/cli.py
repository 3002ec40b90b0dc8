"""``swath`` command line: one subcommand per job kind.

    swath plan PART [--units mm] [--planner raster] [--pad-radius 38.1mm] [--force 20N]
               [--depression 1mm] [--feed 50mm/s] [--spacing 60mm] [--angle 0deg] --out DIR
    swath demo --out DIR              # the same on the built-in helicopter-blade section
    swath run job.toml                # settings from a TOML file

Errors caused by the input exit with status 2 and one line on stderr; no half-written output is
left behind.
"""

from __future__ import annotations

import argparse
import logging
import sys
import time

from .errors import SwathError

log = logging.getLogger("swath")


def _add_plan_options(p: argparse.ArgumentParser, *, with_part_options: bool = True) -> None:
    if with_part_options:
        p.add_argument("--units", default="m", help="unit of a unitless mesh file: m, mm, cm or in (default m)")
        p.add_argument("--side", help="for a closed solid: the direction the tool comes from, e.g. +z")
        p.add_argument("--all-pieces", action="store_true", help="keep every piece of a multi-piece mesh")
        p.add_argument("--force-units", action="store_true", help="accept a part size outside 5 mm .. 20 m")
    p.add_argument("--planner", default="raster", help="path planner (default raster)")
    p.add_argument("--pad-radius", default="38.1mm", help="pad radius, e.g. 38.1mm (default: 3-inch pad)")
    p.add_argument("--force", default="20N", help="normal force, e.g. 20N")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--depression", help="pad depression on a flat surface at the set force (default 1mm)")
    g.add_argument("--stiffness", help="pad foundation stiffness, e.g. 4.4MPa/m")
    p.add_argument("--motion", default="orbital", choices=["orbital", "rotary"], help="pad motion")
    p.add_argument("--feed", default="50mm/s", help="feed along contact passes, e.g. 50mm/s")
    p.add_argument("--spacing", help="pass spacing, e.g. 60mm (default: full coverage from the contact model)")
    p.add_argument("--angle", default="auto",
                   help="pass direction from the part's principal axis, e.g. 30deg (default auto: the direction "
                        "with the shortest full-coverage path)")
    p.add_argument("--point-spacing", default="1mm", help="spacing of points along passes")
    p.add_argument("--clearance", default="20mm", help="lift off the surface for air moves")
    p.add_argument("--max-centripetal", help="limit on centripetal acceleration along passes, e.g. 2m/s2")
    p.add_argument("--max-angular", help="limit on the tool's angular speed, e.g. 1rad/s")
    p.add_argument("--max-accel", help="limit on tangential acceleration along passes, e.g. 1m/s2")
    p.add_argument("--out", required=True, help="output directory (written atomically)")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="swath", description="Plan robotic surface finishing on free-form parts.")
    parser.add_argument("-q", "--quiet", action="store_true", help="only errors")
    parser.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("plan", help="plan a part: trajectory.csv, metrics.json, report.html")
    p.add_argument("part", help="mesh file (STL, PLY, OBJ) or example:NAME (blade, plate, panel)")
    _add_plan_options(p)

    d = sub.add_parser("demo", help="plan the built-in helicopter-blade section")
    d.add_argument("--part", default="example:blade", help="built-in part (example:blade, example:plate, example:panel)")
    _add_plan_options(d, with_part_options=False)

    r = sub.add_parser("run", help="run a TOML job file")
    r.add_argument("job", help="job file (TOML)")
    return parser


class _Progress:
    """Progress lines on stderr: a line per stage, percentages for long steps."""

    def __init__(self, quiet: bool):
        self.quiet = quiet
        self.stage = None
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


def _settings_from_args(args) -> "JobSettings":
    from .job import settings_from_mapping

    keys = ["part", "out", "units", "side", "all_pieces", "force_units", "planner", "pad_radius", "force",
            "depression", "stiffness", "motion", "feed", "spacing", "angle", "point_spacing", "clearance",
            "max_centripetal", "max_angular", "max_accel"]
    values = {k: getattr(args, k) for k in keys if hasattr(args, k)}
    return settings_from_mapping(values)


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    level = logging.ERROR if args.quiet else (logging.DEBUG if args.verbose else logging.WARNING)
    logging.basicConfig(level=level, format="swath: %(levelname)s: %(message)s")
    try:
        from .job import load_job_toml, run_job

        settings = load_job_toml(args.job) if args.command == "run" else _settings_from_args(args)
        progress = _Progress(args.quiet)
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


def _summary(settings, m: dict) -> str:
    return (
        f"wrote {settings.out}/trajectory.csv, metrics.json, report.html\n"
        f"  passes {m.get('n_passes')}, contact path {m['contact_length_m']:.3f} m, air {m['air_length_m']:.3f} m, "
        f"cycle time {m['cycle_time_s']:.1f} s\n"
        f"  coverage {100 * m['coverage_fraction']:.2f} %, removal CoV {m['removal_cov']:.3f}, "
        f"L* {m['coverage_lower_bound_m']:.3f} m, efficiency {m['efficiency']:.3f}"
    )


if __name__ == "__main__":
    sys.exit(main())
