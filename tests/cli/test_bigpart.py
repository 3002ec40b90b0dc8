"""Big parts by regions: the blade generator, span tiles, section passes, joined trajectories, and
the stitched plan against the whole part (seams with no gap and no double removal)."""

from __future__ import annotations

import json
import math

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
    pytest.importorskip("ray")
    inline = run_big_part(_settings(small_blade[1], tmp_path / "a"), regions=2, workers=1)
    on_ray = run_big_part(_settings(small_blade[1], tmp_path / "b"), regions=2, workers=2)
    assert on_ray["where"] == "on a local Ray with 2 workers"
    assert on_ray["interior_removal_cov"] == pytest.approx(inline["interior_removal_cov"], rel=1e-9)
    assert on_ray["n_passes"] == inline["n_passes"]
    assert len(on_ray["worker_peak_rss_bytes"]) >= 1 and 0 < on_ray["max_worker_peak_rss_bytes"] < 8 * 2**30


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
