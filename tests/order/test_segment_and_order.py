"""Segmentation into unbroken-sweep regions, the per-region driver, pass ordering, the hub part."""

from __future__ import annotations

import numpy as np
import pytest

from swath.contact.tool import Tool
from swath.core import Pass, ToolPath
from swath.errors import InputError
from swath.examples import flat_plate, wheel_hub
from swath.order import order_toolpath
from swath.order.tour import (
    group_variants,
    held_karp,
    link_matrix,
    solve_gtsp,
    tour_length,
)
from swath.plan.raster import raster
from swath.plan.regions import plan_regions
from swath.plan.slicing import slice_mesh
from swath.segment import alpha_boundary, segment
from swath.surface import Surface


@pytest.fixture(scope="module")
def hub():
    return wheel_hub()


def plate_with_holes(edge=5e-3):
    """A 0.3 m x 0.2 m plate with two round holes (r = 30 mm) side by side and a square one."""
    from scipy.spatial import Delaunay

    xs, ys = np.arange(0, 0.3 + 1e-9, edge), np.arange(0, 0.2 + 1e-9, edge)
    gx, gy = np.meshgrid(xs, ys)
    p = np.stack([gx.ravel(), gy.ravel()], 1)
    holes = [(0.08, 0.1, 0.03), (0.2, 0.07, 0.03)]
    tri = Delaunay(p).simplices
    c = p[tri].mean(axis=1)
    keep = np.ones(len(tri), bool)
    for x, y, r in holes:
        keep &= np.hypot(c[:, 0] - x, c[:, 1] - y) > r
    keep &= ~((np.abs(c[:, 0] - 0.24) < 0.02) & (np.abs(c[:, 1] - 0.16) < 0.02))
    tri = tri[keep]
    a, b, cc = p[tri[:, 0]], p[tri[:, 1]], p[tri[:, 2]]
    ccw = (b[:, 0] - a[:, 0]) * (cc[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (cc[:, 0] - a[:, 0]) > 0
    tri = np.where(ccw[:, None], tri, tri[:, ::-1])
    return Surface(np.column_stack([p, np.zeros(len(p))]), tri, name="plate_with_holes")


def assert_unbroken(surface, tool, regions, *, short=0.01):
    """Raster every region along its sweep lines: each cutting plane must give at most one pass, and
    a dense set of sweep lines of each region one piece per plane (pieces shorter than ``short``,
    m, left by merging regions of less than ``min_area`` — single triangles at the tip of a hole —
    are not counted)."""
    tp = plan_regions(surface, tool, raster, regions, min_pass_length=0.0, fill_gaps=False)
    assert sum(r.area for r in regions) == pytest.approx(surface.area, rel=1e-9)
    labels = tp.regions
    for i, region in enumerate(regions):
        meta = tp.metadata["regions"][i]
        if "skipped" in meta:
            continue
        assert meta["n_passes"] <= meta["n_planes"], f"region {i}: {meta['n_passes']} passes on {meta['n_planes']} planes"
        # every pass lies on its own plane (one pass per sweep line)
        heights = [float(np.mean(p.points @ region.cross)) for p, lab in zip(tp.passes, labels) if lab == i]
        planes = np.round((np.array(heights) - min(heights)) / meta["spacing_m"]).astype(int)
        assert len(set(planes.tolist())) == len(planes)
        # a dense set of sweep lines, every one a single piece
        h = region.surface.vertices @ region.cross
        offsets = np.linspace(h.min(), h.max(), 41)[1:-1]
        pieces = slice_mesh(region.surface.vertices, region.surface.faces, region.cross, offsets)
        per_plane = np.bincount([pl.plane for pl in pieces if pl.length > short], minlength=len(offsets))
        assert per_plane.max() <= 1, f"region {i}: a sweep line in {per_plane.max()} pieces"
    return tp


def test_plate_with_holes_regions_have_unbroken_sweep_lines():
    plate = plate_with_holes()
    tool = Tool()
    exact = segment(plate, direction=[1.0, 0, 0], min_area=0.0)
    assert sum(r.area < 2e-4 for r in exact) == 4       # single triangles at the tips of the round holes
    regions = segment(plate, direction=[1.0, 0, 0])
    # two holes overlapping in height and a third above: four cells
    assert len(regions) == 4
    assert_unbroken(plate, tool, regions)
    # without segmentation the planes through the holes break into two passes
    whole = raster(plate, tool, direction=[1.0, 0, 0], min_pass_length=0.0)
    assert whole.metadata["n_passes"] > whole.metadata["n_planes"]


def test_hub_regions_have_unbroken_sweep_lines(hub):
    regions = segment(hub)
    assert len(regions) >= 6                     # five windows and a bore break the sweep lines
    assert_unbroken(hub, Tool(), regions)
    assert all(set(r.faces.tolist()) <= set(range(len(hub.faces))) for r in regions)


def test_plate_without_holes_is_one_region():
    regions = segment(flat_plate(), direction=[1.0, 0, 0])
    assert len(regions) == 1
    assert regions[0].area == pytest.approx(flat_plate().area)


def test_alpha_boundary_of_an_annulus():
    rng = np.random.default_rng(3)
    p = rng.uniform(-1, 1, (6000, 2))
    r = np.hypot(p[:, 0], p[:, 1])
    p = p[(r < 1) & (r > 0.5)]
    loops = alpha_boundary(np.column_stack([p, 0.01 * p[:, 0]]))
    assert len(loops) == 2
    outer, inner = (np.hypot(*p[lp].T) for lp in loops)
    assert outer.min() > 0.9 and inner.max() < 0.6


def _passes(points):
    return [Pass(np.array([a, b], float), np.tile([0.0, 0.0, 1.0], (2, 1))) for a, b in points]


def test_order_matches_the_exact_optimum_on_small_instances():
    rng = np.random.default_rng(7)
    for trial in range(5):
        ends = [(a, a + np.r_[rng.normal(size=2) * 0.05, 0.0]) for a in rng.uniform(0, 0.5, (9, 3)) * [1, 1, 0]]
        tp = ToolPath(None, _passes(ends), "test")
        groups = [[0, 1, 2], [3], [4, 5], [6], [7], [8]]
        exact = order_toolpath(tp, groups=groups, method="exact", start=[0, 0, 0.1]).metadata["air_after_m"]
        gtsp = order_toolpath(tp, groups=groups, method="gtsp", start=[0, 0, 0.1], seed=trial).metadata["air_after_m"]
        greedy = order_toolpath(tp, groups=groups, method="greedy", start=[0, 0, 0.1]).metadata["air_after_m"]
        assert exact <= gtsp + 1e-9 and gtsp <= 1.01 * exact
        assert exact <= greedy + 1e-9


def test_exact_order_by_brute_force():
    """Held-Karp against all orders and path types of four single passes."""
    import itertools

    ends = [((0, 0, 0), (1, 0, 0)), ((0, 1, 0), (1, 1, 0)), ((3, 0, 0), (2, 0, 0)), ((0, 3, 0), (0, 2, 0))]
    tp = ToolPath(None, _passes(ends), "test")
    v = group_variants(tp.passes, [[0], [1], [2], [3]], clearance=0.0)
    D = link_matrix(v, 0.0)
    best = min(tour_length(v, D, [2 * g + f for g, f in zip(perm, flips)], None)
               for perm in itertools.permutations(range(4)) for flips in itertools.product((0, 1), repeat=4))
    assert tour_length(v, D, held_karp(v, D, None), None) == pytest.approx(best)
    assert tour_length(v, D, solve_gtsp(v, D, None), None) == pytest.approx(best)
    # the optimum: 0, 1 reversed, ... total air exactly the three shortest joins
    assert best == pytest.approx(1.0 + np.sqrt(2.0) + 1.0)


def test_order_toolpath_keeps_passes_and_flips_them():
    ends = [((0, 0, 0), (1, 0, 0)), ((0, 0.1, 0), (1, 0.1, 0)), ((0, 0.2, 0), (1, 0.2, 0))]
    tp = ToolPath(None, [p.replace(region=i) for i, p in enumerate(_passes(ends))], "test")
    out = order_toolpath(tp, method="gtsp", clearance=0.0)
    assert out.metadata["air_before_m"] == pytest.approx(2 * np.hypot(1, 0.1))
    assert out.metadata["air_after_m"] == pytest.approx(0.2)        # a snake
    assert sorted(out.regions.tolist()) == [0, 1, 2]
    assert out.contact_length == pytest.approx(tp.contact_length)
    # a job writes the plan's metadata into metrics.json's settings: every figure names its unit
    from swath.report.metrics import keys_without_unit

    assert keys_without_unit(out.metadata) == [] and out.metadata["order_time_s"] >= 0
    with pytest.raises(InputError):
        order_toolpath(tp, groups=[[0, 1]])
    with pytest.raises(InputError):
        order_toolpath(tp, method="nearest")


def test_hub_order_beats_index_and_greedy(hub):
    tool = Tool()
    tp = plan_regions(hub, tool, raster, segment(hub))
    singles = [[i] for i in range(len(tp.passes))]
    air = {m: order_toolpath(tp, groups=singles, method=m).metadata["air_after_m"] for m in ("index", "greedy", "gtsp")}
    assert air["gtsp"] < air["greedy"] < air["index"]


def test_wheel_hub_shape(hub):
    r = np.hypot(hub.vertices[:, 0], hub.vertices[:, 1])
    assert r.max() == pytest.approx(0.225, abs=1e-4)
    assert len(hub.boundary_loops) == 7                 # rim, bore and five windows
    assert np.median(hub.edge_lengths) == pytest.approx(5e-3, rel=0.1)
    assert (hub.normals[:, 2] > 0.5).all()              # toward the tool (+z)
    with pytest.raises(InputError):
        wheel_hub(window_inner=0.2, window_outer=0.1)


def _half_pipe(radius=0.1, length=0.3, span=4 * np.pi / 3, n_a=80, n_l=40):
    """Outer side of a cylinder sector about the y axis, centred on +z (normals outward)."""
    from swath.examples import grid_faces

    a = np.linspace(-span / 2, span / 2, n_a)
    y = np.linspace(0, length, n_l)
    A, Y = np.meshgrid(a, y, indexing="ij")
    v = np.stack([radius * np.sin(A), Y, radius * np.cos(A)], -1).reshape(-1, 3)
    f = grid_faces(n_a, n_l)
    s = Surface(v, f, name="half_pipe")
    if (s.face_normals @ [0, 0, 1.0]).mean() < 0:
        s = Surface(v, f[:, ::-1], name="half_pipe")
    return s


@pytest.mark.parametrize("make", [_half_pipe, lambda: wheel_hub(edge=10e-3)])
def test_air_routes_stay_near_the_part(make):
    from swath.order.routing import AirGuard

    surface = make()
    guard = AirGuard(surface, 0.02, pad_radius=0.03)
    rng = np.random.default_rng(11)
    lo, hi = surface.bounds
    idx = rng.integers(0, len(surface.vertices), (40, 2))
    for i, j in idx:
        route = guard.route(surface.vertices[i], surface.normals[i], surface.vertices[j], surface.normals[j])
        assert (route >= lo - 0.05 - 1e-12).all() and (route <= hi + 0.05 + 1e-12).all()
        assert guard._clear(route[1:-1])


def test_boundary_turns_skip_small_wiggles():
    from swath.segment.sweep import boundary_turns

    h = np.array([0, 1, 0.2, 1.1, 0.0, -5, -4.95, -5.2, 3, 2.99, 0.0])
    # the 0.8-high wiggle stays, the 0.05 ones (-5 / -4.95, 3 / 2.99) go
    assert boundary_turns(h, 0.5).tolist() == [1, 2, 3, 7, 8, 10]
    assert boundary_turns(h, 2.0).tolist() == [7, 8]
    assert boundary_turns(0.001 * h, 0.5).tolist() == [7, 8]    # a pin hole keeps its top and bottom


def test_time_ordering_weighs_the_tool_turn_against_the_move():
    ends = [((0, 0, 0), (1, 0, 0)), ((0, 0.05, 0), (1, 0.05, 0)), ((0, 0.1, 0), (1, 0.1, 0))]
    tp = ToolPath(None, _passes(ends), "test")

    def directions(out):
        return [int(np.sign(p.points[-1][0] - p.points[0][0])) for p in out.passes]

    # a 180-degree turn at 1 rad/s (3.1 s) beats going back 1 m at 0.25 m/s (4.25 s): a snake
    snake = order_toolpath(tp, method="exact", link_speed=0.25, link_acceleration=1.0, omega_max=1.0)
    assert directions(snake) in ([1, -1, 1], [-1, 1, -1])
    # at 0.5 rad/s the turn takes 6.3 s: every pass the same way
    one_way = order_toolpath(tp, method="exact", link_speed=0.25, link_acceleration=1.0, omega_max=0.5)
    assert len(set(directions(one_way))) == 1
    # each link: 20 mm retract, the 1.00125 m diagonal, 20 mm approach, no turn: as the trajectory
    # stage times it (rounded corners, toppra at 0.25 m/s, 1 m/s²), to 30 ms
    from swath.trajectory.links import LinkSettings, time_link

    d = np.hypot(1.0, 0.05)
    route = np.array([[0, 0, 0], [0, 0, 0.02], [d, 0, 0.02], [d, 0, 0]])
    q = np.array([1.0, 0, 0, 0])
    timed = time_link(route, q, q, LinkSettings(speed=0.25, acceleration=1.0)).duration
    assert one_way.metadata["link_time_after_s"] == pytest.approx(2 * timed, abs=0.06)
    assert one_way.metadata["link_time_after_s"] > 2 * (0.04 + d) / 0.25 + 2 * 0.25   # more than the trapezoid


def test_the_order_stage_routes_every_link_and_the_trajectory_follows_it():
    from swath.examples import blade
    from swath.order import route_links
    from swath.trajectory import FeedLimit, time_path

    b = blade(span=0.2)
    tp = route_links(order_toolpath(raster(b, Tool(), direction=0.0), method="snake"), clearance=0.02,
                     pad_radius=0.0381)
    assert len(tp.links) == len(tp.passes) - 1
    lo, hi = b.bounds
    for link, a, c in zip(tp.links, tp.passes[:-1], tp.passes[1:]):
        w = link.waypoints
        assert np.allclose(w[0], a.points[-1]) and np.allclose(w[-1], c.points[0])
        assert np.all(w >= lo - 0.0581 - 1e-9) and np.all(w <= hi + 0.0581 + 1e-9)   # inside the reach box
        _, dist, _ = b.closest_points(w[1:-1])
        assert dist.min() >= 0.01 - 1e-9                                           # clear of the part
    tr = time_path(tp, [FeedLimit(0.05)])
    air = tr.position[~tr.contact]
    assert np.all(air >= lo - 0.0581 - 1e-6) and np.all(air <= hi + 0.0581 + 1e-6)
    routed = sum(link.length for link in tp.links) + 2 * 0.02          # links + approach and retract
    assert 0.9 * routed <= tr.air_length <= routed                     # corners rounded, never longer


def test_segment_refuses_an_empty_angle_list():
    with pytest.raises(InputError, match="candidate angle"):
        segment(flat_plate(), angles=())


def test_a_lift_under_an_overhang_tilts_out_from_under_it():
    """A floor (z = 0) with a roof 15 mm above its right half, less than the 20 mm clearance.
    Lifting straight up from a point 2 mm in under the roof's edge would end on the roof; the lift
    tilts out (45° toward the open side) and its top keeps half the clearance from both.  Far from
    the roof the lift is the straight one, as before."""
    from swath.order.routing import AirGuard

    floor, roof = flat_plate(size_x=0.2, size_y=0.1, spacing=0.01), flat_plate(size_x=0.1, size_y=0.1, spacing=0.01)
    v = np.vstack([floor.vertices, roof.vertices + [0.1, 0.0, 0.015]])
    surface = Surface(v, np.vstack([floor.faces, roof.faces + len(floor.vertices)]), name="overhang")
    c, up = 0.02, np.array([0.0, 0.0, 1.0])
    guard = AirGuard(surface, c, pad_radius=0.03)
    p, q = np.array([0.102, 0.05, 0.0]), np.array([0.03, 0.05, 0.0])
    route = guard.route(p, up, q, up)
    top = route[1]
    assert not np.allclose(top, p + c * up)
    assert np.linalg.norm(top - p) == pytest.approx(c) and (top - p) @ up == pytest.approx(c * np.cos(np.pi / 4))
    assert top[0] < p[0]                                       # out from under the roof
    assert surface.closest_points(top[None])[1][0] >= 0.5 * c * 0.999
    assert guard._clear(route[1:-1])
    np.testing.assert_array_equal(route[-2], q + c * up)       # in the open: straight down as before


def test_air_moves_that_cannot_clear_the_part_are_a_job_warning():
    """Two passes on a floor under a roof 20 mm above it (the clearance): no lift can get clear, and the plan carries a warning naming the move (the job's report lists
    the plan's warnings), beside the log line."""
    from swath.order import route_links

    floor, roof = flat_plate(size_x=0.2, size_y=0.1, spacing=0.01), flat_plate(size_x=0.2, size_y=0.1, spacing=0.01)
    v = np.vstack([floor.vertices, roof.vertices + [0.0, 0.0, 0.02]])
    surface = Surface(v, np.vstack([floor.faces, roof.faces + len(floor.vertices)]), name="sandwich")
    up = np.tile([0.0, 0.0, 1.0], (2, 1))
    passes = [Pass(np.array([[0.05, y, 0.0], [0.15, y, 0.0]]), up) for y in (0.04, 0.06)]
    tp = route_links(ToolPath(surface, passes, "test"), clearance=0.02)
    (warning,) = tp.metadata["warnings"]
    assert warning.startswith("1 of 1 air moves pass closer than half the clearance (10 mm)") and "after passes 1)" in warning
    assert tp.metadata["air_moves_near_part_count"] == 1
    # in the open, no warning
    open_tp = route_links(ToolPath(floor, passes, "test"), clearance=0.02)
    assert "warnings" not in open_tp.metadata and open_tp.metadata["air_moves_near_part_count"] == 0


def test_a_route_round_a_fin_under_a_roof_goes_out_sideways():
    """Two pass ends on a floor, on either side of a fin that rises to a roof 60 mm up; the fin and
    the roof close everything but the sides.  Straight across, up, along the normals and away from
    the centre all run into the part; a direction from the spread-out set leads round the fin's end,
    clear of the part and inside the reach box."""
    from swath.examples.parts import grid_faces
    from swath.order.routing import AirGuard

    floor, roof = flat_plate(size_x=0.2, size_y=0.1, spacing=0.01), flat_plate(size_x=0.2, size_y=0.1, spacing=0.01)
    y, z = np.meshgrid(np.linspace(0, 0.1, 11), np.linspace(0, 0.06, 7), indexing="ij")
    fin = np.stack([np.full(y.size, 0.1), y.ravel(), z.ravel()], axis=1)
    parts = [floor.vertices, roof.vertices + [0.0, 0.0, 0.06], fin]
    offsets = np.cumsum([0] + [len(p) for p in parts])
    faces = [floor.faces + offsets[0], roof.faces[:, ::-1] + offsets[1], grid_faces(11, 7) + offsets[2]]
    surface = Surface(np.vstack(parts), np.vstack(faces), name="fin under a roof")
    guard = AirGuard(surface, 0.02, pad_radius=0.03)
    up = np.array([0.0, 0.0, 1.0])
    a, b = np.array([0.05, 0.05, 0.0]), np.array([0.15, 0.05, 0.0])
    route = guard.route(a, up, b, up)
    assert guard._clear(route[1:-1]) and not guard.near_part
    np.testing.assert_allclose(route[[1, -2]], [a + 0.02 * up, b + 0.02 * up])
    assert (route >= guard.box[0] - 1e-12).all() and (route <= guard.box[1] + 1e-12).all()
    assert route[2:4, 1].min() < 0.0 or route[2:4, 1].max() > 0.1         # round the fin's end
