"""Benchmark: the default job's spacing from a plane's ripple rule against the part's own curvature.

For each part the default job (``swath plan PART --units U``, nothing else given) runs twice, each
in its own process:

* ``plane``: the spacing of the least ripple on a plane (:func:`swath.feed.ripple_spacing`),
  with no check of the length budget: the default job before the curvature was read
  (:data:`swath.cli.curved_spacing.FLAT_SAGITTA` set to infinity, ``BUDGET_ROUNDS`` to 0);
* ``curved``: the default now (:func:`swath.cli.curved_spacing.curved_spacing_plan`).

Columns, from the job's ``metrics.json``: interior removal CoV, L / L* (contact length over the
coverage bound), cycle time, which plan was written (``even``: the optimised feed on the
least-ripple passes; ``constant``: those passes at constant feed, W-EVEN-FEED-WORSE; ``plain``:
the plain covering plan, W-EVEN-PLAIN-KEPT), the lead of the plan written, the interior CoV of the
least-ripple plan the plain one was compared with (when it was), the spacing model the job used, and the job's CPU
and wall time (the whole process: imports, report and files included).

Run: ``PYTHONPATH=src python benchmarks/bench_default_spacing.py [PART ...]`` (default: the parts
below; the shared meshes are read from ``../shared/meshes``).
"""

from __future__ import annotations

import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import REPO, SHARED_MESH_UNITS, SHARED_MESHES

PARTS = ("example:plate", "example:panel", "example:blade", "example:hub", "snp_part_scan.ply",
         "bezier_dac_cad.ply", "noether_raw_mesh.ply", "bezier_complex_shape.ply")
MODES = ("plane", "curved")


def part_args(part: str) -> list[str]:
    """``swath plan`` arguments naming ``part`` (a shared mesh file name or ``example:NAME``)."""
    if part.startswith("example:"):
        return [part]
    return [str(SHARED_MESHES / part), "--units", SHARED_MESH_UNITS[part]]


def one(part: str, mode: str) -> dict:
    """Run the default job on ``part`` in this process, the spacing by ``mode``; the row."""
    import swath.cli.curved_spacing as curved_spacing
    from swath.cli.main import main

    if mode == "plane":
        curved_spacing.FLAT_SAGITTA = math.inf
        curved_spacing.BUDGET_ROUNDS = 0
    with tempfile.TemporaryDirectory(prefix="swath-bench-") as tmp:
        out = Path(tmp) / "job"
        code = main(["--quiet", "plan", *part_args(part), "--out", str(out)])
        if code != 0:
            raise SystemExit(f"swath plan {part} exited {code}")
        metrics = json.loads((out / "metrics.json").read_text())["metrics"]
    kept = "plain" if metrics.get("plain_plan_kept") else "constant" if metrics.get("constant_feed_kept") else "even"
    return {"interior_cov": metrics["interior_removal_cov"],
            "length_ratio": metrics["contact_length_m"] / metrics["coverage_lower_bound_m"],
            "cycle_s": metrics["cycle_time_s"], "kept": kept, "lead_deg": metrics.get("lead_angle_deg"),
            "plain_cov": metrics.get("plain_interior_removal_cov"),
            "even_cov": metrics.get("even_plan_interior_removal_cov")}


def run(part: str, mode: str) -> dict:
    """``one(part, mode)`` in a fresh process, with its CPU and wall time."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    env = dict(os.environ, PYTHONPATH=f"{REPO / 'src'}{os.pathsep}{REPO / 'benchmarks'}")
    done = subprocess.run([sys.executable, __file__, "--one", part, mode], capture_output=True, text=True,
                          cwd=REPO, env=env)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        return {"failed": (done.stderr.strip().splitlines() or ["?"])[-1]}
    row = json.loads(done.stdout.strip().splitlines()[-1])
    row["cpu_s"] = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    row["wall_s"] = wall
    return row


def _cov(value) -> str:
    return "" if value is None else f"{value:.3f}"


def main(argv: list[str]) -> None:
    if argv[:1] == ["--one"]:
        print(json.dumps(one(argv[1], argv[2])))
        return
    parts = argv or list(PARTS)
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    print("| part | spacing | interior CoV | L / L* | cycle time | plan written | lead | least-ripple plan's CoV "
          "| CPU time | wall time |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for part in parts:
        for mode in MODES:
            r = run(part, mode)
            if "failed" in r:
                print(f"| {part} | {mode} | FAILED: {r['failed']} |||||||")
                continue
            print(f"| {part} | {mode} | {r['interior_cov']:.3f} | {r['length_ratio']:.2f} | {r['cycle_s']:.0f} s | "
                  f"{r['kept']} | {r['lead_deg']:.1f}° | {_cov(r['even_cov'])} | {r['cpu_s']:.1f} s | {r['wall_s']:.1f} s |", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
