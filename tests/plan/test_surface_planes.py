"""Raster planes equally far apart on the surface: the analytic cylinder, planes, flat parts unchanged."""

import math

import numpy as np
import pytest

from shapes import cylinder_patch
from swath.contact import Tool
from swath.errors import InputError
from swath.examples import flat_plate, grid_faces
from swath.plan.raster import plane_offsets, raster
from swath.plan.surface_planes import SLOPE_FLOOR, surface_distance, surface_plane_offsets
from swath.surface import Surface

TOOL = Tool()
X = np.array([1.0, 0.0, 0.0])


def offsets(surface, cross, spacing, **kw):
    return surface_plane_offsets(surface.vertices @ cross, surface.faces, surface.face_areas, surface.face_normals,
                                 cross, spacing, **kw)


def test_cylinder_planes_at_equal_arc_steps():
    # radius r, planes normal to x (across the axis y): arc length s = r (phi + phi_max) over the
    # patch, so equal arc steps d put the planes at x = r sin(phi_i), phi_i = -phi_max + (m + i d) / r
    r, half, d = 0.2, math.radians(60.0), 0.03
    s = cylinder_patch(r, half, 0.3, n_theta=400, n_len=12)
    off, margin, steps, extent = offsets(s, X, d)
    arc = 2 * r * half
    n = math.ceil(arc / d)                                   # 14 planes over 418.9 mm of arc
    assert len(off) == n == 14 and extent == pytest.approx(arc, rel=1e-4)
    assert margin == pytest.approx(0.5 * (arc - (n - 1) * d), abs=2e-5)
    phi = -half + (0.5 * (arc - (n - 1) * d) + d * np.arange(n)) / r
    np.testing.assert_allclose(off, r * np.sin(phi), atol=5e-5)
    np.testing.assert_allclose(steps, d)
    # projected, the same count of planes would sit 30 mm apart in x and 41 mm apart on the arc at the ends
    old, _ = plane_offsets(s.vertices[:, 0], d)
    assert np.ptp(r * np.diff(np.arcsin(np.clip(old / r, -1, 1)))) > 0.01


def test_cylinder_raster_passes_lie_the_spacing_apart_on_the_arc():
    r, half, d = 0.2, math.radians(60.0), 0.03
    s = cylinder_patch(r, half, 0.3, n_theta=400, n_len=12)
    tp = raster(s, TOOL, spacing=d, direction=(0.0, 1.0, 0.0), fill_gaps=False)
    assert tp.metadata["spacing_on"] == "surface" and tp.metadata["n_planes"] == 14
    phi = np.sort([np.arctan2(p.points[:, 0], p.points[:, 2]).mean() for p in tp.passes])
    np.testing.assert_allclose(np.diff(phi) * r, d, atol=5e-5)
    projected = raster(s, TOOL, spacing=d, direction=(0.0, 1.0, 0.0), fill_gaps=False, spacing_on="projection")
    x = np.sort([p.points[:, 0].mean() for p in projected.passes])
    np.testing.assert_allclose(np.diff(x), d, atol=1e-9)
    assert projected.metadata["n_planes"] == 12 == len(projected.passes)     # ceil(346.4 mm / 30 mm)


def test_tilted_plane_steps_are_the_spacing_over_the_slope():
    # a plane z = x tan(a) cut by planes normal to x: on the surface the steps are dx / cos(a)
    a, d = math.radians(35.0), 0.02
    xs, ys = np.linspace(0, 0.3, 61), np.linspace(0, 0.2, 21)
    X_, Y = np.meshgrid(xs, ys, indexing="ij")
    v = np.stack([X_.ravel(), Y.ravel(), X_.ravel() * math.tan(a)], 1)
    s = Surface(v, grid_faces(61, 21))
    off, margin, steps, extent = offsets(s, X, d)
    assert extent == pytest.approx(0.3 / math.cos(a), rel=1e-9)
    np.testing.assert_allclose(np.diff(off), d * math.cos(a), rtol=1e-9)
    assert len(off) == math.ceil(0.3 / math.cos(a) / d)


def test_flat_parts_keep_the_projected_planes():
    plate = flat_plate()
    for d in (0.02, 0.037):
        a = raster(plate, TOOL, spacing=d, direction=0.0, fill_gaps=False)
        b = raster(plate, TOOL, spacing=d, direction=0.0, fill_gaps=False, spacing_on="projection")
        assert a.metadata["spacing_on"] == "surface"
        assert len(a.passes) == len(b.passes)
        for p, q in zip(a.passes, b.passes):
            np.testing.assert_array_equal(p.points, q.points)
        # and the general rule, on a plane parallel to the cross direction, gives the projected offsets
        cross = np.asarray(a.metadata["cross_direction"])
        old, m_old = plane_offsets(plate.vertices @ cross, d)
        new, m_new, _, _ = offsets(plate, cross, d)
        np.testing.assert_allclose(new, old, atol=1e-12)
        assert m_new == pytest.approx(m_old, abs=1e-12)


def test_edge_margin_spreads_the_planes_over_the_arc():
    r, half, d = 0.2, math.radians(60.0), 0.03
    s = cylinder_patch(r, half, 0.3, n_theta=400, n_len=12)
    off, margin, steps, extent = offsets(s, X, d, edge_margin=math.inf)
    n = len(off)
    assert margin == pytest.approx(extent / (2 * n)) and steps == pytest.approx(extent / n)
    phi = np.arcsin(off / r)
    np.testing.assert_allclose(np.diff(phi) * r, extent / n, atol=5e-5)


def test_steep_faces_count_at_the_slope_floor():
    # the cylinder to 85 deg: past acos(0.3) = 72.5 deg a unit of height counts 1 / 0.3 on the surface
    r, half = 0.2, math.radians(85.0)
    s = cylinder_patch(r, half, 0.3, n_theta=800, n_len=8)
    edges = np.linspace(-r * math.sin(half), r * math.sin(half), 2001)
    total = surface_distance(s.vertices @ X, s.faces, s.face_areas, s.face_normals, X, edges)[-1]
    knee = math.acos(SLOPE_FLOOR)
    expect = 2 * (r * knee + (r * math.sin(half) - r * math.sin(knee)) / SLOPE_FLOOR)
    assert total == pytest.approx(expect, rel=2e-3)
    assert total < 2 * r * half


def test_bad_spacing_on_is_refused():
    with pytest.raises(InputError, match="spacing_on must be one of surface, projection"):
        raster(flat_plate(), TOOL, spacing=0.03, spacing_on="arc")


def test_on_a_steep_cylinder_the_surface_spacing_removes_evenly():
    """A 0.6 m cylinder patch over ±50°, passes along its axis, the 7° lead at 50 mm/s: the planes
    50.4 mm apart on the arc (21 passes, 1.53 L*) against 21 planes 44 mm apart in projection (the
    same contact length; 44 / cos 50° = 68 mm apart on the arc at the flanks).  Measured interior
    CoV 0.069 against 0.155 at 1.53 L* (0.070 against 0.155 on a mesh four times finer)."""
    from swath.contact.widths import coverage_lower_bound
    from swath.order import order_toolpath
    from swath.simulate import simulate_removal
    from swath.trajectory import FeedLimit, time_path

    part = cylinder_patch(0.6, math.radians(50.0), 0.4, n_theta=150, n_len=40)
    figures = []
    for spacing, on in ((0.0504, "surface"), (0.044, "projection")):
        tp = order_toolpath(raster(part, TOOL, spacing=spacing, direction=(0.0, 1.0, 0.0), spacing_on=on,
                                   fill_gaps=False))
        removal = simulate_removal(time_path(tp, [FeedLimit(0.05)], lead_angle=math.radians(7.0)), part, TOOL)
        figures.append((len(tp.passes), tp.contact_length / coverage_lower_bound(part, TOOL),
                        removal.metrics["interior_removal_cov"]))
    (n_s, ratio_s, cov_s), (n_p, ratio_p, cov_p) = figures
    assert n_s == n_p == 21 and ratio_s == pytest.approx(ratio_p, rel=0.01)
    assert cov_s < 0.09 and cov_p > 0.13
