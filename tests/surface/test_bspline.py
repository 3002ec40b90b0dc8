"""BSplinePatch: basis functions, exact differential geometry on exact NURBS, projection,
triangulation and the JSON round trip."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.interpolate import BSpline

from swath.errors import InputError
from swath.io.patch import load_patch_json, save_patch_json
from swath.surface import Surface
from swath.surface.bspline import BSplinePatch
from swath.surface.bspline_basis import basis_derivatives, clamped_knots
from swath.surface.exact_shapes import circle_arc, nurbs_cylinder, nurbs_sphere, nurbs_torus


def _dense(span, vals, n):
    out = np.zeros((len(span), n))
    for a in range(vals.shape[1]):
        out[np.arange(len(span)), span - vals.shape[1] + 1 + a] = vals[:, a]
    return out


@pytest.mark.parametrize("degree", [1, 2, 3, 4])
def test_basis_and_derivatives_match_scipy(degree, rng):
    knots = clamped_knots([0.1, 0.25, 0.6, 0.8], degree, (0.0, 1.0))
    n = len(knots) - degree - 1
    x = np.concatenate([rng.uniform(0, 1, 200), [0.0, 0.25, 0.6, 1.0]])
    span, ders = basis_derivatives(knots, degree, x, order=2)
    assert np.allclose(ders[0].sum(axis=1), 1.0)                      # partition of unity
    ref = BSpline(knots, np.eye(n), degree)
    assert np.allclose(_dense(span, ders[0], n), ref(x), atol=1e-13)
    for d in range(1, min(degree, 2) + 1):
        assert np.allclose(_dense(span, ders[d], n), ref.derivative(d)(x), atol=1e-9)
    if degree < 2:
        assert np.all(ders[2] == 0)


def test_basis_with_repeated_knot(rng):
    knots = clamped_knots([0.3, 0.3, 0.7], 3, (0.0, 1.0))
    n = len(knots) - 4
    x = np.concatenate([rng.uniform(0, 1, 100), [0.3, 1.0]])
    span, ders = basis_derivatives(knots, 3, x, order=1)
    assert np.allclose(_dense(span, ders[0], n), BSpline(knots, np.eye(n), 3)(x), atol=1e-13)
    assert (knots[span] <= x).all() and (x <= knots[span + 1]).all()


def _random_nurbs(rng, nu=6, nv=5, p=3, q=2):
    ctrl = rng.normal(size=(nu, nv, 3))
    ku = clamped_knots(np.sort(rng.uniform(0, 1, nu - p - 1)), p, (0, 1))
    kv = clamped_knots(np.sort(rng.uniform(0, 2, nv - q - 1)), q, (0, 2))
    return BSplinePatch(ctrl, ku, kv, (p, q), rng.uniform(0.5, 2.0, (nu, nv)))


def test_rational_derivatives_match_finite_differences(rng):
    patch = _random_nurbs(rng)
    u = rng.uniform(0.05, 0.95, 30)
    v = rng.uniform(0.1, 1.9, 30)
    D = patch.derivatives(u, v, 2)
    h = 1e-5
    S = patch.evaluate
    assert np.allclose(D[:, 0, 0], S(u, v))
    assert np.allclose(D[:, 1, 0], (S(u + h, v) - S(u - h, v)) / (2 * h), rtol=1e-6, atol=1e-6)
    assert np.allclose(D[:, 0, 1], (S(u, v + h) - S(u, v - h)) / (2 * h), rtol=1e-6, atol=1e-6)
    h = 1e-4
    assert np.allclose(D[:, 2, 0], (S(u + h, v) - 2 * S(u, v) + S(u - h, v)) / h**2, rtol=1e-4, atol=1e-3)
    assert np.allclose(D[:, 0, 2], (S(u, v + h) - 2 * S(u, v) + S(u, v - h)) / h**2, rtol=1e-4, atol=1e-3)
    mixed = (S(u + h, v + h) - S(u + h, v - h) - S(u - h, v + h) + S(u - h, v - h)) / (4 * h * h)
    assert np.allclose(D[:, 1, 1], mixed, rtol=1e-4, atol=1e-3)


def test_circle_arc_is_exact():
    ctrl, w, k = circle_arc(0.3, 0.2, 4.0, centre=(1.0, -2.0))
    patch_like = BSpline(k, np.column_stack([ctrl * w[:, None], w]), 2)
    t = np.linspace(0, 1, 101)
    hw = patch_like(t)
    pts = hw[:, :2] / hw[:, 2:]
    assert np.allclose(np.linalg.norm(pts - [1.0, -2.0], axis=1), 0.3, rtol=1e-13)
    ang = np.unwrap(np.arctan2(pts[:, 1] + 2.0, pts[:, 0] - 1.0))
    assert ang[0] == pytest.approx(0.2) and ang[-1] == pytest.approx(4.2)


def test_cylinder_curvature_and_frames(rng):
    r = 0.2
    cyl = nurbs_cylinder(r, 0.5, sweep=1.5 * np.pi)
    u = rng.uniform(*cyl.domain[0], 200)
    v = rng.uniform(*cyl.domain[1], 200)
    P = cyl.evaluate(u, v)
    assert np.allclose(np.hypot(P[:, 0], P[:, 1]), r, rtol=1e-12)
    c = cyl.curvature(u, v)
    assert np.allclose(c.k1, 1 / r, rtol=1e-6)              # outward normals: convex, +1/r
    assert np.allclose(c.k2, 0.0, atol=1e-6 / r)
    assert np.allclose(np.abs(c.d2[:, 2]), 1.0, atol=1e-9)  # zero curvature along the axis
    assert np.allclose(c.d1[:, 2], 0.0, atol=1e-9)
    n = cyl.normals(u, v)
    assert np.allclose(n[:, :2], P[:, :2] / r, atol=1e-12)   # outward
    inward = nurbs_cylinder(r, 0.5, outward=False).curvature(u % 1.0, v)
    assert np.allclose(inward.k2, -1 / r, rtol=1e-6) and np.allclose(inward.k1, 0.0, atol=1e-6)


def test_sphere_curvature_and_forms(rng):
    r = 0.3
    sph = nurbs_sphere(r, lat=(-1.2, 1.0), lon=(0.3, 2.5))
    u = rng.uniform(*sph.domain[0], 200)
    v = rng.uniform(*sph.domain[1], 200)
    P = sph.evaluate(u, v)
    assert np.allclose(np.linalg.norm(P, axis=1), r, rtol=1e-12)
    c = sph.curvature(u, v)
    assert np.allclose(c.k1, 1 / r, rtol=1e-6) and np.allclose(c.k2, 1 / r, rtol=1e-6)
    assert np.allclose(np.einsum("ij,ij->i", sph.normals(u, v), P / r), 1.0)
    first, second = sph.fundamental_forms(u, v)
    assert np.allclose(second, -first / r, rtol=1e-9, atol=1e-12)     # II = -I / r (n outward)
    S = sph.shape_operator(u, v)
    assert np.allclose(S, np.eye(2) / r, rtol=1e-9, atol=1e-9)


def test_torus_principal_curvatures_and_directions(rng):
    R, a = 0.5, 0.12
    tor = nurbs_torus(R, a)
    u = rng.uniform(*tor.domain[0], 500)
    v = rng.uniform(*tor.domain[1], 500)
    P = tor.evaluate(u, v)
    rho = np.hypot(P[:, 0], P[:, 1])
    assert np.allclose(np.hypot(rho - R, P[:, 2]), a, rtol=1e-12)
    theta = np.arctan2(P[:, 2], rho - R)
    k_tube = np.full_like(theta, 1 / a)
    k_axis = np.cos(theta) / (R + a * np.cos(theta))
    c = tor.curvature(u, v)
    assert np.allclose(c.k1, np.maximum(k_tube, k_axis), rtol=1e-6)
    assert np.allclose(c.k2, np.minimum(k_tube, k_axis), rtol=1e-6, atol=1e-9)
    # The tube curvature's direction lies in the meridian plane (no azimuthal component).
    azimuth = np.stack([-P[:, 1], P[:, 0], np.zeros(len(P))], axis=1) / rho[:, None]
    assert np.allclose(np.einsum("ij,ij->i", c.d1, azimuth), 0.0, atol=1e-9)
    assert np.allclose(np.einsum("ij,ij->i", c.d1, c.d2), 0.0, atol=1e-12)
    # Shape-operator eigenvalues are the principal curvatures.
    ev = np.sort(np.linalg.eigvals(tor.shape_operator(u, v)).real, axis=1)
    assert np.allclose(ev[:, 1], c.k1, rtol=1e-6) and np.allclose(ev[:, 0], c.k2, rtol=1e-6, atol=1e-9)


def test_flipped_reverses_normal_and_curvature_sign(rng):
    sph = nurbs_sphere(0.25)
    f = sph.flipped()
    u = rng.uniform(*sph.domain[0], 50)
    v = rng.uniform(*sph.domain[1], 50)
    uf = sph.domain[0].sum() - u
    assert np.allclose(f.evaluate(uf, v), sph.evaluate(u, v), atol=1e-14)
    assert np.allclose(f.normals(uf, v), -sph.normals(u, v), atol=1e-12)
    assert np.allclose(f.curvature(uf, v).k1, -4.0, rtol=1e-6)


def test_project_recovers_offset_points(rng):
    R, a = 0.5, 0.1
    tor = nurbs_torus(R, a)
    u = rng.uniform(*tor.domain[0], 2000)
    v = rng.uniform(*tor.domain[1], 2000)
    off = rng.uniform(-0.05, 0.05, 2000)
    X = tor.evaluate(u, v) + off[:, None] * tor.normals(u, v)
    uu, vv, dist = tor.project(X)
    assert np.allclose(dist, np.abs(off), atol=1e-9)           # including points across the seams
    assert np.allclose(tor.evaluate(uu, vv), tor.evaluate(u, v), atol=1e-8)


def test_project_clamps_to_the_domain():
    cyl = nurbs_cylinder(0.2, 0.5, sweep=np.pi / 2)        # quarter cylinder, z in [0, 0.5]
    X = np.array([[0.0, 0.3, 0.8],                      # above the top edge
                  [-0.3, 0.0, 0.2]])                    # beyond the angular range
    u, v, d = cyl.project(X)
    P = cyl.evaluate(u, v)
    assert P[0] == pytest.approx([0.0, 0.2, 0.5], abs=1e-9)
    assert d[0] == pytest.approx(np.hypot(0.1, 0.3), abs=1e-9)
    assert P[1] == pytest.approx([0.0, 0.2, 0.2], abs=1e-9)   # nearest point of the edge at 90°
    assert (u >= cyl.domain[0, 0]).all() and (v <= cyl.domain[1, 1]).all()


def test_to_surface_triangulates_on_the_patch(rng):
    sph = nurbs_sphere(0.3, lat=(-0.5, 0.7), lon=(0.0, 1.2))
    surf = sph.to_surface(spacing=0.01)
    assert isinstance(surf, Surface)
    assert np.allclose(np.linalg.norm(surf.vertices, axis=1), 0.3, rtol=1e-12)
    # Edge lengths near the requested spacing, faces facing the patch normal (outward).
    e = surf.edge_lengths
    assert np.median(e) == pytest.approx(0.01, rel=0.35) and e.max() < 0.03
    centroids = surf.vertices[surf.faces].mean(axis=1)
    assert (np.einsum("ij,ij->i", surf.face_normals, centroids) > 0).all()
    exact_area = 0.3**2 * 1.2 * (np.sin(0.7) - np.sin(-0.5))
    assert surf.area == pytest.approx(exact_area, rel=2e-3)
    gu, gv = sph.grid_parameters(resolution=(7, 5))
    coarse = sph.to_surface(resolution=(7, 5))
    assert np.allclose(coarse.vertices, sph.evaluate(np.repeat(gu, 5), np.tile(gv, 7)))   # row-major in u


def test_json_round_trip_is_exact(tmp_path, rng):
    patch = _random_nurbs(rng)
    again = BSplinePatch.from_dict(json.loads(json.dumps(patch.to_dict())))
    assert np.array_equal(again.control_points, patch.control_points)
    assert np.array_equal(again.weights, patch.weights)
    assert np.array_equal(again.knots_u, patch.knots_u) and again.degree == patch.degree
    path = tmp_path / "out" / "patch.json"
    save_patch_json(patch, path)
    loaded = load_patch_json(path)
    u, v = rng.uniform(0, 1, 10), rng.uniform(0, 2, 10)
    assert np.array_equal(loaded.evaluate(u, v), patch.evaluate(u, v))
    assert [p.name for p in path.parent.iterdir()] == ["patch.json"]      # no temporary left behind
    poly = BSplinePatch(patch.control_points, patch.knots_u, patch.knots_v, patch.degree)
    assert BSplinePatch.from_dict(poly.to_dict()).weights is None


def test_load_json_refuses_bad_files(tmp_path):
    with pytest.raises(InputError, match="not found"):
        load_patch_json(tmp_path / "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(InputError, match="not valid JSON.*line 1"):
        load_patch_json(bad)
    other = tmp_path / "other.json"
    other.write_text(json.dumps({"type": "mesh"}))
    with pytest.raises(InputError, match="not a swath B-spline patch"):
        load_patch_json(other)
    d = nurbs_cylinder(0.1, 0.2).to_dict()
    d["knots_u"] = d["knots_u"][:-1]
    broken = tmp_path / "broken.json"
    broken.write_text(json.dumps(d))
    with pytest.raises(InputError, match=r"broken.json.*knot vector u must have"):
        load_patch_json(broken)


def test_constructor_validates():
    ctrl = np.zeros((4, 4, 3))
    k = clamped_knots([], 3, (0, 1))
    with pytest.raises(InputError, match="shape"):
        BSplinePatch(np.zeros((4, 4)), k, k)
    with pytest.raises(InputError, match="non-decreasing"):
        BSplinePatch(ctrl, k[::-1], k)
    with pytest.raises(InputError, match="weights must be positive"):
        BSplinePatch(ctrl, k, k, weights=-np.ones((4, 4)))
    with pytest.raises(InputError, match="at least"):
        BSplinePatch(np.zeros((3, 4, 3)), clamped_knots([], 2, (0, 1))[:-1], k)
    with pytest.raises(InputError, match="outside the patch domain"):
        BSplinePatch(ctrl, k, k).evaluate([1.5], [0.5])
