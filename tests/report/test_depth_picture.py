"""The depth picture of removal on lattice samples: drawn on the part's own connected mesh, every
face drawn, neighbours joined, the depth interpolated from the samples (report.plots.depth_mesh)."""

import numpy as np
import pytest

import shapes
from swath.contact import Tool
from swath.plan import Pass, ToolPath
from swath.report.html import display_mesh, figure_3d
from swath.report.plots import depth_mesh, part_display_mesh, removal_map_figure
from swath.simulate import simulate_removal
from swath.surface.geometry import face_normals_and_areas
from swath.trajectory import FeedLimit, time_path

SIZE_X, SIZE_Y, FEED = 0.4, 0.3, 0.05


def sliver_plate(strip=1.5e-3):
    """The shared sliver plate at this file's size (the lattice gives each strip one row of samples,
    which drew no display triangle before)."""
    return shapes.sliver_plate(SIZE_X, SIZE_Y, strip)


@pytest.fixture(scope="module")
def one_pass_removal():
    part = sliver_plate()
    tp = ToolPath(part, [Pass(np.array([[0.0, 0.15, 0.0], [SIZE_X, 0.15, 0.0]]), np.array([[0, 0, 1.0]] * 2))], "t")
    return part, tp, simulate_removal(time_path(tp, [FeedLimit(FEED)]), part, Tool(), sample_spacing=3e-3,
                                      sampling="lattice")


def boundary_length(vertices, faces):
    """Total length (m) of the edges that belong to one face only."""
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    keys, count = np.unique(e, axis=0, return_counts=True)
    b = keys[count == 1]
    return float(np.linalg.norm(vertices[b[:, 0]] - vertices[b[:, 1]], axis=1).sum())


def test_every_face_is_drawn_and_neighbours_join(one_pass_removal):
    part, _, removal = one_pass_removal
    v, f, d = depth_mesh(removal, max_faces=200_000)
    # the drawn mesh covers the part exactly and has no inner seams: its only open edges are the
    # plate's outline (0.4 m x 0.3 m)
    assert face_normals_and_areas(v, f)[1].sum() == pytest.approx(SIZE_X * SIZE_Y, rel=1e-9)
    assert boundary_length(v, f) == pytest.approx(2 * (SIZE_X + SIZE_Y), rel=1e-9)
    assert len(f) <= 200_000 and d.shape == (len(v),)
    # the lattice's own display triangles leave the sliver rows out: nearly nothing of the plate
    assert face_normals_and_areas(removal.surface.vertices, removal.surface.faces)[1].sum() < 0.1 * SIZE_X * SIZE_Y


def test_the_drawn_depth_is_the_preston_profile(one_pass_removal):
    _, _, removal = one_pass_removal
    tool = Tool()
    v, f, d = depth_mesh(removal, max_faces=200_000)
    mid = np.abs(v[:, 0] - 0.2) < 0.05
    y = np.abs(v[mid, 1] - 0.15)
    inside = y < 0.8 * tool.pad_radius
    expected = tool.preston * tool.k * tool.flat_depression * tool.relative_speed(0.0) \
        * 2 * np.sqrt(tool.pad_radius**2 - y[inside] ** 2) / FEED
    assert inside.sum() > 100
    assert np.allclose(d[mid][inside], expected, rtol=0.05)
    assert np.all(d[mid][y > tool.pad_radius + 6e-3] == 0)           # untouched beyond the pad (+ 1.5 spacings)


def test_budgets_hold_and_the_3d_view_and_map_use_the_part_mesh(one_pass_removal):
    part, tp, removal = one_pass_removal
    for budget in (500, 5_000):
        v, f, d = depth_mesh(removal, max_faces=budget)
        assert 0 < len(f) <= budget and np.all(np.isfinite(d))
    # a part over the budget on its own is coarsened, still one connected sheet
    v, f, edge = part_display_mesh(part, max_faces=300)
    assert len(f) <= 300 and edge > 0
    v, f, d = display_mesh(part, removal, max_faces=20_000)
    assert len(f) <= 20_000
    # along the middle of the pass (the deepest spot is where the pad slows at an end, between the
    # coarse vertices along the strips) the drawn peak is the simulated one
    mid, mid_s = np.abs(v[:, 0] - 0.2) < 0.05, np.abs(removal.surface.vertices[:, 0] - 0.2) < 0.05
    assert d[mid].max() == pytest.approx(removal.depth[mid_s].max(), rel=0.05)
    fig = figure_3d(part, toolpath=tp, removal=removal, max_faces=20_000)
    assert len(fig.data[0].i) == len(f)
    assert len(removal_map_figure(removal, tp, max_faces=20_000).axes) == 3


def test_a_few_deep_spots_do_not_squeeze_the_depth_colours():
    from swath.report.plots import DEEP_OUTLIER_RATIO, depth_scale

    # 1000 samples at 2 µm and three at 8 µm (crs_part_5's facet corners: median 2.1 µm, peak 8.8 µm)
    deep = depth_scale(np.r_[np.full(1000, 2.0), 8.0, 8.0, 8.0])
    assert deep.top == pytest.approx(2.0) and deep.peak == 8.0 and deep.clipped
    assert deep.none_below == pytest.approx(0.08)              # grey stays 1 % of the peak
    assert "red = over 2" in deep.label() and "peak 8" in deep.label()
    # a spread without outliers keeps the scale to its peak, and the plain caption
    even = depth_scale(np.linspace(1.0, 3.0, 1000))
    assert even.top == even.peak == 3.0 and not even.clipped and "red" not in even.label()
    # just under the ratio: still to the peak
    near = depth_scale(np.r_[np.full(1000, 2.0), np.full(3, 2.0 * DEEP_OUTLIER_RATIO * 0.99)])
    assert not near.clipped
    assert depth_scale(np.zeros(4)).top == 1.0                 # nothing removed: a unit scale, no division by 0


def test_the_3d_view_and_the_map_draw_deep_spots_red():
    from swath.report.plots import DEEPER_THAN_SCALE
    from swath.simulate.removal import RemovalMap

    part = shapes.grooved_plate(depth=0.0, n=61)               # a flat 0.3 m plate, 5 mm grid
    v = part.vertices
    depth = 2e-6 * (1.0 + 0.1 * np.sin(v[:, 0] / 0.02))        # 2 µm with a 10 % ripple
    spot = np.linalg.norm(v[:, :2] - [0.15, 0.15], axis=1) < 6e-3
    assert 0 < spot.sum() < 0.005 * len(v)
    spiked = RemovalMap(part, np.where(spot, 4.0 * depth, depth))
    mesh = figure_3d(part, removal=spiked, max_faces=20_000).data[0]
    assert mesh.colorscale[-1][1] == DEEPER_THAN_SCALE and "red" in mesh.colorbar.title.text
    assert mesh.cmax == pytest.approx(2.2 / (1 - 0.03), rel=0.02)   # the scale ends near 2.2 µm, the ripple's top
    cbar = removal_map_figure(spiked, max_faces=20_000).axes[-1]
    assert "red = over 2.2 (peak 8.8)" in cbar.get_ylabel()
    # the same ripple without the spot: a scale to its peak, no red
    plain = figure_3d(part, removal=RemovalMap(part, depth), max_faces=20_000).data[0]
    assert plain.colorscale[-1][1] != DEEPER_THAN_SCALE and plain.cmax == pytest.approx(2.2, rel=1e-3)
    assert "red" not in removal_map_figure(RemovalMap(part, depth), max_faces=20_000).axes[-1].get_ylabel()
