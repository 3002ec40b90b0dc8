"""Equidistant (geodesic-parallel) passes: level sets of a distance field on meshes, arc-length
coordinates on B-spline patches (swath.plan.equidistant, swath.plan.arclength)."""

import functools
import math
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial import cKDTree

from conftest import SHARED_MESH_UNITS, shared_mesh
from swath.contact import Tool
from swath.errors import InfeasibleError, InputError
from swath.examples import blade, doubly_curved_panel, flat_plate
from swath.order import order_toolpath
from swath.plan.arclength import equidistant_patch
from swath.plan.arclength_map import ArcLengthMap
from swath.plan.equidistant import equidistant as plan_equidistant
from swath.plan.raster import raster
from swath.plan.seeds import boundary_seed
from swath.plan.spacing_check import pass_levels, pass_spacing
from swath.surface import Surface
from swath.surface.bspline import BSplinePatch
from swath.surface.bspline_basis import clamped_knots
from swath.surface.exact_shapes import nurbs_cylinder
from swath.surface.geodesic import distance_field, locate_points, refine_mesh
from swath.surface.topology import mesh_edges, split_nonmanifold_vertices


def equidistant(*args, **kwargs):
    """The equidistant planner followed by the order stage at the planner's own order."""
    return order_toolpath(plan_equidistant(*args, **kwargs))

TOOL = Tool()                     # R = 38.1 mm
R = TOOL.pad_radius


@functools.cache
def panel() -> Surface:
    """One panel for every test, so the planner's per-surface field cache is shared."""
    return doubly_curved_panel()


@functools.cache
def load_shared(name: str) -> Surface:
    from swath.io.mesh import load_mesh

    return load_mesh(shared_mesh(name), units=SHARED_MESH_UNITS[name])


def check_on_surface(surface, tp, point_spacing, *, max_checked=8000):
    """Every (strided) point within 0.1 mm of the surface, its normal within 1° of the smooth normal
    there (barycentric in the original face), steps <= point_spacing.  The distance is to the
    nearest of the 32 faces whose centroids are nearest (an upper bound of the distance to the
    mesh) on a copy with long edges split, found without trimesh's R-tree, whose set-up costs
    seconds on the dense scans."""
    pts = np.concatenate([p.points for p in tp.passes])
    nrm = np.concatenate([p.normals for p in tp.passes])
    assert np.isfinite(pts).all() and np.allclose(np.linalg.norm(nrm, axis=1), 1.0)
    stride = max(1, math.ceil(len(pts) / max_checked))
    pts, nrm = pts[::stride], nrm[::stride]
    # The same surface with no edge over 20 mm (slivers split), carrying the smooth normals.
    V, F, N, _ = refine_mesh(surface.vertices, surface.faces, 0.02, values=surface.normals)
    face, bary, dist = locate_points(V, F, pts, candidates=32)
    assert dist.max() <= 1e-4
    smooth = np.einsum("ij,ijk->ik", bary, N[F[face]])
    smooth /= np.linalg.norm(smooth, axis=1, keepdims=True)
    angle = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", nrm, smooth), -1.0, 1.0)))
    assert angle.max() <= 1.0
    for p in tp.passes:
        assert np.linalg.norm(np.diff(p.points, axis=0), axis=1).max() <= point_spacing * 1.01


# ----------------------------------------------------------------------------------------------
# exact spacing measurements on the two curved example parts
# ----------------------------------------------------------------------------------------------
def blade_gaps(tp):
    """Exact geodesic gaps on the blade: it is an extrusion, so it unrolls onto the plane
    (profile arc length, span) and the geodesic distance from a point to the next level's passes
    is a plane distance.  Pass points are located on the mesh and their arc length interpolated
    in their face (the polyhedral blade unrolls exactly)."""
    s = tp.surface
    nv = len(np.unique(s.vertices[:, 1].round(12)))
    prof = s.vertices.reshape(-1, nv, 3)[:, 0, [0, 2]]
    arc = np.repeat(np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(prof, axis=0), axis=1))]), nv)
    flat = []
    for p in tp.passes:
        f, b, _ = locate_points(s.vertices, s.faces, p.points)
        flat.append(np.stack([np.einsum("ij,ij->i", arc[s.faces[f]], b), p.points[:, 1]], axis=1))
    _, levels = pass_levels(tp)
    gaps = []
    for lv in sorted(set(levels.tolist())):
        nxt = [flat[i] for i in np.flatnonzero(levels == lv + 1)]
        if nxt:
            here = np.concatenate([flat[i] for i in np.flatnonzero(levels == lv)])
            gaps.append(cKDTree(np.concatenate(nxt)).query(here)[0])
    return np.concatenate(gaps)


RX, RY = 0.35, 0.9          # doubly_curved_panel radii


def _panel_derivatives(x, y):
    sx, sy = np.sqrt(RX ** 2 - x ** 2), np.sqrt(RY ** 2 - y ** 2)
    return -x / sx, -y / sy, -RX ** 2 / sx ** 3, -RY ** 2 / sy ** 3


def regular_levels(tp):
    """The plan without the level pulled in to the far edge (single-piece plans)."""
    last = tp.metadata["n_levels"] - tp.metadata["pulled_in_levels"]
    return SimpleNamespace(passes=[p for p, k in zip(tp.passes, tp.levels.tolist()) if k < last])


def panel_gaps(tp, step=2.5e-4):
    """Geodesic gaps on the panel z = f(x) + g(y), measured on the analytic surface: from every
    point of a pass (passes run along x, ordered by y) the geodesic leaving it at right angles
    toward the previous pass is integrated (RK4 in arc length, Christoffel symbols of the graph)
    until it crosses that pass; its length is the gap."""
    P = sorted((p.points for p in tp.passes), key=lambda q: q[:, 1].mean())
    out = []
    for a, b in zip(P[:-1], P[1:]):
        fx, fy, _, _ = _panel_derivatives(b[:, 0], b[:, 1])
        n = np.stack([-fx, -fy, np.ones_like(fx)], 1)
        d = np.cross(n, np.gradient(b, axis=0))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        d[d[:, 1] > 0] *= -1
        q = np.stack([b[:, 0], b[:, 1], d[:, 0], d[:, 1]], 1)
        order = np.argsort(a[:, 0])
        ax, ay = a[order, 0], a[order, 1]

        def rhs(q):
            x, y, u, v = q.T
            fx, fy, fxx, fyy = _panel_derivatives(x, y)
            acc = (fxx * u * u + fyy * v * v) / (1 + fx * fx + fy * fy)
            return np.stack([u, v, -fx * acc, -fy * acc], 1)

        side0 = q[:, 1] - np.interp(q[:, 0], ax, ay)
        gap = np.full(len(q), np.nan)
        s = 0.0
        while np.isnan(gap).any() and s < 0.3:
            k1 = rhs(q)
            k2 = rhs(q + 0.5 * step * k1)
            k3 = rhs(q + 0.5 * step * k2)
            k4 = rhs(q + step * k3)
            qn = q + step / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            side = qn[:, 1] - np.interp(qn[:, 0], ax, ay)
            hit = np.isnan(gap) & (np.sign(side) != np.sign(side0))
            gap[hit] = s + step * side0[hit] / (side0[hit] - side[hit])
            q, side0, s = qn, side, s + step
        out.append(gap)
    g = np.concatenate(out)
    assert np.isfinite(g).all()
    return g


def spread(g):
    return float(np.ptp(g) / np.mean(g))


# ----------------------------------------------------------------------------------------------
# mesh helpers
# ----------------------------------------------------------------------------------------------
def test_refinement_is_conforming_and_keeps_the_surface(rng):
    # Long thin triangles like crs_part_5's: a 1 m x 2 cm strip split into 4 slivers.
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 0.02, 0.1], [0, 0.02, 0.1], [0.5, 0.01, 0.05]], float)
    f = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
    values = v @ np.array([1.0, -2.0, 3.0])                       # a linear function of position
    V, F, vals, parent = refine_mesh(v, f, 0.01, values=values[:, None])
    e, fe = mesh_edges(F)
    assert np.linalg.norm(V[e[:, 0]] - V[e[:, 1]], axis=1).max() <= 0.01
    counts = np.bincount(fe.ravel(), minlength=len(e))
    assert counts.max() == 2                                       # manifold
    boundary = e[counts == 1]
    # no cracks: the boundary has the original perimeter
    perim = np.linalg.norm(V[boundary[:, 0]] - V[boundary[:, 1]], axis=1).sum()
    assert perim == pytest.approx(2 * (1 + math.hypot(0.02, 0.1)), rel=1e-12)
    s0, s1 = Surface(v, f), Surface(V, F)
    assert s1.area == pytest.approx(s0.area, rel=1e-12)
    assert np.allclose(s1.face_normals, s0.face_normals[parent], atol=1e-9)     # same winding
    assert np.allclose(vals[:, 0], V @ np.array([1.0, -2.0, 3.0]), atol=1e-12)  # values interpolated


def test_bow_tie_vertices_are_split_so_fast_marching_accepts_them():
    # A 4 x 4-cell grid (10 mm cells) without cells (1, 2) and (2, 1): cells (1, 1) and (2, 2)
    # touch only at grid vertex (2, 2), a bow-tie; the sheet stays connected round the outside.
    from swath.examples import grid_faces

    n = 5
    x = np.arange(n) * 0.01
    X, Y = np.meshgrid(x, x, indexing="ij")
    v = np.stack([X.ravel(), Y.ravel(), np.zeros(n * n)], 1)
    f = grid_faces(n, n)
    cell = np.tile(np.arange((n - 1) ** 2), 2)                     # grid_faces: two triangles per cell
    f = f[(cell != 1 * (n - 1) + 2) & (cell != 2 * (n - 1) + 1)]
    pinch = 2 * n + 2
    assert distance_field(v, f, source_vertices=[0], method="fmm")[1] == "heat"     # refused, fell back
    F, src = split_nonmanifold_vertices(f)
    assert len(src) == n * n + 1 and np.bincount(src)[pinch] == 2
    assert np.array_equal(src[F], f)
    d, method = distance_field(v[src], F, source_vertices=[0], method="fmm")
    assert method == "fmm" and np.isfinite(d).all()
    far = int(np.flatnonzero(src == n * n - 1)[0])                    # corner (4, 4), behind the pinch
    assert d[far] > math.sqrt(2) * 0.04 + 1e-3                         # the diagonal through it is cut


def test_locate_points_finds_the_face_and_barycentrics(rng):
    s = doubly_curved_panel(spacing=0.02)
    face = rng.integers(0, len(s.faces), 200)
    bary = rng.dirichlet(np.ones(3), 200)
    pts = np.einsum("ij,ijk->ik", bary, s.vertices[s.faces[face]])
    f, b, d = locate_points(s.vertices, s.faces, pts)
    assert d.max() < 1e-12
    assert np.allclose(np.einsum("ij,ijk->ik", b, s.vertices[s.faces[f]]), pts, atol=1e-12)


def test_default_seed_is_the_low_side_of_the_boundary_up_to_its_corners():
    s = doubly_curved_panel()
    loop = s.boundary_loops[0]
    run = boundary_seed(s.vertices, loop, np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), window=R)
    assert np.allclose(s.vertices[run, 1], -0.2)
    assert s.vertices[run, 0].min() == pytest.approx(-0.25) and s.vertices[run, 0].max() == pytest.approx(0.25)
    assert np.all(np.abs(np.diff(s.vertices[run, 0])) < 0.0041)   # consecutive along the edge


# ----------------------------------------------------------------------------------------------
# exact answers on the built-in parts
# ----------------------------------------------------------------------------------------------
def test_flat_plate_passes_are_straight_and_exactly_spacing_apart():
    s = flat_plate()                                               # 0.4 x 0.3 m
    tp = equidistant(s, TOOL, spacing=0.05)
    m = tp.metadata
    assert tp.planner == "equidistant" and m["n_passes"] == 6 == len(tp.passes)
    ys = [p.points[:, 1] for p in tp.passes]
    assert [float(np.ptp(y)) for y in ys] == pytest.approx([0.0] * 6, abs=1e-12)            # straight
    assert [float(y[0]) for y in ys] == pytest.approx(0.025 + 0.05 * np.arange(6), abs=1e-12)
    for p, sign in zip(tp.passes, [1, -1] * 3):                    # snake order, whole width
        assert sign * (p.points[-1, 0] - p.points[0, 0]) == pytest.approx(0.4, abs=1e-12)
    assert m["first_offset_m"] == 0.025 and m["far_margin_m"] == pytest.approx(0.025, abs=1e-9)
    assert m["seed"] == "boundary" and m["seed_length_m"] == pytest.approx(0.4)
    # default spacing: the whole pad diameter on a flat plate, evened out over the 0.3 m width
    # (4 levels 75 mm apart, the first and last half a spacing from the edges)
    m = equidistant(s, TOOL).metadata
    assert m["spacing_m"] == pytest.approx(0.075, rel=1e-9) and m["n_levels"] == 4
    assert m["far_margin_m"] == pytest.approx(0.0375, rel=1e-9) and m["direction_rule"].startswith("auto")
    check_on_surface(s, tp, 1e-3)


def test_given_spacing_pulls_the_last_pass_in_to_cover_the_far_edge():
    s = flat_plate()                                               # 0.3 m across the feed
    m0 = equidistant(s, TOOL, spacing=0.05).metadata               # 6 x 50 mm fits exactly
    assert m0["pulled_in_levels"] == 0 and m0["n_levels"] == 6
    tp = equidistant(s, TOOL, spacing=0.07)                        # 4 x 70 mm leaves 55 mm beyond the last level
    m = tp.metadata
    ys = sorted(float(p.points[0, 1]) for p in tp.passes)
    assert m["pulled_in_levels"] == 1 and m["n_levels"] == 5 == len(tp.passes)
    assert ys == pytest.approx([0.035, 0.105, 0.175, 0.245, 0.265], abs=1e-9)
    assert m["far_margin_m"] == pytest.approx(0.035, abs=1e-9) and m["spacing_m"] == 0.07


def test_seed_polyline_gives_passes_on_both_sides_at_exact_offsets():
    s = flat_plate()
    seed = np.array([[0.1234, -0.01, 0.0], [0.1234, 0.31, 0.0]])  # a line across the plate, partly off it
    with pytest.raises(InputError, match="from the surface"):
        equidistant(s, TOOL, spacing=0.04, seed=seed)
    seed[:, 1] = [0.0, 0.3]
    tp = equidistant(s, TOOL, spacing=0.04, seed=seed)
    xs = sorted(float(np.mean(p.points[:, 0])) for p in tp.passes)
    expected = sorted(0.1234 + k * 0.04 * sgn for k in (0.5, 1.5, 2.5, 3.5, 4.5, 5.5, 6.5)
                      for sgn in (-1, 1) if 0 < 0.1234 + k * 0.04 * sgn < 0.4)
    assert xs == pytest.approx(expected, abs=1e-6)
    assert all(float(np.ptp(p.points[:, 0])) < 1e-6 for p in tp.passes)
    assert tp.metadata["seed"] == "polyline"


def test_blade_passes_are_geodesically_equidistant_and_raster_is_not():
    s = blade()
    tp = equidistant(s, TOOL, direction=0.0)                          # passes along the span, across the nose
    d = tp.metadata["spacing_m"]
    g = blade_gaps(tp)
    assert np.mean(g) == pytest.approx(d, rel=1e-3)
    assert spread(g) < 0.02                                        # measured 0.02 %
    check_on_surface(s, tp, 1e-3)
    # The raster along the same feed, same spacing: its planes sit at equal steps of the mean
    # surface distance, but they cut the leading edge at a slant, so the gaps still vary.
    tr = raster(s, TOOL, spacing=d, direction=tp.metadata["feed_direction"])
    assert 0.01 < spread(blade_gaps(tr)) < 0.045                   # measured 2.6 % (5.8 % in projection)
    # Left to choose, the planner runs the passes round the profile instead: the chord across them
    # is along the straight span, the whole pad, so the path is about a third as long.
    auto = equidistant(s, TOOL)
    assert auto.metadata["direction_rule"].startswith("auto")
    assert abs(auto.metadata["feed_direction"][1]) < 1e-6 and auto.metadata["spacing_m"] > 2.5 * d
    assert auto.contact_length < 0.5 * tp.contact_length            # measured 4.2 m against 12.6 m
    assert spread(blade_gaps(auto)) < 0.02


@pytest.mark.parametrize("spacing", [None, 0.05])
def test_panel_passes_are_geodesically_equidistant(spacing):
    s = panel()
    tp = equidistant(s, TOOL, spacing=spacing)
    d = tp.metadata["spacing_m"]
    # a given spacing pulls the last level in to cover the far edge; measure the others
    assert tp.metadata["pulled_in_levels"] == (0 if spacing is None else 1)
    g = panel_gaps(regular_levels(tp))
    assert np.mean(g) == pytest.approx(d, rel=2e-3)
    assert spread(g) < 0.02                                        # measured 0.48 % and 0.57 %
    tr = raster(s, TOOL, spacing=d, direction=tp.metadata["feed_direction"])
    assert spread(panel_gaps(tr)) > spread(g)                      # measured 1.14 % and 1.42 %
    if spacing is None:
        # Passes run along x; the chord across them (along y, radius 0.9 m) is the whole pad,
        # evened out to D / ceil(D / 2R) over the panel's geodesic width D.
        m = tp.metadata
        n = m["n_levels"]
        assert m["feed_direction"] == pytest.approx([1, 0, 0], abs=1e-9)
        assert 2 * R * (n - 1) / n < d <= 2 * R * 1.001
        assert m["far_margin_m"] == pytest.approx(d / 2, rel=1e-9) and m["predicted_gap_fraction"] < 1e-3
        check_on_surface(s, tp, 1e-3)


def test_pass_spacing_measures_fast_marching_gaps():
    s = panel()
    tp = equidistant(s, TOOL, spacing=0.1, direction=0.0)
    ps = pass_spacing(tp)
    # four levels 0.1 m apart and one pulled in to the far edge, whose shorter gap is not measured
    assert tp.metadata["pulled_in_levels"] == 1 and len(tp.passes) == 5
    assert len(ps.pairs) == 3 and ps.method == "fmm"
    assert ps.mean == pytest.approx(0.1, rel=5e-3) and ps.spread < 0.02
    flat = raster(flat_plate(), TOOL, spacing=0.05, direction=[1, 0, 0])
    ps = pass_spacing(flat)
    assert ps.mean == pytest.approx(0.05, rel=2e-3) and ps.spread < 5e-3


def test_heat_method_is_available_and_less_accurate():
    s = panel()
    tp = equidistant(s, TOOL, spacing=0.05, distance="heat", direction=0.0)
    assert tp.metadata["distance_method"] == "heat"
    assert 0.02 < spread(panel_gaps(regular_levels(tp))) < 0.1                    # measured 4.1 % (fast marching: 0.57 %)


def test_bad_inputs_are_refused_and_no_pass_is_infeasible():
    s = flat_plate()
    for kwargs in (dict(spacing=0.0), dict(spacing=float("nan")), dict(point_spacing=-1.0),
                   dict(min_pass_length=-1.0), dict(distance="dijkstra"), dict(seed=np.zeros((3, 2))),
                   dict(max_edge=0.0), dict(along="u")):
        with pytest.raises(InputError):
            equidistant(s, TOOL, **kwargs)
    with pytest.raises(InfeasibleError, match="min_pass_length"):
        equidistant(s, TOOL, spacing=0.05, min_pass_length=1.0)
    # A closed surface (a tetrahedron) has no boundary to start from.
    tet = Surface(np.array([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0], [0, 0, 0.1]], float),
                  np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]))
    with pytest.raises(InputError, match="no boundary"):
        equidistant(tet, TOOL, spacing=0.02)


def test_pieces_are_planned_one_after_the_other():
    a = flat_plate(size_x=0.3, size_y=0.2)
    v = np.vstack([a.vertices, a.vertices + [0.0, 0.5, 0.0]])
    s = Surface(v, np.vstack([a.faces, a.faces + len(a.vertices)]))
    tp = equidistant(s, TOOL, spacing=0.05)
    m = tp.metadata
    assert m["n_components"] == 2 and m["components_without_seed"] == 0
    assert tp.regions.tolist() == sorted(tp.regions.tolist()) and len(set(tp.regions.tolist())) == 2
    # the two plates side by side spread most along y: passes run along y, 6 per plate
    assert m["feed_direction"] == pytest.approx([0, 1, 0], abs=1e-9)
    assert len(tp.passes) == 12 and tp.regions.tolist().count(tp.regions.tolist()[0]) == 6
    assert sorted({round(float(p.points[0, 1]), 6) for p in tp.passes}) == [0.0, 0.2, 0.5, 0.7]


# ----------------------------------------------------------------------------------------------
# shared real meshes
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", sorted(SHARED_MESH_UNITS))
def test_shared_meshes_run_and_cover(name):
    s = load_shared(name)
    for spacing in (None, 0.05, 0.02):
        # the default plan chooses the direction; the given spacings keep the principal axis (time)
        tp = equidistant(s, TOOL, spacing=spacing, point_spacing=5e-3, direction=None if spacing is None else 0.0)
        m = tp.metadata
        d = m["spacing_m"]
        assert m["n_passes"] == len(tp.passes) >= 1 and m["n_levels"] >= 3
        assert set(tp.levels.tolist()) == set(range(m["n_levels"]))        # every level has a pass
        # the default fits the levels to each piece; a given spacing pulls the last level in
        assert 0 < m["far_margin_m"] <= d / 2 * (1 + 1e-6)
        # Geodesic parallels d apart sweep the area once: contact length x spacing ~ area
        # (measured 0.99-1.05 on these meshes; holes, ragged edges and the far margin move it).
        assert 0.9 < tp.contact_length * d / s.area < 1.1
        pts = np.concatenate([p.points for p in tp.passes])
        near = cKDTree(pts).query(s.vertices)[0] <= 0.5 * d + 2.5e-3
        assert s.vertex_areas[near].sum() / s.area > 0.95                  # measured >= 0.970
    check_on_surface(s, tp, 5e-3, max_checked=3000)


# ----------------------------------------------------------------------------------------------
# B-spline patches: arc-length coordinates
# ----------------------------------------------------------------------------------------------
def test_cylinder_lines_are_equidistant_in_arc_length_unlike_iso_parameter_lines():
    r = 0.2
    cyl = nurbs_cylinder(r, 0.4, sweep=np.pi)                     # u along the axis, v round it
    tp = equidistant_patch(cyl, TOOL, spacing=0.05, along="u", connect=False, surface_spacing=0.004)
    taus = np.array(tp.metadata["line_tau_m"])
    assert np.diff(taus) == pytest.approx(np.full(len(taus) - 1, 0.05), rel=1e-12)
    assert len(tp.passes) == len(taus) == 13                      # ceil(π r / 0.05 - 1/2)
    for p, tau in zip(tp.passes, taus):
        arc = r * np.arctan2(p.points[:, 1], p.points[:, 0])      # exact arc length from v = 0
        assert np.abs(arc - tau).max() < 1e-6 * 0.05
        assert np.allclose(np.linalg.norm(p.points[:, :2], axis=1), r, atol=1e-12)
        assert p.points[:, 2].min() == pytest.approx(0.0, abs=1e-12) and p.points[:, 2].max() == pytest.approx(0.4)
    # The same number of lines uniform in the rational parameter v are not equidistant.
    v = np.linspace(0, 1, 2 * len(taus) + 1)[1::2]
    arc = r * np.arctan2(*cyl.evaluate(np.zeros_like(v), v)[:, [1, 0]].T)
    assert np.ptp(np.diff(arc)) / np.mean(np.diff(arc)) > 0.05
    check_on_surface(tp.surface, tp, 1e-3)
    normals = np.concatenate([p.normals for p in tp.passes])
    pts = np.concatenate([p.points for p in tp.passes])
    assert np.allclose(normals[:, :2], pts[:, :2] / r, atol=1e-9)   # exact outward normals


def bumpy_patch(rng):
    """A bicubic B-spline over 0.5 x 0.4 m with random heights (two interior knots each way)."""
    nu, nv = 6, 5
    x, y = np.linspace(0, 0.5, nu), np.linspace(0, 0.4, nv)
    X, Y = np.meshgrid(x, y, indexing="ij")
    Z = 0.06 * rng.standard_normal((nu, nv))
    ku = clamped_knots([1 / 3, 2 / 3], 3, (0, 1))
    kv = clamped_knots([0.5], 3, (0, 1))
    return BSplinePatch(np.stack([X, Y, Z], -1), ku, kv, (3, 3), name="bumpy")


@pytest.mark.parametrize("along", ["u", "v"])
def test_general_patch_lines_follow_the_arc_length_to_1e6(rng, along):
    patch = bumpy_patch(rng)
    amap = ArcLengthMap(patch, along=along)
    # forward and inverse maps agree with direct quadrature
    u = rng.uniform(0, 1, 300)
    v = rng.uniform(0, 1, 300)
    s, t = amap.from_parameters(u, v)
    assert np.abs(t - amap.tau_exact(u, v)).max() < 1e-7
    u2, v2 = amap.to_parameters(s, t)
    assert np.abs(patch.evaluate(u2, v2) - patch.evaluate(u, v)).max() < 1e-6
    tp = equidistant_patch(patch, TOOL, spacing=0.04, along=along, connect=False, surface_spacing=0.003)
    taus = np.array(tp.metadata["line_tau_m"])
    assert np.diff(taus) == pytest.approx(np.full(len(taus) - 1, 0.04), rel=1e-12)
    assert len(tp.passes) >= len(taus) - 1
    for p, level in zip(tp.passes, tp.levels.tolist()):
        tau = taus[level]
        q = np.vstack([p.points[:-1:7], p.points[-1:]])
        uu, vv, dist = patch.project(q)
        assert dist.max() < 1e-9                                     # exactly on the patch
        err = np.abs(amap.tau_exact(uu, vv) - tau)
        assert err.max() < 1e-6 * 0.04
        assert np.allclose(p.normals[:-1:7], patch.normals(uu, vv)[:-1], atol=1e-9)
    check_on_surface(tp.surface, tp, 1e-3)


def test_patch_boundary_polygon_and_interconnection_paths():
    r = 0.2
    cyl = nurbs_cylinder(r, 0.4, sweep=np.pi)
    # A region given in part coordinates: angles 20..140 deg, heights 0.05..0.35 m, its curved
    # sides as polygon vertices every 10 deg (chords 0.8 mm inside the cylinder).
    corners = [(a, 0.05) for a in range(20, 141, 10)] + [(a, 0.35) for a in range(140, 19, -10)]
    poly = np.array([[r * math.cos(math.radians(a)), r * math.sin(math.radians(a)), z] for a, z in corners])
    tp = equidistant_patch(cyl, TOOL, spacing=0.03, boundary=poly, along="u", surface_spacing=0.01)
    m = tp.metadata
    assert len(tp.passes) == 1 and m["n_links"] == m["n_lines"] - 1 >= 5
    pts = tp.passes[0].points
    ang = np.degrees(np.arctan2(pts[:, 1], pts[:, 0]))
    assert ang.min() > 20 + math.degrees(0.015 / r) - 1e-6 and ang.max() < 140 - 1e-6
    assert pts[:, 2].min() == pytest.approx(0.05, abs=1e-6) and pts[:, 2].max() == pytest.approx(0.35, abs=1e-6)
    # each link runs along the end of the region, one spacing of arc round the axis
    assert m["link_length_m"] == pytest.approx(m["n_links"] * 0.03, rel=1e-3)
    assert np.linalg.norm(np.diff(pts, axis=0), axis=1).max() <= 1e-3 * 1.01
    # the dispatching entry point gives the same plan
    same = equidistant(cyl, TOOL, spacing=0.03, boundary=poly, along="u", surface_spacing=0.01)
    assert np.array_equal(same.passes[0].points, pts)
    with pytest.raises(InputError, match="from the patch"):
        equidistant_patch(cyl, TOOL, spacing=0.03, boundary=poly * 1.1)


def test_patch_default_spacing_follows_the_contact_model():
    r = 0.2
    cyl = nurbs_cylinder(r, 0.4, sweep=np.pi)
    # Lines along the axis: the chord across them is across the 0.2 m radius (narrower than 2R);
    # lines round the axis: the chord across them is along the axis (the whole pad).
    across = equidistant_patch(cyl, TOOL, along="u", surface_spacing=0.02).metadata["spacing_m"]
    along = equidistant_patch(cyl, TOOL, along="v", surface_spacing=0.02).metadata["spacing_m"]
    assert along == pytest.approx(2 * R, rel=1e-3)
    assert 0.6 * 2 * R < across < 0.8 * 2 * R                    # measured 53.3 mm
    assert equidistant_patch(cyl, TOOL, spacing=0.1, surface_spacing=0.02).metadata["along"] == "v"   # π r > 0.4

