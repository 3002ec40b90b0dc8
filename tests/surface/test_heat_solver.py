"""The heat-method solver skips the robust intrinsic triangulation only on Delaunay meshes
(:func:`swath.surface.geodesic.is_delaunay`, :func:`swath.surface.geodesic.heat_solver`)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shapes import sphere_cap  # noqa: E402
from swath.examples import grid_faces  # noqa: E402
from swath.surface.geodesic import heat_solver, is_delaunay  # noqa: E402


def _grid(n: int, size: float = 1.0):
    x, y = np.meshgrid(np.linspace(0.0, size, n), np.linspace(0.0, size, n), indexing="ij")
    return np.stack([x.ravel(), y.ravel(), np.zeros(n * n)], 1), grid_faces(n, n)


def test_a_right_triangle_grid_is_delaunay_and_one_flipped_edge_is_not():
    V, F = _grid(11)
    assert is_delaunay(V, F)                  # the diagonals' opposite right angles sum to 180 degrees
    from scipy.spatial import Delaunay

    rng = np.random.default_rng(3)
    xy = np.concatenate([rng.uniform(0.0, 1.0, (200, 2)), [[0, 0], [1, 0], [0, 1], [1, 1]]])
    F = Delaunay(xy).simplices
    V = np.column_stack([xy, np.zeros(len(xy))])
    # scipy's triangulation is Delaunay (random points may leave corners under a degree: no angle floor here)
    assert is_delaunay(V, F, min_angle_deg=0.0)
    flipped = F.copy()
    # flip one interior edge to its other diagonal: the two corners opposite it now sum past 180 degrees
    edges = {}
    for f, tri in enumerate(F):
        for k in range(3):
            edges.setdefault(tuple(sorted((tri[(k + 1) % 3], tri[(k + 2) % 3]))), []).append((f, tri[k]))
    (a, b), [(f1, c), (f2, d)] = next((e, fs) for e, fs in edges.items() if len(fs) == 2)
    flipped[f1], flipped[f2] = [c, d, a], [d, c, b]
    assert not is_delaunay(V, flipped, min_angle_deg=0.0)


def test_a_sliver_is_not_solved_plainly():
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0.5, 0.001, 0], [0.5, 1, 0]])
    F = np.array([[0, 1, 2], [0, 2, 3], [2, 1, 3]])
    assert not is_delaunay(V, F)


@pytest.mark.parametrize("delaunay", [True, False])
def test_the_distances_are_geodesic_either_way(delaunay):
    # a flat grid (Delaunay: the plain Laplacian) and a sphere cap whose grid triangulation is not
    # Delaunay (the robust solver): distance from one vertex against the exact plane distance /
    # great-circle distance
    if delaunay:
        V, F = _grid(61, 0.3)
        src = int(np.argmin(np.linalg.norm(V - [0.15, 0.15, 0.0], axis=1)))
        exact = np.linalg.norm(V - V[src], axis=1)
    else:
        s = sphere_cap(0.2, 0.8, n=80)
        V, F = np.asarray(s.vertices), np.asarray(s.faces)
        src = int(np.argmax(V[:, 2]))
        cosang = np.clip(V @ V[src] / (np.linalg.norm(V, axis=1) * np.linalg.norm(V[src])), -1, 1)
        exact = 0.2 * np.arccos(cosang)
    assert is_delaunay(V, F) == delaunay               # the case runs the solver it is named for
    d = np.asarray(heat_solver(V, F).compute_distance(src))
    far = exact > 0.02
    assert np.median(np.abs(d[far] - exact[far]) / exact[far]) < 0.02
