"""The baseline plane-slice raster planner and the swath widths behind its default spacing."""

import functools
import math

import numpy as np
import pytest

from conftest import SHARED_MESH_UNITS, shared_mesh
from shapes import cylinder_patch
from swath.contact import Tool, local_patch
from swath.contact.widths import area_percentile, max_swath_widths, raster_spacing, swath_widths
from swath.errors import InfeasibleError, InputError
from swath.examples import doubly_curved_panel, flat_plate, grid_faces
from swath.order import order_toolpath
from swath.plan.raster import plane_offsets
from swath.plan.raster import raster as plan_raster
from swath.surface import Surface


def raster(*args, **kwargs):
    """The raster planner followed by the order stage at the planner's own order (snake)."""
    return order_toolpath(plan_raster(*args, **kwargs))


TOOL = Tool()                     # R = 38.1 mm, 1 mm depression on flat
R = TOOL.pad_radius


@functools.cache
def load_shared(name: str) -> Surface:
    """A shared mesh as a Surface (swath.io.mesh.load_mesh when available, else plain trimesh:
    merged vertices, largest connected piece, scaled to metres)."""
    path = shared_mesh(name)
    units = SHARED_MESH_UNITS[name]
    try:
        from swath.io.mesh import load_mesh
    except ImportError:
        import trimesh

        from swath.units import length_unit_factor

        m = trimesh.load(path, process=True, force="mesh")
        m = max(m.split(only_watertight=False), key=lambda c: c.area)
        return Surface(np.asarray(m.vertices) * length_unit_factor(units), np.asarray(m.faces), name=name)
    return load_mesh(path, units=units)


@functools.cache
def _mm_copy(surface: Surface) -> Surface:
    return Surface(surface.vertices * 1e3, surface.faces, name=surface.name)


def closest_on_surface(surface: Surface, points: np.ndarray):
    """``surface.closest_points`` evaluated on a millimetre copy of the surface.

    trimesh's point-triangle routine compares products of coordinates with an absolute 1e-12;
    on triangles about 1 mm across in metres that misplaces the closest point by up to 0.2 mm
    (seen on snp_part_scan and the bezier scan).  In millimetres the same query is exact.
    Returns distances (m), closest points (m) and faces.
    """
    cp, dist, face = _mm_copy(surface).closest_points(np.asarray(points) * 1e3)
    return dist * 1e-3, cp * 1e-3, face


def check_toolpath(surface, tp, point_spacing, *, max_distance=1e-4, max_angle_deg=1.0, max_checked=20000):
    """Points on the surface with the smooth normal there, steps <= point_spacing, no NaN.  The
    (slow) closest-point check runs on at most ``max_checked`` evenly strided points per plan;
    test_slicing checks every slice point against its own face exactly."""
    assert tp.planner == "raster" and len(tp.passes) >= 1
    pts = np.concatenate([p.points for p in tp.passes])
    nrm = np.concatenate([p.normals for p in tp.passes])
    assert np.isfinite(pts).all() and np.isfinite(nrm).all()
    assert np.allclose(np.linalg.norm(nrm, axis=1), 1.0)
    stride = max(1, math.ceil(len(pts) / max_checked))
    pts, nrm = pts[::stride], nrm[::stride]
    dist, cp, face = closest_on_surface(surface, pts)
    assert dist.max() <= max_distance
    smooth = surface.interpolate_normals(cp, face)
    cosang = np.clip(np.einsum("ij,ij->i", nrm, smooth), -1.0, 1.0)
    assert np.degrees(np.arccos(cosang)).max() <= max_angle_deg
    for p in tp.passes:
        assert np.linalg.norm(np.diff(p.points, axis=0), axis=1).max() <= point_spacing * 1.01


# ----------------------------------------------------------------------------------------------
# widths
# ----------------------------------------------------------------------------------------------
def test_cylinder_chord_across_the_axis():
    r = 0.1
    s = cylinder_patch(r, math.pi / 2, 0.3)                          # exact open half-cylinder along y
    w = swath_widths(s, TOOL, np.array([0.0, 1.0, 0.0]))            # feed along the axis
    sink = local_patch(1.0 / r, 0.0, TOOL).sink[0]
    chord = 2 * math.sqrt(2 * sink * r - sink**2)                   # circle chord at depth s
    # The local model is the quadric z = x²/(2r), whose chord 2·sqrt(2 s r) exceeds the circle's
    # by s/(4r) (0.55 % here); the rest is the curvature fit on the mesh.
    assert sink > TOOL.flat_depression                               # the pad sinks deeper on convex
    assert np.median(w) == pytest.approx(2 * math.sqrt(2 * sink * r), rel=1e-3)
    assert np.abs(w / chord - 1).max() <= sink / (4 * r) + 2e-3
    # Feeding round the cylinder, the swath spans the pad along the axis; that is also the widest.
    across = swath_widths(s, TOOL, np.array([1.0, 0.0, 0.0]))
    assert np.median(across) == pytest.approx(2 * R, rel=1e-3)
    assert np.median(max_swath_widths(s, TOOL)) == pytest.approx(2 * R, rel=1e-3)


def test_flat_widths_are_the_pad_diameter_in_every_direction(rng):
    s = flat_plate(size_x=0.2, size_y=0.2, spacing=0.01)
    feeds = rng.standard_normal((len(s.vertices), 3))
    assert swath_widths(s, TOOL, feeds) == pytest.approx(np.full(len(s.vertices), 2 * R), rel=2e-4)
    with pytest.raises(InputError, match="feed_directions"):
        swath_widths(s, TOOL, np.ones((3, 3)))


def test_area_percentile_by_hand():
    v = np.array([5.0, 1.0, 3.0, 2.0])
    a = np.array([1.0, 1.0, 1.0, 97.0])
    assert area_percentile(v, a, 0.0) == 1.0
    assert area_percentile(v, a, 0.005) == 1.0            # 1 % of the area lies below 2
    assert area_percentile(v, a, 0.01) == 2.0
    assert area_percentile(v, a, 0.99) == 5.0


# ----------------------------------------------------------------------------------------------
# flat plate: analytic layout
# ----------------------------------------------------------------------------------------------
def test_flat_plate_default_spacing_is_the_pad_diameter_and_passes_are_straight():
    s = flat_plate()                                        # 0.4 x 0.3 m, z = 0
    tp = raster(s, TOOL)
    m = tp.metadata
    assert m["spacing_m"] == pytest.approx(2 * R, rel=0.01)
    n_planes = math.ceil(0.3 / m["spacing_m"])              # 4
    assert m["n_planes"] == n_planes == m["n_passes"] == len(tp.passes) == 4
    assert m["dropped_fragments"] == 0
    assert m["margin_m"] == pytest.approx((0.3 - 3 * m["spacing_m"]) / 2)
    assert abs(m["feed_direction"][0]) == pytest.approx(1.0)          # along the long side
    ys, dirs = [], []
    for p in tp.passes:
        assert np.ptp(p.points[:, 1]) < 1e-12 and np.abs(p.points[:, 2]).max() < 1e-15   # straight
        assert p.length == pytest.approx(0.4, rel=1e-12)
        assert np.allclose(p.normals, [0, 0, 1])
        ys.append(p.points[0, 1])
        dirs.append(np.sign(p.points[-1, 0] - p.points[0, 0]))
    assert dirs == [dirs[0], -dirs[0], dirs[0], -dirs[0]]                 # snake
    gaps = np.diff(ys)
    assert np.allclose(np.abs(gaps), m["spacing_m"], rtol=1e-9) and len(set(np.sign(gaps))) == 1
    assert min(ys) == pytest.approx(m["margin_m"]) and 0.3 - max(ys) == pytest.approx(m["margin_m"])
    check_toolpath(s, tp, 1e-3)
    assert len(tp.passes[0].points) == 401


def test_angle_and_direction_turn_the_passes():
    s = flat_plate()
    a = raster(s, TOOL, spacing=0.05, direction=math.pi / 2)
    b = raster(s, TOOL, spacing=0.05, direction=(0.0, -1.0, 0.3))
    for tp in (a, b):
        assert abs(tp.metadata["feed_direction"][1]) == pytest.approx(1.0)
        assert tp.metadata["n_planes"] == math.ceil(0.4 / 0.05) == len(tp.passes)
        assert all(np.ptp(p.points[:, 0]) < 1e-12 for p in tp.passes)
    assert b.metadata["feed_direction"] == pytest.approx([0, -1, 0], abs=1e-9)


def test_plane_offsets_centre_the_planes():
    off, margin = plane_offsets(np.array([0.0, 1.0]), 0.3)
    assert len(off) == 4 and margin == pytest.approx(0.05)
    assert off == pytest.approx([0.05, 0.35, 0.65, 0.95])
    off, margin = plane_offsets(np.array([0.0, 0.9]), 0.3)          # integer ratio: margin = spacing/2
    assert len(off) == 3 and margin == pytest.approx(0.15)
    off, margin = plane_offsets(np.array([2.0, 2.01]), 0.3)
    assert off == pytest.approx([2.005]) and margin == pytest.approx(0.005)


def test_plane_offsets_edge_margin_moves_the_outer_planes_in():
    heights = np.array([0.0, 0.3])
    d = 0.0718                                                   # 5 planes, 6.4 mm left at each end
    off0, m0 = plane_offsets(heights, d)
    assert len(off0) == 5 and m0 == pytest.approx(0.0064)
    off, m = plane_offsets(heights, d, edge_margin=0.02)
    assert len(off) == 5 and m == pytest.approx(0.02)
    assert off == pytest.approx(0.02 + np.arange(5) * 0.065)      # (0.3 - 2 * 0.02) / 4 apart
    # capped where the planes are spread evenly: the middles of 5 strips of 60 mm
    for em in (0.03, 0.05, math.inf):
        off, m = plane_offsets(heights, d, edge_margin=em)
        assert m == pytest.approx(0.03) and off == pytest.approx([0.03, 0.09, 0.15, 0.21, 0.27])
    # a margin already at least edge_margin, or a single plane, is left as it was
    off, m = plane_offsets(heights, d, edge_margin=0.005)
    assert m == pytest.approx(m0) and off == pytest.approx(off0)
    off, m = plane_offsets(np.array([2.0, 2.01]), 0.3, edge_margin=1.0)
    assert off == pytest.approx([2.005]) and m == pytest.approx(0.005)


def test_raster_edge_margin_keeps_the_passes_and_the_coverage():
    """The rotary pad at its least-ripple spacing on the flat plate: the outer passes 6.5 mm from
    the edge (the pad more than half off); edge_margin = R/2 moves them in, the same five passes
    spread evenly between, still covering the plate; a bad edge_margin is refused."""
    import dataclasses

    from swath.feed import ripple_spacing

    s = flat_plate()                                        # 0.4 x 0.3 m
    rot = dataclasses.replace(TOOL, motion="rotary")
    d = ripple_spacing(rot)[0]
    base = plan_raster(s, rot, spacing=d, direction=0.0)
    inset = plan_raster(s, rot, spacing=d, direction=0.0, edge_margin=R / 2)
    ys = lambda tp: sorted(float(p.points[0, 1]) for p in tp.passes)   # noqa: E731
    assert base.metadata["margin_m"] == pytest.approx((0.3 - 4 * d) / 2) and ys(base)[0] == pytest.approx(0.00646, abs=1e-5)
    assert base.metadata["edge_rule"].startswith("spacing kept") and base.metadata["plane_spacing_m"] == pytest.approx([d])
    assert len(inset.passes) == len(base.passes) == 5
    assert inset.contact_length == pytest.approx(base.contact_length, rel=1e-9)
    step = (0.3 - R) / 4
    assert ys(inset) == pytest.approx(R / 2 + np.arange(5) * step, abs=1e-9)
    m = inset.metadata
    assert m["margin_m"] == pytest.approx(R / 2) and m["edge_rule"] == "outer planes at least 19.05 mm in"
    assert m["plane_spacing_m"] == pytest.approx([step]) and step < d
    assert m["n_fill_passes"] == 0 and m["predicted_gap_fraction"] == 0.0
    even = plan_raster(s, rot, spacing=d, direction=0.0, edge_margin=math.inf)
    assert ys(even) == pytest.approx([0.03, 0.09, 0.15, 0.21, 0.27], abs=1e-9)
    assert even.metadata["edge_rule"] == "planes spread evenly"
    for bad in (-1e-3, float("nan")):
        with pytest.raises(InputError, match="edge_margin"):
            plan_raster(s, rot, spacing=d, edge_margin=bad)


def test_raster_edge_margin_evens_the_default_orbital_raster_on_the_panel():
    """The panel's default raster leaves 0.37 R at the edges with planes 1.95 R apart; spread evenly
    (edge_margin = inf) the same six planes lie 1.75 R apart, nearer the orbital pad's least-ripple
    spacing: the simulated removal at constant feed evens out (CoV over the samples at least R in
    0.267 -> 0.124) at the same contact length and coverage."""
    from swath.feed import interior_mask
    from swath.simulate.removal import simulate_removal
    from swath.trajectory import FeedLimit, time_path

    s = doubly_curved_panel()
    rows = []
    for em in (None, math.inf):
        tp = plan_raster(s, TOOL, direction=0.0, edge_margin=em)
        rm = simulate_removal(time_path(tp, [FeedLimit(0.05)]), s, TOOL)
        inner = interior_mask(rm.surface, R)
        a, z = rm.surface.vertex_areas[inner], rm.depth[inner]
        mean = np.average(z, weights=a)
        rows.append((len(tp.passes), tp.contact_length, np.sqrt(np.average((z - mean) ** 2, weights=a)) / mean,
                     rm.metrics["coverage_fraction"], tp.metadata))
    (n0, l0, cov0, c0, m0), (n1, l1, cov1, c1, m1) = rows
    assert n0 == n1 == 6 and l1 == pytest.approx(l0, rel=1e-3)
    assert m0["plane_spacing_m"][0] / R == pytest.approx(1.95, abs=0.01)
    assert m1["plane_spacing_m"][0] / R == pytest.approx(1.75, abs=0.01)
    assert cov0 == pytest.approx(0.267, abs=0.01) and cov1 == pytest.approx(0.124, abs=0.01)
    assert c1 >= c0 == pytest.approx(1.0) and m1["predicted_gap_fraction"] <= m0["predicted_gap_fraction"] + 1e-4


def test_planes_exactly_through_grid_vertices():
    # Binary-exact grid, planes on every other grid line: crossings at vertices, along edges.
    cell = 1.0 / 64.0
    xs, ys = np.arange(25) * cell, np.arange(17) * cell          # 0.375 x 0.25 m
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    v = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], 1)
    s = Surface(v, grid_faces(25, 17))
    tp = raster(s, TOOL, spacing=2 * cell, direction=(1.0, 0.0, 0.0), point_spacing=5e-3)
    assert tp.metadata["n_planes"] == 8 == len(tp.passes)
    for p in tp.passes:
        assert np.ptp(p.points[:, 1]) < 1e-15
        assert np.min(np.abs(p.points[0, 1] / cell - np.round(p.points[0, 1] / cell))) < 1e-9   # on a grid line
        assert p.length == pytest.approx(0.375, rel=1e-12)
    check_toolpath(s, tp, 5e-3)


def test_snake_visits_fragments_on_a_plane_in_travel_order():
    # A plate with a square hole: the middle planes give two fragments each.
    s0 = flat_plate(size_x=0.4, size_y=0.3, spacing=0.01)
    cen = s0.vertices[s0.faces].mean(axis=1)
    keep = ~((np.abs(cen[:, 0] - 0.2) < 0.05) & (np.abs(cen[:, 1] - 0.15) < 0.05))
    s = Surface(s0.vertices, s0.faces[keep])
    tp = raster(s, TOOL, spacing=0.02, point_spacing=5e-3)
    feed = np.array(tp.metadata["feed_direction"])
    cross = np.array(tp.metadata["cross_direction"])
    # the hole spans y in [0.10, 0.20]: planes y = 0.11 .. 0.19 (5 of 15) meet it
    assert tp.metadata["n_planes"] == 15 and len(tp.passes) == 15 + 5
    offsets = [float(p.points[0] @ cross) for p in tp.passes]
    assert np.all(np.diff(offsets) >= -1e-12)                            # planes in order
    plane_dirs = []
    for i, p in enumerate(tp.passes):
        d = np.sign((p.points[-1] - p.points[0]) @ feed)
        if i and abs(offsets[i] - offsets[i - 1]) < 1e-9:                 # same plane: same direction,
            assert d == plane_dirs[-1]                                    # visited along it
            assert (p.points[0] - tp.passes[i - 1].points[-1]) @ (d * feed) > 0
        else:
            if plane_dirs:
                assert d == -plane_dirs[-1]
            plane_dirs.append(d)


# ----------------------------------------------------------------------------------------------
# inputs and infeasible requests
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("kwargs,fragment", [
    (dict(spacing=0.0), "spacing must be a positive, finite length in metres, got 0.0"),
    (dict(spacing=-0.02), "got -0.02"),
    (dict(spacing=float("nan")), "spacing must be a positive"),
    (dict(spacing=float("inf")), "spacing must be a positive"),
    (dict(spacing="20mm"), "spacing must be a positive"),
    (dict(point_spacing=0.0), "point_spacing must be a positive, finite length in metres, got 0.0"),
    (dict(point_spacing=float("nan")), "point_spacing must be"),
    (dict(min_pass_length=-1.0), "min_pass_length must be"),
    (dict(direction=float("inf")), "direction angle must be"),
    (dict(direction=(0.0, 0.0, 0.0)), "direction must be"),
    (dict(direction=(0.0, 0.0, 2.0)), "along the part's mean normal"),
    (dict(spacing=1e-6), "cutting planes"),
])
def test_bad_inputs_are_refused(kwargs, fragment):
    s = flat_plate(size_x=0.2, size_y=0.1, spacing=0.02)
    with pytest.raises(InputError, match=fragment.replace("(", r"\(").replace(")", r"\)").replace(".", r"\.")):
        raster(s, TOOL, **{"spacing": 0.05, **kwargs})


def test_no_pass_is_infeasible_with_a_reason():
    s = flat_plate(size_x=0.03, size_y=0.02, spacing=0.005)
    with pytest.raises(InfeasibleError, match="min_pass_length=50.0 mm"):
        raster(s, TOOL, spacing=0.01, min_pass_length=0.05)
    tp = raster(s, TOOL, spacing=0.01, min_pass_length=0.0)
    assert len(tp.passes) == 2


# ----------------------------------------------------------------------------------------------
# real meshes
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", sorted(SHARED_MESH_UNITS))
def test_shared_meshes_at_every_spacing(name):
    s = load_shared(name)
    s.normals                                                         # cached outside the timing
    for spacing in (0.01, 0.02, 0.05, 0.1):          # (speed is measured in benchmarks/bench_plan.py)
        tp = raster(s, TOOL, spacing=spacing, point_spacing=5e-3)
        m = tp.metadata
        assert m["spacing_m"] == spacing and m["n_passes"] == len(tp.passes) >= 1
        # a given spacing is measured on the surface across the passes: each piece's extent there is
        # at least its extent along the cross direction
        extents = m["plane_extent_m"]
        assert m["spacing_on"] == "surface" and len(extents) == m["n_pieces"]
        assert m["n_planes"] == sum(max(math.ceil(e / spacing), 1) for e in extents)
        if m["n_pieces"] == 1:
            assert extents[0] >= np.ptp(s.vertices @ np.array(m["cross_direction"])) * (1 - 1e-12)
        for key in ("angle_rad", "feed_direction", "dropped_fragments", "point_spacing_m", "spacing_rule"):
            assert key in m
        check_toolpath(s, tp, 5e-3)


def test_wavy_mesh_drops_short_fragments_and_counts_them():
    s = load_shared("noether_wavy_mesh_with_hole.ply")
    # planes 20 mm apart along the cross direction, where a plane grazes the hole's rim
    a = raster(s, TOOL, spacing=0.02, point_spacing=5e-3, direction=0.0, fill_gaps=False, spacing_on="projection")
    b = raster(s, TOOL, spacing=0.02, point_spacing=5e-3, min_pass_length=0.0, direction=0.0, fill_gaps=False,
               spacing_on="projection")
    assert a.metadata["min_pass_length_m"] == pytest.approx(R / 4)
    assert a.metadata["dropped_fragments"] >= 1 and b.metadata["dropped_fragments"] == 0
    assert len(b.passes) == len(a.passes) + a.metadata["dropped_fragments"]
    assert all(p.length >= R / 4 for p in a.passes)
    assert a.metadata["dropped_length_m"] == pytest.approx(
        sum(p.length for p in b.passes) - sum(p.length for p in a.passes), rel=1e-3, abs=1e-9)


def test_default_spacing_on_the_doubly_curved_panel_follows_the_contact_model():
    s = doubly_curved_panel()
    tp = raster(s, TOOL, point_spacing=5e-3)
    m = tp.metadata
    # Slices run along x (the 0.5 m side) and are spaced along y, where the radius is 0.9 m: the
    # chord across them, 2·sqrt(2·s·0.9) > 2R, is the whole pad, but at the panel's y-edges the
    # surface is tilted by asin(0.2/0.9) to the planes, so they must be cos(12.8°) closer.
    choice = raster_spacing(s, TOOL, m["cross_direction"], percentile=0.0, slope_floor=0.0)
    assert abs(m["cross_direction"][1]) == pytest.approx(1.0)
    assert m["spacing_m"] >= choice.spacing == choice.narrowest
    assert m["spacing_m"] == pytest.approx(2 * R * math.cos(math.asin(0.2 / 0.9)), rel=3e-3)
    assert m["predicted_gap_fraction"] < 1e-3
    check_toolpath(s, tp, 5e-3)


def test_closed_slices_start_at_their_rearmost_point_and_snake_reverses_them():
    # A tube along z cut by planes across its axis: every pass is a closed loop.
    n_th, n_z, r = 72, 41, 0.05
    th = np.arange(n_th) * 2 * np.pi / n_th
    zs = np.linspace(0.0, 0.4, n_z)
    T, Z = np.meshgrid(th, zs, indexing="ij")
    v = np.stack([r * np.cos(T).ravel(), r * np.sin(T).ravel(), Z.ravel()], 1)
    i, j = np.meshgrid(np.arange(n_th), np.arange(n_z - 1), indexing="ij")
    a = (i * n_z + j).ravel()
    b = (((i + 1) % n_th) * n_z + j).ravel()
    s = Surface(v, np.concatenate([np.stack([a, b, b + 1], 1), np.stack([a, b + 1, a + 1], 1)]))
    axes = s.principal_axes[1]
    assert abs(axes[0][2]) == pytest.approx(1.0)                     # the tube's axis spreads most
    tp = raster(s, TOOL, spacing=0.05, direction=axes[1], point_spacing=2e-3)
    cross = np.array(tp.metadata["cross_direction"])
    feed = np.array(tp.metadata["feed_direction"])
    assert abs(cross[2]) == pytest.approx(1.0)
    assert tp.metadata["n_planes"] == 8 == len(tp.passes)
    turns = []
    for k, p in enumerate(tp.passes):
        assert np.array_equal(p.points[0], p.points[-1])
        assert p.points[0] @ feed == pytest.approx((p.points @ feed).min(), abs=1e-12)   # rearmost on the feed
        assert p.length == pytest.approx(2 * n_th * r * math.sin(math.pi / n_th), rel=1e-3)
        rel = p.points - p.points[0]
        turns.append(np.sign(np.cross(rel[:-1], rel[1:]).sum(axis=0) @ cross))
    assert turns == [turns[0], -turns[0]] * 4                             # snake: every other loop reversed
    check_toolpath(s, tp, 2e-3)
