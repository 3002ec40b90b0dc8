"""Plane slicing of meshes into polylines, and resampling on the surface (swath.plan.slicing)."""

import math

import numpy as np
import pytest

from swath.errors import InputError
from swath.examples import grid_faces
from swath.plan.slicing import MERGE_TOLERANCE, resample, slice_mesh
from swath.surface import Surface
from swath.surface.topology import mesh_edges


def grid(nx, ny, cell, z=None):
    """A flat grid in z = 0 (or heights ``z``) with corner at the origin; coordinates are exact
    binary fractions when ``cell`` is."""
    x = np.arange(nx + 1) * cell
    y = np.arange(ny + 1) * cell
    X, Y = np.meshgrid(x, y, indexing="ij")
    Z = np.zeros_like(X) if z is None else z
    return np.stack([X.ravel(), Y.ravel(), Z.ravel()], 1), grid_faces(nx + 1, ny + 1)


def on_face_check(vertices, faces, pl):
    """Every point of a polyline lies on the closed triangles of the faces of its segments: the end
    of each segment to round-off, its start to the merge tolerance (a merged zero-length piece
    moves it by at most that)."""
    for end, tol in ((1, 1e-12), (0, 10 * MERGE_TOLERANCE)):
        pts = pl.points[end:len(pl.points) - 1 + end]
        tri = vertices[faces[pl.faces]]
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        area2 = np.linalg.norm(n, axis=1)
        n = n / area2[:, None]
        assert np.abs(np.einsum("ij,ij->i", pts - tri[:, 0], n)).max() < tol
        # barycentric coordinates from sub-areas, all >= 0 up to round-off
        for k in range(3):
            a, b = tri[:, (k + 1) % 3], tri[:, (k + 2) % 3]
            sub = np.einsum("ij,ij->i", np.cross(b - a, pts - a), n) / area2
            assert sub.min() > -tol / np.sqrt(area2).min() - 1e-9


def test_mesh_edges_counts_a_grid():
    v, f = grid(3, 2, 1.0)
    edges, face_edges = mesh_edges(f)
    # (nx+1)·ny + nx·(ny+1) axis edges + nx·ny diagonals
    assert len(edges) == 4 * 2 + 3 * 3 + 6
    assert face_edges.shape == (12, 3)
    assert np.array_equal(np.sort(f[:, :2], axis=1), edges[face_edges[:, 0]])


def test_planes_through_grid_lines_and_vertices():
    cell = 1.0 / 64.0
    v, f = grid(24, 16, cell)                       # 0.375 x 0.25 m
    offsets = np.arange(0, 17) * cell               # every grid line, including both borders
    slices = slice_mesh(v, f, [0.0, 1.0, 0.0], offsets)
    planes = [pl.plane for pl in slices]
    # y = 0 is the lower border: every vertex is on or above it, no face is cut (symbolic
    # perturbation); every other line, including the upper border, gives exactly one polyline.
    assert planes == list(range(1, 17))
    for pl in slices:
        assert pl.points[:, 1] == pytest.approx(offsets[pl.plane], abs=0.0)   # exactly on the line
        assert not pl.closed
        assert pl.length == pytest.approx(24 * cell, rel=1e-12)
        seg = np.linalg.norm(np.diff(pl.points, axis=0), axis=1)
        assert seg.min() > MERGE_TOLERANCE                          # zero-length pieces merged away
        assert np.all(np.diff(pl.points[:, 0]) * np.sign(pl.points[-1, 0] - pl.points[0, 0]) > 0)
        on_face_check(v, f, pl)


def test_planes_along_the_diagonal_edges():
    v, f = grid(8, 8, 0.125)
    c = np.array([1.0, -1.0, 0.0])                  # grid_faces splits each cell along a diagonal x − y = const
    offsets = (v @ c / np.linalg.norm(c))[[9 * k for k in range(1, 8)]]   # through vertices (k, 0)
    slices = slice_mesh(v, f, c, offsets)
    assert sorted(pl.plane for pl in slices) == list(range(7))
    for pl in slices:
        k = pl.plane + 1
        assert pl.length == pytest.approx(math.sqrt(2) * 0.125 * (8 - k), rel=1e-12)
        on_face_check(v, f, pl)


def test_a_hole_breaks_the_slice():
    cell = 0.01
    v, f = grid(20, 20, cell)
    cen = v[f].mean(axis=1)
    keep = ~((np.abs(cen[:, 0] - 0.1) < 0.04) & (np.abs(cen[:, 1] - 0.1) < 0.04))
    slices = slice_mesh(v, f[keep], [0, 1, 0], [0.1 + 1e-3, 0.185])
    through = [pl for pl in slices if pl.plane == 0]
    assert len(through) == 2
    xs = sorted((min(pl.points[[0, -1], 0]), max(pl.points[[0, -1], 0])) for pl in through)
    assert xs[0] == pytest.approx((0.0, 0.06)) and xs[1] == pytest.approx((0.14, 0.2))
    assert len([pl for pl in slices if pl.plane == 1]) == 1


def test_branch_at_a_non_manifold_edge_splits_the_chain():
    # A plate z = 0, y in [-0.1, 0.1], and a fin in the plane y = 0 sharing the plate's row of
    # vertices at y = 0: the edges of that row have three faces.
    nx, cell = 10, 0.02
    v, f = grid(nx, 10, cell)
    v[:, 1] -= 0.1
    shared = np.nonzero(np.isclose(v[:, 1], 0.0))[0]             # row y = 0, sorted by x
    nz = 5
    fin_v = np.array([[x, 0.0, (k + 1) * cell] for x in v[shared, 0] for k in range(nz)])
    idx = np.empty((nx + 1, nz + 1), int)
    idx[:, 0] = shared
    idx[:, 1:] = len(v) + np.arange(len(fin_v)).reshape(nx + 1, nz)
    ff = grid_faces(nx + 1, nz + 1)
    fin_f = idx.ravel()[ff]
    V = np.vstack([v, fin_v])
    F = np.vstack([f, fin_f])
    slices = slice_mesh(V, F, [1, 0, 0], [0.105])
    assert len(slices) == 3
    junction = np.array([0.105, 0.0, 0.0])
    ends = [min(np.linalg.norm(pl.points[[0, -1]] - junction, axis=1)) for pl in slices]
    assert max(ends) < 1e-12
    assert sorted(round(pl.length, 9) for pl in slices) == [0.1, 0.1, 0.1]


def test_tube_gives_closed_loops():
    n_th, n_z, r = 36, 5, 0.05
    th = np.arange(n_th) * 2 * np.pi / n_th
    zs = np.linspace(0, 0.2, n_z)
    v = np.array([[r * math.cos(t), r * math.sin(t), z] for t in th for z in zs])
    i, j = np.meshgrid(np.arange(n_th), np.arange(n_z - 1), indexing="ij")
    a = (i * n_z + j).ravel()
    b = (((i + 1) % n_th) * n_z + j).ravel()
    f = np.concatenate([np.stack([a, b, b + 1], 1), np.stack([a, b + 1, a + 1], 1)])
    slices = slice_mesh(v, f, [0, 0, 1], [0.03, 0.05, 0.1])       # 0.05 and 0.1 through vertex rings
    assert len(slices) == 3
    for pl in slices:
        assert pl.closed
        assert np.array_equal(pl.points[0], pl.points[-1])
        assert pl.length == pytest.approx(2 * n_th * r * math.sin(math.pi / n_th), rel=1e-9)
        on_face_check(v, f, pl)


def test_random_bumpy_surface_every_point_on_its_face(rng):
    n = 30
    z = 0.01 * rng.standard_normal((n + 1, n + 1))
    v, f = grid(n, n, 0.01, z)
    c = rng.standard_normal(3)
    c[2] = 0.2
    h = v @ (c / np.linalg.norm(c))
    # Half the planes pass exactly through vertices, the others 1e-13 m beside one.
    picks = rng.choice(len(v), 20, replace=False)
    offsets = np.concatenate([h[picks[:10]], h[picks[10:]] + 1e-13])
    slices = slice_mesh(v, f, c, offsets)
    assert len(slices) >= 20
    for pl in slices:
        on_face_check(v, f, pl)
        assert np.abs(pl.points @ (c / np.linalg.norm(c)) - offsets[pl.plane]).max() < 1e-12
        assert np.linalg.norm(np.diff(pl.points, axis=0), axis=1).min() > MERGE_TOLERANCE


def test_duplicate_faces_and_coincident_vertices_do_not_confuse_chaining():
    v, f = grid(4, 4, 0.25)
    # Duplicate every face and add a vertex 1e-12 m from an existing one, used by two new faces.
    v2 = np.vstack([v, v[12] + [1e-12, 0, 0]])
    f2 = np.vstack([f, f, [[12, 25, 13], [25, 17, 13]]])
    slices = slice_mesh(v2, f2, [0, 1, 0], [0.3, 0.5])
    assert len(slices) >= 2
    for pl in slices:
        assert np.linalg.norm(np.diff(pl.points, axis=0), axis=1).min() > MERGE_TOLERANCE


def test_resample_is_uniform_on_the_mesh_and_interpolates_values():
    from shapes import sphere_cap

    s = sphere_cap(0.2, 0.6, n=40)
    c = np.array([0.3, 1.0, 0.0])
    slices = slice_mesh(s.vertices, s.faces, c, [0.0, 0.05], values=s.normals)
    assert len(slices) == 2
    for pl in slices:
        sm = resample(pl, 2e-3)
        step = np.linalg.norm(np.diff(sm.points, axis=0), axis=1)
        assert step.max() <= 2e-3 * (1 + 1e-9)
        k = math.ceil(pl.length / 2e-3)
        assert len(sm.points) == k + 1
        assert np.array_equal(sm.points[0], pl.points[0]) and np.array_equal(sm.points[-1], pl.points[-1])
        # every sample in the face it is tagged with, on the plane
        tri = s.vertices[s.faces[sm.faces]]
        nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
        assert np.abs(np.einsum("ij,ij->i", sm.points - tri[:, 0], nrm)).max() < 1e-12
        assert np.abs(sm.points @ (c / np.linalg.norm(c)) - [0.0, 0.05][pl.plane]).max() < 1e-12
        # values interpolated along the slice = barycentric interpolation in the face
        n_ref = s.interpolate_normals(sm.points, sm.faces)
        n_lin = sm.values / np.linalg.norm(sm.values, axis=1, keepdims=True)
        assert np.abs(n_lin - n_ref).max() < 1e-9


def test_slice_inputs_are_checked():
    v, f = grid(2, 2, 1.0)
    with pytest.raises(InputError, match="normal"):
        slice_mesh(v, f, [0, 0, 0], [0.5])
    with pytest.raises(InputError, match="offsets must be finite"):
        slice_mesh(v, f, [1, 0, 0], [np.nan])
    with pytest.raises(InputError, match="one row per vertex"):
        slice_mesh(v, f, [1, 0, 0], [0.5], values=np.zeros((3, 3)))
    assert slice_mesh(v, f, [1, 0, 0], [5.0]) == []
    pl = slice_mesh(v, f, [1, 0, 0], [0.5])[0]
    with pytest.raises(InputError, match="positive"):
        resample(pl, 0.0)


def test_surface_arrays_are_accepted_read_only():
    v, f = grid(4, 4, 0.25)
    s = Surface(v, f)
    out = slice_mesh(s.vertices, s.faces, [1, 0, 0], [0.4], values=s.normals)
    assert len(out) == 1 and out[0].values.shape == (len(out[0].points), 3)


def test_level_sets_of_a_distance_field_are_circles():
    from swath.examples import flat_plate
    from swath.plan.slicing import level_sets

    s = flat_plate(spacing=2e-3)
    centre = np.array([0.2, 0.15, 0.0])
    field = np.linalg.norm(s.vertices - centre, axis=1)
    lines = level_sets(s.vertices, s.faces, field, [0.05, 0.1])
    assert [pl.plane for pl in lines] == [0, 1]
    assert all(pl.closed for pl in lines)
    for pl, r in zip(lines, (0.05, 0.1)):
        d = np.linalg.norm(pl.points - centre, axis=1)
        # linear interpolation of |x - c| over 2 mm triangles: chord error below 0.1 mm
        assert np.allclose(d, r, atol=1e-4)
        assert np.linalg.norm(np.diff(pl.points, axis=0), axis=1).sum() == pytest.approx(2 * np.pi * r, rel=2e-3)
    # a face mask stops the level set at the mask's border: keep the half x < 0.2
    half = s.vertices[s.faces].mean(axis=1)[:, 0] < 0.2
    cut = level_sets(s.vertices, s.faces, field, [0.05], face_mask=half)
    assert len(cut) == 1 and not cut[0].closed
    assert cut[0].points[:, 0].max() <= 0.2 + 1e-9
    assert np.all(half[cut[0].faces])
