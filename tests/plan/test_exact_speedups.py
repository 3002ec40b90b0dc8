"""Speed-ups of the planners' inner loops that must not change a plan: each fast path against the
code it replaces, compared bit for bit."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from swath.contact import Tool
from swath.examples import doubly_curved_panel, flat_plate
from swath.plan import gaps
from swath.plan.gaps import within_reach
from swath.plan.slicing import level_sets
from swath.plan.uniform import _band_widths
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
