"""``swath big --address``: the job on a Ray head that is already running (one started here, on the
loopback address, stopped at the end whatever happens), and the messages for a Ray that cannot be
joined."""

from __future__ import annotations

import csv
import json
import os
import secrets
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from swath.cli.bigpart_head import LocalRayHead, ray_start_available
from swath.cli.bigpart_work import cluster_error
from swath.examples.large import large_blade

SMALL = {"n_faces": 3000, "length": 1.2, "root_chord": 0.3, "max_chord": 0.4, "tip_chord": 0.25, "twist": 0.15}
SRC = str(Path(__file__).resolve().parents[2] / "src")


@pytest.fixture(scope="module")
def blade(tmp_path_factory):
    surface = large_blade(**SMALL)
    path = tmp_path_factory.mktemp("blade") / "blade.npz"
    np.savez(path, vertices=surface.vertices, faces=surface.faces, name=surface.name)
    return path


@pytest.fixture(scope="module")
def head():
    """A head with 2 CPUs and a token of its own; stopped at the end of the module even if a test fails."""
    reason = ray_start_available()
    if reason is not None:
        pytest.skip(reason)
    auth = {"RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(16)}
    with LocalRayHead(2, env=auth) as h:
        yield h
    assert h.process is None


def swath_big(args: list[str], env: dict) -> subprocess.CompletedProcess:
    """``swath big ARGS`` in a new process (this checkout's swath first on its path)."""
    env = {**os.environ, **env, "PYTHONPATH": os.pathsep.join(p for p in (SRC, os.environ.get("PYTHONPATH")) if p)}
    return subprocess.run([sys.executable, "-c", "import sys; from swath.cli import main; sys.exit(main())", "big",
                           *args], env=env, capture_output=True, text=True, timeout=600)


def tasks_at_once(rows: list[dict]) -> int:
    """The most tasks of ``tasks.csv`` running at the same time."""
    events = sorted([(float(r["start_s"]), 1) for r in rows] + [(float(r["end_s"]), -1) for r in rows],
                    key=lambda e: (e[0], e[1]))
    now = most = 0
    for _, step in events:
        now += step
        most = max(most, now)
    return most


@pytest.mark.slow
def test_big_on_a_running_head_with_one_and_two_workers(blade, head, tmp_path):
    from swath.cli.bigpart import run_big_part
    from swath.cli.settings import JobSettings

    here = run_big_part(JobSettings(part=str(blade), out=str(tmp_path / "here"), spacing=0.06), regions=3,
                        workers=1)
    common = [str(blade), "--spacing", "60mm", "--regions", "3", "--address", head.address]
    for workers in (1, 2):
        out = tmp_path / f"w{workers}"
        run = swath_big([*common, "--workers", str(workers), "--out", str(out)], head.env)
        assert run.returncode == 0, run.stderr[-3000:]
        assert f"3 regions on the Ray at {head.address}, {workers} at a time" in run.stdout
        # the same job as in this process, byte for byte
        assert (out / "trajectory.csv").read_bytes() == (tmp_path / "here" / "trajectory.csv").read_bytes()
        metrics = json.loads((out / "metrics.json").read_text())["metrics"]
        assert metrics["interior_removal_cov"] == pytest.approx(here["interior_removal_cov"], rel=1e-12)
        assert metrics["n_passes"] == here["n_passes"] and metrics["workers"] == workers
        # the workers honoured: never more tasks at once than asked for; two at once with two
        with open(out / "tasks.csv", newline="") as fh:
            rows = list(csv.DictReader(fh))
        assert len(rows) == 9
        assert tasks_at_once(rows) == workers
        # every worker ran the driver's swath, shipped to the head (unpacked in its own folder)
        dirs = metrics["worker_swath_dirs"]
        assert dirs and all(d != here["worker_swath_dirs"][0] and d.endswith("swath") for d in dirs)
        assert all("runtime_resources" in d for d in dirs)
        # the region files are gone (the work folder beside the output is removed)
        assert not [p for p in tmp_path.iterdir() if p.name.startswith(".swath-regions-")]


def test_cluster_error_names_the_fix():
    class GcsDown(RuntimeError):
        pass

    try:
        try:
            raise GcsDown("Failed to connect to GCS. RPC error: InvalidAuthToken: Authentication token is missing")
        except GcsDown as inner:
            raise ConnectionError("Failed to connect to Ray cluster at 10.0.0.1:6379") from inner
    except ConnectionError as exc:
        text = cluster_error("10.0.0.1:6379", exc)
    assert "10.0.0.1:6379" in text and "RAY_AUTH_MODE=token" in text
    text = cluster_error("10.0.0.1:6379", ConnectionError("Failed to connect to Ray cluster at 10.0.0.1:6379"))
    assert "no Ray answered at 10.0.0.1:6379" in text and "ray start --head" in text


def test_big_refuses_an_address_with_no_ray_behind_it(blade, tmp_path):
    pytest.importorskip("ray")
    from swath.cli.bigpart_head import free_port

    port = free_port()
    run = swath_big([str(blade), "--regions", "2", "--workers", "2", "--address", f"127.0.0.1:{port}",
                     "--out", str(tmp_path / "o")], {})
    assert run.returncode != 0
    assert f"no Ray answered at 127.0.0.1:{port}" in run.stderr
    assert not (tmp_path / "o").exists()


def test_a_region_file_missing_on_a_worker_names_the_work_dir(tmp_path):
    from swath.cli.bigpart_work import load_region
    from swath.errors import InputError
    from swath.segment.tiles import span_tiles

    tile = span_tiles(np.linspace(0.0, 1.0, 11), 0.1, 1, band=0.05)[0]
    with pytest.raises(InputError, match="--work-dir a folder every node mounts"):
        load_region(str(tmp_path / "region0000.npz"), owned_only=False, tile=tile, axis=(1.0, 0.0, 0.0))
