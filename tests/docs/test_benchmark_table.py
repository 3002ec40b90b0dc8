"""The benchmark table's page (benchmarks/run_all.py writes docs/BENCHMARKS.md): rows, ratios and the
plan stage's budget verdict."""

from __future__ import annotations

import sys

from conftest import REPO

sys.path.insert(0, str(REPO / "benchmarks"))
import run_all  # noqa: E402

INFO = {"version": "9.9", "command": "python benchmarks/run_all.py", "cpus": 2, "machine": "x86_64",
        "python": "3.11", "load_before": 0.5, "load_after": 0.7, "minutes": 3.0}


def _row(part, faces, plan_warm_s, slice_s, **kw):
    row = {"part": part, "planner": "raster", "faces": faces, "n_passes": 12, "coverage_fraction": 1.0,
           "removal_cov": 0.25, "cycle_time_s": 100.0, "load_s": 0.1, "plan_s": plan_warm_s + 1.0,
           "trajectory_s": 0.5, "simulate_s": 0.5, "report_s": 2.0, "job_s": 6.0, "job_cpu_s": 5.0,
           "peak_MB": 400.0, "plan_warm_s": plan_warm_s, "slice_s": slice_s,
           "plan_over_slice": plan_warm_s / slice_s, "process_s": 8.0, "process_cpu_s": 6.0}
    row.update(kw)
    return row


def _plan_row(text, part):
    section = text.split("## Raster plan stage")[1].split("##")[0]
    return next(line for line in section.splitlines() if line.startswith(f"| {part} |"))


def test_budget_verdict_takes_the_slicing_ratio_only_over_10k_faces():
    rows = [_row("small", 5_000, 0.5, 0.001, plan_s=0.9,   # 500x slicing, but a small mesh: within budget
                 plan_sha256="0123456789ab"),
            _row("big_ok", 20_000, 0.5, 0.1),            # 5x; the job's plan stage 1.5 s is over 1 s
            _row("big_slow", 20_000, 0.9, 0.1),          # 9x > 7x
            _row("over_1s", 5_000, 1.2, 1.0)]            # 1.2 s > 1 s
    text = run_all.markdown(rows, [], INFO)
    assert _plan_row(text, "small").endswith("| 500 | yes / yes | 0123456789ab |")
    assert _plan_row(text, "big_ok").endswith("| 5 | no / yes |  |")
    assert _plan_row(text, "big_slow").endswith("| 9 | no / no |  |")
    assert _plan_row(text, "over_1s").endswith("| no / no |  |")
    assert "swath 9.9" in text and "2 CPUs" in text and "load average 0.50" in text


def test_the_jobs_plan_stage_is_judged_against_the_slicing_of_its_own_planes():
    rows = [_row("job_fast", 20_000, 0.9, 0.1, plan_s=0.3, slice_job_s=0.05, job_over_slice=6.0),   # 6x; warm 9x
            _row("job_slow", 20_000, 0.5, 0.1, plan_s=0.4, slice_job_s=0.05, job_over_slice=8.0)]   # 8x; warm 5x
    text = run_all.markdown(rows, [], INFO)
    assert _plan_row(text, "job_fast") == "| job_fast | 20000 | 0.300 | 0.0500 | 6.0 | 0.90 | 0.1000 | 9 | yes / no |  |"
    assert _plan_row(text, "job_slow").endswith("| 8.0 | 0.50 | 0.1000 | 5 | no / yes |  |")


def test_plan_hash_tells_plans_apart():
    import numpy as np

    from swath.core import Pass, ToolPath
    from swath.examples import flat_plate

    surface = flat_plate(size_x=0.1, size_y=0.1)
    pts = np.column_stack([np.linspace(0, 0.1, 5), np.zeros(5), np.zeros(5)])
    nrm = np.tile([0.0, 0.0, 1.0], (5, 1))
    a = ToolPath(surface, [Pass(pts, nrm)], "raster", {})
    moved = pts.copy()
    moved[2, 1] = np.nextafter(0.0, 1.0)                 # one coordinate, one bit
    assert run_all.plan_hash(a) == run_all.plan_hash(ToolPath(surface, [Pass(pts.copy(), nrm)], "raster", {}))
    assert run_all.plan_hash(a) != run_all.plan_hash(ToolPath(surface, [Pass(moved, nrm)], "raster", {}))
    assert len(run_all.plan_hash(a)) == 12


def test_uniform_ratio_and_failed_rows():
    rows = [_row("crs", 997, 0.5, 0.01), {"part": "bad.ply", "planner": "raster", "failed": "over 900 s"}]
    uniform = [dict(_row("crs", 997, 0.5, 0.01), planner="uniform", process_s=20.0, process_cpu_s=15.0)]
    text = run_all.markdown(rows, uniform, INFO)
    line = next(ln for ln in text.split("## Uniform")[1].splitlines() if ln.startswith("| crs |"))
    assert "| 8.0 | 20.0 | 2.50 | 6.0 | 15.0 | 2.50 |" in line
    assert "| bad.ply | FAILED: over 900 s |" in text


def test_the_spacing_search_has_its_own_column_and_counts_in_the_job_cpu():
    rows = [_row("curved", 20_000, 0.5, 0.1, spacing_s=2.25, plan_s=0.75)]
    text = run_all.markdown(rows, [], INFO)
    line = next(ln for ln in text.split("## Raster plan stage")[0].splitlines() if ln.startswith("| curved |"))
    assert "| 0.10 | 2.25 | 0.75 | 0.50 | 0.50 |" in line          # load, spacing, plan, trajectory, simulate
    assert _plan_row(text, "curved").startswith("| curved | 20000 | 0.750 |  |  | 0.50 |")
    assert "spacing_s" in run_all.STAGES
