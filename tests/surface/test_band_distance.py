"""The narrow-band geodesic distance (:class:`swath.surface.geodesic.BandDistance`) against
analytic geodesics: planes (regular and irregular triangulations), a sphere and a cylinder; the
stop distance; bad input."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shapes import cylinder_patch, sphere_cap  # noqa: E402
from swath.errors import InputError  # noqa: E402
from swath.examples import grid_faces  # noqa: E402
from swath.surface.geodesic import BandDistance, band_distance  # noqa: E402
from swath.surface.topology import mesh_edges  # noqa: E402


def _edge_length(V, F) -> float:
    """Median edge length of the mesh, m."""
    e = mesh_edges(np.asarray(F, np.int64))[0]
    return float(np.median(np.linalg.norm(V[e[:, 0]] - V[e[:, 1]], axis=1)))


def _grid(n: int, size: float = 1.0):
    x, y = np.meshgrid(np.linspace(0.0, size, n), np.linspace(0.0, size, n), indexing="ij")
    return np.stack([x.ravel(), y.ravel(), np.zeros(n * n)], 1), grid_faces(n, n)


def _delaunay_square(n_points: int, seed: int = 0):
    """An irregular triangulation of the unit square: Delaunay of seeded random points and its corners."""
    from scipy.spatial import Delaunay

    rng = np.random.default_rng(seed)
    xy = np.concatenate([rng.uniform(0.0, 1.0, (n_points, 2)), [[0, 0], [1, 0], [0, 1], [1, 1]]])
    F = Delaunay(xy).simplices
    return np.column_stack([xy, np.zeros(len(xy))]), F


def test_a_straight_source_on_a_flat_grid_is_exact():
    # the plane front through two accepted corners is the exact distance from a straight source
    V, F = _grid(81)
    src = np.flatnonzero(np.isclose(V[:, 0], 0.25))
    d = band_distance(V, F, src)
    np.testing.assert_allclose(d, np.abs(V[:, 0] - 0.25), rtol=0, atol=1e-12)


def test_a_point_on_an_irregular_plane_within_two_edges():
    V, F = _delaunay_square(6000)
    h = _edge_length(V, F)
    centre = int(np.argmin(np.linalg.norm(V[:, :2] - 0.5, axis=1)))
    d = band_distance(V, F, [centre])
    exact = np.linalg.norm(V - V[centre], axis=1)
    err = d - exact
    # first order: measured max 0.73 h, mean 0.46 h (h the median edge, 14 mm here); never below the
    # exact distance, since every update is the length of some path on the faces
    assert np.abs(err).max() < 1.0 * h and np.abs(err).mean() < 0.6 * h
    assert err.min() > -1e-12


def test_a_curve_of_vertices_on_an_irregular_plane_within_one_edge():
    V, F = _delaunay_square(6000, seed=1)
    h = _edge_length(V, F)
    src = np.flatnonzero(np.abs(V[:, 0] - 0.3) < 0.6 * h)             # a ragged band of vertices
    d = band_distance(V, F, src)
    exact = np.min(np.linalg.norm(V[:, None, :2] - V[None, src, :2], axis=2), axis=1)
    err = d - exact
    # measured max 0.48 h, mean 0.16 h: below the distance to the vertices between them, since the
    # front through two neighbouring sources is the straight line joining them
    assert np.abs(err).max() < 0.7 * h and np.abs(err).mean() < 0.25 * h


def test_great_circle_distance_on_a_sphere():
    radius = 0.2
    s = sphere_cap(radius, 0.9, n=121)
    V, F = np.asarray(s.vertices), np.asarray(s.faces)
    h = _edge_length(V, F)
    pole = int(np.argmax(V[:, 2]))
    d = band_distance(V, F, [pole])
    exact = radius * np.arccos(np.clip(V @ V[pole] / radius ** 2, -1.0, 1.0))
    err = d - exact
    assert np.abs(err).max() < 1.6 * h and np.abs(err).mean() < 0.6 * h     # measured 1.35 h and 0.45 h


def test_distances_on_a_cylinder():
    radius, length = 0.08, 0.3
    s = cylinder_patch(radius, 1.2, length, n_theta=121, n_len=111)
    V, F = np.asarray(s.vertices), np.asarray(s.faces)
    h = _edge_length(V, F)
    theta = np.arctan2(V[:, 0], V[:, 2])
    # from the generator at theta = 0: the arc radius * |theta| (the surface unrolls to a plane)
    line = np.flatnonzero(np.abs(theta) < 1e-9)
    assert len(line) == 111
    d = band_distance(V, F, line)
    arc = radius * np.abs(theta)
    assert np.abs(d - arc).max() < 0.01 * h         # measured 6e-4 h: chord against arc
    # from a point: the straight line on the unrolled cylinder
    p = int(np.argmin(np.abs(theta) + np.abs(V[:, 1])))
    d = band_distance(V, F, [p])
    exact = np.hypot(radius * (theta - theta[p]), V[:, 1] - V[p, 1])
    err = d - exact
    assert np.abs(err).max() < 1.3 * h and np.abs(err).mean() < 0.5 * h     # measured 1.01 h and 0.36 h


def test_the_stop_distance_is_honoured_and_costs_no_accuracy():
    V, F = _delaunay_square(6000, seed=2)
    h = _edge_length(V, F)
    bd = BandDistance(V, F)
    src = np.flatnonzero(V[:, 0] < 0.05)
    whole = bd(src)
    stop = 0.2
    band = bd(src, stop=stop)
    reached = np.isfinite(band)
    # the band is the whole solve's values up to the stop distance, bit for bit, and nothing else
    np.testing.assert_array_equal(band[reached], whole[reached])
    np.testing.assert_array_equal(reached, whole <= stop)
    assert 0.2 < reached.mean() < 0.35
    # initial distances shift the field
    shifted = bd(src, np.full(len(src), 0.01), stop=stop)
    assert np.nanmax(np.where(np.isfinite(shifted), shifted, np.nan)) <= stop
    np.testing.assert_allclose(shifted[np.isfinite(shifted)], whole[np.isfinite(shifted)] + 0.01, atol=1e-12)
    assert np.isfinite(shifted).sum() < reached.sum()
    assert np.abs(whole[whole > 0.3] - (V[whole > 0.3, 0] - 0.05)).max() < 2 * h


def test_pieces_without_a_source_stay_at_infinity():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 0, 0], [6, 0, 0], [5, 1, 0]], float)
    F = np.array([[0, 1, 2], [3, 4, 5]])
    d = band_distance(V, F, [0])
    np.testing.assert_allclose(d[:3], [0.0, 1.0, 1.0])
    assert np.isinf(d[3:]).all()


def test_bad_sources_and_stops_are_refused():
    V, F = _grid(5)
    bd = BandDistance(V, F)
    with pytest.raises(InputError, match="sources"):
        bd([])
    with pytest.raises(InputError, match="one finite distance each"):
        bd([0, 1], [0.0])
    with pytest.raises(InputError, match="source vertices must lie"):
        bd([25])
    with pytest.raises(InputError, match="stop distance"):
        bd([0], stop=-1.0)
