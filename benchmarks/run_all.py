"""The benchmark table of swath in one command: stage times of the default job per part, the ratios
against references measured in the same run, peak memory; writes ``docs/BENCHMARKS.md``.

    PYTHONPATH=src python benchmarks/run_all.py            # every built-in part and shared mesh
    PYTHONPATH=src python benchmarks/run_all.py --quick    # a subset, a few minutes
    PYTHONPATH=src python benchmarks/run_all.py --parts example:plate,crs_part_5.stl --out /tmp/B.md

Each part runs in its own process (``--one PART``), so the peak resident memory is that part's.  In
that process:

* the default job, ``swath plan PART --units U`` (raster planner, nothing else given), runs through
  the CLI's own ``main``; its ``metrics.json`` gives the stage times ``load_s``, ``spacing_s`` (the
  default job's spacing search: the plans at the spacings tried, the curvature read from them, and where
  the planes spread the equidistant passes and the leads simulated),
  ``plan_s`` (the plan kept and its order), ``trajectory_s``, ``simulate_s`` (and ``feed_s`` /
  ``pad_study_s`` when the job ran them),
  here read on the process's CPU clock (the job's stage clocks are pointed at ``time.process_time``:
  on a loaded machine a stage's wall time measures the other work as much as swath's);
  ``report_s`` is the rest of the job's CPU time (the report, its pictures and the files);
* ``plan_warm_s``: the raster planner alone at its default spacing, plan and order (CPU s), on the loaded
  part in the same process (imports done, compiled kernels loaded): what the planner itself costs,
  without the process's first-use costs and without a spacing search;
* ``slice_s``: CPU s of ``trimesh.intersections.mesh_multiplane`` cutting the part with the plan's own planes
  (same normal, count and spacing), best of 3: the reference of the raster plan stage, and
  ``plan / slice`` the ratio of the warm plan stage to it (issue "Fast by default": at most 7 on
  meshes over 10k faces);
* ``peak_MB``: the process's peak resident memory.

With ``--uniform`` parts (default ``snp_part_scan.ply`` and ``crs_part_5.stl``) the same job runs with
``--planner uniform`` in its own process, and ``uniform / raster`` is the ratio of the two jobs' wall
times (and CPU times, worker processes included), measured minutes apart in the same run.

Wall times suffer from other load on the machine; the CPU times less.  The table states the
machine's CPU count and the load average before and after, and is dated by swath's version.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import REPO, SHARED_MESH_UNITS, SHARED_MESHES

BUILT_IN = ("example:plate", "example:panel", "example:blade", "example:hub")
QUICK = ("example:plate", "snp_part_scan.ply", "crs_part_5.stl")
UNIFORM = ("snp_part_scan.ply", "crs_part_5.stl")
STAGES = ("load_s", "spacing_s", "plan_s", "trajectory_s", "feed_s", "simulate_s", "pad_study_s")
#: Issue "Fast by default": the raster plan stage's budget (s) and its ratio to the slicing
#: reference on meshes over this many faces.
PLAN_BUDGET_S, SLICE_RATIO_BUDGET, SLICE_RATIO_FACES = 1.0, 7.0, 10_000


def part_args(part: str) -> list[str]:
    """``swath plan`` arguments naming ``part`` (a shared mesh file name or ``example:NAME``)."""
    if part.startswith("example:"):
        return [part]
    return [str(SHARED_MESHES / part), "--units", SHARED_MESH_UNITS[part]]


def slicing_reference(surface, toolpath) -> float:
    """CPU seconds (best of 3) trimesh takes to cut ``surface`` with the planes of the raster plan
    ``toolpath`` (:func:`bench_plan_speed.trimesh_reference`)."""
    from bench_plan_speed import trimesh_reference

    return trimesh_reference(surface, toolpath)[1]


def plan_hash(toolpath) -> str:
    """The first 12 hex digits of the SHA-256 of the ordered plan's points and normals, pass by pass
    (float64 bytes): equal hashes, the same plan to the bit."""
    import hashlib

    import numpy as np

    digest = hashlib.sha256()
    for p in toolpath.passes:
        digest.update(np.ascontiguousarray(p.points, np.float64).tobytes())
        digest.update(np.ascontiguousarray(p.normals, np.float64).tobytes())
    return digest.hexdigest()[:12]


def _keep_job_plans():
    """Point ``swath.cli.job.make_plan`` at a wrapper that keeps what the job's own plan stage gets
    from it (the call whose time is the job's ``plan_s``, made from the job's run in
    ``swath/cli/job.py``; not the comparison plans other stages make): ``.plans`` (list),
    ``.original`` (to put back)."""
    import types

    import swath.cli.job

    kept = types.SimpleNamespace(plans=[], original=swath.cli.job.make_plan)

    def wrapper(*args, **kwargs):
        caller = sys._getframe(1).f_code
        toolpath = kept.original(*args, **kwargs)
        if caller.co_filename == swath.cli.job.__file__ and caller.co_name != "make_plan":
            kept.plans.append(toolpath)
        return toolpath

    swath.cli.job.make_plan = wrapper  # type: ignore[assignment]
    return kept


def one(part: str, planner: str) -> dict:
    """Run the default job on ``part`` in this process (and, for raster, the warm plan stage and the
    slicing reference); return the row."""
    import types

    import swath.cli.job
    import swath.cli.jobwrap
    from swath.cli.main import main

    # The job's stage clocks read CPU time, this process's (all its threads): on a loaded machine the
    # wall time of a stage measures the other work as much as swath's.
    # (the spacing search's per-call clock too: spacing_s is the search's time less the kept call's, one clock)
    cpu_clock = types.SimpleNamespace(perf_counter=time.process_time)
    swath.cli.job.time = cpu_clock  # type: ignore[assignment]
    swath.cli.jobwrap.time = cpu_clock  # type: ignore[assignment]
    row: dict = {"part": part, "planner": planner}
    kept = _keep_job_plans()
    with tempfile.TemporaryDirectory(prefix="swath-bench-") as tmp:
        out = Path(tmp) / "job"
        argv = ["--quiet", "plan", *part_args(part), "--planner", planner, "--out", str(out)]
        t0, c0 = time.perf_counter(), time.process_time()
        code = main(argv)
        row["job_s"], row["job_cpu_s"] = time.perf_counter() - t0, time.process_time() - c0
        if code != 0:
            raise SystemExit(f"swath {' '.join(argv)} exited {code}")
        metrics = json.loads((out / "metrics.json").read_text())["metrics"]
    swath.cli.job.make_plan = kept.original  # type: ignore[assignment]
    for k in STAGES:
        if k in metrics:
            row[k] = float(metrics[k])
    row["report_s"] = row["job_cpu_s"] - sum(row.get(k, 0.0) for k in STAGES)
    for k in ("n_passes", "coverage_fraction", "removal_cov", "cycle_time_s", "interior_removal_cov", "length_ratio",
              "lead_angle_deg", "plain_plan_kept", "constant_feed_kept", "equidistant_kept",
              "constant_feed_interior_removal_cov", "plain_interior_removal_cov"):
        row[k] = metrics.get(k)
    row["even_codes"] = sorted({w[w.rindex("[W-") + 1:-1] for w in metrics.get("warnings", [])
                                if "[W-" in w and w.endswith("]") and ("EVEN" in w or "STIFF" in w or "COARSE" in w)})
    if planner == "raster":
        from swath.cli.job import JobSettings, load_part_info, make_plan

        args = part_args(part)
        settings = JobSettings(part=args[0], out="unused", units=args[2] if len(args) > 2 else "m")
        surface, _ = load_part_info(settings)
        row["faces"] = len(surface.faces)
        t0, c0 = time.perf_counter(), time.process_time()
        toolpath = make_plan(surface, settings)
        row["plan_warm_wall_s"], row["plan_warm_s"] = time.perf_counter() - t0, time.process_time() - c0
        row["plan_sha256"] = plan_hash(toolpath)
        if "cross_direction" in toolpath.metadata and "n_planes" in toolpath.metadata:
            row["slice_s"] = slicing_reference(surface, toolpath)
            row["plan_over_slice"] = row["plan_warm_s"] / max(row["slice_s"], 1e-9)
        job_plan = kept.plans[-1] if kept.plans else None
        if job_plan is not None and "cross_direction" in job_plan.metadata and "n_planes" in job_plan.metadata:
            # the issue's own measure: the job's plan stage against the slicing of the planes it cut
            row["slice_job_s"] = slicing_reference(surface, job_plan)
            row["job_over_slice"] = row["plan_s"] / max(row["slice_job_s"], 1e-9)
    row["peak_MB"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return row


def even_table(rows: list[dict]) -> list[str]:
    """The even-removal figures of the default jobs above: interior CoV (a pad radius in from the
    edges), against the same passes at constant feed and the plain plan, with what the job kept."""
    lines = [
        "",
        "## Even removal, part by part",
        "",
        "The same default jobs (raster, or the uniform planner where `W-EVEN-RIDGE` says so): *interior CoV* a pad radius in from the open edges, the figure the "
        "job optimises; *constant feed* the same passes at constant feed; *plain* the plain plan (covering "
        "spacing, flat pad, constant feed) the job compares with; *kept* what the job wrote (the plain plan's "
        "passes, the equidistant passes where the raster's planes spread, the constant feed) and the evenness "
        "warnings it gave.",
        "",
        "| part | interior CoV | constant feed | plain | L / L\\* | coverage | cycle time s | lead deg | kept |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if "failed" in r or r.get("interior_removal_cov") is None:
            continue
        kept = [name for key, name in (("plain_plan_kept", "plain plan's passes"), ("equidistant_kept", "equidistant"),
                                       ("constant_feed_kept", "constant feed")) if r.get(key)]
        if not r.get("constant_feed_kept"):
            kept.append("optimised feed")
        kept += [f"`{c}`" for c in r.get("even_codes", [])]
        lines.append(
            f"| {r['part']} | {cell(r['interior_removal_cov'], '.3f')} "
            f"| {cell(r.get('constant_feed_interior_removal_cov'), '.3f')} | {cell(r.get('plain_interior_removal_cov'), '.3f')} "
            f"| {cell(r.get('length_ratio'), '.2f')} | {cell(r['coverage_fraction'], '.4f')} "
            f"| {cell(r['cycle_time_s'], '.1f')} | {cell(r.get('lead_angle_deg'), '.1f')} | {', '.join(kept)} |")
    return lines


def run(part: str, planner: str, timeout: float) -> dict:
    """``one(part, planner)`` in a fresh process; the row, with its wall and CPU time (children
    included), or a ``FAILED`` row naming the error."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    env = dict(os.environ, PYTHONPATH=str(REPO / "src"))
    try:
        done = subprocess.run([sys.executable, __file__, "--one", part, "--planner", planner], capture_output=True,
                              text=True, cwd=REPO, env=env, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"part": part, "planner": planner, "failed": f"over {timeout:.0f} s"}
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    line = next((ln for ln in done.stdout.splitlines() if ln.startswith("ROW ")), None)
    if line is None:
        return {"part": part, "planner": planner,
                "failed": (done.stderr.strip().splitlines() or ["no output"])[-1][:160]}
    row = json.loads(line[4:])
    row["process_s"] = time.perf_counter() - t0
    row["process_cpu_s"] = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return row


def cell(value, fmt: str) -> str:
    return "" if value is None else format(value, fmt)


def markdown(rows: list[dict], uniform: list[dict], info: dict) -> str:
    """The ``BENCHMARKS.md`` text."""
    lines = [
        "# Benchmarks",
        "",
        f"swath {info['version']}, measured by `{info['command']}` (`benchmarks/run_all.py`, which "
        "writes this page). Machine: "
        f"{info['cpus']} CPUs ({info['machine']}), Python {info['python']}, load average {info['load_before']:.2f} "
        f"before the run and {info['load_after']:.2f} after, {info['minutes']:.1f} min in all. Wall times grow "
        "with the machine's load (a load average above the CPU count means other work shared the CPUs); the "
        "ratios are measured in the same run, part by part, and suffer less.",
        "",
        "## The default job, stage by stage",
        "",
        "`swath plan PART` with nothing else given (raster planner), each part in a fresh process. Stage times "
        "are CPU seconds of the job's own stage clocks (`metrics.json`, the clocks read on the CPU clock); "
        "*spacing* the default job's spacing search (`spacing_s`: the plans at the spacings it tried and the "
        "curvature read from them; where the planes spread, the equidistant passes and the leads simulated), *plan* the plan the job keeps and its order (`plan_s`); *other "
        "stages* the softer-pad study and the feed optimisation when the job ran them; *report* the rest of the "
        "job's CPU time (report, pictures, files; this process's: the figures and plans made by forked children "
        "beside it are not in it); *job wall* the job's wall time; *peak* the process's peak "
        "resident memory.",
        "",
        "| part | faces | passes | coverage | removal CoV | cycle time s | load | spacing | plan | trajectory "
        "| simulate | other stages | report | job CPU | job wall | peak MB |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if "failed" in r:
            lines.append(f"| {r['part']} | FAILED: {r['failed']} |" + " |" * 14)
            continue
        other = sum(r.get(k, 0.0) for k in ("feed_s", "pad_study_s"))
        lines.append(
            f"| {r['part']} | {r.get('faces', '')} | {r['n_passes']} | {cell(r['coverage_fraction'], '.3f')} "
            f"| {cell(r['removal_cov'], '.3f')} | {cell(r['cycle_time_s'], '.1f')} | {r.get('load_s', 0):.2f} "
            f"| {r.get('spacing_s', 0):.2f} | {r.get('plan_s', 0):.2f} | {r.get('trajectory_s', 0):.2f} | {r.get('simulate_s', 0):.2f} "
            f"| {other:.2f} | {r['report_s']:.2f} | {r['job_cpu_s']:.1f} | {r['job_s']:.1f} | {r['peak_MB']:.0f} |")
    lines += [
        "",
        "## Raster plan stage against plane slicing",
        "",
        f"Budget (issue \"Fast by default\"): the plan stage at most {PLAN_BUDGET_S:g} s on every shared mesh, and at "
        f"most {SLICE_RATIO_BUDGET:g}x the slicing reference on meshes over {SLICE_RATIO_FACES // 1000}k faces. "
        "All CPU seconds (the wall-clock budget holds on a quiet machine, where wall and CPU time agree). "
        "*plan (job)* is `plan_s` of the job: the plan it keeps, at the spacing its search chose, and the order "
        "(the search, `spacing_s`, is timed apart: it pays the part's analyses at pad scale (smooth normals, principal "
        "axes, the contact model's curvature over the pad), the process's first imports of the planning code and the "
        "loading of its compiled kernels); *slicing (job)* is `trimesh.intersections.mesh_multiplane` cutting the part "
        "with the planes of that plan (the same normal, count and spacing; best of 3), the issue's own reference. "
        "*plan (warm)* is the raster planner alone at its own default spacing (plan and order) on the part loaded "
        "afresh in the same process, so it pays the part's analyses again, and *slicing (warm)* cuts that plan's "
        "planes. *within budget* judges the job's plan stage against its slicing (the issue's measure) and, after "
        "the slash, the warm plan against its own. *plan hash*: the first digits of the SHA-256 of the warm plan's "
        "ordered points and normals, to tell whether a change to the code changed a plan.",
        "",
        "| part | faces | plan (job) s | slicing (job) s | job / slicing | plan (warm) s | slicing (warm) s "
        "| warm / slicing | within budget (job / warm) | plan hash |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]

    def within(plan_s, ratio, faces) -> str:
        ok = plan_s <= PLAN_BUDGET_S and (ratio is None or faces <= SLICE_RATIO_FACES or ratio <= SLICE_RATIO_BUDGET)
        return "yes" if ok else "no"

    for r in rows:
        if "failed" in r or "plan_warm_s" not in r:
            continue
        job_ratio, warm_ratio = r.get("job_over_slice"), r.get("plan_over_slice")
        lines.append(f"| {r['part']} | {r['faces']} | {r['plan_s']:.3f} | {cell(r.get('slice_job_s'), '.4f')} "
                     f"| {cell(job_ratio, '.1f')} | {r['plan_warm_s']:.2f} | {cell(r.get('slice_s'), '.4f')} "
                     f"| {cell(warm_ratio, '.0f')} | {within(r['plan_s'], job_ratio, r['faces'])} / "
                     f"{within(r['plan_warm_s'], warm_ratio, r['faces'])} | {r.get('plan_sha256', '')} |")
    if uniform:
        by_part = {r["part"]: r for r in rows}
        lines += [
            "",
            "## Uniform against raster, end to end",
            "",
            "The default job with `--planner uniform` against the raster job of the table above (budget: at most "
            "2x on crs_part_5 and snp_part_scan). Wall and CPU time of the whole process, worker processes "
            "included.",
            "",
            "| part | raster wall s | uniform wall s | uniform / raster wall | raster CPU s | uniform CPU s "
            "| uniform / raster CPU | uniform passes | uniform removal CoV | uniform peak MB |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        for u in uniform:
            r = by_part.get(u["part"], {"failed": "raster row missing"})
            if "failed" in u or "failed" in r:
                lines.append(f"| {u['part']} | FAILED: {u.get('failed', 'raster row missing')} |" + " |" * 8)
                continue
            lines.append(
                f"| {u['part']} | {r['process_s']:.1f} | {u['process_s']:.1f} | {u['process_s'] / r['process_s']:.2f} "
                f"| {r['process_cpu_s']:.1f} | {u['process_cpu_s']:.1f} | {u['process_cpu_s'] / r['process_cpu_s']:.2f} "
                f"| {u['n_passes']} | {cell(u['removal_cov'], '.3f')} | {u['peak_MB']:.0f} |")
    lines += even_table(rows)
    lines += [
        "",
        "## Running it",
        "",
        "```bash",
        "PYTHONPATH=src python benchmarks/run_all.py            # every built-in part and shared mesh",
        "PYTHONPATH=src python benchmarks/run_all.py --quick    # plate, snp_part_scan, crs_part_5",
        "```",
        "",
        "The shared meshes are read from `../shared/meshes` beside the repository (their units as in "
        "`tests/conftest.py`); a mesh not found there is left out. The older scripts in `benchmarks/` "
        "(`bench_*.py`) measure single topics in more depth; each prints its own table.",
        "",
    ]
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help=f"only {', '.join(QUICK)}")
    parser.add_argument("--parts", help="comma-separated parts (example:NAME or a shared mesh file name)")
    parser.add_argument("--uniform", help=f"parts to time with the uniform planner too (default {','.join(UNIFORM)}; "
                        "'' for none)")
    parser.add_argument("--out", default=str(REPO / "docs" / "BENCHMARKS.md"), help="the Markdown file written")
    parser.add_argument("--timeout", type=float, default=1800.0, help="seconds allowed per part and planner")
    parser.add_argument("--one", help=argparse.SUPPRESS)
    parser.add_argument("--planner", default="raster", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        print("ROW " + json.dumps(one(args.one, args.planner)), flush=True)
        return 0

    if args.parts:
        parts = args.parts.split(",")
    elif args.quick:
        parts = list(QUICK)
    else:
        parts = list(BUILT_IN) + list(SHARED_MESH_UNITS)
    parts = [p for p in parts if p.startswith("example:") or (SHARED_MESHES / p).exists()]
    uniform_parts = UNIFORM if args.uniform is None else tuple(p for p in args.uniform.split(",") if p)
    if args.quick and args.uniform is None:
        uniform_parts = ("snp_part_scan.ply",)
    uniform_parts = tuple(p for p in uniform_parts if p in parts)

    import swath

    command = "python benchmarks/run_all.py" + (" --quick" if args.quick else "") + \
        (f" --parts {args.parts}" if args.parts else "")
    load_before, t_start = os.getloadavg()[0], time.perf_counter()
    rows, uniform = [], []
    for part in parts:
        rows.append(run(part, "raster", args.timeout))
        print(json.dumps(rows[-1]), flush=True)
        if part in uniform_parts:
            uniform.append(run(part, "uniform", args.timeout))
            print(json.dumps(uniform[-1]), flush=True)
    info = {"version": swath.__version__, "command": command, "cpus": os.cpu_count(),
            "machine": platform.machine(), "python": platform.python_version(), "load_before": load_before,
            "load_after": os.getloadavg()[0], "minutes": (time.perf_counter() - t_start) / 60}
    text = markdown(rows, uniform, info)
    out = Path(args.out)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_text(text)
    tmp.replace(out)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
