"""The process model end to end (issue 36): force and contact, the calibration loop on simulated
trials, a 20-minute job with a 300 s media schedule, and the landing transients.

Run from the repository root:  PYTHONPATH=src python benchmarks/bench_process.py [--out DIR]

Prints:
1. the force sweep on a cylinder (r = 100 mm): sink, contact chord against 2·sqrt(2·s·r) and the
   uniform planner's pass count at 10, 20, 40 N;
2. the closed loop for an orbital and a rotary pad: doe (3 forces × 2 feeds × 4 pad ages × 3
   replicates) → trials run in the simulator at k_p0 = 2e-10 1/Pa and λ = 1/900 s with 8 % scatter
   → calibrate on 54 → the job's tool predicts the 18 held back (error against the noise-free depth)
   and the wear rate;
3. a 20-minute job (example:plate at 1.35 mm/s) with fresh media, and with a pad wearing at
   λ = 1/900 s changed every 300 s, compensated and not: removal CoV and mean, media changes, and the
   operator stops in every program format;
4. a force-controlled job: landing and lift hold times, overshoot and the depth of the landing marks.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

K_P0, WEAR = 2.0e-10, 1.0 / 900.0


def force_sweep() -> None:
    from shapes import cylinder_patch
    from swath.contact import Tool
    from swath.contact.model import local_patch
    from swath.plan import get_planner

    print("1. force sweep on a cylinder, r = 100 mm (default pad: 1 mm at 20 N, R = 38.1 mm)")
    surf = cylinder_patch(0.1, 0.8, 0.2, n_theta=120, n_len=50)
    print("   force   flat e   sink s   chord (model)  2·sqrt(2·s·r)  uniform passes")
    for F in (10.0, 20.0, 40.0):
        tool = Tool(force=F)
        p = local_patch([10.0], [0.0], tool, n_rays=720)
        s = float(p.sink[0])
        n = len(get_planner("uniform")(surf, tool, direction=0.0).passes)
        print(f"   {F:4.0f} N  {tool.flat_depression * 1e3:5.2f} mm  {s * 1e3:5.3f} mm  {p.width_across(0.0)[0] * 1e3:8.2f} mm"
              f"  {2 * math.sqrt(2 * s * 0.1) * 1e3:10.2f} mm  {n:6d}")


def closed_loop(tmp: Path) -> None:
    from swath.cli.settings import settings_from_mapping
    from swath.cli.stages import job_tool
    from swath.contact import Tool
    from swath.simulate.calibrate import calibrate, write_calibration
    from swath.simulate.preston_doe import parse_factor, write_doe
    from swath.simulate.trials import fill_trials, hold_back, trial_depth, trial_tool

    print(f"2. closed loop: k_p0 = {K_P0:.3g} 1/Pa, wear λ = {WEAR:.4g} 1/s, 8 % scatter, 54 trials fitted, 18 held back")
    factors = dict([parse_factor("force=10N,20N,30N"), parse_factor("feed_m_per_s=0.02,0.05"),
                    parse_factor("pad_age=0s,300s,600s,900s")])
    for motion in ("orbital", "rotary"):
        t0 = time.perf_counter()
        d = tmp / motion
        d.mkdir()
        template = write_doe(d / "trials.csv", factors, fixed={"passes": 3}, tool=Tool(motion=motion), replicates=3)
        filled = fill_trials(template, d / "filled.csv", preston=K_P0, wear_rate=WEAR, noise=0.08, seed=7,
                             sample_spacing=3e-3)
        rows = list(csv.DictReader(open(filled)))
        fitted, held = hold_back(rows)
        with open(d / "fit.csv", "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(fitted)
        cal = calibrate(d / "fit.csv")
        write_calibration(d / "cal.json", cal)
        fit = cal.fit_for()
        tool = job_tool(settings_from_mapping({"part": "example:plate", "out": str(d / "o"),
                                               "calibration": str(d / "cal.json")}))
        errors = []
        for r in held:
            truth_tool = trial_tool(force=float(r["force_N"]), spindle_speed_rpm=10000,
                                    orbit_radius=float(r["orbit_radius_m"]), pad_radius=0.0381, preston=K_P0,
                                    wear_rate=WEAR)
            errors.append(trial_depth(tool, r, sample_spacing=3e-3) / trial_depth(truth_tool, r, sample_spacing=3e-3) - 1)
        errors = np.abs(errors)
        print(f"   {motion:7s}: job tool {tool.motion}, k_p0 {fit.preston:.4g} ({fit.preston / K_P0 - 1:+.1%}), "
              f"λ {fit.wear_rate:.4g} 1/s ({fit.wear_rate / WEAR - 1:+.1%}, 90 % interval "
              f"{fit.wear_rate_interval[0]:.3g}..{fit.wear_rate_interval[1]:.3g}); held-back depth per pass error "
              f"mean {errors.mean():.1%}, max {errors.max():.1%}  [{time.perf_counter() - t0:.0f} s]")


def media_job(tmp: Path) -> None:
    from swath.cli.job import run_job
    from swath.cli.settings import settings_from_mapping

    print("3. a 20-minute job: example:plate at 1.35 mm/s (raster), pad wear λ = 1/900 s, media every 300 s")
    base = {"part": "example:plate", "feed": "1.35mm/s"}
    runs = {"fresh media": {},
            "worn, 300 s changes, compensated": {"wear_rate": "0.0011111/s", "media_change": "300s",
                                                 "robot": "ur10e", "base": "0.5,-0.15,0,0,0,0",
                                                 "programs": "urscript,rapid,krl,ros"},
            "worn, 300 s changes, feed not compensated": {"wear_rate": "0.0011111/s", "media_change": "300s",
                                                          "wear_compensation": False}}
    fresh_cov = None
    for name, extra in runs.items():
        t0 = time.perf_counter()
        out = tmp / name.replace(" ", "_").replace(",", "")
        m = run_job(settings_from_mapping({**base, **extra, "out": str(out)}))
        fresh_cov = m["removal_cov"] if fresh_cov is None else fresh_cov
        line = (f"   {name:42s}: cycle {m['cycle_time_s']:6.0f} s, removal mean {m['removal_mean_m'] * 1e6:.3f} µm, "
                f"CoV {m['removal_cov']:.4f} ({100 * (m['removal_cov'] - fresh_cov):+.2f} points)")
        if "media_changes" in m:
            line += f", {m['media_changes']} changes at {', '.join(f'{t:.0f}' for t in m['media_change_times_s'])} s"
        print(line + f"  [{time.perf_counter() - t0:.0f} s]")
        robot = out / "robot"
        if robot.exists():
            counts = {"urscript popup": (robot / "swath_job.script").read_text().count("popup("),
                      "RAPID TPWrite+Stop": (robot / "SwathJob.mod").read_text().count("Stop;"),
                      "KRL HALT": (robot / "swath_job.src").read_text().count("HALT"),
                      "ROS YAML comments": (robot / "joint_trajectory.yaml").read_text().count("# media change")}
            header = (out / "trajectory.csv").read_text().split("\n", 1)[0]
            print(f"      operator stops per program: {counts}; trajectory.csv columns end {header.split(',')[-2:]}")


def transients(tmp: Path) -> None:
    from swath.cli.job import run_job
    from swath.cli.settings import settings_from_mapping

    print("4. force control on example:plate: the landing and lift of every pass")
    for damping in ("0ms", "20ms"):
        m = run_job(settings_from_mapping({"part": "example:plate", "force_control": True, "pad_damping": damping,
                                           "out": str(tmp / f"fc{damping}")}))
        print(f"   pad damping {damping:4s}: landing hold {m['landing_hold_time_s']:.2f} s, lift hold "
              f"{m['lift_hold_time_s']:.2f} s, landing overshoot {m['landing_force_overshoot_fraction']:.1%}; "
              f"landing marks {m['landing_depth_excess_m'] * 1e6:.3f} µm deep "
              f"({m['landing_depth_excess_fraction']:.0%} of the mean removal {m['removal_mean_m'] * 1e6:.3f} µm), "
              f"lift marks {m['lift_depth_excess_m'] * 1e6:.3f} µm; removal CoV {m['removal_cov']:.3f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", help="keep the outputs here (default: a temporary folder)")
    ap.add_argument("--only", choices=["force", "loop", "media", "transients"], help="run one part")
    args = ap.parse_args()
    tmp = Path(args.out or tempfile.mkdtemp(prefix="bench_process_"))
    tmp.mkdir(parents=True, exist_ok=True)
    parts = {"force": force_sweep, "loop": lambda: closed_loop(tmp), "media": lambda: media_job(tmp),
             "transients": lambda: transients(tmp)}
    for name, fn in parts.items():
        if args.only in (None, name):
            fn()


if __name__ == "__main__":
    main()
