"""Tests of the report stage: metrics.json, PNG figures, the offline HTML report (and a browser check)."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from swath.core import Pass, ToolPath
from swath.errors import InputError
from swath.examples import doubly_curved_panel, flat_plate
from swath.report import write_report
from swath.report.html import MAX_VIEW_FACES, display_mesh, figure_3d, write_report_html
from swath.report.metrics import format_value, key_unit, to_jsonable, write_metrics_json
from swath.report.plots import cluster_decimate, covered_mask, view_frame, write_plots
from swath.simulate.removal import RemovalMap
from swath.surface import Surface
from swath.trajectory.trajectory import Trajectory

PAD_RADIUS = 0.0381
PEAK_DEPTH = 4e-6           # m, removal under the centre line of a pass
PASS_Y = (0.1, 0.2)         # m, the two passes run along x at these y
PASS_X = (0.02, 0.38)       # m


# --- hand-made records --------------------------------------------------------------------------
def _line(a, b, step):
    a, b = np.asarray(a, float), np.asarray(b, float)
    n = max(int(np.ceil(np.linalg.norm(b - a) / step)), 1)
    return a + np.linspace(0, 1, n + 1)[:, None] * (b - a)


def make_job(surface=None):
    """A flat plate, two straight opposite passes, a timed trajectory with air moves between them and
    the removal of an orbital pad: depth = PEAK·sqrt(1 − (d/R)²) at distance d < R from a pass line."""
    surface = surface or flat_plate()
    up = np.array([0.0, 0.0, 1.0])
    passes = []
    for i, y in enumerate(PASS_Y):
        x0, x1 = PASS_X if i % 2 == 0 else PASS_X[::-1]
        pts = _line([x0, y, 0], [x1, y, 0], 0.002)
        passes.append(Pass(pts, np.tile(up, (len(pts), 1))))
    toolpath = ToolPath(surface, passes, planner="raster", metadata={"spacing_m": 0.1})

    feed, air_feed, lift = 0.05, 0.2, 0.05
    chunks = []   # (points, contact, feed, pass index, quaternion)
    q_fwd, q_back = np.array([0.0, 1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0, 0.0])
    prev = None
    for i, p in enumerate(passes):
        start, end = p.points[0], p.points[-1]
        q = q_fwd if i % 2 == 0 else q_back
        if prev is None:
            air = _line(start + lift * up, start, 0.002)
        else:
            air = np.vstack([_line(prev, prev + lift * up, 0.002), _line(prev + lift * up, start + lift * up, 0.002)[1:],
                             _line(start + lift * up, start, 0.002)[1:]])[1:]
        chunks.append((air[:-1], False, air_feed, -1, q))
        chunks.append((p.points, True, feed, i, q))
        prev = end
    ret = _line(prev, prev + lift * up, 0.002)[1:]
    chunks.append((ret, False, air_feed, -1, q))
    pos = np.vstack([c[0] for c in chunks])
    contact = np.concatenate([np.full(len(c[0]), c[1]) for c in chunks])
    feeds = np.concatenate([np.full(len(c[0]), c[2]) for c in chunks])
    pidx = np.concatenate([np.full(len(c[0]), c[3]) for c in chunks])
    quat = np.vstack([np.tile(c[4], (len(c[0]), 1)) for c in chunks])
    step = np.linalg.norm(np.diff(pos, axis=0), axis=1)
    t = np.concatenate([[0.0], np.cumsum(step / feeds[1:])])
    traj = Trajectory(t=t, position=pos, quaternion=quat, contact=contact, feed=feeds, pass_index=pidx)

    sampled = surface
    v = sampled.vertices
    inside = (v[:, 0] >= PASS_X[0]) & (v[:, 0] <= PASS_X[1])
    depth = np.zeros(len(v))
    for y in PASS_Y:
        d = np.abs(v[:, 1] - y)
        depth += np.where(inside & (d < PAD_RADIUS), PEAK_DEPTH * np.sqrt(np.clip(1 - (d / PAD_RADIUS) ** 2, 0, 1)), 0)
    covered = depth > 0
    area = sampled.vertex_areas
    mean = np.average(depth[covered], weights=area[covered])
    std = np.sqrt(np.average((depth[covered] - mean) ** 2, weights=area[covered]))
    inner = sampled.farther_from_boundary(PAD_RADIUS)
    mean_i = np.average(depth[inner], weights=area[inner])
    std_i = np.sqrt(np.average((depth[inner] - mean_i) ** 2, weights=area[inner]))
    metrics = {
        "coverage_fraction": np.float64(area[covered].sum() / area.sum()),
        "removal_cov": np.float64(std / mean),
        "interior_removal_cov": np.float64(std_i / mean_i),
        "mean_depth_m": np.float64(mean),
        "contact_length_m": traj.contact_length,
        "air_length_m": traj.air_length,
        "cycle_time_s": np.float32(traj.duration),
        "n_passes": np.int64(len(passes)),
        "force_rms_error_n": float("nan"),
    }
    removal = RemovalMap(sampled, depth, metrics)
    settings = {"pad_radius_m": PAD_RADIUS, "force_n": 20, "feed_m_per_s": feed, "planner": "raster",
                "tool": {"kind": "orbital", "depression_m": 5e-4}}
    return surface, toolpath, traj, removal, metrics, settings


@pytest.fixture(scope="module")
def job():
    return make_job()


# --- metrics.json -------------------------------------------------------------------------------
def test_metrics_json_round_trip(tmp_path, job):
    *_, metrics, settings = job
    metrics = dict(metrics, depth_percentiles_m=np.array([1e-6, 2e-6, np.inf]))
    path = write_metrics_json(tmp_path / "metrics.json", metrics, settings)
    text = path.read_text()
    assert "NaN" not in text and "Infinity" not in text
    doc = json.loads(text, parse_constant=lambda c: pytest.fail(f"non-JSON constant {c} written"))
    assert set(doc) == {"format_version", "swath_version", "created_utc", "metrics", "settings"}
    m = doc["metrics"]
    assert m["force_rms_error_n"] is None
    assert m["depth_percentiles_m"] == [1e-6, 2e-6, None]
    assert m["n_passes"] == 2 and isinstance(m["n_passes"], int)
    assert m["coverage_fraction"] == pytest.approx(float(metrics["coverage_fraction"]), rel=1e-15)
    assert m["cycle_time_s"] == pytest.approx(float(metrics["cycle_time_s"]), rel=1e-6)
    assert doc["settings"] == {"pad_radius_m": 0.0381, "force_n": 20, "feed_m_per_s": 0.05, "planner": "raster",
                               "tool": {"kind": "orbital", "depression_m": 5e-4}}
    # Every numeric key states its unit.
    for key, value in {**m, **doc["settings"]}.items():
        if not isinstance(value, (str, dict)):
            assert key_unit(key).kind != "unknown", key
    assert list(tmp_path.iterdir()) == [path]          # no temporary file left behind


def test_metrics_json_bad_value_leaves_old_file(tmp_path):
    path = write_metrics_json(tmp_path / "metrics.json", {"cycle_time_s": 1.0}, {})
    before = path.read_text()
    with pytest.raises(InputError, match="cannot write a value of type object"):
        write_metrics_json(path, {"cycle_time_s": object()}, {})
    assert path.read_text() == before
    assert len(list(tmp_path.iterdir())) == 1


def test_key_units_and_human_format():
    assert key_unit("contact_length_m") == key_unit("contact_length_m").__class__("contact length", "m", "length")
    assert key_unit("feed_m_per_s").unit == "m/s"
    assert key_unit("n_passes").kind == "count"
    assert key_unit("planner").kind == "unknown"
    # pure numbers that say what they are: the robot's and the force loop's measures
    assert key_unit("robot_min_wrist_sin") == key_unit("x").__class__("robot min wrist sine", "", "plain")
    assert key_unit("robot_min_manipulability").label == "robot min manipulability"
    assert key_unit("force_gain_margin").label == "force gain margin"
    assert key_unit("robot_placement_score").kind == "plain"
    assert key_unit("stability_margin").kind == "unknown"          # a margin says nothing without its unit
    assert format_value("pad_radius_m", 0.0381) == "38.1 mm"
    assert format_value("contact_length_m", 12.25) == "12.25 m"
    assert format_value("mean_depth_m", 2.5e-6) == "2.5 µm"
    assert format_value("coverage_fraction", 0.9731) == "97.3 %"
    assert format_value("removal_cov", 0.125) == "12.5 %"
    assert format_value("feed_m_per_s", 0.05) == "50 mm/s"
    assert format_value("cycle_time_s", 523.2) == "523.2 s (8 min 43 s)"
    assert format_value("force_n", 20) == "20 N"
    assert format_value("force_rms_error_n", float("nan")) == "–"
    assert to_jsonable({"a": np.float32(0.5), "b": (np.int16(3), np.nan)}) == {"a": 0.5, "b": [3, None]}


# --- geometry helpers ---------------------------------------------------------------------------
def test_view_frame_faces_the_normals():
    plate = flat_plate(size_x=0.4, size_y=0.3, spacing=0.02)
    f = view_frame(plate)
    assert f.axes[2] == pytest.approx([0, 0, 1], abs=1e-12)
    assert np.cross(f.axes[0], f.axes[1]) == pytest.approx(f.axes[2], abs=1e-12)
    uvw = f.project(plate.vertices)
    # The corner vertices' areas differ with the diagonal direction, which tilts the in-plane axes by a
    # few milliradians; the normal axis is exact.
    assert np.ptp(uvw, axis=0) == pytest.approx([0.4, 0.3, 0.0], abs=3e-3)
    assert abs(f.axes[0] @ [1, 0, 0]) > 0.999
    flipped = Surface(plate.vertices, plate.faces[:, ::-1])          # normals now -z
    g = view_frame(flipped)
    assert g.axes[2] == pytest.approx([0, 0, -1], abs=1e-12)
    assert np.cross(g.axes[0], g.axes[1]) == pytest.approx(g.axes[2], abs=1e-12)


def test_cluster_decimate_keeps_linear_fields_and_budget():
    plate = flat_plate(spacing=0.004)                                # 100 x 75 cells, 15,000 faces
    field = 3.0 * plate.vertices[:, 0] - 2.0 * plate.vertices[:, 1]
    v, f, val = cluster_decimate(plate.vertices, plate.faces, field, plate.vertex_areas, max_faces=2000)
    assert 500 < len(f) <= 2000
    # A weighted mean of a linear field is the field at the weighted mean position: exact.
    assert val == pytest.approx(3.0 * v[:, 0] - 2.0 * v[:, 1], abs=1e-12)
    assert v[:, 2] == pytest.approx(0.0, abs=1e-15)
    area = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    assert area.sum() == pytest.approx(0.4 * 0.3, rel=0.08)          # only the rim shrinks a little
    normals = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])[:, 2]
    assert (normals > 0).all()                                       # winding kept


def test_cluster_decimate_carries_several_fields_on_the_same_cells():
    plate = flat_plate(spacing=0.004)
    one = plate.vertices[:, 0]
    two = np.sin(40.0 * plate.vertices[:, 1])
    v, f, both = cluster_decimate(plate.vertices, plate.faces, np.stack([one, two], 1), plate.vertex_areas,
                                  max_faces=2000)
    for k, field in enumerate((one, two)):
        v1, f1, val = cluster_decimate(plate.vertices, plate.faces, field, plate.vertex_areas, max_faces=2000)
        np.testing.assert_array_equal(v1, v)
        np.testing.assert_array_equal(f1, f)
        np.testing.assert_array_equal(val, both[:, k])


@pytest.mark.parametrize("scale", [1, 2 ** 59])        # the codes, and the rows themselves past int64
def test_row_codes_label_rows_as_unique_rows_does(scale):
    from swath.report.plots import _row_codes

    rows = np.random.default_rng(3).integers(0, 6, (500, 3))
    rows[:, 0] *= scale
    codes = _row_codes(rows)
    assert (codes.dtype.names is None) == (scale == 1)
    for a, b in zip(np.unique(rows, axis=0, return_inverse=True, return_index=True)[1:],
                    np.unique(codes, return_inverse=True, return_index=True)[1:]):
        np.testing.assert_array_equal(a.ravel(), b.ravel())


def test_display_mesh_maps_depth_onto_the_part(job):
    part = flat_plate(spacing=0.01)                                  # 2,400 faces
    fine = part.subdivided(0.004)
    depth = 1e-6 * (1 + 10 * fine.vertices[:, 0])
    removal = RemovalMap(fine, depth)
    v, f, d = display_mesh(part, removal, max_faces=len(part.faces))
    assert len(f) == len(part.faces) and np.array_equal(v, part.vertices)
    # Area-weighted mean of a linear field over the samples nearest each vertex: exact inside,
    # off by at most half a part spacing on the rim.
    assert np.abs(d - 1e-6 * (1 + 10 * v[:, 0])).max() <= 1e-5 * 0.005 + 1e-15
    v2, f2, d2 = display_mesh(part, removal, max_faces=1000)          # neither fits: clustering
    assert len(f2) <= 1000 and len(d2) == len(v2)
    v3, f3, d3 = display_mesh(part, RemovalMap(part, np.zeros(len(part.vertices))))
    assert len(f3) == len(part.faces) and not d3.any()


def test_covered_mask_threshold(job):
    removal = job[3]
    assert covered_mask(removal).sum() == (removal.depth > 0).sum()
    assert covered_mask(removal, min_depth=2e-6).sum() == (removal.depth > 2e-6).sum() < (removal.depth > 0).sum()


def test_bad_inputs_raise(tmp_path, job):
    surface, toolpath, traj, removal, metrics, settings = job
    with pytest.raises(InputError, match="does not exist"):
        write_report(tmp_path / "missing", surface=surface, removal=removal)
    with pytest.raises(InputError, match="one value per sampled vertex"):
        write_plots(tmp_path, removal=RemovalMap(surface, np.zeros(5)))


# --- PNGs ---------------------------------------------------------------------------------------
def _image(path):
    import matplotlib.image as mpimg

    img = mpimg.imread(path)
    assert img.ndim == 3 and img.shape[2] in (3, 4)
    return img


def _n_colours(img) -> int:
    rgb = (img[..., :3] * 255).round().astype(np.uint32)
    return len(np.unique(rgb[..., 0] << 16 | rgb[..., 1] << 8 | rgb[..., 2]))


def test_plots_are_real_images(tmp_path, job):
    surface, toolpath, traj, removal, *_ = job
    paths = write_plots(tmp_path, toolpath=toolpath, trajectory=traj, removal=removal)
    assert set(paths) == {"removal_map", "feed_contact", "depth_histogram"}
    for name, path in paths.items():
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        img = _image(path)
        assert img.shape[0] > 400 and img.shape[1] > 700, name
        white = np.all(img[..., :3] > 0.98, axis=2).mean()
        assert white < 0.95, name
        assert _n_colours(img) > 40, name
    # The removal map is dominated by colour (the depth field), the viridis mapping is used and the
    # gaps between passes are grey.
    img = _image(paths["removal_map"])[..., :3]
    grey = (np.abs(img - 217 / 255).max(axis=2) < 0.02).mean()
    assert grey > 0.05
    assert _n_colours(img) > 500
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in paths.values())


# --- HTML ---------------------------------------------------------------------------------------
_REMOTE = re.compile(r"<(?:script|link|img|iframe|source|embed)\b[^>]*\b(?:src|href)\s*=\s*[\"']?\s*(?:https?:)?//",
                     re.IGNORECASE)


def _plotly_call(text):
    """(data, layout) of the ``Plotly.newPlot("view3d", data, layout, config)`` call in the page."""
    m = re.search(r'Plotly\.newPlot\(\s*"view3d",\s*', text)
    dec = json.JSONDecoder()
    data, end = dec.raw_decode(text, m.end())
    layout, _ = dec.raw_decode(text, end + len(re.match(r",\s*", text[end:]).group()))
    return data, layout


def test_write_report_outputs_offline_html(tmp_path, job):
    surface, toolpath, traj, removal, metrics, settings = job
    paths = write_report(tmp_path, surface=surface, toolpath=toolpath, trajectory=traj, removal=removal,
                         metrics=metrics, settings=settings)
    assert set(paths) == {"metrics", "html", "removal_map", "feed_contact", "depth_histogram"}
    assert all(p.parent == tmp_path and p.exists() for p in paths.values())
    text = paths["html"].read_text(encoding="utf-8")
    assert _REMOTE.search(text) is None
    assert "<script src" not in text      # (plotly.js itself names a CDN only as its unused geo-map default)
    assert "Plotly.newPlot" in text and len(text) > 3_000_000            # plotly.js is inlined
    data, layout = _plotly_call(text)
    assert [t["type"] for t in data] == ["mesh3d"] + ["scatter3d"] * 5
    assert [t.get("name") for t in data[1:]] == ["passes", "travel direction", None, "start", "air moves"]
    assert data[0]["i"]["dtype"] == "i4"                                # compact binary arrays
    assert layout["scene"]["aspectmode"] == "data"                      # axes to scale, spanning the part
    lo, hi = surface.vertices.min(axis=0), surface.vertices.max(axis=0)
    assert layout["scene"]["xaxis"]["range"][0] < lo[0] and layout["scene"]["xaxis"]["range"][1] > hi[0]
    assert data[0]["colorbar"]["title"]["text"] == "removal depth (µm)"
    assert len(re.findall(r"<img alt='[^']+' src='data:image/png;base64,", text)) == 3
    # Metrics and settings in human units; the raw keys alongside.
    assert "38.1 mm" in text and "pad_radius_m" in text and "20 N" in text
    assert "raster" in text and surface.name in text
    cov = float(metrics["coverage_fraction"]) * 100
    assert f"{cov:.1f} %" in text or f"{cov:.3g} %" in text
    # the CoV inside the edge band, explained and in the table
    inner = float(metrics["interior_removal_cov"]) * 100
    assert "interior removal CoV" in text and (f"{inner:.1f} %" in text or f"{inner:.3g} %" in text)
    assert len(text.encode()) < 8e6


def test_figures_drawn_beside_are_the_figures_drawn_here_in_their_order(tmp_path, job, monkeypatch):
    import swath.core.beside

    surface, toolpath, traj, removal, metrics, settings = job
    (tmp_path / "beside").mkdir()
    beside = write_report(tmp_path / "beside", surface=surface, toolpath=toolpath, trajectory=traj,
                          removal=removal, metrics=metrics, settings=settings)
    monkeypatch.setattr(swath.core.beside, "can_fork", lambda: False)       # every figure drawn in this process
    (tmp_path / "here").mkdir()
    here = write_report(tmp_path / "here", surface=surface, toolpath=toolpath, trajectory=traj, removal=removal,
                        metrics=metrics, settings=settings)
    assert list(beside) == list(here) == ["metrics", "removal_map", "feed_contact", "depth_histogram", "html"]
    for name in ("removal_map", "feed_contact", "depth_histogram"):
        assert beside[name].read_bytes() == here[name].read_bytes()
    embedded = [re.findall(r"<img alt='([^']+)' src='data:image/png;base64,", p.read_text(encoding="utf-8"))
                for p in (beside["html"], here["html"])]
    assert embedded[0] == embedded[1] and len(embedded[0]) == 3


def test_figure_3d_content(job):
    surface, toolpath, traj, removal, *_ = job
    fig = figure_3d(surface, toolpath=toolpath, trajectory=traj, removal=removal)
    mesh, passes, strokes, heads, start, air = fig.data
    assert len(heads.x) == len(toolpath.passes)                        # a travel-direction tip per pass
    assert len(mesh.i) == len(surface.faces)
    assert np.asarray(mesh.intensity).max() == pytest.approx(PEAK_DEPTH * 1e6, rel=1e-3)
    assert np.asarray(mesh.intensity).min() == 0.0
    pz = np.asarray(passes.z, float)
    assert np.nanmin(pz) > 0                                           # lifted above the plate
    assert set(np.unique(np.asarray(passes.line.color)[np.isfinite(pz)])) == {1.0, 2.0}
    assert start.x[0] == pytest.approx(PASS_X[0]) and start.y[0] == pytest.approx(PASS_Y[0])
    az = np.asarray(air.z, float)
    assert np.nanmax(az) == pytest.approx(0.05)                       # the retract height
    assert fig.layout.scene.aspectmode == "data"


def test_large_part_html_stays_small(tmp_path, rng):
    big = doubly_curved_panel(spacing=1.6e-3)                        # ~156k faces
    assert len(big.faces) > 100_000
    depth = 1e-6 * (2 + np.sin(40 * big.vertices[:, 0]) + rng.uniform(0, 0.2, len(big.vertices)))
    removal = RemovalMap(big, depth, {"coverage_fraction": 1.0})
    passes = [Pass(_line([-0.2, y, 0.0], [0.2, y, 0.0], 5e-4) + 0.0, np.tile([0, 0, 1.0], (801, 1)))
              for y in np.linspace(-0.15, 0.15, 40)]
    toolpath = ToolPath(big, passes, planner="raster")
    path = write_report_html(tmp_path / "report.html", surface=big, toolpath=toolpath, removal=removal,
                             metrics=removal.metrics, settings={}, images={})
    text = path.read_text(encoding="utf-8")
    size = len(text.encode())
    assert size < 15e6
    fig = figure_3d(big, toolpath=toolpath, removal=removal)
    assert len(fig.data[0].i) <= MAX_VIEW_FACES
    assert np.isfinite(np.asarray(fig.data[1].x, float)).sum() <= 20_000 + 40


# --- browser ------------------------------------------------------------------------------------
def _chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome", "chrome"):
        found = shutil.which(name)
        if found:
            return found
    return None


def screenshot(html: Path, png: Path, profile: Path, *, timeout: float = 120.0) -> None:
    """Render ``html`` in headless Chromium (software WebGL, every network host unresolvable)."""
    exe = _chromium()
    cmd = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
           "--use-angle=swiftshader", "--disable-quic", "--no-first-run", "--disable-background-networking",
           "--disable-component-update", "--disable-sync", "--host-resolver-rules=MAP * ~NOTFOUND",
           f"--user-data-dir={profile}", "--window-size=1400,1000", "--virtual-time-budget=10000",
           f"--screenshot={png}", html.resolve().as_uri()]
    subprocess.run(cmd, check=True, timeout=timeout, capture_output=True)


@pytest.mark.browser
def test_report_renders_in_headless_chromium(tmp_path, job):
    if _chromium() is None:
        pytest.skip("no chromium binary on PATH (Debian: apt-get install chromium)")
    surface, toolpath, traj, removal, metrics, settings = job
    html = write_report_html(tmp_path / "report.html", surface=surface, toolpath=toolpath, trajectory=traj,
                             removal=removal, metrics=metrics, settings=settings, images={})
    # Put the 3D view at the top of the page so the screenshot shows it.
    page = tmp_path / "view.html"
    text = html.read_text(encoding="utf-8")
    for panel in ("<section><h2>Summary</h2>", "<section class='ok'>", "<section class='warn'>"):
        text = text.replace(panel, panel.replace("<section", "<section style='display:none'"), 1)
    page.write_text(text, encoding="utf-8")
    png = tmp_path / "shot.png"
    screenshot(page, png, tmp_path / "profile")
    img = _image(png)[..., :3]
    assert img.shape[:2] == (1000, 1400)
    assert not np.all(img > 0.98)
    # A shaded, coloured mesh gives thousands of colours (measured ~4,600); without WebGL the page
    # has under 1,000 (text anti-aliasing) and almost no viridis pixels (~0.4 % against ~12 %).
    assert _n_colours(img) > 2000
    # The removal colours (viridis) fill a good part of the 3D view: many strongly green/blue pixels.
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    viridis_like = (g > r + 0.1) | (b > r + 0.15)
    assert viridis_like.mean() > 0.05
