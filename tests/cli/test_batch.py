"""swath batch: grid expansion, validation before work, serial and local-Ray runs, resume, failures."""

from __future__ import annotations

import csv
import json
import os
from pathlib import Path

import pytest

from swath.cli.batch import load_sweep, main, make_job_id, run_sweep
from swath.errors import InputError

#: A coarse setup: each job plans, times, simulates and reports in about a second.
COARSE = """
out = "{out}"
pad_radius = "50mm"
point_spacing = "5mm"
sample_spacing = "4mm"
feed = "100mm/s"
angle = "0deg"
constant_feed = true
"""
GRID = """
[grid]
part = ["example:plate", "example:panel"]
planner = ["raster", "uniform"]
"""
IDS = ["0000-plate-raster", "0001-plate-uniform", "0002-panel-raster", "0003-panel-uniform"]
#: Columns that are wall times, so differ between runs.
TIMES = {"load_s", "plan_s", "trajectory_s", "simulate_s", "job_s", "job_cpu_s", "resumed"}


def write_sweep(folder: Path, out: str, grid: str = GRID, extra: str = "") -> Path:
    path = folder / f"{out}.toml"
    path.write_text(COARSE.format(out=out) + extra + grid, encoding="utf-8")
    return path


def read_table(path: Path) -> list[dict]:
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def same_figures(a: list[dict], b: list[dict]) -> None:
    assert [r["job_id"] for r in a] == [r["job_id"] for r in b]
    for ra, rb in zip(a, b):
        assert {k: v for k, v in ra.items() if k not in TIMES} == {k: v for k, v in rb.items() if k not in TIMES}


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    """The 2 parts x 2 planners sweep run serially: (sweep file, results rows)."""
    folder = tmp_path_factory.mktemp("batch")
    path = write_sweep(folder, "serial")
    assert main([str(path), "--workers", "1", "-q"]) == 0
    return path, read_table(folder / "serial" / "results.csv")


def test_job_ids_are_readable_and_ordered():
    assert make_job_id(7, {"part": "example:panel", "planner": "raster", "force": "20N"}) == "0007-panel-raster-f20N"
    assert make_job_id(12, {"part": "/data/crs_part_5.stl", "feed": "50mm/s", "pad_radius": 0.05}) == \
        "0012-crs_part_5-v50mmps-r0.05"


def test_serial_sweep_writes_one_sorted_row_per_job(serial):
    path, rows = serial
    assert [r["job_id"] for r in rows] == IDS
    assert [r["planner"] for r in rows] == ["raster", "uniform"] * 2
    assert [r["part"] for r in rows] == ["example:plate"] * 2 + ["example:panel"] * 2
    for r in rows:
        assert r["status"] == "ok" and r["error"] == ""
        assert float(r["pad_radius_m"]) == pytest.approx(0.05) and float(r["feed_m_per_s"]) == pytest.approx(0.1)
        assert float(r["coverage_fraction"]) > 0.99
        assert 0.0 < float(r["removal_cov"]) < 1.0 and float(r["cycle_time_s"]) > 0.0
        # the deepest removal and the hot spot's area (none on these even parts) are columns too
        assert float(r["removal_max_m"]) > float(r["removal_p95_m"]) and float(r["hot_spot_area_m2"]) >= 0.0
        folder = path.parent / "serial" / r["job_id"]
        assert (folder / "metrics.json").is_file() and (folder / "trajectory.csv").is_file()
    # The plate is 0.4 m x 0.3 m: a full-coverage path is at least its area over the pad diameter.
    plate = rows[0]
    assert float(plate["contact_length_m"]) >= 0.4 * 0.3 / 0.1


def test_local_ray_gives_the_same_table(serial, tmp_path):
    _, rows = serial
    ray_sweep = write_sweep(tmp_path, "ray")
    env = os.environ.pop("RAY_ADDRESS", None)
    try:
        assert main([str(ray_sweep), "--workers", "2", "-q"]) == 0
    finally:
        if env is not None:
            os.environ["RAY_ADDRESS"] = env
    same_figures(read_table(tmp_path / "ray" / "results.csv"), rows)


def test_resume_skips_finished_jobs(serial, tmp_path):
    path, rows = serial
    sweep = load_sweep(path)
    done = {j.job_id: (Path(j.settings.out) / "metrics.json").stat().st_mtime_ns for j in sweep.jobs}
    again = run_sweep(sweep, workers=1, resume=True)
    assert [r["resumed"] for r in again] == [True] * 4
    assert {j.job_id: (Path(j.settings.out) / "metrics.json").stat().st_mtime_ns for j in sweep.jobs} == done
    same_figures(read_table(sweep.out / "results.csv"), rows)
    # A job whose stored settings differ (as after an edit of the sweep) is not finished: it runs again.
    first = Path(sweep.jobs[0].settings.out) / "metrics.json"
    doc = json.loads(first.read_text(encoding="utf-8"))
    doc["settings"]["force_N"] = 10.0
    first.write_text(json.dumps(doc), encoding="utf-8")
    redo = run_sweep(sweep, workers=1, resume=True)
    assert [r["resumed"] for r in redo] == [False, True, True, True]
    assert json.loads(first.read_text(encoding="utf-8"))["settings"]["force_N"] == 20.0
    same_figures(read_table(sweep.out / "results.csv"), rows)


def test_parquet_table_matches_the_csv(serial):
    pq = pytest.importorskip("pyarrow.parquet")
    path, rows = serial
    sweep = load_sweep(path)
    run_sweep(sweep, workers=1, resume=True)
    table = pq.read_table(sweep.out / "results.parquet").to_pylist()
    assert [r["job_id"] for r in table] == IDS
    assert [r["coverage_fraction"] for r in table] == [float(r["coverage_fraction"]) for r in rows]


def test_a_failed_job_is_reported_and_the_rest_kept(tmp_path, capsys):
    grid = '[grid]\npart = ["example:plate", "no_such_part.stl"]\nplanner = ["raster"]\n'
    path = write_sweep(tmp_path, "fail", grid=grid)
    assert main([str(path), "--workers", "1"]) == 1
    rows = read_table(tmp_path / "fail" / "results.csv")
    assert [(r["job_id"], r["status"]) for r in rows] == [("0000-plate-raster", "ok"),
                                                        ("0001-no_such_part-raster", "failed")]
    assert "InputError" in rows[1]["error"] and "no_such_part.stl" in rows[1]["error"]
    assert rows[1]["coverage_fraction"] == "" and float(rows[0]["coverage_fraction"]) > 0.99
    assert not (tmp_path / "fail" / "0001-no_such_part-raster").exists()
    assert "2/2" in capsys.readouterr().err


@pytest.mark.parametrize("grid, named", [
    ('[grid]\npart = ["example:plate"]\nforse = ["10N", "20N"]\n', "forse"),
    ('[grid]\npart = ["example:plate"]\nforce = ["20N", "20 parsecs"]\n', "0001-plate-f20_parsecs: force = "),
    ('[grid]\npart = ["example:plate"]\nplanner = "raster"\n', "planner"),
    ('[grid]\npart = ["example:plate"]\nangle = ["0deg"]\n', "angle"),       # both base and grid
    ('[grid]\nout = ["a", "b"]\n', "out"),
    ('[grid]\npart = ["example:plate", "example:plat"]\n', "0001-plat: part = 'example:plat'"),
    ('[grid]\npart = ["example:plate"]\npad-radius = ["30mm"]\n', "pad-radius"),  # pad_radius in the base
])
def test_a_bad_sweep_is_refused_before_any_work(tmp_path, grid, named, capsys):
    path = write_sweep(tmp_path, "bad", grid=grid)
    with pytest.raises(InputError, match=named):
        load_sweep(path)
    assert main([str(path), "--workers", "1"]) == 2
    assert named in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()


def test_an_unexpected_failure_leaves_its_traceback(tmp_path, monkeypatch):
    import swath.cli.job

    def broken(settings, **kwargs):
        raise RuntimeError("solver diverged\nsecond line")

    monkeypatch.setattr(swath.cli.job, "run_job", broken)
    path = write_sweep(tmp_path, "boom", grid='[grid]\nplanner = ["raster"]\n', extra='part = "example:plate"\n')
    rows = run_sweep(load_sweep(path), workers=1)
    assert [(r["job_id"], r["status"], r["error"]) for r in rows] == [
        ("0000-raster", "failed", "RuntimeError: solver diverged")]
    trace = (tmp_path / "boom" / "errors" / "0000-raster.txt").read_text(encoding="utf-8")
    assert "Traceback" in trace and "second line" in trace


def test_ray_sweeps_start_the_longest_jobs_first(tmp_path):
    from swath.cli.batch import expected_job_work

    (tmp_path / "big.stl").write_bytes(b"\0" * 3_000_000)
    (tmp_path / "small.stl").write_bytes(b"\0" * 1_000)
    sweep = load_sweep(write_sweep(tmp_path, "out", grid='[grid]\npart = ["small.stl", "big.stl"]\n'
                                                      'planner = ["raster", "uniform"]\n'))
    work = {(j.values["part"], j.values["planner"]): expected_job_work(j, sweep.base_dir) for j in sweep.jobs}
    assert work[("big.stl", "uniform")] == pytest.approx(3.0 * 4.0)
    assert work[("big.stl", "raster")] == pytest.approx(4.0)
    assert work[("small.stl", "uniform")] == pytest.approx(3.0 * 1.001)
    assert work[("small.stl", "raster")] == pytest.approx(1.001)
    missing = load_sweep(write_sweep(tmp_path, "out2", grid='[grid]\npart = ["nowhere.stl"]\n'))
    assert expected_job_work(missing.jobs[0], missing.base_dir) == pytest.approx(1.0)


def test_local_ray_workers_find_this_swath_and_the_environment_is_restored(monkeypatch):
    ray = pytest.importorskip("ray")
    import swath
    from swath.cli import batch_ray

    seen = {}
    monkeypatch.setattr(ray, "init", lambda **kw: seen.update(kw, path=os.environ.get("PYTHONPATH")))
    monkeypatch.setenv("PYTHONPATH", "/elsewhere")
    batch_ray.start_local_ray(2, warm=False)
    src = str(Path(swath.__file__).resolve().parent.parent)
    # set while Ray starts its processes (the workers inherit it), this swath first; no runtime_env,
    # whose workers Ray would start only when the first task arrives
    assert seen["path"] == os.pathsep.join([src, "/elsewhere"])
    assert seen["num_cpus"] == 2 and "runtime_env" not in seen
    assert os.environ["PYTHONPATH"] == "/elsewhere"


def test_warm_up_runs_a_real_job_and_leaves_nothing(monkeypatch, tmp_path):
    import tempfile

    from swath.cli import batch
    from swath.errors import SwathError

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    assert batch.warm_up() > 0.0
    assert list(tmp_path.iterdir()) == []                 # the scratch folder is gone
    import swath.cli.job

    monkeypatch.setattr(swath.cli.job, "run_job", lambda settings, **kw: 1 / 0)
    with pytest.raises(SwathError, match="warm-up job failed.*ZeroDivisionError"):
        batch.warm_up()
    assert list(tmp_path.iterdir()) == []


def test_a_failed_warm_up_is_logged_and_the_sweep_goes_on(monkeypatch, caplog):
    ray = pytest.importorskip("ray")
    from swath.cli import batch_ray

    class Remote:
        def remote(self):
            return object()

    monkeypatch.setattr(ray, "remote", lambda **kw: lambda fn: Remote())
    monkeypatch.setattr(ray, "get", lambda refs: (_ for _ in ()).throw(RuntimeError("worker died")))
    with caplog.at_level("WARNING"):
        assert batch_ray.warm_workers(2) == []
    assert "warming the Ray workers up failed" in caplog.text and "worker died" in caplog.text


def test_local_ray_jobs_run_on_the_warmed_workers():
    ray = pytest.importorskip("ray")
    from swath.cli import batch_ray

    env = os.environ.pop("RAY_ADDRESS", None)
    try:
        batch_ray.start_local_ray(2, warm=False)
        try:
            warmed = batch_ray.warm_workers(2)
            assert len(set(warmed)) == 2                  # one warm-up on each worker

            @ray.remote(num_cpus=1)
            def probe():
                import sys
                import time

                time.sleep(0.5)                           # both probes in flight at once
                return os.getpid(), {"swath.cli.job", "swath.report", "toppra"} <= set(sys.modules)

            seen = ray.get([probe.remote() for _ in range(2)])
        finally:
            ray.shutdown()
    finally:
        if env is not None:
            os.environ["RAY_ADDRESS"] = env
    assert {pid for pid, _ in seen} == set(warmed)
    assert all(loaded for _, loaded in seen)


@pytest.mark.parametrize("n_jobs, warm", [(2, False), (3, True)])
def test_local_ray_is_warmed_only_when_a_worker_runs_two_jobs(monkeypatch, n_jobs, warm):
    ray = pytest.importorskip("ray")
    from swath.cli import batch_ray

    seen = {}

    def start(n_cpus, *, warm=True):
        seen.update(n_cpus=n_cpus, warm=warm)
        raise KeyboardInterrupt                       # stop before any task is sent

    monkeypatch.setattr(ray, "is_initialized", lambda: False)
    monkeypatch.setattr(batch_ray, "start_local_ray", start)
    with pytest.raises(KeyboardInterrupt):
        list(batch_ray.run_on_ray([object()] * n_jobs, ".", workers=2, address=None))
    assert seen == {"n_cpus": 2, "warm": warm}
