"""The air-route clearance check's vertex shortcut gives the answers of the full closest-point search."""

import numpy as np
import pytest

from conftest import SHARED_MESH_UNITS, shared_mesh
from shapes import sphere_cap
from swath.io.mesh import load_mesh
from swath.order.routing import AirGuard


class FullSearchGuard(AirGuard):
    """The clearance check as it was: the closest surface point of every sample."""

    def _clear(self, route):
        seg = np.linalg.norm(np.diff(route, axis=0), axis=1)
        pieces = [a + np.linspace(0, 1, max(int(np.ceil(L / (0.25 * self.clearance))), 1), endpoint=False)[:, None] * (b - a)
                  for a, b, L in zip(route[:-1], route[1:], seg)]
        pts = np.vstack(pieces + [route[-1:]])
        _, dist, _ = self.surface.closest_points(pts)
        return bool(dist.min() >= 0.5 * self.clearance * 0.999)


def _surfaces():
    yield sphere_cap(0.15, 0.7, n=50)
    yield load_mesh(shared_mesh("bezier_dac_cad.ply"), units=SHARED_MESH_UNITS["bezier_dac_cad.ply"])


@pytest.mark.parametrize("which", [0, 1])
def test_clear_same_as_full_search(rng, which):
    surface = list(_surfaces())[which]
    clearance = 0.01
    fast, full = AirGuard(surface, clearance), FullSearchGuard(surface, clearance)
    answers = []
    for _ in range(300):
        # two-segment routes from surface points lifted by 0 to 2 clearances, through the box
        ends = surface.vertices[rng.integers(len(surface.vertices), size=2)]
        normals = surface.normals[rng.integers(len(surface.vertices), size=2)]
        lift = rng.uniform(0.0, 2.0, size=2)[:, None] * clearance
        a, b = ends + lift * normals
        mid = 0.5 * (a + b) + 0.5 * (normals[0] + normals[1]) * rng.uniform(0.0, 4.0) * clearance
        route = np.array([a, mid, b])
        answer = fast._clear(route)
        assert answer == full._clear(route)
        answers.append(answer)
    # both answers occur, so the check is not trivially one-sided
    assert 30 < sum(answers) < 270


def test_clear_at_the_limit(rng):
    """Points at half the clearance (the limit) above a flat facet, just inside and just outside."""
    surface = sphere_cap(0.15, 0.7, n=50)
    clearance = 0.01
    fast, full = AirGuard(surface, clearance), FullSearchGuard(surface, clearance)
    top = surface.vertices[np.argmax(surface.vertices[:, 2])]
    limit = 0.5 * clearance * 0.999
    for h in limit * np.array([0.99, 0.999999, 1.0, 1.000001, 1.01, 1.5]):
        route = np.array([top + [0, 0, h], top + [0, 0, h + 0.05]])
        assert fast._clear(route) == full._clear(route)


def test_routes_same_as_full_search(rng):
    surface = sphere_cap(0.15, 1.0, n=50)
    fast, full = AirGuard(surface, 0.01, pad_radius=0.02), FullSearchGuard(surface, 0.01, pad_radius=0.02)
    lengths = []
    for _ in range(40):
        i, j = rng.integers(len(surface.vertices), size=2)
        args = (surface.vertices[i], surface.normals[i], surface.vertices[j], surface.normals[j])
        expected = full.route(*args)
        np.testing.assert_array_equal(fast.route(*args), expected)
        lengths.append(len(expected))
    # direct and lifted routes both occur
    assert min(lengths) == 4 and max(lengths) >= 6


def _lift_directions_as_a_list(guard, p, n):
    """The lift directions as :meth:`AirGuard._lift` listed them before it tried them lazily."""
    tries = [n]
    n = n / max(float(np.linalg.norm(n)), 1e-12)
    away = p - guard.center
    away = away / max(float(np.linalg.norm(away)), 1e-12)
    e1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    phi = np.arange(8) * np.pi / 4
    fan = [np.cos(t) * n + np.sin(t) * (np.cos(f) * e1 + np.sin(f) * e2)
           for t in np.radians([30.0, 45.0]) for f in phi]
    for v in [n + guard.up, guard.up, n + away, away, *fan]:
        length = float(np.linalg.norm(v))
        if length > 1e-9 and float(v @ n) / length >= 0.5:
            tries.append(v / length)
    return tries


def test_lift_directions_are_tried_in_the_order_listed_before(rng):
    """The lift tries the same directions, bit for bit and in the same order, as the list it built
    before (now only when the normal as given runs into the part)."""
    surface = sphere_cap(0.15, 0.7, n=30)
    guard = AirGuard(surface, 0.01)
    counts = set()
    for k in rng.integers(len(surface.vertices), size=40):
        p, n = surface.vertices[k], surface.normals[k] * rng.uniform(0.5, 2.0)      # a normal not of unit length
        n = n if rng.random() < 0.8 else -n                                          # some facing the part
        got = list(guard._lift_directions(p, n, n / np.linalg.norm(n)))
        expected = _lift_directions_as_a_list(guard, p, n)
        assert len(got) == len(expected)
        for u, v in zip(got, expected):
            np.testing.assert_array_equal(u, v)
        counts.add(len(got))
    assert max(counts) > 1                              # tilted directions were listed too
