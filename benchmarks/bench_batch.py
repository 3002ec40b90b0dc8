"""Batch throughput: the same 12-job sweep serially (``--workers 1``) and on a local Ray with 2 workers.

    python benchmarks/bench_batch.py [--order 1 2 1] [--point-spacing 2mm] [--parts snp_part_scan.ply bezier_dac_cad.ply]

The sweep: example:plate and example:panel x raster, uniform, equidistant x 10 N, 20 N (default
3-inch pad, 50 mm/s, angle 0), run serially, then on a local Ray with 2 workers, then serially
again (``--order``), so drift of the machine's load shows.  Prints wall time and jobs per minute
of each run with and without its start-up (timed apart, before the sweep), the speed-up over the mean serial run, the sum of the jobs' own wall and CPU times, and
the load average before and after, since the cores are shared.  Checks that every run gives the
same table (all columns but times).

On a machine shared through sessions (Linux autogroup scheduling: ``/proc/self/autogroup``; the
local Ray's workers join the session of the process that starts them), a busy machine gives the
session a fixed share of the CPUs however many workers it runs: the speed-up shows only when the
session's share exceeds one CPU.  ``sum_cpu_s`` staying flat while ``sum_job_s`` grows is the sign.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import tempfile
import time
from pathlib import Path

from common import REPO, print_table

SWEEP = """
out = "{out}"
point_spacing = "{point_spacing}"
angle = "0deg"

[grid]
part = {parts}
planner = ["raster", "uniform", "equidistant"]
force = ["10N", "20N"]
"""
TIMES = {"load_s", "plan_s", "trajectory_s", "simulate_s", "job_s", "job_cpu_s", "resumed"}


def table(path: Path) -> list[dict]:
    with open(path, newline="", encoding="utf-8") as fh:
        return [{k: v for k, v in row.items() if k not in TIMES} for row in csv.DictReader(fh)]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--order", type=int, nargs="+", default=[1, 2, 1],
                        help="workers of each run, in order (default 1 2 1: serial before and after, to see drift)")
    parser.add_argument("--point-spacing", default="2mm", help="job point spacing (sets the job size)")
    parser.add_argument("--parts", nargs=2, default=["example:plate", "example:panel"],
                        help="the sweep's two parts: example:NAME or a shared mesh's file name (longer jobs; "
                             "the shared meshes used here are in metres)")
    args = parser.parse_args()

    from swath.cli.batch import load_sweep, run_sweep

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tables = {}
        for run, workers in enumerate(args.order):
            path = Path(tmp) / f"run{run}.toml"
            parts = [p if p.startswith("example:") else str(REPO.parent / "shared" / "meshes" / p) for p in args.parts]
            path.write_text(SWEEP.format(out=f"run{run}", point_spacing=args.point_spacing,
                                         parts=json.dumps(parts)), encoding="utf-8")
            sweep = load_sweep(path)
            load_before = os.getloadavg()[0]
            t0 = time.perf_counter()
            if workers > 1:
                import ray

                from swath.cli.batch_ray import start_local_ray

                start_local_ray(workers)                      # and the warm-up on each worker
            else:
                from swath.cli.batch import warm_up

                warm_up()                                     # the same warm-up, in this process
            startup = time.perf_counter() - t0
            t0 = time.perf_counter()
            result = run_sweep(sweep, workers=workers, resume=False)
            wall = time.perf_counter() - t0
            if workers > 1:
                ray.shutdown()
            failed = [r["job_id"] for r in result if r["status"] != "ok"]
            rows.append({"workers": workers, "jobs": len(result), "failed": len(failed), "startup_s": startup,
                         "wall_s": wall, "jobs_per_min": 60.0 * len(result) / wall,
                         "jobs_per_min_with_startup": 60.0 * len(result) / (wall + startup),
                         "sum_job_s": sum(r["job_s"] or 0.0 for r in result),
                         "sum_cpu_s": sum(r.get("job_cpu_s") or 0.0 for r in result),
                         "load_before": load_before, "load_after": os.getloadavg()[0]})
            tables[run] = table(sweep.out / "results.csv")
            print(f"  {workers} worker(s): {wall:.1f} s{' failed: ' + ', '.join(failed) if failed else ''}", flush=True)
        serial = [r for r in rows if r["workers"] == 1]
        wall = sum(r["wall_s"] for r in serial) / max(len(serial), 1)
        cold = sum(r["wall_s"] + r["startup_s"] for r in serial) / max(len(serial), 1)
        for row in rows:
            row["speedup"] = wall / row["wall_s"]
            row["speedup_with_startup"] = cold / (row["wall_s"] + row["startup_s"])
        same = all(t == tables[0] for t in tables.values())
    print(f"\nbatch throughput on {os.cpu_count()} CPUs (load average: 1-min, shared machine)")
    print_table(rows, [("workers", "d"), ("jobs", "d"), ("failed", "d"), ("startup_s", ".1f"), ("wall_s", ".1f"),
                       ("sum_job_s", ".1f"), ("sum_cpu_s", ".1f"), ("jobs_per_min", ".1f"), ("speedup", ".2f"),
                       ("jobs_per_min_with_startup", ".1f"), ("speedup_with_startup", ".2f"),
                       ("load_before", ".2f"), ("load_after", ".2f")])
    print("speedup: against the mean serial wall time, each run after its warm-up (startup_s: Ray's start and "
          "a warm-up job on each worker, or the same warm-up in this process for a serial run); "
          "speedup_with_startup: both with their start-up; sum_cpu_s: CPU time the jobs got (a loaded machine gives "
          "parallel jobs less of it)")
    print(f"same results table in every run (wall times aside): {same}")


if __name__ == "__main__":
    main()
