"""fit_patch on simulated point-laser scans (accuracy targets, parameterisations, refusals),
the curvature-based knot distribution, and the scan simulator."""

from __future__ import annotations

import json

import numpy as np
import pytest

from swath.contact import Tool, local_patch
from swath.errors import InfeasibleError, InputError
from swath.examples import blade, doubly_curved_panel, flat_plate
from swath.examples.scansim import blade_patch, panel_patch, simulate_laser_scan
from swath.scan.fit import fit_patch
from swath.scan.fit_knots import curvature_knots
from swath.surface.exact_shapes import nurbs_sphere


def _errors(truth, patch, scan, rng, n_width=300):
    """Normal angles (deg) at every scanned point and relative errors of the widest and narrowest
    contact swath of the default pad on a subsample."""
    u, v, dist = patch.project(scan.true_points)
    cos = np.einsum("ij,ij->i", patch.normals(u, v), scan.true_normals)
    ang = np.degrees(np.arccos(np.clip(cos, -1, 1)))
    sub = rng.choice(len(scan), size=n_width, replace=False)
    true = truth.curvature(scan.uv[sub, 0], scan.uv[sub, 1])
    fitted = patch.curvature(u[sub], v[sub])
    t, f = local_patch(true.k1, true.k2, Tool()), local_patch(fitted.k1, fitted.k2, Tool())
    wmax = np.abs(f.max_width() - t.max_width()) / t.max_width()
    wmin = np.abs(f.min_width() - t.min_width()) / t.min_width()
    return ang, wmax, wmin, dist


# ----------------------------------------------------------------------------------------------
# Accuracy targets at σ = 0.1 mm with 0.2 mm row offsets (smaller versions of the benchmark)
# ----------------------------------------------------------------------------------------------
def test_blade_scan_round_the_leading_edge_meets_targets():
    rng = np.random.default_rng(7)
    truth = blade_patch(span=0.12)
    scan = simulate_laser_scan(truth, row_spacing=3e-3, point_spacing=0.75e-3, sigma=1e-4, row_offset=2e-4,
                               rng=rng)
    patch, report = fit_patch(scan.points, rows=scan.rows)
    assert report.parameterization == "rows"
    ang, wmax, wmin, dist = _errors(truth, patch, scan, rng)
    assert np.percentile(ang, 95) < 0.5
    assert np.percentile(wmax, 95) < 0.05 and np.percentile(wmin, 95) < 0.05
    assert np.sqrt(np.mean(dist**2)) < 1e-4                  # the raw points are 0.22 mm RMS off
    # The fit wraps: normals on the lower surface, at the leading edge and on the upper surface.
    n = patch.normals(*patch.project(np.array([[0.1, 0.06, -0.0215], [0.0, 0.06, 0.0], [0.1, 0.06, 0.0215]]))[:2])
    assert n[0, 2] < -0.9 and n[1, 0] < -0.99 and n[2, 2] > 0.9


def test_panel_scan_meets_targets():
    rng = np.random.default_rng(8)
    truth = panel_patch(size_x=0.25, size_y=0.2)
    scan = simulate_laser_scan(truth, row_spacing=3e-3, point_spacing=0.75e-3, rng=rng)
    patch, report = fit_patch(scan.points, rows=scan.rows)
    ang, wmax, wmin, _ = _errors(truth, patch, scan, rng)
    assert np.percentile(ang, 95) < 0.5
    assert np.percentile(wmax, 95) < 0.05 and np.percentile(wmin, 95) < 0.05
    # Curvature itself at the crown: 1/0.35 across x, 1/0.9 across y (normals +z).
    c = patch.curvature(*patch.project(np.array([[0.0, 0.0, 0.0]]))[:2])
    assert c.k1[0] == pytest.approx(1 / 0.35, rel=0.05) and c.k2[0] == pytest.approx(1 / 0.9, rel=0.08)
    assert report.rms == pytest.approx(np.sqrt(1e-4**2 + 2e-4**2), rel=0.3)   # noise + offset along the normal


def test_pca_baseline_is_much_worse_than_the_fit():
    """The benchmark's baseline, on the same kind of scan: local PCA normals are degrees off."""
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(9)
    scan = simulate_laser_scan(panel_patch(size_x=0.2, size_y=0.15), row_spacing=3e-3, point_spacing=0.75e-3,
                               rng=rng)
    _, idx = cKDTree(scan.points).query(scan.points, k=30)
    nb = scan.points[idx] - scan.points[idx].mean(axis=1, keepdims=True)
    n = np.linalg.eigh(np.einsum("nki,nkj->nij", nb, nb))[1][:, :, 0]
    ang = np.degrees(np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", n, scan.true_normals)), 0, 1)))
    assert np.percentile(ang, 95) > 2.0


# ----------------------------------------------------------------------------------------------
# Other parameterisations
# ----------------------------------------------------------------------------------------------
def _noisy_vertices(surface, truth, sigma, rng):
    u, v, _ = truth.project(surface.vertices)
    n = truth.normals(u, v)
    return surface.vertices + sigma * rng.standard_normal(len(n))[:, None] * n, n


def test_projection_fit_of_a_height_field_cloud(rng):
    surf = doubly_curved_panel(size_x=0.3, size_y=0.24, spacing=5e-3)
    truth = panel_patch(size_x=0.3, size_y=0.24)
    X, n_true = _noisy_vertices(surf, truth, 1e-4, rng)
    patch, report = fit_patch(X)
    assert report.parameterization == "projection"
    u, v, dist = patch.project(surf.vertices)
    ang = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", patch.normals(u, v), n_true), -1, 1)))
    assert np.percentile(ang, 95) < 0.5                       # and facing +z (the convex side)
    assert np.sqrt(np.mean(dist**2)) < 5e-5
    assert report.rms == pytest.approx(1e-4, rel=0.2)
    assert report.n_ctrl == patch.shape and report.degree == (3, 3)
    json.dumps(report.to_dict())


def test_lscm_fit_of_a_wrapping_mesh(rng):
    surf = blade(span=0.1, max_spacing=5e-3)
    truth = blade_patch(span=0.1)
    X, n_true = _noisy_vertices(surf, truth, 5e-5, rng)
    patch, report = fit_patch(X, mesh_faces=surf.faces)
    assert report.parameterization == "lscm"
    u, v, dist = patch.project(surf.vertices)
    ang = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", patch.normals(u, v), n_true), -1, 1)))
    assert np.percentile(ang, 95) < 0.5                       # normal side from the face winding
    assert np.sqrt(np.mean(dist**2)) < 3e-5


def test_normals_argument_sets_the_normal_side(rng):
    surf = doubly_curved_panel(size_x=0.2, size_y=0.16, spacing=6e-3)
    X = surf.vertices + rng.normal(0, 5e-5, surf.vertices.shape)
    up, _ = fit_patch(X)
    down, _ = fit_patch(X, normals=-surf.vertex_normals)
    centre = np.array([[0.0, 0.0, 0.0]])
    assert up.normals(*up.project(centre)[:2])[0, 2] > 0.99        # default: convex side
    assert down.normals(*down.project(centre)[:2])[0, 2] < -0.99
    assert down.curvature(*down.project(centre)[:2]).k1[0] < 0      # concave seen from below


def test_bidirectional_rows_are_handled():
    rng = np.random.default_rng(11)
    truth = panel_patch(size_x=0.2, size_y=0.16)
    scan = simulate_laser_scan(truth, row_spacing=4e-3, point_spacing=1e-3, rng=rng, bidirectional=True)
    assert np.linalg.norm(scan.points[scan.rows == 1][0] - scan.points[scan.rows == 0][-1]) < 0.02   # zig-zag
    patch, _ = fit_patch(scan.points, rows=scan.rows)
    ang, _, _, _ = _errors(truth, patch, scan, rng, n_width=10)
    assert np.percentile(ang, 95) < 0.5


def test_fixed_smoothing_is_used(rng):
    surf = flat_plate(size_x=0.2, size_y=0.1, spacing=5e-3)
    X = surf.vertices + rng.normal(0, 1e-4, surf.vertices.shape) * [0, 0, 1]
    heights = {}
    for ell in (0.005, 0.2):
        patch, report = fit_patch(X, smoothing=ell, n_ctrl=(8, 6))
        assert report.smoothing == (ell, ell) and patch.shape == (8, 6)
        g = np.meshgrid(np.linspace(*patch.domain[0], 9), np.linspace(*patch.domain[1], 9))
        heights[ell] = np.abs(patch.evaluate(*g)[:, 2]).max()
    assert heights[0.2] < 6e-5 < heights[0.005]             # long smoothing keeps the plate flat


# ----------------------------------------------------------------------------------------------
# Refusals
# ----------------------------------------------------------------------------------------------
def test_refuses_too_few_and_collinear_points(rng):
    with pytest.raises(InputError, match="too few points"):
        fit_patch(rng.normal(size=(10, 3)))
    line = np.outer(np.linspace(0, 1, 100), [1.0, 2.0, 3.0])
    with pytest.raises(InputError, match="collinear"):
        fit_patch(line)
    with pytest.raises(InputError, match=r"shape \(n, 3\)"):
        fit_patch(np.zeros((100, 2)))


def test_refuses_separate_pieces(rng):
    a = flat_plate(size_x=0.1, size_y=0.1, spacing=5e-3).vertices
    X = np.concatenate([a, a + [0.3, 0.0, 0.0]])
    with pytest.raises(InfeasibleError, match="2 separate pieces"):
        fit_patch(X)
    # A few stray specks are dropped rather than refused.
    patch, report = fit_patch(np.concatenate([a, [[1.0, 1.0, 1.0], [1.0, 1.0, 1.001]]]))
    assert report.n_dropped == 2 and report.n_points == len(a)


def test_refuses_a_projection_that_folds_over():
    rng = np.random.default_rng(3)
    scan = simulate_laser_scan(blade_patch(span=0.05), row_spacing=5e-3, point_spacing=2e-3, rng=rng)
    with pytest.raises(InfeasibleError, match="folds over"):
        fit_patch(scan.points, rows=scan.rows, parameterization="projection")
    with pytest.raises(InfeasibleError, match="mesh_faces .*rows="):       # auto, nothing else to go on
        fit_patch(scan.points)
    mesh = blade(span=0.05, max_spacing=8e-3)
    with pytest.raises(InfeasibleError, match="triangles flip over"):
        fit_patch(mesh.vertices, mesh_faces=mesh.faces, parameterization="projection")


def test_refuses_an_lscm_map_that_folds_over(monkeypatch):
    igl = pytest.importorskip("igl")
    mesh = flat_plate(size_x=0.1, size_y=0.1, spacing=1e-2)

    def folded(V, F, b, bc):
        uv = V[:, :2].copy()
        uv[55] = [0.02, 0.08]            # one vertex dragged across its neighbours
        return uv, None

    monkeypatch.setattr(igl, "lscm", folded)
    with pytest.raises(InfeasibleError, match="LSCM parameterisation folds over: [1-9][0-9]* of 200 triangles"):
        fit_patch(mesh.vertices, mesh_faces=mesh.faces, parameterization="lscm")


def test_refuses_closed_and_split_meshes():
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.1)
    with pytest.raises(InfeasibleError, match="closed"):
        fit_patch(sphere.vertices, mesh_faces=sphere.faces)
    a = flat_plate(size_x=0.1, size_y=0.1, spacing=1e-2)
    V = np.concatenate([a.vertices, a.vertices + [0.0, 0.0, 0.05]])
    F = np.concatenate([a.faces, a.faces + len(a.vertices)])
    with pytest.raises(InfeasibleError, match="2 separate pieces"):
        fit_patch(V, mesh_faces=F)


def test_refuses_bad_options(rng):
    X = flat_plate(size_x=0.1, size_y=0.1, spacing=1e-2).vertices
    with pytest.raises(InputError, match="parameterization must be one of"):
        fit_patch(X, parameterization="spherical")
    with pytest.raises(InputError, match="degree 3 to 5"):
        fit_patch(X, degree=2)
    with pytest.raises(InputError, match=r"q must lie in \[0, 1\]"):
        fit_patch(X, knot_curvature_weight=1.5)
    with pytest.raises(InputError, match="smoothing"):
        fit_patch(X, smoothing=-1.0)
    with pytest.raises(InputError, match="needs mesh_faces"):
        fit_patch(X, parameterization="lscm")
    with pytest.raises(InputError, match="needs the scan-row id"):
        fit_patch(X, parameterization="rows")


def test_refuses_rows_out_of_scan_order():
    rng = np.random.default_rng(4)
    scan = simulate_laser_scan(panel_patch(size_x=0.2, size_y=0.1), row_spacing=5e-3, point_spacing=2e-3, rng=rng)
    pts = scan.points.copy()
    first = np.nonzero(scan.rows == 3)[0]
    pts[first] = pts[first][rng.permutation(len(first))]
    with pytest.raises(InputError, match="scan row 3 jumps"):
        fit_patch(pts, rows=scan.rows)


# ----------------------------------------------------------------------------------------------
# Curvature-based knots R(s) = q b(s)/B + (1 - q) s/L
# ----------------------------------------------------------------------------------------------
def test_curvature_knots_follow_the_distribution():
    s = np.linspace(0.0, 1.0, 100001)
    assert np.allclose(curvature_knots(s, np.ones_like(s), 10, q=0.7), np.arange(1, 10) / 10)
    assert np.allclose(curvature_knots(s, 25 * np.exp(-s), 8, q=0.0), np.arange(1, 8) / 8)
    # κ² = K on [0, a) and 0 beyond: R(s) = q min(s, a)/a + (1 - q) s, inverted exactly.
    a, q = 0.2, 0.6
    kappa2 = np.where(s < a, 100.0, 0.0)
    knots = curvature_knots(s, kappa2, 5, q=q)
    targets = np.arange(1, 5) / 5
    slope_in = q / a + (1 - q)
    expected = np.where(targets < slope_in * a, targets / slope_in, (targets - q) / (1 - q))
    assert np.allclose(knots, expected, atol=1e-4)


def test_curvature_knots_respect_span_bounds():
    s = np.linspace(0.0, 1.0, 20001)
    kappa2 = np.exp(-(((s - 0.5) / 0.01) ** 2)) * 1e6             # a sharp bend in the middle
    free = curvature_knots(s, kappa2, 20, q=0.9)
    assert np.diff(free).min() < 0.005
    capped = curvature_knots(s, kappa2, 20, q=0.9, min_span=0.02)
    spans = np.diff(np.concatenate([[0.0], capped, [1.0]]))
    assert spans.min() >= 0.02 * 0.98 and spans.max() < 0.1
    # A bend with modest κ² but large turning still gets knots through the max_turn floor.
    kabs = np.where(np.abs(s - 0.5) < 0.1, 20.0, 0.0)            # turns 4 rad over [0.4, 0.6]
    floor = curvature_knots(s, np.zeros_like(s), 20, q=0.5, kappa_abs=kabs, max_turn=0.5)
    inside = np.diff(floor[(floor > 0.4) & (floor < 0.6)])
    assert inside.max() <= 0.5 / 20 * 1.05                      # spans turn by at most 0.5 rad
    assert np.allclose(curvature_knots(s, np.zeros_like(s), 20, q=0.5), np.arange(1, 20) / 20)


# ----------------------------------------------------------------------------------------------
# The scan simulator and the exact example patches
# ----------------------------------------------------------------------------------------------
def test_scan_spacing_noise_and_row_offsets():
    truth = nurbs_sphere(0.5, lat=(-0.3, 0.3), lon=(0.0, 0.6))
    rng = np.random.default_rng(5)
    scan = simulate_laser_scan(truth, row_spacing=4e-3, point_spacing=1e-3, sigma=2e-4, row_offset=0.0, rng=rng)
    dev = np.einsum("ij,ij->i", scan.points - scan.true_points, scan.true_normals)
    assert np.std(dev) == pytest.approx(2e-4, rel=0.05)
    assert np.allclose(scan.points - scan.true_points, dev[:, None] * scan.true_normals, atol=1e-15)
    assert np.allclose(np.linalg.norm(scan.true_points, axis=1), 0.5)
    along = np.linalg.norm(np.diff(scan.true_points[scan.rows == 10], axis=0), axis=1)
    assert along == pytest.approx(1e-3, rel=1e-3)
    # rows along u (meridians here, u runs over latitude): consecutive rows 4 mm apart
    r0, r1 = scan.true_points[scan.rows == 10], scan.true_points[scan.rows == 11]
    assert np.linalg.norm(r1.mean(0) - r0.mean(0)) == pytest.approx(4e-3, rel=0.02)
    shifted = simulate_laser_scan(truth, row_spacing=4e-3, point_spacing=1e-3, sigma=0.0, row_offset=2e-4,
                                  rng=np.random.default_rng(5))
    d = shifted.points - shifted.true_points
    per_row = np.array([d[shifted.rows == r].std(axis=0).max() for r in range(shifted.rows.max() + 1)])
    assert per_row.max() < 1e-15                                 # one rigid shift per row
    offsets = np.array([d[shifted.rows == r][0] for r in range(shifted.rows.max() + 1)])
    assert offsets.std() == pytest.approx(2e-4, rel=0.15)


def test_scan_is_reproducible_and_view_direction_culls():
    truth = blade_patch(span=0.03)
    a = simulate_laser_scan(truth, row_spacing=5e-3, point_spacing=2e-3, rng=42)
    b = simulate_laser_scan(truth, row_spacing=5e-3, point_spacing=2e-3, rng=42)
    assert np.array_equal(a.points, b.points)
    top = simulate_laser_scan(truth, row_spacing=5e-3, point_spacing=2e-3, rng=42, view_direction=[0, 0, -1])
    assert (top.true_normals[:, 2] > 0).all() and len(top) < len(a)


def test_scan_of_a_mesh_surface():
    surf = blade(span=0.05, max_spacing=4e-3)
    scan = simulate_laser_scan(surf, row_spacing=5e-3, point_spacing=1e-3, sigma=0.0, row_offset=0.0, rng=1,
                               across_direction=[0.0, 1.0, 0.0])
    _, dist, _ = surf.closest_points(scan.points)
    assert dist.max() < 1e-9
    ys = np.array([scan.points[scan.rows == r, 1].mean() for r in range(scan.rows.max() + 1)])
    assert np.allclose(np.diff(ys), 5e-3, rtol=1e-6) or np.allclose(np.diff(ys), -5e-3, rtol=1e-6)
    # Each row runs round the whole profile (wrapping the leading edge).
    row = scan.points[scan.rows == 2]
    assert row[:, 0].min() < 1e-3 and row[:, 2].min() < -0.02 and row[:, 2].max() > 0.02


def test_example_patches_match_the_example_meshes():
    mesh = blade()
    bp = blade_patch()
    u, v, d = bp.project(mesh.vertices)
    assert d.max() < 1e-6
    assert (np.einsum("ij,ij->i", bp.normals(u, v), mesh.vertex_normals) > 0.99).all()
    panel = doubly_curved_panel()
    pp = panel_patch()
    u, v, d = pp.project(panel.vertices)
    assert d.max() < 1e-12
    g = np.linspace(0.05, 0.95, 7)
    P = pp.evaluate(np.repeat(g, 7), np.tile(g, 7))
    z = np.sqrt(0.35**2 - P[:, 0] ** 2) - 0.35 + np.sqrt(0.9**2 - P[:, 1] ** 2) - 0.9
    assert np.allclose(P[:, 2], z, atol=1e-14)


def test_rows_fit_with_a_fixed_smoothing_length():
    # The numeric-smoothing path of the skinning (no cross-validation) fits as well as GCV here.
    from swath.examples.scansim import panel_patch, simulate_laser_scan
    from swath.scan.fit import fit_patch

    rng = np.random.default_rng(7)
    scan = simulate_laser_scan(panel_patch(), row_spacing=4e-3, point_spacing=2e-3, rng=rng)
    patch, report = fit_patch(scan.points, rows=scan.rows, parameterization="rows", smoothing=5e-3)
    _, _, dist = patch.project(scan.true_points[::50])
    assert report.rms < 3e-4
    assert np.percentile(dist, 95) < 3e-4


# ----------------------------------------------------------------------------------------------
# Trimming a fitted patch to its footprint (swath fit / plan --fit)
# ----------------------------------------------------------------------------------------------
def _rect_footprint(patch, cell):
    """A footprint as scan_footprint lays it out: the domain ends on cell edges, one cell of
    margin, every cell over the domain occupied."""
    from swath.surface.footprint import Footprint

    lo = patch.domain[:, 0]
    n = np.ceil((patch.domain[:, 1] - lo) / cell).astype(int) + 2
    return Footprint(lo - cell, cell, np.ones(n, dtype=bool)), n


def test_footprint_cells_are_closed_on_their_edges():
    from swath.surface.footprint import Footprint

    mask = np.zeros((3, 3), dtype=bool)
    mask[1, 1] = True
    fp = Footprint(np.array([0.0, 0.0]), 0.1, mask)
    # on the edge between an empty and the occupied cell (as computed, not exactly): in
    edge = 0.1 * 3 / 3
    assert fp.contains(np.array([edge, 0.15, 0.2 + 1e-12, 0.05]), np.array([0.15, edge, 0.15, 0.15])).tolist() == \
        [True, True, True, False]


def test_trimmed_triangulation_changes_only_locally_when_an_edge_cell_comes_or_goes():
    # The same scan read in m and in mm fits to patches a few nm apart, whose footprints can differ
    # by a cell at the rim; the trimmed surface (and so the plan) must not change by a whole row.
    from swath.surface.footprint import Footprint, patch_surface

    patch = panel_patch(size_x=0.2, size_y=0.15)
    fp, n = _rect_footprint(patch, 2.2e-3)
    base, _ = patch_surface(patch, spacing=2e-3, footprint=fp)
    inner = np.zeros_like(fp.mask)
    inner[3:-3, 3:-3] = True           # a scan that stops short of the domain, with a ragged rim
    fp = Footprint(fp.origin, fp.cell, inner)
    base, _ = patch_surface(patch, spacing=2e-3, footprint=fp)
    for extra in ((2, n[1] // 2), (n[0] // 2, 2), (n[0] - 3, n[1] // 3)):
        mask = fp.mask.copy()
        mask[extra] = True             # one more cell at the rim, beyond the occupied box
        other, _ = patch_surface(patch, spacing=2e-3, footprint=Footprint(fp.origin, fp.cell, mask))
        assert abs(other.area - base.area) < 2e-3 * base.area
        assert 0 <= len(other.vertices) - len(base.vertices) <= 2


# ----------------------------------------------------------------------------------------------
# Warnings beyond the fit tolerance, and progress
# ----------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def small_scan():
    return simulate_laser_scan(panel_patch(size_x=0.2, size_y=0.15), row_spacing=4e-3, point_spacing=2e-3,
                               rng=np.random.default_rng(3))


def test_fit_warns_when_points_lie_beyond_the_tolerance(small_scan, caplog):
    from swath.scan.fit import FIT_TOLERANCE

    # σ = 0.1 mm noise and 0.2 mm row offsets: within the default 1 mm, not within 0.25 mm
    patch, report = fit_patch(small_scan.points, parameterization="projection")
    assert report.warnings == () and report.tolerance == FIT_TOLERANCE == 1e-3
    caplog.clear()
    patch, report = fit_patch(small_scan.points, parameterization="projection", tolerance=2.5e-4)
    _, _, dist = patch.project(small_scan.points)
    n_far = int((dist > 2.5e-4).sum())
    assert 0 < n_far < len(dist) // 4
    assert len(report.warnings) == 1
    assert report.warnings[0].startswith(f"{n_far} of {len(dist)} points") and "0.25 mm" in report.warnings[0]
    assert f"up to {dist.max() * 1e3:.3g} mm" in report.warnings[0]
    logged = [r for r in caplog.records if r.levelname == "WARNING" and "fit tolerance" in r.getMessage()]
    assert len(logged) == 1
    assert report.to_dict()["warnings"] == list(report.warnings) and report.to_dict()["tolerance_m"] == 2.5e-4
    with pytest.raises(InputError, match="tolerance must be a positive length"):
        fit_patch(small_scan.points, tolerance=0.0)


def test_residual_warning_rule():
    from swath.scan.fit import _residual_warnings

    tol = 1e-3
    assert _residual_warnings(np.r_[np.full(999, 5e-4), 2e-3], tol) == []       # 0.1 % just beyond
    assert len(_residual_warnings(np.r_[np.full(999, 5e-4), 6e-3], tol)) == 1   # one point 6x beyond
    warned = _residual_warnings(np.r_[np.full(990, 5e-4), np.full(10, 2e-3)], tol)  # 1 % beyond
    assert len(warned) == 1 and warned[0].startswith("10 of 1000 points (1 %) lie more than 1 mm")


@pytest.mark.parametrize("how", ["rows", "projection"])
def test_fit_reports_progress_at_every_stage(small_scan, how):
    calls = []
    kwargs = {"rows": small_scan.rows} if how == "rows" else {"parameterization": "projection"}
    fit_patch(small_scan.points, progress=lambda *call: calls.append(call), **kwargs)
    assert all(isinstance(s, str) and s.startswith("fit: ") and 0 <= d <= t and t >= 1 for s, d, t in calls)
    stages = list(dict.fromkeys(s for s, _, _ in calls))
    assert stages[0] == "fit: checking the points" and stages[-1] == "fit: done" and calls[-1] == ("fit: done", 1, 1)
    assert "fit: measuring the distances of the points to the patch" in stages
    if how == "projection":
        assert stages[1].startswith("fit: parameterising the points")
        assert "fit: pilot fits that place the knots by curvature" in stages
    else:
        assert "fit: skinning the scan rows (pilot fits that place the knots)" in stages
    # the smoothing search counts every length it tries, up to its total
    gcv = [(d, t) for s, d, t in calls if s == "fit: choosing the smoothing by cross-validation"]
    assert len(gcv) > 10 and [d for d, _ in gcv] == sorted(d for d, _ in gcv) and gcv[-1][0] <= gcv[-1][1]


def test_swath_fit_writes_its_warnings_and_reports_every_stage(small_scan, tmp_path):
    from swath.cli.fitjob import FitSettings, run_fit

    np.savetxt(tmp_path / "scan.xyz", small_scan.points)
    calls = []
    doc = run_fit(FitSettings(scan=str(tmp_path / "scan.xyz"), out=str(tmp_path / "o"), tolerance=2.5e-4),
                  progress=lambda *call: calls.append(call))
    saved = json.loads((tmp_path / "o" / "fit.json").read_text())
    assert saved["warnings"] == doc["warnings"] and len(doc["warnings"]) == 1
    assert "fit tolerance" in doc["warnings"][0] and doc["figures"]["fit_tolerance_m"] == 2.5e-4
    assert "<b>Warnings</b>" in (tmp_path / "o" / "fit.html").read_text()
    stages = list(dict.fromkeys(s for s, _, _ in calls))
    for stage in ("loading scan", "fit: checking the points", "fit: done", "measuring residuals",
                  "finding the scanned area (footprint)", "writing fit report", "done"):
        assert stage in stages
    doc = run_fit(FitSettings(scan=str(tmp_path / "scan.xyz"), out=str(tmp_path / "o2")))
    assert doc["warnings"] == [] and "<b>Warnings</b>" not in (tmp_path / "o2" / "fit.html").read_text()
