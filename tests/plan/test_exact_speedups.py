"""Speed-ups of the planners' inner loops that must not change a plan: each fast path against the
code it replaces, compared bit for bit."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from swath.contact import Tool
from swath.errors import InputError
from swath.examples import doubly_curved_panel, flat_plate
from swath.plan import gaps
from swath.plan.gaps import CoverageCheck, within_reach
from swath.plan.raster import raster
from swath.plan.slicing import level_sets
from swath.plan.uniform_layout import _band_widths
from swath.plan.uniform_model import _Context, _vertex_gradient_directions

TOOL = Tool()


@pytest.fixture(scope="module")
def context():
    return _Context(doubly_curved_panel(spacing=8e-3), TOOL, None)


def _kdtree_within_reach(samples, reach, points):
    d = cKDTree(points).query(samples, distance_upper_bound=float(reach.max()) + 1e-9)[0]
    return d <= reach


@pytest.mark.parametrize("n_points", [1, 40, 3000])
def test_within_reach_is_the_kdtree_answer(rng, n_points):
    points = rng.random((n_points, 3)) * [0.4, 0.2, 0.05]
    samples = rng.random((20_000, 3)) * [0.5, 0.3, 0.05] - [0.05, 0.05, 0.0]
    reach = rng.uniform(0.005, 0.02, len(samples))
    got = within_reach(samples, reach, points)
    expected = _kdtree_within_reach(samples, reach, points)
    np.testing.assert_array_equal(got, expected)
    assert 0 < got.sum() < len(got)


def test_a_point_grid_with_wider_cells_gives_the_same_answer(rng):
    """One grid of the pass points serves every reach up to its cell (the coverage check asks it
    about triangles and samples alike); a reach over the cell is refused."""
    from swath.plan.gaps import PointGrid

    points = rng.random((3000, 3)) * [0.4, 0.2, 0.05]
    samples = rng.random((20_000, 3)) * [0.5, 0.3, 0.05] - [0.05, 0.05, 0.0]
    grid = PointGrid(points, 0.04)
    for hi in (0.004, 0.02, 0.04):
        reach = rng.uniform(0.2 * hi, hi, len(samples))
        got = grid.within(samples, reach)
        np.testing.assert_array_equal(got, _kdtree_within_reach(samples, reach, points))
        assert 0 < got.sum() < len(got)
    with pytest.raises(ValueError, match="over the grid's cell"):
        grid.within(samples[:3], np.full(3, 0.05))


def test_within_reach_on_a_sample_exactly_at_reach_and_with_nothing_near():
    points = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    samples = np.array([[0.0, 0.003, 0.004], [0.5, 0.0, 0.0], [5.0, 5.0, 5.0]])
    reach = np.array([0.005, 0.1, 0.1])                    # first: 3-4-5 triangle, exactly at reach
    np.testing.assert_array_equal(within_reach(samples, reach, points), [True, False, False])
    assert within_reach(samples[:0], reach[:0], points).shape == (0,)
    np.testing.assert_array_equal(within_reach(samples, reach, points[:0]), [False] * 3)


def test_within_reach_falls_back_to_the_kdtree_on_a_huge_grid(rng, monkeypatch):
    points = rng.random((500, 3))
    samples = rng.random((2000, 3))
    reach = rng.uniform(0.01, 0.05, len(samples))
    fast = within_reach(samples, reach, points)
    monkeypatch.setattr(gaps, "MAX_GRID_CELLS", 0)
    np.testing.assert_array_equal(within_reach(samples, reach, points), fast)
    np.testing.assert_array_equal(fast, _kdtree_within_reach(samples, reach, points))


def test_compiled_gradient_directions_are_those_of_the_face_gradient(context, rng):
    W = context.work
    for field in (W.vertices @ np.array([0.3, -0.8, 0.1]),
                  np.linalg.norm(W.vertices - W.vertices[7], axis=1),
                  rng.random(len(W.vertices))):
        expected = context.gradient.vertex_directions(field, W.normals)
        got = _vertex_gradient_directions(context.gradient, field, W.normals)
        np.testing.assert_array_equal(got, expected)
        np.testing.assert_allclose(np.linalg.norm(got, axis=1), 1.0, atol=1e-12)
        some = np.sort(rng.choice(len(W.vertices), 200, replace=False))[::-1]     # any order
        np.testing.assert_array_equal(_vertex_gradient_directions(context.gradient, field, W.normals, some),
                                      expected[some])
        np.testing.assert_array_equal(context.gradient_directions(field, some), expected[some])


def test_width_bound_holds_at_every_vertex_in_every_direction(context, rng):
    W = context.work
    idx = np.arange(len(W.vertices))
    for _ in range(4):
        feed = rng.normal(size=(len(idx), 3))
        w = context.widths.across(idx, feed)
        assert np.all(w <= context.widths.max_width)
        assert np.all(w >= context.widths.min_width)
    assert np.median(context.widths.min_width / context.widths.max_width) > 0.5      # bounds that bite
    # a flat plate: every chord is the pad's diameter, and both bounds are that diameter
    flat = _Context(flat_plate(size_x=0.2, size_y=0.1), TOOL, None)
    assert flat.widths.max_width == pytest.approx(2 * TOOL.pad_radius, rel=1e-6)
    assert flat.widths.min_width == pytest.approx(2 * TOOL.pad_radius, rel=1e-3)


@pytest.mark.parametrize("reach", [0.4, 0.1])
def test_widths_on_the_cut_faces_only_give_the_level_set_of_all_widths(context, reach):
    W = context.work
    R = TOOL.pad_radius
    edge = W.boundary_loops[0][:30]
    d = context.distance(edge)
    left = d > 0
    band = np.flatnonzero((d <= 2.5 * R) & left)
    lazy = _band_widths(context, d, band, reach)
    full = _band_widths(context, d, band, reach, everywhere=True)
    exact = lazy == full
    assert not exact.all()                                   # some widths were skipped ...
    skipped = ~exact                                         # ... and replaced by a bound on g's side
    np.testing.assert_array_equal(d[skipped] - reach * lazy[skipped] < 0, d[skipped] - reach * full[skipped] < 0)
    pieces_lazy = level_sets(W.vertices, W.faces, d - reach * lazy, [0.0], edges=context.edges)
    pieces_full = level_sets(W.vertices, W.faces, d - reach * full, [0.0], edges=context.edges)
    assert len(pieces_lazy) == len(pieces_full) > 0
    for a, b in zip(pieces_lazy, pieces_full):
        np.testing.assert_array_equal(a.points, b.points)
        assert a.closed == b.closed


def test_a_negative_reach_computes_every_band_width(context):
    d = context.distance(context.work.boundary_loops[0][:30])
    band = np.flatnonzero((d > 0) & (d <= 0.1))
    np.testing.assert_array_equal(_band_widths(context, d, band, -0.1),
                                  _band_widths(context, d, band, -0.1, everywhere=True))


def _all_rays(patch, rows, psi):
    from swath.contact.widths import _widths_across_kernel

    rows = np.ascontiguousarray(rows, np.int64)
    psi = np.ascontiguousarray(np.broadcast_to(np.asarray(psi, float), rows.shape))
    return _widths_across_kernel(rows, psi, np.ascontiguousarray(patch.phi, float),
                                 np.ascontiguousarray(patch.rho_in, float), np.ascontiguousarray(patch.rho_out, float))


def _query_angles(patch, rng, n):
    """Random angles, the rays' own angles, the half-way angles between rays and the ends of the range."""
    phi = np.asarray(patch.phi, float)
    half_way = phi + 0.5 * (phi[1] - phi[0])
    special = np.concatenate([phi, half_way, phi - np.pi, half_way - np.pi, [-np.pi, np.pi, 0.0, np.nextafter(0, 1)]])
    return np.concatenate([rng.uniform(-np.pi, np.pi, n), special])


def test_widths_from_the_rays_near_the_query_are_those_of_every_ray(rng):
    from swath.contact import local_patch
    from swath.contact.widths import widths_across

    k1 = np.concatenate([rng.uniform(-60.0, 60.0, 400), [0.0, 40.0, -40.0]])
    k2 = np.concatenate([rng.uniform(-60.0, 60.0, 400), [0.0, -40.0, -40.0]])
    patch = local_patch(np.maximum(k1, k2), np.minimum(k1, k2), TOOL)
    psi = _query_angles(patch, rng, 20_000)
    rows = rng.integers(0, len(k1), len(psi))
    got = widths_across(patch, rows, psi)
    np.testing.assert_array_equal(got, _all_rays(patch, rows, psi))
    assert np.all(got > 0)


def test_widths_from_the_rays_near_the_query_on_patches_with_gaps_and_odd_rays(rng):
    from swath.contact.model import LocalPatch
    from swath.contact.widths import widths_across

    for n_rays in (7, 180, 181):
        phi = (np.arange(n_rays) + 0.5) * 2 * np.pi / n_rays
        n = 60
        rho_out = 0.02 * (1 + 0.5 * rng.random((n, n_rays)))            # uneven patches
        rho_in = np.where(rng.random((n, n_rays)) < 0.3, 0.005 * rng.random((n, n_rays)), 0.0)
        rho_out[rng.random((n, n_rays)) < 0.2] = 0.0                    # rays without contact
        rho_out[0] = 0.0                                                # a row without any contact
        rho_out[1, : n_rays // 2] = 0.0                                 # contact on one side only
        rho_in[2, 0] = -0.004                                           # a ray through the centre: full loop
        rho_out[3, 1] = np.nan                                          # NaN ray
        patch = LocalPatch(np.zeros(n), phi, rho_in, rho_out)
        psi = np.concatenate([_query_angles(patch, rng, 5000), [np.nan]])
        rows = np.concatenate([rng.integers(0, n, len(psi) - 4), [0, 1, 2, 3]])
        np.testing.assert_array_equal(widths_across(patch, rows, psi), _all_rays(patch, rows, psi))


def test_widths_on_unevenly_spaced_rays_take_every_ray(rng):
    from swath.contact.model import LocalPatch
    from swath.contact.widths import _even_ray_spacing, widths_across

    phi = np.sort(rng.uniform(0, 2 * np.pi, 50))
    assert _even_ray_spacing(phi) is None
    assert _even_ray_spacing((np.arange(180) + 0.5) * 2 * np.pi / 180) == pytest.approx(2 * np.pi / 180)
    patch = LocalPatch(np.zeros(5), phi, np.zeros((5, 50)), 0.02 * (1 + rng.random((5, 50))))
    rows, psi = rng.integers(0, 5, 300), rng.uniform(-np.pi, np.pi, 300)
    np.testing.assert_array_equal(widths_across(patch, rows, psi), _all_rays(patch, rows, psi))


def test_widths_near_the_query_on_the_working_mesh_of_a_real_part(context, rng):
    # every vertex of the working mesh, across its gradient direction and across random ones
    W, model = context.work, context.widths
    idx = np.arange(len(W.vertices))
    feed = np.cross(W.normals, rng.normal(size=(len(idx), 3)))
    n = W.normals
    t = feed - np.einsum("ij,ij->i", feed, n)[:, None] * n
    cross = np.cross(n, t / np.linalg.norm(t, axis=1, keepdims=True))
    psi = np.arctan2(np.einsum("ij,ij->i", cross, model.curvature.d2), np.einsum("ij,ij->i", cross, model.curvature.d1))
    np.testing.assert_array_equal(model.across(idx, feed), _all_rays(model.patch, model.inverse[idx], psi))


def _numpy_frontier(faces, covered):
    c = covered[faces]
    mixed = c.any(axis=1) & ~c.all(axis=1)
    return np.unique(faces[mixed][c[mixed]])


def test_compiled_frontier_is_the_numpy_one(context, rng):
    W = context.work
    d = np.linalg.norm(W.vertices - W.vertices[0], axis=1)
    for covered in (d < 0.3 * d.max(), rng.random(len(d)) < 0.5, np.zeros(len(d), bool), np.ones(len(d), bool)):
        got = context.frontier(covered)
        expected = _numpy_frontier(np.asarray(W.faces), covered)
        np.testing.assert_array_equal(got, expected)
        assert got.dtype == expected.dtype
    assert 0 < len(context.frontier(d < 0.3 * d.max())) < len(d)


def _all_pairs_within(points, others, reach):
    return bool(np.min(np.linalg.norm(points[:, None, :] - others[None, :, :], axis=2)) <= reach)


def test_fill_pass_reach_test_is_the_answer_of_every_pair(rng):
    from swath.plan.gaps import _comes_within

    others = rng.random((50, 3)) * [0.3, 0.01, 0.01]
    for _ in range(200):
        points = rng.random((rng.integers(1, 400), 3)) * 0.3
        reach = float(rng.uniform(0.001, 0.08))
        assert _comes_within(points, others, reach) == _all_pairs_within(points, others, reach)
    # exactly at reach (a 3-4-5 triangle), just inside and just outside
    points, others = np.array([[0.0, 0.003, 0.004], [1.0, 1.0, 1.0]]), np.zeros((1, 3))
    assert _comes_within(points, others, 0.005) and _all_pairs_within(points, others, 0.005)
    below = np.nextafter(0.005, 0)
    assert _comes_within(points, others, below) == _all_pairs_within(points, others, below)
    assert not _comes_within(points, others, 0.0049)


def test_gap_patches_are_the_connected_uncovered_samples_in_label_order(rng):
    """Grouping the uncovered samples by component with one sort gives the patches of testing each
    label in turn: the same members, in the same order, patches in label order."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    surface = doubly_curved_panel(spacing=8e-3)
    tp = raster(surface, TOOL, spacing=0.09, fill_gaps=False)
    check = CoverageCheck(surface, TOOL, np.asarray(tp.metadata["feed_direction"]))
    patches = check.gap_patches(tp.passes, min_share=0.0)
    free = np.flatnonzero(~check.covered(tp.passes))
    pairs = cKDTree(check.points[free]).query_pairs(1.5 * check.step, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(free), len(free)))
    _, label = connected_components(graph, directed=False)
    expected = [free[label == lab] for lab in np.unique(label)]
    assert len(patches) == len(expected) > 1
    for got, want in zip(patches, expected):
        np.testing.assert_array_equal(got, want)


def _chain_by_graph_search(ends: np.ndarray, seg_face: np.ndarray, n_nodes: int):
    """The chains as the slicer found them before the compiled walk: closed loops cut at their
    lowest-numbered segment, one depth-first traversal from a virtual root joined to one end of
    every chain visiting each chain in order."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components, depth_first_order

    S = len(ends)
    adj = sp.coo_matrix((np.ones(2 * S), (np.r_[ends[:, 0], ends[:, 1]], np.r_[ends[:, 1], ends[:, 0]])),
                        shape=(n_nodes, n_nodes)).tocsr()
    _, label = connected_components(adj, directed=False)
    degree = np.bincount(ends.ravel(), minlength=n_nodes)
    n_comp = int(label.max()) + 1
    seg_label = label[ends[:, 0]]
    open_ends = np.bincount(label, weights=(degree == 1), minlength=n_comp)
    has_seg = np.bincount(seg_label, minlength=n_comp) > 0
    is_loop = has_seg & (open_ends == 0)

    # Cut each loop at its first segment.
    comp_first_seg = np.full(n_comp, -1)
    first_idx = np.unique(seg_label, return_index=True)
    comp_first_seg[first_idx[0]] = first_idx[1]
    cut = comp_first_seg[is_loop]
    keep = np.ones(S, bool)
    keep[cut] = False
    kept = ends[keep]

    # Start of each chain: the loop's cut segment's first node, or the lowest-numbered open end.
    start = np.full(n_comp, -1)
    start[np.nonzero(is_loop)[0]] = ends[cut, 0]
    openers = np.nonzero(degree == 1)[0]
    lab_open = label[openers]
    uniq_lab, first_open = np.unique(lab_open, return_index=True)
    start[uniq_lab] = openers[first_open]
    comps = np.nonzero(has_seg)[0]
    root = n_nodes
    rows = np.r_[kept[:, 0], kept[:, 1], np.full(len(comps), root)]
    cols = np.r_[kept[:, 1], kept[:, 0], start[comps]]
    g = sp.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n_nodes + 1, n_nodes + 1)).tocsr()
    order = depth_first_order(g, root, directed=True, return_predecessors=False)[1:]
    lab = label[order]
    breaks = np.nonzero(lab[1:] != lab[:-1])[0] + 1
    chains = np.split(order, breaks)

    # Face of each consecutive pair, looked up by the sorted node pair.
    seg_key = np.minimum(ends[:, 0], ends[:, 1]) * np.int64(n_nodes) + np.maximum(ends[:, 0], ends[:, 1])
    key_order = np.argsort(seg_key)
    sorted_keys = seg_key[key_order]
    loop_of = dict(zip(np.nonzero(is_loop)[0].tolist(), cut.tolist()))
    faces_out, closed_out, chains_out = [], [], []
    for ch in chains:
        comp = int(label[ch[0]])
        if comp in loop_of:
            ch = np.append(ch, ch[0])
        u, v = ch[:-1], ch[1:]
        k = np.minimum(u, v) * np.int64(n_nodes) + np.maximum(u, v)
        faces_out.append(seg_face[key_order[np.searchsorted(sorted_keys, k)]])
        closed_out.append(comp in loop_of)
        chains_out.append(ch)
    return chains_out, closed_out, faces_out


def _random_chains(rng, n_chains):
    """Segments (S, 2) of random open chains and loops over shuffled node numbers, in random order,
    with some nodes left without a segment."""
    sizes = rng.integers(1, 12, n_chains)
    loops = rng.random(n_chains) < 0.4
    n_nodes = int(sizes.sum() + n_chains + 5)
    label = rng.permutation(n_nodes)
    segs, at = [], 0
    for k, loop in zip(sizes, loops):
        path = list(range(at, at + k + 1))
        at += k + 1
        pairs = list(zip(path[:-1], path[1:]))
        if loop and k >= 2:
            pairs.append((path[-1], path[0]))
        segs += [p if rng.random() < 0.5 else p[::-1] for p in pairs]
    ends = label[np.array(segs)]
    return ends[rng.permutation(len(ends))], n_nodes


def test_compiled_chain_walk_gives_the_chains_of_the_graph_search(rng):
    from swath.plan.slicing import _chain

    for n_chains in (1, 2, 5, 40):
        for _ in range(20):
            ends, n_nodes = _random_chains(rng, n_chains)
            seg_face = rng.permutation(len(ends)) + 100
            got = _chain(ends, seg_face, n_nodes)
            want = _chain_by_graph_search(ends, seg_face, n_nodes)
            assert len(got[0]) == len(want[0]) == n_chains
            for g, w in zip(got[0], want[0]):
                np.testing.assert_array_equal(g, w)
            assert got[1] == want[1]
            for g, w in zip(got[2], want[2]):
                np.testing.assert_array_equal(g, w)


def test_slices_of_a_scan_with_holes_and_a_non_manifold_edge_are_those_of_the_graph_search(monkeypatch):
    from conftest import SHARED_MESH_UNITS, shared_mesh
    from swath.io.mesh import load_mesh
    from swath.plan import slicing

    name = "noether_wavy_mesh_with_hole.ply"
    surface = load_mesh(shared_mesh(name), units=SHARED_MESH_UNITS[name])
    V, F = surface.vertices, surface.faces
    F = np.vstack([F, [[F[0, 0], F[0, 1], F[5, 2]]]])            # a third face on an edge: a branch
    c = np.array([0.3, 1.0, 0.05])
    h = V @ (c / np.linalg.norm(c))
    offsets = np.linspace(h.min(), h.max(), 61)[1:-1]
    fast = slicing.slice_mesh(V, F, c, offsets, values=surface.normals)
    monkeypatch.setattr(slicing, "_chain", _chain_by_graph_search)
    slow = slicing.slice_mesh(V, F, c, offsets, values=surface.normals)
    assert len(fast) == len(slow) > 60
    for a, b in zip(fast, slow):
        np.testing.assert_array_equal(a.points, b.points)
        np.testing.assert_array_equal(a.faces, b.faces)
        np.testing.assert_array_equal(a.values, b.values)
        assert (a.plane, a.closed) == (b.plane, b.closed)


def test_plane_slicer_gives_the_slices_of_the_whole_mesh():
    """Fill passes slice one piece again and again: looking only at the faces a plane can cut
    gives the polylines of slicing every face, bit for bit, through vertices and on long slivers."""
    from conftest import SHARED_MESH_UNITS, shared_mesh
    from swath.io.mesh import load_mesh
    from swath.plan.slicing import PlaneSlicer, slice_mesh

    for name in ("noether_wavy_mesh_with_hole.ply", "crs_part_5.stl"):
        surface = load_mesh(shared_mesh(name), units=SHARED_MESH_UNITS[name])
        V, F = surface.vertices, surface.faces
        c = np.array([0.2, 1.0, 0.1])
        slicer = PlaneSlicer(V, F, c, values=surface.normals)
        h = slicer.heights
        offsets = np.concatenate([np.linspace(h.min(), h.max(), 41), h[::max(len(h) // 20, 1)]])   # through vertices too
        n_cut = 0
        for d in offsets:
            got, want = slicer(d), slice_mesh(V, F, c, [d], values=surface.normals)
            assert len(got) == len(want)
            n_cut += len(got)
            for a, b in zip(got, want):
                np.testing.assert_array_equal(a.points, b.points)
                np.testing.assert_array_equal(a.faces, b.faces)
                np.testing.assert_array_equal(a.values, b.values)
                assert (a.plane, a.closed) == (b.plane, b.closed)
        assert n_cut >= 40                                  # most planes cut the part


def test_component_labels_are_those_of_the_sparse_graph_search(rng):
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    from swath.plan.gaps import component_labels

    for n, e in ((1, 0), (5, 0), (50, 30), (2000, 1500), (2000, 4000)):
        pairs = rng.integers(0, n, (e, 2))
        graph = coo_matrix((np.ones(e), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
        count, expected = connected_components(graph, directed=False)
        got = component_labels(n, pairs)
        np.testing.assert_array_equal(got, expected)
        assert got.max() + 1 == count


def test_pad_neighbours_are_the_ball_queries(rng):
    """The neighbour pairs of the coverage check's reach bound are those of a ball query per point,
    at every radius, with points sitting exactly on a radius and repeated points among them."""
    from swath.plan.gaps import pad_neighbours

    points = rng.random((600, 3)) * [0.3, 0.2, 0.02]
    points = np.vstack([points, points[:5], [[0.0, 0.0, 0.0], [0.03, 0.04, 0.0]]])   # a 3-4-5 pair at 0.05
    tree = cKDTree(points)
    rows = pad_neighbours(tree, [0.05, 0.0125, 0.1, 0.025])
    assert [r for r, _, _ in rows] == [0.0125, 0.025, 0.05, 0.1]
    for radius, i, j in rows:
        balls = tree.query_ball_point(points, radius)
        expected = {(k, m) for k, ball in enumerate(balls) for m in ball}
        assert len(i) == len(j) == len(expected) == len(set(zip(i.tolist(), j.tolist())))
        assert set(zip(i.tolist(), j.tolist())) == expected


def test_a_pass_length_worked_out_once_is_its_polyline_length(rng):
    """``Pass.length`` is remembered (the candidate directions and the order stage ask for it again
    and again); it is the polyline's length, for the pass, its reversal and a changed copy."""
    import math

    from swath.core import Pass

    pts = np.cumsum(rng.normal(size=(50, 3)), axis=0) * 1e-3
    p = Pass(pts, np.tile([0.0, 0.0, 1.0], (50, 1)))
    expected = sum(math.dist(a, b) for a, b in zip(pts[:-1], pts[1:]))
    assert p.length == pytest.approx(expected, rel=1e-12)
    assert p.length == p.length == float(np.linalg.norm(np.diff(p.points, axis=0), axis=1).sum())
    assert p.reversed().length == pytest.approx(expected, rel=1e-12)
    shorter = p.replace(points=pts[:2], normals=p.normals[:2])
    assert shorter.length == pytest.approx(math.dist(pts[0], pts[1]), rel=1e-12)


def test_the_surface_edge_lengths_are_those_the_halving_measures(rng):
    """The coverage check takes the long triangles from ``Surface.edge_lengths``: the same numbers,
    bit for bit, as the halving's own measure of each corner's edge."""
    from swath.examples import blade

    for surface in (blade(), doubly_curved_panel(spacing=8e-3)):
        V, F = surface.vertices, surface.faces
        d = V[F] - V[F[:, [1, 2, 0]]]
        np.testing.assert_array_equal(surface.edge_lengths.reshape(-1, 3), ((d * d).sum(axis=2)) ** 0.5)


def test_resampling_every_fragment_at_once_gives_the_samples_of_each_alone(rng):
    """A plan's fragments are resampled in one compiled walk: the points, faces and values of
    resampling each alone, bit for bit, on the slices of a scan with a hole (planes through
    vertices too), a closed loop, and polylines with repeated points and shorter than the spacing."""
    from conftest import SHARED_MESH_UNITS, shared_mesh
    from swath.io.mesh import load_mesh
    from swath.plan.resampling import resample_all
    from swath.plan.slicing import SlicePolyline, resample, slice_mesh

    name = "noether_wavy_mesh_with_hole.ply"
    surface = load_mesh(shared_mesh(name), units=SHARED_MESH_UNITS[name])
    V = surface.vertices
    lines = []
    for c in ([1.0, 0.0, 0.0], [0.3, 1.0, 0.05]):
        h = V @ (np.asarray(c) / np.linalg.norm(c))
        offsets = np.concatenate([np.linspace(h.min(), h.max(), 31)[1:-1], h[::97]])    # through vertices too
        lines += slice_mesh(V, surface.faces, c, offsets, values=surface.normals)
    assert len(lines) > 60
    t = np.linspace(0.0, 2 * np.pi, 33)
    loop = np.column_stack([0.1 * np.cos(t), 0.07 * np.sin(t), 0.01 * np.sin(3 * t)])
    loop[-1] = loop[0]                                               # a closed loop
    lines.append(SlicePolyline(loop, np.arange(32), np.tile([0.0, 0.0, 1.0], (33, 1)), 2, True))
    pts = np.cumsum(rng.normal(size=(40, 3)), axis=0) * 1e-3
    pts[7] = pts[6]                                                  # a zero-length segment
    lines.append(SlicePolyline(pts, np.arange(39), rng.normal(size=(40, 3)), 0, False))
    lines.append(SlicePolyline(pts[:2] * [1, 1, 1], np.arange(1), rng.normal(size=(2, 3)), 1, False))
    for spacing in (1e-3, 4e-3, 0.05):
        got = resample_all(lines, spacing)
        assert len(got) == len(lines)
        for pl, g in zip(lines, got):
            want = resample(pl, spacing)
            np.testing.assert_array_equal(g.points, want.points)
            np.testing.assert_array_equal(g.faces, want.faces)
            np.testing.assert_array_equal(g.values, want.values)
    bare = [SlicePolyline(pl.points, pl.faces, None, pl.plane, pl.closed) for pl in lines[:20]]
    for pl, g in zip(bare, resample_all(bare, 2e-3)):
        np.testing.assert_array_equal(g.points, resample(pl, 2e-3).points)
        assert g.values is None
    assert resample_all([], 1e-3) == []
    with pytest.raises(InputError, match="spacing"):
        resample_all(lines[:1], 0.0)


@pytest.mark.parametrize("step", [4e-3, 1.0])
def test_coverage_base_areas_are_those_of_the_faces_kept(step):
    """The coverage check's vertex areas of the faces it does not halve come from the surface's own
    face (or vertex) areas: the numbers of working the kept faces' areas out again, bit for bit,
    with long faces to halve (4 mm) and without (1 m)."""
    from swath.plan.gaps import _coverage_base
    from swath.surface.geometry import face_normals_and_areas, vertex_areas

    surface = doubly_curved_panel(spacing=6e-3)
    V, F = surface.vertices, surface.faces
    base = _coverage_base(surface, cKDTree(V[::7]), step)
    d = V[F] - V[F[:, [1, 2, 0]]]
    long_face = ((((d * d).sum(axis=2)) ** 0.5) > step).any(axis=1)
    kept = F[~long_face]
    np.testing.assert_array_equal(base.areas, vertex_areas(len(V), kept, face_normals_and_areas(V, kept)[1]))
    np.testing.assert_array_equal(base.split, F[long_face])
    assert (len(base.split) > 0) == (step < 0.01)


def _mesh_edges_by_unique(faces):
    """The edge table as :func:`swath.surface.topology.mesh_edges` made it with ``np.unique``."""
    f = np.asarray(faces, np.int64)
    pairs = np.sort(np.stack([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]], axis=1).reshape(-1, 2), axis=1)
    n = np.int64(pairs.max() + 1) if len(pairs) else np.int64(1)
    keys, inverse = np.unique(pairs[:, 0] * n + pairs[:, 1], return_inverse=True)
    return np.stack([keys // n, keys % n], axis=1), inverse.reshape(-1, 3)


def test_mesh_edges_are_those_of_the_sorted_unique_keys(rng):
    """The edge table from a counting sort is the one of ``np.unique`` on the edge keys, bit for bit:
    on a real scan, on random faces with repeated and degenerate triangles, and around a vertex
    shared by 600 triangles; an empty mesh gives empty tables."""
    from conftest import SHARED_MESH_UNITS, shared_mesh
    from swath.io.mesh import load_mesh
    from swath.plan.raster import piece_vertices
    from swath.surface.topology import mesh_edges

    name = "noether_wavy_mesh_with_hole.ply"
    scan = load_mesh(shared_mesh(name), units=SHARED_MESH_UNITS[name])
    soup = rng.integers(0, 400, size=(3000, 3))
    soup[:50] = soup[50:100]                                       # repeated triangles
    soup[100:120, 1] = soup[100:120, 0]                            # degenerate ones
    fan = np.column_stack([np.zeros(600, np.int64), 1 + np.arange(600), 1 + (np.arange(600) + 1) % 600])
    for faces in (scan.faces, soup, fan, fan[::-1] + 3):
        got, want = mesh_edges(faces), _mesh_edges_by_unique(faces)
        for g, w in zip(got, want):
            assert g.dtype == w.dtype and g.shape == w.shape
            np.testing.assert_array_equal(g, w)
    edges, face_edges = mesh_edges(np.zeros((0, 3), np.int64))
    assert edges.shape == (0, 2) and face_edges.shape == (0, 3)
    pieces = scan.face_pieces()
    for k in range(len(pieces)):
        np.testing.assert_array_equal(piece_vertices(scan, pieces, k), np.unique(scan.faces[pieces[k]]))
