"""``swath fit``, ``swath plan --fit`` / ``plan patch.json`` and ``swath register`` from the command
line: outputs that reload and match the truth, recovered transforms, and refusals (exit 2, one
line, nothing written)."""

from __future__ import annotations

import csv
import json
import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from conftest import shared_mesh
from swath.cli import main
from swath.examples import doubly_curved_panel
from swath.examples.scansim import panel_patch, simulate_laser_scan
from swath.io.mesh import load_mesh, save_surface_ply
from swath.io.patch import load_patch_json
from swath.io.points import load_points
from swath.io.scan import infer_scan_rows
from swath.scan.register_result import rigid_matrix, rotation_angle
from swath.surface import BSplinePatch, Surface
from swath.trajectory import read_csv

#: The scanned part: a 0.20 x 0.15 m piece of the doubly curved panel (radii 0.35 m and 0.9 m).
PANEL = dict(size_x=0.2, size_y=0.15)
#: Laser scan: rows 3 mm apart, points 1.5 mm apart, noise 0.1 mm, row offsets 0.2 mm per axis.
SCAN = dict(row_spacing=3e-3, point_spacing=1.5e-3, sigma=1e-4, row_offset=2e-4)


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "swath.cli", *map(str, args)], capture_output=True, text=True,
                          timeout=300)


def max_deviation(patch: BSplinePatch, truth: BSplinePatch, n: int = 41, inset: float = 0.05) -> float:
    """Largest distance (m) to ``truth`` from an n x n grid over ``patch``'s domain less ``inset``
    of it at each side (the very corners of a fitted domain lie just outside the scanned area)."""
    (u0, u1), (v0, v1) = patch.domain
    g = np.linspace(inset, 1.0 - inset, n)
    U, V = np.meshgrid(u0 + (u1 - u0) * g, v0 + (v1 - v0) * g, indexing="ij")
    _, _, d = truth.project(patch.evaluate(U.ravel(), V.ravel()))
    return float(d.max())


@pytest.fixture(scope="module")
def truth():
    return panel_patch(**PANEL)


@pytest.fixture(scope="module")
def scan_files(tmp_path_factory, truth):
    """The simulated scan as .xyz in metres and in millimetres."""
    d = tmp_path_factory.mktemp("scan")
    scan = simulate_laser_scan(truth, rng=21, **SCAN)
    np.savetxt(d / "scan.xyz", scan.points)
    np.savetxt(d / "scan_mm.xyz", scan.points * 1e3, fmt="%.6f")
    return d, scan


@pytest.fixture(scope="module")
def fitted(scan_files):
    """``swath fit scan_mm.xyz --units mm --spacing 3mm`` run as a user would (a subprocess)."""
    d, _ = scan_files
    out = d / "fit"
    r = run_cli("fit", d / "scan_mm.xyz", "--units", "mm", "--spacing", "3mm", "--out", out)
    assert r.returncode == 0, r.stderr
    return out, r


# --------------------------------------------------------------------------------------------
# swath fit
# --------------------------------------------------------------------------------------------
def test_fit_writes_patch_surface_and_report(fitted, scan_files, truth):
    out, r = fitted
    _, scan = scan_files
    assert {p.name for p in out.iterdir()} == {"patch.json", "surface.ply", "fit.json", "fit.html", "fit.png",
                                               ".swath-output"}
    assert "fitting a B-spline patch" in r.stderr and "triangulating the patch at 3 mm" in r.stderr
    assert r.stdout.startswith(f"wrote {out}/patch.json")
    # the patch reloads, is in metres, and lies within 0.5 mm of the true panel wherever it was
    # scanned (0.25 mm over its domain less 5 % at the edges)
    patch = load_patch_json(out / "patch.json")
    _, _, d = patch.project(scan.true_points)
    assert d.max() < 5e-4
    assert max_deviation(patch, truth) < 2.5e-4
    # surface.ply: the patch triangulated at 3 mm with unit normals that agree with the patch
    pts, nrm = load_points(out / "surface.ply")
    assert nrm is not None and np.allclose(np.linalg.norm(nrm, axis=1), 1.0, atol=1e-6)
    u, v, dist = patch.project(pts)
    assert dist.max() < 1e-6
    assert np.min(np.einsum("ij,ij->i", nrm, patch.normals(u, v))) > 0.999
    mesh = load_mesh(out / "surface.ply")
    corners = mesh.vertices[mesh.faces]                                  # (m, 3, 3)
    edges = np.sort(np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2), axis=1)
    assert np.median(edges[:, :2]) == pytest.approx(3e-3, rel=0.05)      # grid legs; the diagonal is longer
    # fit.json: figures in SI with units in the key names; rms near the noise (0.1 mm normal
    # noise + 0.2 mm row offsets per axis)
    doc = json.loads((out / "fit.json").read_text())
    f = doc["figures"]
    assert doc["parameterization"] == "projection" and doc["input"]["units"] == "mm"
    assert f["n_points"] == len(scan) and f["n_dropped"] == 0
    assert 1e-4 < f["rms_m"] < 3e-4 and f["residual_p95_m"] < 6e-4
    assert f["rms_m"] == pytest.approx(f["residual_rms_all_points_m"], rel=1e-3)
    assert doc["surface"]["spacing_m"] == pytest.approx(3e-3)
    assert doc["surface"]["n_vertices"] == len(pts)
    assert doc["surface"]["area_m2"] == pytest.approx(0.2 * 0.15, rel=0.05)
    # the report is self-contained: the PNG embedded, nothing fetched
    page = (out / "fit.html").read_text()
    assert "data:image/png;base64," in page and "http" not in page.replace("http-equiv", "")
    assert (out / "fit.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_scan_rows_read_off_the_point_order(truth):
    for bidirectional in (False, True):
        scan = simulate_laser_scan(truth, rng=5, bidirectional=bidirectional, **SCAN)
        np.testing.assert_array_equal(infer_scan_rows(scan.points), scan.rows)


def test_fit_rows_parameterisation_on_a_zigzag_scan(tmp_path, truth, capsys):
    scan = simulate_laser_scan(truth, rng=22, bidirectional=True, **SCAN)
    np.savetxt(tmp_path / "zigzag.xyz", scan.points)
    assert main(["fit", str(tmp_path / "zigzag.xyz"), "--parameterization", "rows", "--out",
                 str(tmp_path / "o")]) == 0
    assert "rows parameterisation" in capsys.readouterr().out
    doc = json.loads((tmp_path / "o" / "fit.json").read_text())
    assert doc["parameterization"] == "rows"
    assert doc["surface"]["spacing_m"] == pytest.approx(2e-3)        # default: 0.2 m / 150 -> 2 mm floor
    patch = load_patch_json(tmp_path / "o" / "patch.json")
    assert max_deviation(patch, truth) < 2.5e-4
    # skinning is tighter than projection inside, but the last points of some rows miss by up
    # to ~0.9 mm (fit_patch's rows mode at the row ends)
    d = patch.project(scan.true_points)[2]
    assert np.percentile(d, 99) < 2.5e-4 and d.max() < 1.5e-3


def test_fit_of_a_round_scan_is_trimmed_to_the_scanned_area(tmp_path, scan_files):
    """A disc cut out of the scan: the rectangular patch beyond the disc is not part of the
    surface, neither in surface.ply nor when planning on the saved patch.json."""
    from swath.cli.job import load_part, settings_from_mapping

    _, scan = scan_files
    radius = 0.07
    disc = scan.points[np.hypot(scan.points[:, 0], scan.points[:, 1]) < radius]
    np.savetxt(tmp_path / "disc.xyz", disc)
    out = tmp_path / "o"
    assert main(["-q", "fit", str(tmp_path / "disc.xyz"), "--out", str(out)]) == 0
    surface = load_mesh(out / "surface.ply")
    assert len(surface.boundary_loops) == 1
    assert surface.area == pytest.approx(np.pi * radius ** 2, rel=0.06)      # a square would be 27 % more
    gap, _ = cKDTree(disc).query(surface.vertices)
    assert gap.max() < 5e-3
    planned = load_part(settings_from_mapping({"part": str(out / "patch.json"), "out": str(tmp_path / "p")}))
    assert planned.area == pytest.approx(surface.area, rel=1e-6)


# --------------------------------------------------------------------------------------------
# swath plan --fit, swath plan patch.json
# --------------------------------------------------------------------------------------------
def test_plan_on_the_fitted_scan_and_on_the_saved_patch(tmp_path, scan_files, fitted, capsys):
    d, _ = scan_files
    out_fit, out_patch = tmp_path / "plan_fit", tmp_path / "plan_patch"
    assert main(["plan", "--constant-feed", str(d / "scan.xyz"), "--fit", "--out", str(out_fit)]) == 0
    assert "fit rms" in capsys.readouterr().err
    tr = read_csv(out_fit / "trajectory.csv")
    assert tr.contact.any() and tr.contact_length > 0.3
    m = json.loads((out_fit / "metrics.json").read_text())
    fit_doc = json.loads((fitted[0] / "fit.json").read_text())
    # the same scan (in metres rather than mm) fits to the same patch
    assert m["metrics"]["fit_rms_m"] == pytest.approx(fit_doc["figures"]["rms_m"], rel=1e-3)
    assert m["metrics"]["surface_spacing_m"] == pytest.approx(2e-3)
    assert m["settings"]["fit"] is True
    assert m["metrics"]["coverage_fraction"] > 0.99
    assert (out_fit / "patch.json").exists()
    # the patch written by swath fit plans the same way
    assert main(["plan", "--constant-feed", str(fitted[0] / "patch.json"), "--surface-spacing", "2mm", "--out", str(out_patch)]) == 0
    m2 = json.loads((out_patch / "metrics.json").read_text())
    assert read_csv(out_patch / "trajectory.csv").contact.any()
    assert m2["metrics"]["contact_length_m"] == pytest.approx(m["metrics"]["contact_length_m"], rel=0.01)


# --------------------------------------------------------------------------------------------
# swath register
# --------------------------------------------------------------------------------------------
def featured_panel(spacing: float) -> Surface:
    """The doubly curved panel with a 20 mm bump (so no motion slides it on itself)."""
    p = doubly_curved_panel(spacing=spacing)
    v = p.vertices.copy()
    v[:, 2] += 0.02 * np.exp(-((v[:, 0] - 0.12) ** 2 + (v[:, 1] + 0.06) ** 2) / (2 * 0.04 ** 2))
    return Surface(v, p.faces, name="featured panel")


def pose_errors(estimate, truth, points) -> tuple[float, float]:
    """Rotation error (deg) and largest displacement error (m) over ``points``."""
    angle = np.degrees(rotation_angle(np.asarray(estimate)[:3, :3].T @ truth[:3, :3]))
    moved = points @ (np.asarray(estimate)[:3, :3] - truth[:3, :3]).T + np.asarray(estimate)[:3, 3] - truth[:3, 3]
    return angle, float(np.linalg.norm(moved, axis=1).max())


@pytest.mark.parametrize("table", [False, True])
def test_register_recovers_a_known_transform(tmp_path, capsys, table):
    cad = featured_panel(8e-3)
    save_surface_ply(cad, tmp_path / "cad.ply")
    if table:       # a turn about z, a shift along the table and a different table height
        cad2scan = rigid_matrix(Rotation.from_rotvec([0, 0, np.radians(35)]).as_matrix(), [0.06, -0.04, 0.015])
    else:
        axis = np.array([0.2, -0.3, 0.9]) / np.linalg.norm([0.2, -0.3, 0.9])
        cad2scan = rigid_matrix(Rotation.from_rotvec(np.radians(20) * axis).as_matrix(), [0.05, -0.03, 0.02])
    dense = featured_panel(3e-3)
    rng = np.random.default_rng(3)
    scan = dense.vertices @ cad2scan[:3, :3].T + cad2scan[:3, 3] + rng.normal(0, 1e-4, dense.vertices.shape)
    if table:
        save_surface_ply(Surface(scan, dense.faces), tmp_path / "scan.ply")
        scan_file, extra = tmp_path / "scan.ply", ["--table"]
    else:
        np.savetxt(tmp_path / "scan_mm.xyz", scan * 1e3)
        scan_file, extra = tmp_path / "scan_mm.xyz", ["--scan-units", "mm"]
    out = tmp_path / "reg"
    assert main(["register", str(tmp_path / "cad.ply"), str(scan_file), *extra, "--out", str(out)]) == 0
    summary = capsys.readouterr().out.strip().splitlines()
    assert len(summary) == 1 and summary[0].startswith("cad2scan") and "converged" in summary[0]
    doc = json.loads((out / "transform.json").read_text())
    angle, shift = pose_errors(doc["cad2scan"], cad2scan, cad.vertices)
    assert angle < 0.1 and shift < 5e-4
    assert doc["method"] == ("table" if table else "rigid") and doc["converged"] is True
    assert doc["rms_m"] < 2e-4 and doc["inlier_fraction"] > 0.95 and doc["iterations"] >= 1
    if table:
        np.testing.assert_allclose(np.asarray(doc["cad2scan"])[2, :3], [0, 0, 1], atol=1e-12)
    with open(out / "residuals.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == len(cad.vertices)
    res = np.array([float(r["residual_m"]) for r in rows])
    assert np.sqrt(np.nanmean(res ** 2)) < 2e-4
    # the scan-frame column is the CAD point moved by the written transform
    i = int(rows[100]["point_index"])
    q = np.array([float(rows[100][k]) for k in ("scan_x_m", "scan_y_m", "scan_z_m")])
    m = np.asarray(doc["cad2scan"])
    np.testing.assert_allclose(q, m[:3, :3] @ cad.vertices[i] + m[:3, 3], atol=1e-8)


def test_register_bezier_cad_onto_its_real_scan_on_the_table(tmp_path, caplog):
    cad, scan = shared_mesh("bezier_dac_cad.ply"), shared_mesh("bezier_dac_scan.ply")
    out = tmp_path / "reg"
    assert main(["register", str(cad), str(scan), "--table", "--out", str(out)]) == 0
    doc = json.loads((out / "transform.json").read_text())
    assert doc["converged"] and doc["rms_m"] < 3.5e-3 and doc["inlier_fraction"] > 0.6
    np.testing.assert_allclose(np.asarray(doc["cad2scan"])[2, :3], [0, 0, 1], atol=1e-12)
    # 73 % inliers and a 3 mm rms: the answer says it is poor, in transform.json and as a warning
    assert any(w.startswith("only 73.") for w in doc["warnings"]) and "only 73." in caplog.text
    # the rigid mode compares the outlines along the same table normal and agrees within 1 mm
    assert main(["register", str(cad), str(scan), "--out", str(tmp_path / "rigid")]) == 0
    rigid = json.loads((tmp_path / "rigid" / "transform.json").read_text())
    centroid = load_mesh(cad).vertices.mean(axis=0)
    a, b = np.asarray(doc["cad2scan"]), np.asarray(rigid["cad2scan"])
    assert np.linalg.norm((a[:3, :3] - b[:3, :3]) @ centroid + a[:3, 3] - b[:3, 3]) < 1e-3
    assert "perimeter seen along the table normal" in rigid["method_description"]


# --------------------------------------------------------------------------------------------
# refusals
# --------------------------------------------------------------------------------------------
def _blob(rng, centre, n=1500):
    xy = rng.uniform(-0.04, 0.04, (n, 2))
    return np.c_[xy + centre, 0.5 * (xy ** 2).sum(axis=1)]


def _write_bad_scan(path, kind):
    rng = np.random.default_rng(4)
    if kind == "five points":
        np.savetxt(path, rng.uniform(0, 0.1, (5, 3)))
    elif kind == "twenty points":
        np.savetxt(path, np.c_[rng.uniform(0, 0.1, (20, 2)), np.zeros(20)])
    elif kind == "two blobs":
        np.savetxt(path, np.vstack([_blob(rng, [0.0, 0.0]), _blob(rng, [0.2, 0.0])]))
    elif kind == "empty":
        path.write_bytes(b"")
    elif kind == "folds over":       # 270 degrees of a 30 mm tube: no plane sees it as a height field
        t, y = rng.uniform(-0.75 * np.pi, 0.75 * np.pi, 3000), rng.uniform(0.0, 0.06, 3000)
        np.savetxt(path, np.c_[0.03 * np.sin(t), y, 0.03 * np.cos(t)])


@pytest.mark.parametrize("kind,fragment", [
    ("five points", "has 5 points; at least 10"),
    ("twenty points", "too few points to fit a degree (3, 3) patch: got 20, need at least 32"),
    ("two blobs", "the points form 2 separate pieces"),
    ("empty", "is empty (0 bytes)"),
    ("folds over", "fold over their best-fit plane"),
])
def test_fit_refuses_bad_scans_with_one_line(tmp_path, capsys, kind, fragment):
    path = tmp_path / "scan.xyz"
    _write_bad_scan(path, kind)
    out = tmp_path / "out"
    for command in (["fit", str(path)], ["plan", str(path), "--fit"]):
        assert main([*command, "--out", str(out)]) == 2
        errors = [line for line in capsys.readouterr().err.splitlines() if line.startswith("swath: error:")]
        assert len(errors) == 1 and fragment in errors[0]
        assert not out.exists() and not [p for p in tmp_path.iterdir() if p.name.startswith(".out")]


def test_fit_refuses_a_projection_that_folds_over(tmp_path, capsys):
    from swath.examples import blade

    save_surface_ply(blade(chord=0.15, span=0.05, max_spacing=5e-3, min_spacing=1e-3), tmp_path / "blade.ply")
    assert main(["fit", str(tmp_path / "blade.ply"), "--parameterization", "projection",
                 "--out", str(tmp_path / "o")]) == 2
    assert "the projection parameterisation folds over" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_register_refuses_no_convergence_and_clouds_as_cad(tmp_path, capsys):
    cad = featured_panel(10e-3)
    save_surface_ply(cad, tmp_path / "cad.ply")
    moved = rigid_matrix(Rotation.from_rotvec([0.0, 0.0, 0.3]).as_matrix(), [0.03, 0.0, 0.01])
    np.savetxt(tmp_path / "scan.xyz", cad.vertices @ moved[:3, :3].T + moved[:3, 3])
    out = tmp_path / "reg"
    assert main(["register", str(tmp_path / "cad.ply"), str(tmp_path / "scan.xyz"), "--max-iterations", "1",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "ICP did not converge within 1 iterations" in err and not out.exists()
    assert main(["register", str(tmp_path / "scan.xyz"), str(tmp_path / "cad.ply"), "--out", str(out)]) == 2
    assert "is a point cloud; the CAD must be a mesh" in capsys.readouterr().err


def test_plan_refuses_a_point_cloud_without_fit_and_fit_on_a_patch(tmp_path, scan_files, fitted, capsys):
    d, _ = scan_files
    assert main(["plan", "--constant-feed", str(d / "scan.xyz"), "--out", str(tmp_path / "o")]) == 2
    assert "is a point cloud, not a mesh; add --fit" in capsys.readouterr().err
    assert main(["plan", "--constant-feed", str(fitted[0] / "patch.json"), "--fit", "--out", str(tmp_path / "o")]) == 2
    assert "already a fitted patch" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_job_settings_carry_the_fit_options():
    from swath.cli.job import settings_from_mapping
    from swath.errors import InputError

    s = settings_from_mapping({"part": "scan.xyz", "out": "o", "fit": True, "parameterization": "rows",
                               "surface_spacing": "3mm"})
    assert s.fit is True and s.parameterization == "rows" and s.surface_spacing == pytest.approx(3e-3)
    assert s.as_record()["surface_spacing_m"] == pytest.approx(3e-3)
    with pytest.raises(InputError, match="parameterization must be one of auto, projection, lscm, rows, got 'harmonic'"):
        settings_from_mapping({"part": "scan.xyz", "out": "o", "fit": True, "parameterization": "harmonic"})
    with pytest.raises(InputError, match="surface_spacing must be positive"):
        settings_from_mapping({"part": "p.json", "out": "o", "surface_spacing": "0mm"})
