"""Surface record and curvature against analytic answers."""

import numpy as np
import pytest

from shapes import cylinder_patch, sphere_cap
from swath.errors import InputError
from swath.examples import blade, doubly_curved_panel, flat_plate
from swath.surface import Surface


def interior(surface, margin):
    """Vertices at least ``margin`` from the boundary."""
    loops = surface.boundary_loops
    b = np.concatenate(loops) if loops else np.zeros(0, int)
    d, _ = __import__("scipy.spatial", fromlist=["cKDTree"]).cKDTree(surface.vertices[b]).query(surface.vertices)
    return d > margin


def test_sphere_curvature_is_one_over_r():
    s = sphere_cap(0.1, 0.6)
    inside = interior(s, 0.01)
    c = s.curvature
    assert np.allclose(c.k1[inside], 10.0, rtol=0.01)
    assert np.allclose(c.k2[inside], 10.0, rtol=0.01)
    # outward normals = radial direction
    radial = s.vertices / np.linalg.norm(s.vertices, axis=1, keepdims=True)
    assert np.all(np.einsum("ij,ij->i", s.normals, radial) > 0.9999)


def test_cylinder_curvature_is_one_over_r_and_zero():
    s = cylinder_patch(0.05, 1.0, 0.3)
    inside = interior(s, 0.01)
    c = s.curvature
    assert np.allclose(c.k1[inside], 20.0, rtol=0.01)
    assert np.allclose(c.k2[inside], 0.0, atol=0.05)
    # k1 direction runs round the axis (perpendicular to y), k2 along it
    assert np.all(np.abs(c.d2[inside, 1]) > 0.999)


def test_concave_cylinder_has_negative_curvature():
    s = cylinder_patch(0.2, 0.8, 0.3, concave=True)
    inside = interior(s, 0.02)
    c = s.curvature
    assert np.allclose(c.k2[inside], -5.0, rtol=0.01)
    assert np.allclose(c.k1[inside], 0.0, atol=0.05)


def test_plane_curvature_is_zero_and_normals_up():
    s = flat_plate()
    assert np.allclose(s.curvature.k1, 0.0, atol=1e-9)
    assert np.allclose(s.curvature.k2, 0.0, atol=1e-9)
    assert np.allclose(s.normals, [0, 0, 1])
    assert s.area == pytest.approx(0.4 * 0.3)
    assert len(s.boundary_loops) == 1 and len(s.boundary_loops[0]) == 2 * (80 + 60)


def test_panel_principal_curvatures_at_crown():
    s = doubly_curved_panel()
    i = np.argmin(np.linalg.norm(s.vertices[:, :2], axis=1))
    assert s.curvature.k1[i] == pytest.approx(1 / 0.35, rel=0.01)
    assert s.curvature.k2[i] == pytest.approx(1 / 0.9, rel=0.01)


def test_blade_leading_edge_radius_matches_naca_formula():
    b = blade()
    i = np.argmin(b.vertices[:, 0] + 10 * np.abs(b.vertices[:, 1] - 0.3))
    r_le = 1.1019 * 0.12**2 * 0.4
    assert b.curvature.k1[i] == pytest.approx(1 / r_le, rel=0.06)
    assert b.normals[i, 0] == pytest.approx(-1.0, abs=1e-3)
    # normals point out of the material: up on the upper surface, down on the lower
    upper = (b.vertices[:, 2] > 0.01)
    lower = (b.vertices[:, 2] < -0.01)
    assert np.all(b.normals[upper, 2] > 0) and np.all(b.normals[lower, 2] < 0)


def test_surface_refuses_bad_arrays():
    with pytest.raises(InputError, match="NaN or infinite"):
        Surface([[0, 0, 0], [1, 0, 0], [np.nan, 1, 0]], [[0, 1, 2]])
    with pytest.raises(InputError, match="no area"):
        Surface([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1, 2]])
    with pytest.raises(InputError, match="face indices must lie"):
        Surface([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 3]])
    with pytest.raises(InputError, match="expected vertices of shape"):
        Surface(np.zeros((3, 2)), [[0, 1, 2]])


def test_surface_arrays_are_read_only():
    s = flat_plate()
    with pytest.raises(ValueError):
        s.vertices[0, 0] = 1.0
    with pytest.raises(ValueError):
        s.normals[0, 0] = 1.0


def test_closest_points_and_interpolated_normals_on_sphere():
    s = sphere_cap(0.1, 0.5)
    q = np.array([[0.0, 0.0, 0.13], [0.02, -0.01, 0.09]])
    p, d, f = s.closest_points(q)
    assert np.allclose(np.linalg.norm(p, axis=1), 0.1, atol=2e-5)
    n = s.interpolate_normals(p, f)
    assert np.allclose(n, p / np.linalg.norm(p, axis=1, keepdims=True), atol=1e-3)


def test_closest_points_far_from_origin_and_after_pickling():
    """A plate placed 2 m out in a robot cell: a point 5 mm above it maps straight down, exactly;
    the surface survives a pickle round trip (its libigl tree is rebuilt, not copied)."""
    import pickle

    plate = flat_plate()
    offset = np.array([2.0, -1.5, 0.8])
    moved = Surface(plate.vertices + offset, plate.faces)
    lo, hi = plate.bounds
    q = offset + np.array([[0.1234, 0.0456, 0.005], [hi[0] + 0.3, 0.1, 0.02]])   # second: beyond the edge
    p, d, _ = moved.closest_points(q)
    assert np.allclose(p[0], q[0] - [0, 0, 0.005], atol=1e-12)
    assert d[0] == pytest.approx(0.005, abs=1e-12)
    assert d[1] == pytest.approx(np.hypot(0.3, 0.02), abs=1e-9)
    again = pickle.loads(pickle.dumps(moved))
    assert np.array_equal(again.closest_points(q)[0], p)
