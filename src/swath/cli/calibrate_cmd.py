"""``swath calibrate`` (fit the Preston coefficient from trials) and ``swath doe`` (a trials template)."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from ..errors import InputError


def add_calibrate_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("trials", help="trials CSV (columns: trial, grit, force_N, spindle_speed_rpm, orbit_radius_m, "
                                  "pad_radius_m, feed_m_per_s, passes, depth_m, pad_age_s; see "
                                  "swath.simulate.calibrate)")
    p.add_argument("--fit-exponents", action="store_true", help="also fit the pressure and speed exponents")
    p.add_argument("--error-model", default="relative", choices=["relative", "absolute"],
                   help="how the depth measurement error scales")
    p.add_argument("--confidence", default="90%", help="level of the intervals")
    p.add_argument("--out", required=True, help="output directory: calibration.json, calibration.png")
    p.add_argument("--overwrite", action="store_true", help="replace an existing non-empty folder swath did not write")


def add_doe_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--factor", action="append", required=True,
                   help="a factor and its levels, e.g. force=10N,20N,30N (repeat for each factor)")
    p.add_argument("--generator", action="append", default=[],
                   help="a fractional design: a factor set from others, e.g. speed=grit+force")
    p.add_argument("--replicates", default="1", help="runs per design point")
    p.add_argument("--seed", help="shuffle the run order with this seed (default: standard order)")
    p.add_argument("--fixed", action="append", default=[],
                   help="a column every run shares, e.g. passes=3 or feed_m_per_s=0.05")
    p.add_argument("--out", required=True, help="the trials template to write (CSV); an existing file is refused")
    p.add_argument("--overwrite", action="store_true", help="replace an existing file at --out")
    p.add_argument("--motion", default="orbital", choices=["orbital", "rotary"],
                   help="the pad motion of the trials (as swath plan --motion)")
    p.add_argument("--spindle-speed", default="10000rpm", help="pad (or orbit) speed of the trials, unless a factor")
    p.add_argument("--orbit-radius", default="2.5mm", help="orbit of an orbital pad, unless a factor")
    p.add_argument("--pad-radius", default="38.1mm", help="pad radius of the trials, unless a factor")


def run_calibrate(args) -> int:
    from ..io.atomic import atomic_directory
    from ..report.force_plots import write_force_plots
    from ..simulate.calibrate import calibrate, read_trials, write_calibration
    from ..units import parse_quantity

    confidence = parse_quantity(args.confidence, "fraction")
    if not 0 < confidence < 1:
        raise InputError(f"--confidence must lie between 0 and 100 %, got {args.confidence!r}")
    trials = read_trials(args.trials)
    cal = calibrate(trials, fit_exponents=args.fit_exponents, error_model=args.error_model, confidence=confidence)
    with atomic_directory(args.out, overwrite=args.overwrite) as tmp:
        write_calibration(tmp / "calibration.json", cal)
        write_force_plots(tmp, calibration=cal, trials=trials)
    if not args.quiet:
        tool = cal.metadata.get("tool", {})
        for fit in cal.fits.values():
            wear = (f", pad wear {fit.wear_rate:.4g} 1/s ({fit.wear_rate_interval[0]:.4g} .. "
                    f"{fit.wear_rate_interval[1]:.4g}), k_p of fresh media" if fit.error_model == "wear" else "")
            print(f"grit {fit.grit}: k_p = {fit.preston:.4g} 1/Pa ({100 * confidence:.0f} % interval "
                  f"{fit.preston_low:.4g} .. {fit.preston_high:.4g}){wear} from {fit.n_trials} trials "
                  f"({tool.get('motion', 'unstated')} pad) -> {Path(args.out) / 'calibration.json'}")
    return 0


def run_doe(args) -> int:
    from ..simulate.preston_doe import parse_factor, parse_generator, write_doe

    factors = dict(parse_factor(f) for f in args.factor)
    generators = dict(parse_generator(g) for g in args.generator)
    fixed = {}
    for item in args.fixed:
        key, _, value = item.partition("=")
        if not key or not value:
            raise InputError(f"--fixed takes column=value, e.g. passes=3, got {item!r}")
        fixed[key.strip()] = value.strip()
    try:
        replicates = int(args.replicates)
        seed = None if args.seed is None else int(args.seed)
    except ValueError:
        raise InputError(f"--replicates and --seed must be whole numbers, got {args.replicates!r}, {args.seed!r}") \
            from None
    from ..contact import Tool
    from ..units import parse_quantity

    tool = Tool(pad_radius=parse_quantity(args.pad_radius, "length"), motion=args.motion,
                spindle_speed=parse_quantity(args.spindle_speed, "frequency", default_unit="rpm") * 2 * math.pi,
                orbit_radius=parse_quantity(args.orbit_radius, "length"))
    path = write_doe(args.out, factors, generators=generators or None, replicates=replicates, seed=seed,
                     fixed=fixed or None, tool=tool, overwrite=args.overwrite)
    if not args.quiet:
        print(f"wrote {path}: fill in depth_m for each run, then: swath calibrate {path} --out cal/", file=sys.stdout)
    return 0
