"""End to end as a user runs it: ``swath plan PART --planner raster`` against ``--planner uniform``.

Issue 16 asks for uniform (auto direction) within 3x raster's end-to-end time on every shared mesh.
``bench_plan_speed.py`` times the planning stages in one process (plan + order + timing +
simulation, no loading, no report, no files); this script times the whole command in a fresh
process each run: interpreter start and imports, loading and checking the mesh, planning,
ordering, timing, the removal simulation, the report (PNG pictures and HTML) and writing every
output file.  Both planners run with the job defaults (``swath plan`` without options but the
planner), on every shared mesh found and on the built-in parts.

Each planner runs ``--repeat`` times, alternating raster and uniform so a change of the machine's
load hits both; the table gives the least wall time of each (and the CPU time of that run,
children included), the ratio uniform / raster of both, and the load average before and after.

    PYTHONPATH=src python benchmarks/bench_cli_e2e.py [--repeat 2] [snp_part_scan.ply example:plate ...]

The stage times ``load_s``, ``plan_s`` (plan and order), ``trajectory_s`` and ``simulate_s`` come from the
job's own ``metrics.json``, of the run with the least wall time; the rest of the wall time is the
interpreter, imports, the report and the files.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import REPO, SHARED_MESH_UNITS, print_table

PLANNERS = ("raster", "uniform")
STAGES = ("load_s", "plan_s", "trajectory_s", "simulate_s")


def run_once(part: str, units: str, planner: str, out: Path) -> tuple[float, float, dict]:
    """Wall (s) and CPU (s, children included) of one ``swath plan``, and its metrics' timings."""
    cmd = [sys.executable, "-m", "swath.cli", "plan", part, "--units", units, "--planner", planner,
           "--out", str(out), "--overwrite"]
    env = dict(os.environ, PYTHONPATH=str(REPO / "src"))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    done = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({done.returncode}):\n{done.stderr[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    metrics = json.loads((out / "metrics.json").read_text())
    return wall, cpu, metrics


def stage_times(metrics: dict) -> dict:
    timings = metrics.get("metrics", {})
    return {k: float(timings[k]) for k in STAGES if k in timings}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("parts", nargs="*", help="shared mesh file names or example:NAME (default: all)")
    parser.add_argument("--repeat", type=int, default=2, help="runs per planner (least wall time kept)")
    args = parser.parse_args()
    mesh_dir = REPO.parent / "shared" / "meshes"
    parts = args.parts or [*SHARED_MESH_UNITS, "example:plate", "example:panel", "example:blade"]
    rows = []
    print(f"load average before: {os.getloadavg()[0]:.2f}", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        for name in parts:
            if name.startswith("example:"):
                part, units = name, "m"
            else:
                path = mesh_dir / name
                if not path.exists():
                    print(f"skip {name}: not in {mesh_dir}")
                    continue
                part, units = str(path), SHARED_MESH_UNITS[name]
            best: dict[str, tuple[float, float, dict]] = {}
            for _ in range(args.repeat):
                for planner in PLANNERS:
                    run = run_once(part, units, planner, Path(tmp) / planner)
                    if planner not in best or run[0] < best[planner][0]:
                        best[planner] = run
            row: dict = {"part": name}
            for planner in PLANNERS:
                wall, cpu, metrics = best[planner]
                row[f"{planner}_wall_s"], row[f"{planner}_cpu_s"] = wall, cpu
                for k, v in stage_times(metrics).items():
                    row[f"{planner[0]}_{k}"] = v
            row["uniform/raster_wall"] = row["uniform_wall_s"] / row["raster_wall_s"]
            row["uniform/raster_cpu"] = row["uniform_cpu_s"] / row["raster_cpu_s"]
            rows.append(row)
            print(f"{name}: raster {row['raster_wall_s']:.1f} s, uniform {row['uniform_wall_s']:.1f} s, "
                  f"ratio {row['uniform/raster_wall']:.2f}", flush=True)
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    columns = [("part", "s"), ("raster_wall_s", ".2f"), ("raster_cpu_s", ".2f"), ("uniform_wall_s", ".2f"),
               ("uniform_cpu_s", ".2f"), ("uniform/raster_wall", ".2f"), ("uniform/raster_cpu", ".2f")]
    columns += [(f"{p[0]}_{k}", ".2f") for p in PLANNERS for k in STAGES]
    print_table(rows, columns)


if __name__ == "__main__":
    main()
