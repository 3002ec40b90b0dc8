"""Preston removal against the analytic single-pass profile, and the plan metrics."""


import numpy as np
import pytest

from swath.contact import Tool
from swath.examples import flat_plate
from swath.plan import Pass, ToolPath
from swath.simulate import simulate_removal
from swath.trajectory import FeedLimit, Trajectory, time_path


def one_pass(surface, y, x0=0.0, x1=0.4):
    return Pass(np.array([[x0, y, 0.0], [x1, y, 0.0]]), np.array([[0, 0, 1.0]] * 2))


def test_single_pass_on_flat_plate_gives_the_preston_profile():
    tool = Tool()
    s = flat_plate()
    feed = 0.05
    tr = time_path(ToolPath(s, [one_pass(s, 0.15)], "test"), [FeedLimit(feed)])
    rm = simulate_removal(tr, s, tool, sample_spacing=2e-3)
    v = rm.surface.vertices
    mid = (np.abs(v[:, 0] - 0.2) < 0.05)
    y = np.abs(v[mid, 1] - 0.15)
    inside = y < 0.9 * tool.pad_radius
    # depth(y) = k_p · (k e) · v_rel · (chord at y) / feed, chord = 2 sqrt(R² − y²)
    expected = tool.preston * tool.k * tool.flat_depression * tool.relative_speed(0.0) \
        * 2 * np.sqrt(tool.pad_radius**2 - y[inside] ** 2) / feed
    assert np.allclose(rm.depth[mid][inside], expected, rtol=0.04)
    assert np.all(rm.depth[mid][y > tool.pad_radius + 1e-3] == 0)


def test_metrics_of_full_coverage_raster_by_hand():
    tool = Tool()
    s = flat_plate()
    d = 2 * tool.pad_radius
    n = int(np.ceil((0.3 - d) / (0.9 * d))) + 1
    ys = np.linspace(0.45 * d, 0.3 - 0.45 * d, n)   # edge passes just inside R of the edges
    ps = [one_pass(s, y) for y in ys]
    ps = [p if i % 2 == 0 else p.reversed() for i, p in enumerate(ps)]
    tr = time_path(ToolPath(s, ps, "test"))
    m = simulate_removal(tr, s, tool).metrics
    assert m["coverage_fraction"] > 0.995
    assert m["contact_length_m"] == pytest.approx(0.4 * len(ys), rel=1e-9)
    # L* on a flat plate is area / pad diameter
    assert m["coverage_lower_bound_m"] == pytest.approx(0.12 / d, rel=1e-3)
    assert m["efficiency"] == pytest.approx(m["coverage_lower_bound_m"] / m["contact_length_m"])
    assert 0.0 < m["removal_cov"] < 1.0
    assert m["cycle_time_s"] > m["contact_time_s"] == pytest.approx(0.4 * len(ys) / 0.05, rel=1e-6)


def test_uncovered_strip_lowers_coverage_by_its_area():
    tool = Tool()
    s = flat_plate()
    # one pass along y = 0.0381: covers the strip 0 .. 0.0762 of the 0.3 m plate (plus end caps)
    tr = time_path(ToolPath(s, [one_pass(s, tool.pad_radius)], "test"))
    m = simulate_removal(tr, s, tool).metrics
    assert m["coverage_fraction"] == pytest.approx(2 * tool.pad_radius / 0.3, rel=0.02)


def test_rotary_pad_removes_more_at_the_rim():
    tool = Tool(motion="rotary")
    s = flat_plate()
    tr = time_path(ToolPath(s, [one_pass(s, 0.15)], "test"))
    rm = simulate_removal(tr, s, tool, sample_spacing=2e-3)
    v = rm.surface.vertices
    mid = np.abs(v[:, 0] - 0.2) < 0.02
    y = np.abs(v[mid, 1] - 0.15)
    centre = rm.depth[mid][y < 2e-3].mean()
    off = rm.depth[mid][np.abs(y - 0.02) < 2e-3].mean()
    # rotary: ∫ ω r dt along the chord at offset y grows with y near the centre line
    assert off > centre


def test_a_trajectory_that_never_touches_the_part_gives_zero_coverage_not_an_error():
    s = flat_plate(size_x=0.3, size_y=0.2, spacing=5e-3)
    tr = time_path(ToolPath(s, [one_pass(s, 0.15)], "test"), [FeedLimit(0.05)])
    lifted = Trajectory(t=tr.t, position=tr.position + np.array([0.0, 0.0, 0.05]), quaternion=tr.quaternion,
                        contact=np.zeros(len(tr), bool), feed=tr.feed, pass_index=np.full(len(tr), -1))
    m = simulate_removal(lifted, s, Tool()).metrics
    assert m["coverage_fraction"] == 0.0 and m["covered_area_m2"] == 0.0
    assert m["contact_length_m"] == 0.0 and m["n_passes"] == 0
    assert np.isnan(m["removal_cov"]) and np.isnan(m["removal_mean_m"])


@pytest.mark.parametrize("spacing", [5e-3, 0.4])
def test_interior_is_the_plate_shrunk_by_a_pad_radius_and_evener_than_the_whole(spacing):
    """A plate sampled finely or made of two triangles only (the edge is then sampled along its
    length, not at its four corners): the samples more than a pad radius from its edge cover the
    inner rectangle (0.4 − 2R) x (0.3 − 2R).  A close raster that runs past the edges removes nearly
    evenly there: the ripple of passes R/2 apart (0.038, :func:`swath.feed.ripple_cov`) and the
    simulator's spacing of its poses along the passes (about 0.03) leave a CoV near 0.05, while the
    whole part, with the band where the pad hangs over the edge, varies ten times more."""
    tool = Tool()
    R = tool.pad_radius
    s = flat_plate(spacing=spacing)
    ys = np.arange(-0.5 * R, 0.3 + 0.5 * R + 1e-9, 0.5 * R)         # step R/2: a ripple of a few %
    ps = [one_pass(s, y, x0=-R, x1=0.4 + R) for y in ys]
    tr = time_path(ToolPath(s, ps, "test"), [FeedLimit(0.05)])
    rm = simulate_removal(tr, s, tool, sample_spacing=2e-3)
    m = rm.metrics
    inner = (0.4 - 2 * R) * (0.3 - 2 * R)
    assert m["interior_area_m2"] == pytest.approx(inner, rel=0.03)
    mask = rm.surface.farther_from_boundary(R)
    v = rm.surface.vertices[mask]
    assert v[:, 0].min() >= R - 1e-3 and v[:, 0].max() <= 0.4 - R + 1e-3 and v[:, 1].max() <= 0.3 - R + 1e-3
    a, d = rm.surface.vertex_areas[mask], rm.depth[mask]
    mean = np.average(d, weights=a)
    assert m["interior_removal_cov"] == pytest.approx(np.sqrt(np.average((d - mean) ** 2, weights=a)) / mean, rel=1e-9)
    assert 0.03 < m["interior_removal_cov"] < 0.06 and m["removal_cov"] > 0.3
