"""Big parts by regions: the blade generator, span tiles, section passes, joined trajectories, and
the stitched plan against the whole part (seams with no gap and no double removal)."""

from __future__ import annotations

import json
import math
import os
import time

import numpy as np
import pytest
from scipy.spatial import cKDTree

from swath.cli.bigpart import run_big_part
from swath.cli.settings import JobSettings
from swath.errors import InputError
from swath.examples.large import large_blade
from swath.segment.tiles import principal_axes, span_tiles
from swath.simulate import simulate_removal

SMALL = {"n_faces": 3000, "length": 1.2, "root_chord": 0.3, "max_chord": 0.4, "tip_chord": 0.25, "twist": 0.15}


@pytest.fixture(scope="module")
def small_blade(tmp_path_factory):
    surface = large_blade(**SMALL)
    path = tmp_path_factory.mktemp("blade") / "blade.npz"
    np.savez(path, vertices=surface.vertices, faces=surface.faces, name=surface.name)
    return surface, path


def _settings(path, out, **kw):
    return JobSettings(part=str(path), out=str(out), spacing=0.06, **kw)


def test_large_blade_sections_face_count_and_normals():
    b = large_blade(n_faces=40_000, length=20.0)
    assert abs(len(b.faces) - 40_000) <= 400
    assert b.vertices[:, 0].min() == 0.0 and b.vertices[:, 0].max() == pytest.approx(20.0)
    assert (b.face_normals[:, 2] > 0.5).all()            # the skin faces the tool (+z)
    # the tip section is untwisted: chord fractions 0.1..0.95 of 0.35 m about the quarter chord
    tip = b.vertices[np.isclose(b.vertices[:, 0], 20.0)]
    assert tip[:, 1].min() == pytest.approx((0.1 - 0.25) * 0.35, abs=1e-12)
    assert tip[:, 1].max() == pytest.approx((0.95 - 0.25) * 0.35, abs=1e-12)
    # at 20 % span the chord is 1.6 m, turned by 14 deg * 0.8² about x: its projected width is
    # 0.85 * 1.6 * cos(theta) give or take the profile's height times sin(theta)
    x20 = b.vertices[:, 0][np.argmin(np.abs(b.vertices[:, 0] - 4.0))]
    sec = b.vertices[b.vertices[:, 0] == x20]
    theta = np.deg2rad(14.0) * (1 - x20 / 20.0) ** 2
    width = np.ptp(sec[:, 1])
    assert abs(width - 0.85 * 1.6 * math.cos(theta)) < 1.6 * 0.3 * math.sin(theta) + 0.01


def test_large_blade_refuses_bad_sizes():
    with pytest.raises(InputError, match="first < last"):
        large_blade(n_faces=1000, first=0.9, last=0.5)


def test_span_tiles_planes_one_spacing_apart_and_owned_once():
    h = np.linspace(0.0, 1.0, 101)
    tiles = span_tiles(h, 0.07, 3, band=0.1)
    planes = np.concatenate([t.offsets for t in tiles])
    assert len(planes) == math.ceil(1.0 / 0.07)
    np.testing.assert_allclose(np.diff(planes), 0.07)
    np.testing.assert_array_equal(np.concatenate([t.levels for t in tiles]), np.arange(len(planes)))
    for a, b in zip(tiles[:-1], tiles[1:]):
        assert a.hi == b.lo == pytest.approx(0.5 * (a.offsets[-1] + b.offsets[0]))
    owners = np.array([[t.owns(np.array([p]))[0] for t in tiles] for p in planes])
    assert (owners.sum(axis=1) == 1).all()
    with pytest.raises(InputError, match="at most 15 regions"):
        span_tiles(h, 0.07, 16, band=0.1)


def test_principal_axes_of_the_blade():
    axis, across = principal_axes(large_blade(**SMALL).vertices)
    assert axis[0] > 0.99                       # the span, tilted a little by the taper and the twist
    assert abs(across[1]) > 0.95


def test_join_trajectories_renumbers_passes_and_times(small_blade, tmp_path):
    from swath.trajectory.join import join_trajectories

    m = run_big_part(_settings(small_blade[1], tmp_path / "a"), regions=2)
    tr = m["trajectory"]
    joined = join_trajectories([tr, tr], link_speed=0.5)
    n = len(tr)
    assert len(joined) == 2 * n
    assert joined.pass_index.max() == 2 * tr.pass_index.max() + 1
    gap = np.linalg.norm(tr.position[0] - tr.position[-1])
    assert joined.t[n] - joined.t[n - 1] == pytest.approx(gap / 0.5)
    assert joined.duration == pytest.approx(2 * tr.duration + gap / 0.5)
    assert joined.contact_length == pytest.approx(2 * tr.contact_length)


def test_stitched_removal_equals_whole_part_simulation(small_blade, tmp_path):
    surface, path = small_blade
    settings = _settings(path, tmp_path / "two")
    two = run_big_part(settings, regions=2)
    one = run_big_part(_settings(path, tmp_path / "one"), regions=1)
    # every region's passes are there, on their own planes, in the order of the planes
    tr = two["trajectory"]
    assert sum(r["n_passes"] for r in two["regions"]) == one["n_passes"] == tr.pass_index.max() + 1
    assert all(r["n_passes"] > 0 for r in two["regions"])
    x_of_pass = [tr.position[tr.pass_index == i, 0].mean() for i in range(tr.pass_index.max() + 1)]
    assert np.all(np.diff(x_of_pass) > 0.05)             # one spacing on, across the seam too
    np.testing.assert_allclose(np.diff(x_of_pass), 0.06, atol=0.01)
    # the stitched removal, sample by sample, against the whole part simulated on the same trajectory
    whole = simulate_removal(tr, surface, settings.tool(), sampling=settings.removal_sampling)
    points = np.concatenate([r["points"] for r in two["stitched"]]).astype(float)
    depth = np.concatenate([r["depth"] for r in two["stitched"]])
    dist, idx = cKDTree(whole.surface.vertices).query(points)
    assert len(points) == len(whole.depth) and dist.max() < 1e-6     # every sample once: none lost, none twice
    mean = float(np.mean(whole.depth[whole.depth > 0]))
    seam = two["regions"][0]["to_m"]
    near = np.abs(points[:, 0] - seam) < 2 * settings.pad_radius
    assert near.sum() > 1000
    assert np.abs(depth - whole.depth[idx]).max() < 0.02 * mean
    assert np.abs(depth[near] - whole.depth[idx][near]).max() < 0.02 * mean
    # and the figures of the one-region run of the same planes
    assert two["interior_removal_cov"] == pytest.approx(one["interior_removal_cov"], abs=1e-6)
    assert two["coverage_fraction"] == pytest.approx(one["coverage_fraction"], abs=1e-9)
    doc = json.loads((tmp_path / "two" / "metrics.json").read_text())
    assert doc["metrics"]["n_regions"] == 2
    rows = (tmp_path / "two" / "regions.csv").read_text().splitlines()
    assert len(rows) == 3 and rows[0].startswith("region,from_m,to_m")


def test_big_refuses_settings_it_does_not_take(small_blade, tmp_path):
    with pytest.raises(InputError, match="planner"):
        run_big_part(_settings(small_blade[1], tmp_path / "x", planner="uniform"), regions=2)
    with pytest.raises(InputError, match="at least 1"):
        run_big_part(_settings(small_blade[1], tmp_path / "x"), regions=0)
    with pytest.raises(InputError, match="a count or 'auto'"):        # before the (missing) part is read
        run_big_part(_settings(tmp_path / "missing.npz", tmp_path / "x"), regions="x")
    assert not (tmp_path / "x").exists()


def test_cli_big_in_process(small_blade, tmp_path, capsys):
    from swath.cli.main import main

    out = tmp_path / "cli"
    assert main(["big", str(small_blade[1]), "--regions", "2", "--workers", "1", "--spacing", "60mm",
                 "--out", str(out)]) == 0
    assert "2 regions in this process" in capsys.readouterr().out
    assert {"trajectory.csv", "metrics.json", "regions.csv"} <= {p.name for p in out.iterdir()}


@pytest.mark.slow
def test_two_ray_workers_give_the_in_process_result(small_blade, tmp_path):
    ray = pytest.importorskip("ray")
    inline = run_big_part(_settings(small_blade[1], tmp_path / "a"), regions=2, workers=1)
    on_ray = run_big_part(_settings(small_blade[1], tmp_path / "b"), regions=2, workers=2)
    assert on_ray["where"] == "on a local Ray with 2 workers"
    assert not ray.is_initialized()                  # shut down beside the stitching, and waited for
    assert on_ray["stitched"][0]["depth"].sum() > 0   # the removal that came back is readable after it
    assert on_ray["interior_removal_cov"] == pytest.approx(inline["interior_removal_cov"], rel=1e-9)
    assert on_ray["n_passes"] == inline["n_passes"]
    assert len(on_ray["worker_peak_rss_bytes"]) >= 1 and 0 < on_ray["max_worker_peak_rss_bytes"] < 8 * 2**30


@pytest.mark.slow
def test_a_local_ray_of_the_job_starts_without_the_dashboard_and_monitors():
    """The local Ray ``swath big`` starts runs its tasks with none of the dashboard's API server, the
    autoscaler monitor and the log monitor, and Ray's node starts them again afterwards."""
    ray = pytest.importorskip("ray")
    from ray._private.node import Node

    from swath.cli.bigpart_work import RAY_EXTRAS, RayExecutor, peak_rss_bytes

    if ray.is_initialized():
        pytest.skip("a Ray is already running in this process")
    before = {name: Node.__dict__[name] for name in RAY_EXTRAS}
    executor = RayExecutor(1)
    try:
        kinds = set(ray._private.worker._global_node.all_processes)
        assert not kinds & {"dashboard", "monitor", "log_monitor"}
        assert {"gcs_server", "raylet"} <= kinds

        def task(n):                                   # a local function: Ray ships it by value
            return n * 2, {"pid": os.getpid(), "rss": peak_rss_bytes()}

        executor.submit(("plan", 0), task, (3,))
        key, info = executor.next_done()
        assert key == ("plan", 0) and info["pid"] != os.getpid() and info["rss"] > 0
        assert executor.result(("plan", 0)) == 6
    finally:
        executor.close()
    assert not ray.is_initialized()
    assert {name: Node.__dict__[name] for name in RAY_EXTRAS} == before


def test_close_aside_waits_for_the_close_and_raises_its_error_once():
    from swath.cli.bigpart_work import CloseAside

    class Slow:
        closed = False

        def close(self):
            time.sleep(0.2)
            self.closed = True

    class Failing:
        def close(self):
            raise RuntimeError("no shutdown")

    slow = Slow()
    closing = CloseAside(slow)
    assert not slow.closed                           # closing in its own thread
    closing.wait()
    assert slow.closed
    closing = CloseAside(Failing())
    closing.wait(raise_error=False)                  # a job's own error goes first: the close's is dropped
    closing = CloseAside(Failing())
    with pytest.raises(RuntimeError, match="no shutdown"):
        closing.wait()
    closing.wait()                                   # raised once


def test_big_prints_its_help(capsys):
    from swath.cli.main import main

    with pytest.raises(SystemExit) as exc:
        main(["big", "--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: swath big") and "--regions" in out and "--address" in out


def test_submesh_keeps_the_faces_and_only_their_vertices_in_order():
    from swath.segment.tiles import submesh

    rng = np.random.default_rng(3)
    vertices = rng.random((200, 3))
    faces = rng.integers(0, 200, (500, 3))
    keep = rng.random(500) < 0.3
    v, f = submesh(vertices, faces, keep)
    used = np.unique(faces[keep])
    np.testing.assert_array_equal(v, vertices[used])              # the used vertices, in their old order
    np.testing.assert_array_equal(v[f], vertices[faces[keep]])    # the same triangles
    # faces that use a window of the vertices (a region of a mesh laid out along the part)
    window = (faces.min(axis=1) >= 120) & (faces.max(axis=1) < 170) & keep
    v, f = submesh(vertices, faces, window)
    used = np.unique(faces[window])
    assert used.min() >= 120 and len(used) > 3
    np.testing.assert_array_equal(v, vertices[used])
    np.testing.assert_array_equal(v[f], vertices[faces[window]])
    v, f = submesh(vertices, faces, np.zeros(500, bool))            # nothing kept
    assert v.shape == (0, 3) and f.shape == (0, 3)


def test_trajectory_csv_from_the_regions_rows_is_the_joined_trajectory(small_blade, tmp_path):
    m = run_big_part(_settings(small_blade[1], tmp_path / "three"), regions=3)
    assert m["trajectory_rows_by"] == "regions"
    text = (tmp_path / "three" / "trajectory.csv").read_text()
    assert text == m["trajectory"].to_csv_text()            # byte for byte
    # every task ran once, each after what it needs: a simulation after the plans reaching it,
    # a region's rows after the plans of the regions before it
    tasks = m["tasks"]
    assert sorted((t["task"], t["region"]) for t in tasks) == sorted(
        (kind, k) for kind in ("plan", "simulate", "rows") for k in range(3))
    end = {(t["task"], t["region"]): t["end_s"] for t in tasks}
    for t in tasks:
        k = t["region"]
        before = {"plan": [], "simulate": [j for j in (k - 1, k, k + 1) if 0 <= j < 3], "rows": range(k + 1)}
        assert all(end[("plan", j)] <= t["start_s"] + 1e-3 for j in before[t["task"]])
    assert (tmp_path / "three" / "tasks.csv").read_text().startswith("task,region,worker,start_s,end_s,cpu_s")


def test_rows_of_each_part_concatenate_to_the_joined_csv():
    from swath.trajectory import Trajectory
    from swath.trajectory.join import Ends, csv_header, csv_rows, join_offsets, join_trajectories

    rng = np.random.default_rng(7)

    def part(n, n_pass, extra):
        t = np.cumsum(rng.uniform(0.01, 0.1, n)) + rng.uniform(0, 5)
        contact = np.zeros(n, bool)
        contact[2:-2] = True
        pass_index = np.where(contact, np.minimum(np.arange(n) * n_pass // n, n_pass - 1), -1)
        q = rng.normal(size=(n, 4))
        return Trajectory(t, rng.normal(size=(n, 3)), q / np.linalg.norm(q, axis=1)[:, None], contact,
                          rng.uniform(0.01, 0.05, n), pass_index, extra={k: rng.normal(size=n) for k in extra})

    parts = [part(40, 3, ("force",)), part(25, 2, ("force",)), part(31, 4, ("force",))]
    joined = join_trajectories(parts, link_speed=0.3)
    shifts, first, link = join_offsets([Ends.of(p) for p in parts], link_speed=0.3)
    assert first == [0, 3, 5]
    assert link == pytest.approx(joined.metadata["join_link_length_m"])
    # the move between parts takes its length over the link speed
    gap = np.linalg.norm(parts[1].position[0] - parts[0].position[-1])
    assert shifts[1] + parts[1].t[0] - (parts[0].t[-1] + shifts[0]) == pytest.approx(gap / 0.3)
    text = csv_header(("force",)) + "".join(
        csv_rows(p, shift=s, first_pass=f, names=("force",)) for p, s, f in zip(parts, shifts, first))
    assert text == joined.to_csv_text()
    # a column only a later part has: 0 in the parts without it, as join_trajectories fills it
    parts[1] = part(25, 2, ("force", "wear"))
    joined = join_trajectories(parts, link_speed=0.3)
    shifts, first, _ = join_offsets([Ends.of(p) for p in parts], link_speed=0.3)
    names = ("force", "wear")
    assert csv_header(names) + "".join(csv_rows(p, shift=s, first_pass=f, names=names)
                                       for p, s, f in zip(parts, shifts, first)) == joined.to_csv_text()
    with pytest.raises(InputError, match="at least one"):
        join_offsets([], link_speed=0.3)


def test_work_order_starts_at_the_heavier_end_and_idle_figures():
    from swath.cli.bigpart_schedule import idle_figures, work_order

    assert work_order([5, 4, 3, 1]) == [0, 1, 2, 3]
    assert work_order([1, 3, 4, 5]) == [3, 2, 1, 0]
    assert work_order([2, 9, 2]) == [0, 1, 2]                   # the middle region counts for neither half
    timeline = [{"worker": 1, "start_s": 1.0, "end_s": 4.0}, {"worker": 2, "start_s": 1.5, "end_s": 3.0},
                {"worker": 1, "start_s": 4.0, "end_s": 6.0}, {"worker": 2, "start_s": 3.0, "end_s": 5.0}]
    # span 1..6 s; busy 3 + 1.5 + 2 + 2 s; at the end worker 2 idles 1 s
    assert idle_figures(timeline, 2) == pytest.approx({"regions_s": 5.0, "tasks_busy_s": 8.5, "tail_idle_s": 1.0})
    # a third worker that ran nothing idles the whole span
    assert idle_figures(timeline, 3)["tail_idle_s"] == pytest.approx(6.0)


def test_region_tasks_respect_their_needs_whatever_order_they_finish_in(tmp_path):
    """The scheduler on an executor whose tasks finish in a random order: at most ``workers`` run,
    each starts only once what it needs has finished, and every task runs once."""
    from swath.cli.bigpart import reaching
    from swath.cli.bigpart_schedule import RegionTasks
    from swath.trajectory.join import Ends

    class Shuffled:
        workers = 3

        def __init__(self, seed):
            self.rng = np.random.default_rng(seed)
            self.running: list = []
            self.finished: set = set()
            self.log: list = []
            self.args: dict = {}

        @property
        def in_flight(self):
            return len(self.running)

        def submit(self, key, fn, args):
            self.log.append((key, set(self.finished), len(self.running) + 1))
            self.args[key] = args
            self.running.append(key)

        def handle(self, key):
            return key

        def next_done(self):
            key = self.running.pop(int(self.rng.integers(len(self.running))))
            self.finished.add(key)
            info = {"pid": 1, "started": 0.0, "ended": 1.0, "cpu_s": 1.0}
            if key[0] == "plan":
                info["ends"] = Ends(0.0, 2.0, (0.0, 0.0, float(key[1])), (1.0, 0.0, float(key[1])), 2, (), 10, False)
            return key, info

    tiles = span_tiles(np.linspace(0.0, 1.0, 50), 0.05, 6, band=0.06)
    reach = [reaching(tiles, k) for k in range(6)]
    assert reach[0] == [0, 1] and reach[3] == [2, 3, 4]
    for seed in range(5):
        ex = Shuffled(seed)
        tasks = RegionTasks(ex, tiles, reach, list(range(6)), plan_args=(), simulate_args=(), link_speed=0.5,
                            rows_folder=tmp_path)
        for k in range(6):
            tasks.file_ready(k, f"region{k}")
        tasks.run()
        assert len(ex.log) == 18 and len({key for key, _, _ in ex.log}) == 18
        assert max(n for _, _, n in ex.log) <= 3
        for (kind, k), done, _ in ex.log:
            needs = reach[k] if kind == "simulate" else range(k + 1) if kind == "rows" else []
            assert all(("plan", j) in done for j in needs)
        # the rows tasks got the offsets the regions before them give: 2 s and 2 passes each, and a
        # move of sqrt(2) m at 0.5 m/s from one region's end to the next one's start
        for k in range(6):
            _, _, shift, first_pass, names = ex.args[("rows", k)]
            assert shift == pytest.approx(k * (2.0 + math.sqrt(2.0) / 0.5)) and first_pass == 2 * k and names == ()
