"""Removal samples (swath.simulate.samples): spacing in both directions, exact areas, and the
simulation on them against the analytic Preston profile and against the subdivided-mesh samples."""

import numpy as np
import pytest

import swath.simulate.removal as removal_module
from shapes import sliver_plate, sphere_cap
from swath.contact import Tool
from swath.errors import InputError
from swath.examples import flat_plate
from swath.plan import Pass, ToolPath
from swath.simulate import simulate_removal
from swath.simulate.samples import count_removal_samples, removal_samples
from swath.surface import Surface
from swath.trajectory import FeedLimit, time_path


def test_a_sliver_gets_one_row_of_samples_at_the_spacing():
    v = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.03, 0.001, 0.0]])
    s = removal_samples(Surface(v, [[0, 1, 2]]), 0.002)
    assert len(s) == 50 == count_removal_samples(Surface(v, [[0, 1, 2]]), 0.002)
    x = np.sort(s.vertices[:, 0])
    assert np.allclose(np.diff(x), 0.002)                           # 50 equal columns along the 100 mm edge
    assert s.area == pytest.approx(0.5 * 0.1 * 0.001, rel=1e-12)
    # every sample inside the triangle, normals the face's
    assert np.all(s.vertices[:, 1] > 0) and np.all(s.vertices[:, 1] < 0.001)
    assert np.allclose(s.normals, [0.0, 0.0, 1.0])


def test_large_triangle_is_covered_at_the_spacing_and_areas_are_exact():
    v = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.02, 0.05, 0.0]])
    part = Surface(v, [[0, 1, 2]])
    spacing = 0.004
    s = removal_samples(part, spacing)
    assert s.area == pytest.approx(part.area, rel=1e-12)
    # about one sample per spacing² (plus half a row per column at the slanted sides)
    assert part.area / spacing**2 < len(s) < 1.35 * part.area / spacing**2
    # any point of the triangle is within about a spacing / √2 of a sample
    rng = np.random.default_rng(3)
    a, b = rng.random((2, 20000))
    flip = a + b > 1
    a[flip], b[flip] = 1 - a[flip], 1 - b[flip]
    pts = v[0] + a[:, None] * (v[1] - v[0]) + b[:, None] * (v[2] - v[0])
    gap = s.kdtree.query(pts)[0].max()
    # (cells are at most a spacing wide and high; the slanted column tops add a little to s / √2)
    assert spacing / 2 < gap <= 0.9 * spacing
    # the display triangles lie on the part, wound as it
    assert s.faces.min() >= 0 and s.faces.max() < len(s)
    assert np.all(s.face_normals[:, 2] > 0.99)


def test_a_mesh_at_the_spacing_keeps_its_vertices():
    part = flat_plate(spacing=4e-3)
    s = removal_samples(part, 4e-3)
    assert np.array_equal(s.vertices, part.vertices)
    assert np.allclose(s.vertex_areas, part.vertex_areas, rtol=1e-12)
    assert np.array_equal(s.normals, part.normals)
    assert np.array_equal(s.faces, part.faces)


def test_slivers_get_one_row_each_and_no_more():
    part = sliver_plate()                                            # 200 strips 1.5 mm wide, 400 mm long
    spacing = 3e-3
    lattice = removal_samples(part, spacing)
    # each of the 400 triangles: one row of ceil(diagonal / spacing) samples
    assert len(lattice) == 400 * int(np.ceil(np.hypot(0.4, 1.5e-3) / spacing))
    assert len(lattice) <= len(part.subdivided(spacing).vertices)
    assert lattice.area == pytest.approx(part.area, rel=1e-12)


def one_pass(y, x0=0.0, x1=0.4):
    return Pass(np.array([[x0, y, 0.0], [x1, y, 0.0]]), np.array([[0, 0, 1.0]] * 2))


def test_preston_profile_on_a_plate_of_slivers():
    tool = Tool()
    s = sliver_plate()
    feed = 0.05
    tr = time_path(ToolPath(s, [one_pass(0.15)], "test"), [FeedLimit(feed)])
    rm = simulate_removal(tr, s, tool, sample_spacing=2e-3, sampling="lattice")
    assert rm.metrics["removal_sample_spacing_m"] == 2e-3
    v = rm.surface.vertices
    mid = np.abs(v[:, 0] - 0.2) < 0.05
    y = np.abs(v[mid, 1] - 0.15)
    # (within 0.8 R: nearer the rim the chord holds few integration poses, 2 mm apart, and the
    # depth of a sample depends on where it sits between them)
    inside = y < 0.8 * tool.pad_radius
    expected = tool.preston * tool.k * tool.flat_depression * tool.relative_speed(0.0) \
        * 2 * np.sqrt(tool.pad_radius**2 - y[inside] ** 2) / feed
    assert np.allclose(rm.depth[mid][inside], expected, rtol=0.04)
    assert np.all(rm.depth[mid][y > tool.pad_radius + 1e-3] == 0)


def raster(surface, ys):
    ps = [one_pass(y) for y in ys]
    ps = [p if i % 2 == 0 else p.reversed() for i, p in enumerate(ps)]
    return time_path(ToolPath(surface, ps, "test"), [FeedLimit(0.05)])


def test_lattice_metrics_converge_to_the_fine_mesh_ones():
    s = flat_plate(spacing=0.01)                                     # 10 mm grid: both samplings refine it
    tr = raster(s, np.linspace(0.04, 0.26, 5))                       # passes 55 mm apart: a strong ripple
    fine = simulate_removal(tr, s, Tool(), sample_spacing=1e-3, sampling="mesh").metrics
    for spacing in (2e-3, 3e-3):
        lat = simulate_removal(tr, s, Tool(), sample_spacing=spacing, sampling="lattice").metrics
        mesh = simulate_removal(tr, s, Tool(), sample_spacing=spacing, sampling="mesh").metrics
        assert lat["surface_area_m2"] == pytest.approx(fine["surface_area_m2"], rel=1e-12)
        assert lat["n_removal_samples"] < 0.5 * mesh["n_removal_samples"]
        # measured, lattice (mesh) against the 1 mm mesh: CoV -0.7 % (+2.2 %) at 3 mm, -1.6 % (+0.1 %)
        # at 2 mm; median -1.1 % (-1.4 %) and +1.1 % (+1.1 %); coverage and mean within 0.2 %
        for key, tol in [("coverage_fraction", 3e-3), ("removal_mean_m", 3e-3), ("removal_median_m", 1.5e-2),
                         ("removal_cov", 2e-2), ("removal_p95_m", 1.5e-2), ("efficiency", 3e-3)]:
            assert lat[key] == pytest.approx(fine[key], rel=tol), (key, spacing)


def test_sphere_cap_depth_agrees_between_samplings():
    s = sphere_cap(0.2, 0.5, n=24)                                   # edges about 9 mm
    x = np.linspace(-0.07, 0.07, 60)
    passes = []
    for y in (-0.02, 0.02):
        d = np.stack([x, np.full_like(x, y), np.sqrt(0.2**2 - x**2 - y**2)], 1)
        passes.append(Pass(d, d / np.linalg.norm(d, axis=1, keepdims=True)))
    tr = time_path(ToolPath(s, passes, "test"), [FeedLimit(0.05)])
    lat = simulate_removal(tr, s, Tool(), sample_spacing=2e-3, sampling="lattice")
    mesh = simulate_removal(tr, s, Tool(), sample_spacing=2e-3, sampling="mesh")
    # the samples lie on the facets, within the chord sag of the sphere
    r = np.linalg.norm(lat.surface.vertices, axis=1)
    assert np.all(r <= 0.2 + 1e-12) and np.all(r > 0.2 - 1e-4)
    for key, tol in [("covered_area_m2", 1e-2), ("removal_mean_m", 1e-2), ("removal_max_m", 3e-2),
                     ("removal_cov", 3e-2)]:
        assert lat.metrics[key] == pytest.approx(mesh.metrics[key], rel=tol), key
    # depth at the lattice samples equals the mesh depth interpolated there (nearest mesh vertex)
    near = mesh.surface.kdtree.query(lat.surface.vertices)[1]
    centre = np.linalg.norm(lat.surface.vertices[:, :2], axis=1) < 0.04
    assert np.allclose(lat.depth[centre], mesh.depth[near][centre], rtol=0.05, atol=0.03 * mesh.depth.max())


def test_the_cap_widens_the_spacing_before_sampling(monkeypatch):
    s = flat_plate(spacing=0.01)
    tr = raster(s, [0.15])
    n = count_removal_samples(s, 2e-3)
    monkeypatch.setattr(removal_module, "MAX_REMOVAL_SAMPLES", n // 2)
    rm = simulate_removal(tr, s, Tool(), sample_spacing=2e-3, sampling="lattice")
    assert len(rm.depth) <= n // 2 and rm.metrics["removal_sample_spacing_m"] > 2e-3


def test_bad_sampling_and_spacing_are_refused():
    s = flat_plate(spacing=0.01)
    tr = raster(s, [0.15])
    with pytest.raises(InputError, match="sampling must be one of"):
        simulate_removal(tr, s, Tool(), sampling="random")
    with pytest.raises(InputError, match="positive length"):
        removal_samples(s, 0.0)


def test_engines_agree_and_the_report_draws_lattice_samples():
    from swath.report.html import display_mesh
    from swath.report.plots import depth_histogram_figure, removal_map_figure

    s = flat_plate(spacing=0.01)
    tr = raster(s, np.linspace(0.04, 0.26, 3))
    compiled = simulate_removal(tr, s, Tool(), sample_spacing=3e-3, sampling="lattice", engine="compiled")
    numpy_ = simulate_removal(tr, s, Tool(), sample_spacing=3e-3, sampling="lattice", engine="numpy")
    assert np.abs(compiled.depth - numpy_.depth).max() <= 1e-4 * numpy_.depth.max()
    assert compiled.metrics["removal_cov"] == pytest.approx(numpy_.metrics["removal_cov"], rel=5e-5)
    # drawn on the part's own mesh (its vertices first, split within the budget), depth read off the samples
    v, f, d = display_mesh(s, compiled, max_faces=2 * len(s.faces))
    assert np.array_equal(v[:len(s.vertices)], s.vertices) and len(f) <= 2 * len(s.faces)
    assert d.max() == pytest.approx(compiled.depth.max(), rel=0.2)
    assert len(removal_map_figure(compiled).axes) >= 1 and len(depth_histogram_figure(compiled).axes) == 1


def test_samples_pickle_before_and_after_drawing():
    import pickle

    v = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.02, 0.05, 0.0], [0.1, 0.05, 0.0]])
    s = removal_samples(Surface(v, [[0, 1, 2], [1, 3, 2]]), 0.004)
    again = pickle.loads(pickle.dumps(s))
    assert np.array_equal(again.faces, s.faces) and np.array_equal(again.vertices, s.vertices)
    assert len(s.faces) > len(s) and s.faces.max() < len(s)


# --- depth read off the samples (the report's picture), and the samplings on built-in parts ---------
def test_depth_at_reproduces_constant_and_linear_depth_and_keeps_the_skins_apart():
    from swath.simulate.samples import interpolate_depth

    part = sliver_plate()                                            # samples on slivers: one row each
    s = removal_samples(part, 3e-3)
    rng = np.random.default_rng(7)
    pts = np.column_stack([rng.uniform(0.02, 0.38, 500), rng.uniform(0.02, 0.28, 500), np.zeros(500)])
    assert np.allclose(s.depth_at(pts, np.full(len(s), 2e-6)), 2e-6, rtol=1e-12)
    # a linear field is read back within a fraction of its change over one spacing (the tent averages
    # over a disc of 1.5 spacings; the rows of a sliver are uneven across it)
    slope = 1e-4                                                     # m of depth per m along y
    got = s.depth_at(pts, slope * s.vertices[:, 1])
    assert np.abs(got - slope * pts[:, 1]).max() < 0.5 * slope * 3e-3
    # two skins 1 mm apart (a thin part's two sides): with normals, each reads its own side only
    top = np.column_stack([s.vertices[:, :2], np.full(len(s), 5e-4)])
    both = np.concatenate([s.vertices, top])
    normals = np.concatenate([np.tile([0.0, 0.0, -1.0], (len(s), 1)), np.tile([0.0, 0.0, 1.0], (len(s), 1))])
    depth = np.concatenate([np.zeros(len(s)), np.full(len(s), 3e-6)])
    areas = np.concatenate([s.vertex_areas, s.vertex_areas])
    up = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    assert np.allclose(interpolate_depth(both, normals, areas, depth, pts + [0, 0, 5e-4], normals=up, radius=4.5e-3),
                       3e-6)
    assert np.allclose(interpolate_depth(both, normals, areas, depth, pts, normals=-up, radius=4.5e-3), 0.0)
    with pytest.raises(InputError, match="one value per sample"):
        s.depth_at(pts, np.zeros(3))


@pytest.mark.parametrize("name", ["panel", "blade"])
def test_lattice_and_mesh_metrics_agree_on_built_in_parts(name):
    """The job's default sampling (lattice) against the subdivided mesh, 3 mm, default raster.

    Measured (lattice against mesh): panel CoV -0.31 %, median +0.19 %, p95 -0.17 %, coverage both
    100 %; blade CoV +0.64 %, coverage 99.99 % against 99.84 %, mean -0.14 %."""
    from swath.examples import example_part
    from swath.order import order_toolpath
    from swath.plan.raster import raster as plan_raster

    part = example_part(name)
    tr = time_path(order_toolpath(plan_raster(part, Tool(), point_spacing=2e-3)), [FeedLimit(0.05)])
    lat = simulate_removal(tr, part, Tool(), sample_spacing=3e-3, sampling="lattice").metrics
    mesh = simulate_removal(tr, part, Tool(), sample_spacing=3e-3, sampling="mesh").metrics
    assert lat["n_removal_samples"] < mesh["n_removal_samples"]
    assert lat["surface_area_m2"] == pytest.approx(mesh["surface_area_m2"], rel=1e-9)
    assert lat["coverage_fraction"] == pytest.approx(mesh["coverage_fraction"], abs=2.5e-3)
    for key, tol in [("removal_mean_m", 5e-3), ("removal_median_m", 1e-2), ("removal_p95_m", 1e-2),
                     ("removal_cov", 1.5e-2), ("efficiency", 1e-2)]:
        assert lat[key] == pytest.approx(mesh[key], rel=tol), key
