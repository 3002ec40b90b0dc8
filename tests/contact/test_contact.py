"""The pad contact model against analytic answers (FORMATS.md tool model)."""

import math

import numpy as np
import pytest
from scipy import integrate

from shapes import cylinder_patch, sphere_cap
from swath.contact import Tool, local_patch, mesh_contact, solve_sink
from swath.errors import InputError
from swath.examples import flat_plate


def test_tool_defaults_and_stiffness_from_depression():
    t = Tool()
    assert t.pad_radius == pytest.approx(0.0381) and t.force == 20.0
    assert t.flat_depression == pytest.approx(1e-3)
    assert t.k == pytest.approx(20.0 / (1e-3 * math.pi * 0.0381**2))
    t2 = Tool(stiffness=t.k)
    assert t2.flat_depression == pytest.approx(1e-3)


@pytest.mark.parametrize("kwargs,fragment", [
    (dict(depression=1e-3, stiffness=1e6), "either the pad stiffness or the depression"),
    (dict(force=-1.0), "force must be a positive"),
    (dict(depression=0.05), "depression on flat must lie"),
    (dict(motion="linear"), "motion must be"),
])
def test_tool_refuses_bad_settings(kwargs, fragment):
    with pytest.raises(InputError, match=fragment):
        Tool(**kwargs)


def test_solve_sink_matches_hand_solution():
    # group 0: three samples at z = 0, 1, 2 (area 1): f(s) = s + (s-1) + ... ; target 4 -> s = 7/3
    z = np.array([0.0, 1.0, 2.0, 5.0])
    w = np.array([1.0, 1.0, 1.0, 2.0])
    g = np.array([0, 0, 0, 1])
    s = solve_sink(z, w, g, np.array([4.0, 1.0]))
    assert s[0] == pytest.approx(7.0 / 3.0)
    assert s[1] == pytest.approx(5.5)
    assert np.isnan(solve_sink(z, w, g, np.array([1.0, 1.0, 1.0]))[2])


def test_flat_patch_is_the_whole_pad():
    t = Tool()
    p = local_patch(0.0, 0.0, t)
    assert p.sink[0] == pytest.approx(t.flat_depression, rel=1e-9)
    assert p.contact_area[0] == pytest.approx(t.pad_area, rel=1e-9)
    assert p.width_across(0.3)[0] == pytest.approx(2 * t.pad_radius, rel=2e-4)


def test_flat_plate_mesh_contact_is_the_whole_pad_at_uniform_pressure():
    t = Tool()
    s = flat_plate(spacing=1e-3)
    mc = mesh_contact(s.vertices, s.normals, s.vertex_areas, s.kdtree, np.array([[0.2, 0.15, 0.0]]),
                      np.array([[0.0, 0.0, -1.0]]), t)
    # vertex areas within R add up to πR² only to the sampling resolution
    assert mc.sink[0] == pytest.approx(t.flat_depression, rel=2e-3)
    assert np.allclose(mc.pressure, t.k * mc.sink[0])
    # every sample within R touched, none outside
    r = np.linalg.norm(s.vertices[:, :2] - [0.2, 0.15], axis=1)
    assert set(mc.sample) == set(np.flatnonzero(r <= t.pad_radius))


def test_sphere_sink_and_chord_are_analytic():
    # On a sphere the patch is a disc: F = k π s² ρ (paraboloid), so s = R sqrt(e/ρ)·... exactly
    t = Tool()
    rho = 0.05
    p = local_patch(1 / rho, 1 / rho, t)
    s_expected = t.pad_radius * math.sqrt(t.flat_depression / rho)
    assert p.sink[0] == pytest.approx(s_expected, rel=1e-9)
    assert p.width_across(0.0)[0] == pytest.approx(2 * math.sqrt(2 * s_expected * rho), rel=1e-3)


def test_cylinder_chord_is_2_sqrt_2_e_r():
    t = Tool()
    r = 0.05
    p = local_patch(1 / r, 0.0, t)
    s = p.sink[0]
    # force balance on the strip |x| < sqrt(2 s r) inside the pad disc, by independent quadrature
    f = lambda y, x: t.k * max(s - x * x / (2 * r), 0.0)
    xm = math.sqrt(2 * s * r)
    force, _ = integrate.dblquad(f, -xm, xm, lambda x: -math.sqrt(t.pad_radius**2 - x * x),
                                 lambda x: math.sqrt(t.pad_radius**2 - x * x), epsabs=1e-8)
    assert force == pytest.approx(t.force, rel=1e-3)
    assert p.width_across(0.0)[0] == pytest.approx(2 * math.sqrt(2 * s * r), rel=1e-3)
    assert p.width_across(math.pi / 2)[0] == pytest.approx(2 * t.pad_radius, rel=1e-3)


def test_mesh_contact_on_exact_cylinder_matches_circle_chord():
    t = Tool()
    r = 0.05
    s = cylinder_patch(r, 1.2, 0.2, n_theta=300, n_len=150)
    mc = mesh_contact(s.vertices, s.normals, s.vertex_areas, s.kdtree, np.array([[0.0, 0.0, r]]),
                      np.array([[0.0, 0.0, -1.0]]), t)
    sink = mc.sink[0]
    x = s.vertices[mc.sample, 0]
    chord = x.max() - x.min()
    assert chord == pytest.approx(2 * math.sqrt(2 * sink * r - sink * sink), abs=1.5e-3)
    # the quadric model agrees with the exact mesh model on the sink within a few per cent
    assert sink == pytest.approx(local_patch(1 / r, 0.0, t).sink[0], rel=0.05)


def test_concave_cylinder_rides_on_the_rim():
    t = Tool()
    p = local_patch(0.0, -1 / 0.1, t)
    # rays along the curved direction touch only beyond rho_in > 0
    along_curve = np.abs(np.sin(p.phi)) > 0.99
    assert np.all(p.rho_in[0, along_curve] > 0.005)
    assert p.width_across(np.pi / 2)[0] == pytest.approx(2 * t.pad_radius, rel=1e-3)


def test_sphere_mesh_and_quadric_agree():
    t = Tool()
    s = sphere_cap(0.1, 0.5, n=200)
    mc = mesh_contact(s.vertices, s.normals, s.vertex_areas, s.kdtree, np.array([[0.0, 0.0, 0.1]]),
                      np.array([[0.0, 0.0, -1.0]]), t)
    assert mc.sink[0] == pytest.approx(local_patch(10.0, 10.0, t).sink[0], rel=0.03)
    # force balance holds on the mesh
    assert (mc.pressure * s.vertex_areas[mc.sample]).sum() == pytest.approx(t.force, rel=1e-9)
