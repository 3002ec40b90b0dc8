"""The coarse-tessellation check, the smooth surface through a mesh's vertices, and the ridge profile."""

import json
import math

import numpy as np
import pytest

from shapes import cylinder_patch
from swath.contact import Tool
from swath.contact.tessellation import KINK_DEPRESSION_RATIO, facet_kinks, shared_edges, tessellation_check
from swath.errors import InputError
from swath.simulate.facets import kink_convexity, ridge_profile
from swath.surface.phong import phong_smoothed

TOOL = Tool()                # 38.1 mm pad, 1 mm depression at 20 N
RADIUS = 0.15


def _cylinder(facets_round: int, *, concave: bool = False):
    """An open 120° cylinder patch of radius 0.15 m, 0.4 m long, cut into ``facets_round / 3`` flat facets."""
    return cylinder_patch(RADIUS, math.pi / 3, 0.4, n_theta=facets_round // 3 + 1, n_len=21, concave=concave)


@pytest.mark.parametrize("facets_round", [24, 48, 192])
def test_kink_angle_width_and_height_are_the_cylinder_facets(facets_round):
    kinks = facet_kinks(_cylinder(facets_round), TOOL)
    ridge = kinks.angle > 1e-6                      # the edges along the axis; the quads' diagonals are flat
    theta = 2 * math.pi / facets_round
    width = 2 * RADIUS * math.sin(theta / 2)       # the facet's width round the cylinder
    assert kinks.angle[ridge] == pytest.approx(theta, rel=1e-9)
    assert kinks.width[ridge] == pytest.approx(width, rel=1e-9)
    # narrower than 4R (0.152 m) in every case here: the chord error of the facets, w²/(8r) to second order
    assert kinks.height[ridge] == pytest.approx(theta * width / 8, rel=1e-9)
    assert kinks.height[ridge] == pytest.approx(width**2 / (8 * RADIUS), rel=theta**2)
    assert np.all(kinks.height[~ridge] < 1e-9)


def test_wide_facets_kink_by_half_the_pad_radius():
    # three facets 0.3 m wide meeting at 5°: wider than 4R, so the pad centred on a kink sees R θ / 2
    theta = math.radians(5.0)
    x = np.array([-0.45, -0.15, 0.15, 0.45])
    z = np.array([-0.3 * math.sin(theta), 0.0, 0.0, -0.3 * math.sin(theta)])
    xz = np.stack([x, z], 1)
    xz[0] = [-0.15 - 0.3 * math.cos(theta), -0.3 * math.sin(theta)]
    xz[3] = [0.15 + 0.3 * math.cos(theta), -0.3 * math.sin(theta)]
    ys = np.array([0.0, 0.3])
    v = np.array([[px, py, pz] for px, pz in xz for py in ys])
    f = []
    for i in range(3):
        a, b, c, d = 2 * i, 2 * i + 1, 2 * i + 2, 2 * i + 3
        f += [[a, c, b], [b, c, d]]
    from swath.surface import Surface

    s = Surface(v, np.array(f))
    kinks = facet_kinks(s, TOOL)
    ridge = kinks.angle > 1e-6
    assert ridge.sum() == 2
    assert kinks.angle[ridge] == pytest.approx(theta, rel=1e-9)
    assert kinks.height[ridge] == pytest.approx(theta * TOOL.pad_radius / 2, rel=1e-9)


def test_coarse_cylinder_warns_and_the_fine_one_does_not():
    e, R = TOOL.flat_depression, TOOL.pad_radius
    coarse = tessellation_check(_cylinder(24), TOOL)           # 15° facets, 39 mm wide: 1.28 mm off the circle
    fine = tessellation_check(_cylinder(192), TOOL)            # 1.9° facets, 4.9 mm wide: 0.02 mm
    assert coarse.coarse and not fine.coarse
    assert coarse.angle_deg == pytest.approx(15.0, rel=1e-9)
    w = 2 * RADIUS * math.sin(math.pi / 24)
    assert coarse.kink_height_m == pytest.approx(math.radians(15.0) * w / 8, rel=1e-9)
    assert coarse.ratio == pytest.approx(coarse.kink_height_m / e, rel=1e-12)
    assert fine.ratio < 0.15 * KINK_DEPRESSION_RATIO
    (text,) = coarse.warnings("cyl")
    assert text.endswith("[W-MESH-COARSE]")
    assert "chord tolerance 0.2 mm" in text and "STEP" in text
    assert fine.warnings("cyl") == []
    assert coarse.chord_tolerance_m == pytest.approx(KINK_DEPRESSION_RATIO * e)
    assert coarse.angle_tolerance_deg == pytest.approx(math.degrees(2 * KINK_DEPRESSION_RATIO * e / R))
    # a cylinder cut to the chord tolerance offered passes: w²/(8r) <= 0.2 mm, i.e. w <= 21.9 mm -> 44 facets round
    facets = 3 * math.ceil(2 * math.pi / (2 * math.asin(math.sqrt(8 * RADIUS * coarse.chord_tolerance_m) / (2 * RADIUS))) / 3)
    assert not tessellation_check(_cylinder(facets), TOOL).coarse
    # a stiffer press (twice the force, twice the depression) halves the ratio
    assert tessellation_check(_cylinder(24), TOOL.with_force(40.0)).ratio == pytest.approx(coarse.ratio / 2, rel=1e-9)


def test_check_refuses_bad_settings():
    with pytest.raises(InputError, match="ratio"):
        tessellation_check(_cylinder(24), TOOL, ratio=0.0)
    with pytest.raises(InputError, match="percentile"):
        tessellation_check(_cylinder(24), TOOL, percentile=120.0)


def test_shared_edges_and_convexity():
    s = _cylinder(24)
    edges, pair = shared_edges(s.faces)
    assert len(edges) == len(pair)
    n_theta, n_len = 9, 21
    # interior edges of a grid of (n_theta-1)(n_len-1) quads, each split by one diagonal
    assert len(edges) == (n_theta - 2) * (n_len - 1) + (n_theta - 1) * (n_len - 2) + (n_theta - 1) * (n_len - 1)
    kinks = facet_kinks(s, TOOL)
    ridge = kinks.angle > 1e-6
    assert np.all(kink_convexity(s)[ridge] == 1)
    assert np.all(kink_convexity(_cylinder(24, concave=True))[ridge] == -1)
    assert np.all(kink_convexity(s)[~ridge] == 0)


def test_phong_surface_returns_to_the_cylinder():
    s = _cylinder(24)
    smooth = phong_smoothed(s, 4e-3)
    flat = s.subdivided(4e-3)
    assert np.array_equal(smooth.vertices[:len(s.vertices)], s.vertices)      # the corners stay
    assert np.array_equal(smooth.faces, flat.faces)
    th = np.arctan2(smooth.vertices[:, 0], smooth.vertices[:, 2])
    inner = np.abs(th) < math.pi / 3 - 2 * math.pi / 24 - 1e-6                # the border facets' normals are one-sided
    r_flat = np.hypot(flat.vertices[:, 0], flat.vertices[:, 2])
    r_smooth = np.hypot(smooth.vertices[:, 0], smooth.vertices[:, 2])
    w = 2 * RADIUS * math.sin(math.pi / 24)
    assert RADIUS - r_flat[inner].min() == pytest.approx(w**2 / (8 * RADIUS), rel=0.02)     # the chord error
    assert np.abs(r_smooth[inner] - RADIUS).max() < 0.02 * w**2 / (8 * RADIUS)
    assert tessellation_check(smooth, TOOL).ratio < 0.1 * KINK_DEPRESSION_RATIO
    with pytest.raises(InputError, match="alpha"):
        phong_smoothed(s, 4e-3, alpha=2.0)


class _Removal:
    def __init__(self, surface, depth):
        self.surface, self.depth = surface, depth


def test_ridge_profile_reads_depth_against_the_distance_to_a_convex_kink():
    s = _cylinder(24)
    samples = s.subdivided(3e-3)
    theta_v = np.arctan2(samples.vertices[:, 0], samples.vertices[:, 2])
    step = 2 * math.pi / 24
    ridge_angle = np.abs((theta_v + math.pi / 3) / step - np.round((theta_v + math.pi / 3) / step)) * step
    d = RADIUS * ridge_angle                                             # distance round to the nearest ridge, m
    depth = 1.0 + 0.5 * np.exp(-d / 5e-3)                                 # half again on the ridges
    prof = ridge_profile(_Removal(samples, depth), s, TOOL, min_ratio=0.5)
    assert prof["convex_marked_edges"] > 0 and prof["concave_marked_edges"] == 0
    means = [row[3] for row in prof["convex_bins"] if np.isfinite(row[3])]
    assert means == sorted(means, reverse=True)                          # deepest on the ridges
    assert prof["near_cov"] > 5 * prof["far_cov"] if np.isfinite(prof["far_cov"]) else prof["near_cov"] > 0.05
    with pytest.raises(InputError, match="bins"):
        ridge_profile(_Removal(samples, depth), s, TOOL, bins=(0.0, 1.0))


def test_job_warns_on_a_coarse_mesh(tmp_path):
    import trimesh

    from swath.cli import main

    s = cylinder_patch(RADIUS, math.pi / 4, 0.25, n_theta=7, n_len=11)     # 15° facets
    trimesh.Trimesh(s.vertices, s.faces, process=False).export(tmp_path / "coarse.stl")
    assert main(["plan", str(tmp_path / "coarse.stl"), "--units", "m", "--constant-feed",
                 "--out", str(tmp_path / "o")]) == 0
    metrics = json.loads((tmp_path / "o" / "metrics.json").read_text())["metrics"]
    assert any(w.endswith("[W-MESH-COARSE]") for w in metrics["warnings"])
    assert metrics["tessellation_coarse"] is True
    assert metrics["tessellation_kink_angle_deg"] == pytest.approx(15.0, rel=1e-6)
