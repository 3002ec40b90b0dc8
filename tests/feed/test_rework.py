"""Rework from a scan: the excess map, the area, the floor, and the whole loop on a synthetic pair."""

import json

import numpy as np
import pytest

from swath.contact import Tool
from swath.errors import InputError
from swath.examples import doubly_curved_panel, flat_plate
from swath.examples.scansim import simulate_laser_scan
from swath.feed.rework import excess_on_cad, register_excluding_excess, removal_floor, residual_figures, rework_area
from swath.feed.ripple import cross_profile
from swath.surface import Surface


def _dome(vertices, depth, half_x, half_y):
    """A dome of excess: ``depth`` at the centre, 0 at the edges of a half_x x half_y rectangle."""
    x, y = vertices[:, 0] / half_x, vertices[:, 1] / half_y
    return depth * np.clip(1 - x * x, 0, None) * np.clip(1 - y * y, 0, None)


def test_a_uniform_layer_maps_to_its_thickness_and_nothing_below():
    plate = flat_plate(size_x=0.2, size_y=0.1, spacing=5e-3)
    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(0, 0.2, 40000), rng.uniform(0, 0.1, 40000), np.full(40000, 5e-6)])
    pts[:, 2] += rng.normal(0, 1e-6, len(pts))
    ex = excess_on_cad(plate, pts, radius=5e-3)
    assert ex.measured.all()
    np.testing.assert_allclose(ex.target.depth, 5e-6, atol=1e-6)
    # the noise figure is the standard error of the mean height: sigma / sqrt(points per disc)
    per_disc = 40000 * np.pi * 5e-3 ** 2 / 0.02
    assert ex.noise == pytest.approx(1e-6 / np.sqrt(per_disc), rel=0.5)
    below = pts.copy()
    below[:, 2] = -5e-6
    assert np.all(excess_on_cad(plate, below, radius=5e-3).target.depth == 0.0)


def test_scan_points_beyond_the_part_do_not_count_and_a_scan_off_the_part_is_refused():
    plate = flat_plate(size_x=0.1, size_y=0.1, spacing=5e-3)
    far = np.column_stack([np.full(50, 0.5), np.linspace(0, 0.1, 50), np.zeros(50)])
    with pytest.raises(InputError, match="scan does not lie on the part"):
        excess_on_cad(plate, far, radius=5e-3)
    with pytest.raises(InputError, match="rigid transform"):
        excess_on_cad(plate, far, scan2cad=np.diag([2.0, 1, 1, 1]))


def test_rework_area_reaches_a_pad_radius_round_the_excess():
    plate = flat_plate(size_x=0.4, size_y=0.3, spacing=5e-3)
    depth = np.where(np.linalg.norm(plate.vertices[:, :2] - [0.2, 0.15], axis=1) < 0.02, 5e-6, 0.0)
    faces = rework_area(plate, depth, min_excess=1e-6, grow=0.04)
    centres = plate.vertices[plate.faces[faces]].mean(axis=1)
    reach = np.linalg.norm(centres[:, :2] - [0.2, 0.15], axis=1)
    assert reach.max() < 0.02 + 0.04 and reach.max() > 0.05
    assert len(rework_area(plate, depth, min_excess=1e-5, grow=0.04)) == 0


def test_removal_floor_is_the_summed_profile_of_passes_at_the_fastest_feed():
    tool = Tool(pad_radius=0.0381, force=20.0, depression=1e-3)
    y = np.linspace(-0.04, 0.04, 4001)
    integral = np.trapezoid(cross_profile(tool, y, speed=0.05), y)
    # the summed depth's mean is the profile's integral over the spacing; its peak lies above by the
    # ripple, which vanishes as the passes close up
    d = 0.05
    floor = removal_floor(tool, feed=0.05, spacing=d)
    assert integral / d < floor < 1.4 * integral / d
    assert removal_floor(tool, feed=0.05, spacing=0.008) == pytest.approx(integral / 0.008, rel=0.03)
    assert removal_floor(tool, feed=0.10, spacing=d) == pytest.approx(floor / 2, rel=1e-9)


def test_residual_figures_of_a_removal_that_takes_half():
    plate = flat_plate(size_x=0.1, size_y=0.1, spacing=1e-2)
    pts = np.column_stack([plate.vertices[:, :2], np.full(len(plate.vertices), 4e-6)])
    ex = excess_on_cad(plate, np.repeat(pts, 3, axis=0), radius=6e-3)
    fig = residual_figures(ex, plate.vertices, np.full(len(plate.vertices), 2e-6), min_excess=1e-6)
    assert fig["residual_rms_fraction"] == pytest.approx(0.5, abs=1e-6)
    assert fig["over_removal_max_m"] == 0.0


@pytest.fixture(scope="module")
def scan_pair():
    """A 300 x 220 mm panel (radii 1.5 m, 2.5 m) under a 10 µm dome of excess, scanned with 2 µm noise
    in 3 mm rows of 1 mm points, then turned and moved as a scanner's frame would be."""
    from scipy.spatial.transform import Rotation

    cad = doubly_curved_panel(size_x=0.3, size_y=0.22, radius_x=1.5, radius_y=2.5, spacing=5e-3)
    planted = _dome(cad.vertices, 10e-6, 0.15, 0.11)
    after = Surface(cad.vertices + planted[:, None] * cad.normals, cad.faces, name="after")
    scan = simulate_laser_scan(after, row_spacing=3e-3, point_spacing=1e-3, sigma=2e-6, row_offset=0.0, rng=3)
    cad2scan = np.eye(4)
    cad2scan[:3, :3] = Rotation.from_euler("xyz", [1.0, -1.5, 25.0], degrees=True).as_matrix()
    cad2scan[:3, 3] = [0.04, -0.03, 0.2]
    points = scan.points @ cad2scan[:3, :3].T + cad2scan[:3, 3]
    return cad, planted, points


def test_registration_refined_on_the_nominal_area_maps_the_excess_within_a_micrometre(scan_pair):
    cad, planted, points = scan_pair
    matrix = register_excluding_excess(cad, points, radius=1e-2)
    ex = excess_on_cad(cad, points, scan2cad=np.linalg.inv(matrix), radius=1e-2)
    err = ex.target.depth - planted
    assert np.sqrt(np.mean(err ** 2)) < 1e-6
    assert abs(err.mean()) < 0.5e-6


def test_swath_rework_removes_the_planted_excess_within_ten_percent_rms(scan_pair, tmp_path):
    from swath.cli import main
    from swath.io.mesh import load_mesh, save_surface_ply
    from swath.simulate import simulate_removal
    from swath.trajectory import read_csv

    cad, planted, points = scan_pair
    save_surface_ply(cad, tmp_path / "cad.ply")
    np.savetxt(tmp_path / "scan.xyz", points * 1e3, fmt="%.5f")
    out = tmp_path / "rework"
    assert main(["-q", "rework", str(tmp_path / "cad.ply"), str(tmp_path / "scan.xyz"), "--scan-units", "mm",
                 "--out", str(out)]) == 0
    doc = json.loads((out / "rework.json").read_text())
    assert doc["residual_rms_fraction"] < 0.12 and doc["rework_area_m2"] > 0.5 * doc["part_area_m2"]
    # the plan removes the dome deeper in its middle on purpose: no hot spot is judged (nor warned of)
    assert not [k for k in json.loads((out / "plan" / "metrics.json").read_text())["metrics"] if k.startswith("hot_spot")]
    # judged against the planted truth, on the part as a whole, a pad radius in from its edges
    part = load_mesh(tmp_path / "cad.ply")
    removal = simulate_removal(read_csv(out / "plan" / "trajectory.csv"), part,
                               Tool(pad_radius=0.0381, force=20.0, depression=1e-3), sampling="lattice")
    truth = _dome(removal.surface.vertices, 10e-6, 0.15, 0.11)
    inner = removal.surface.farther_from_boundary(0.0381) & (truth > 2e-6)
    left = truth[inner] - removal.depth[inner]
    assert np.sqrt(np.mean(left ** 2)) < 0.10 * np.sqrt(np.mean(truth[inner] ** 2))
    # nothing left: a second rework of a scan at the nominal surface writes no plan
    flat = part.vertices + 0.0
    again = tmp_path / "again"
    np.savetxt(tmp_path / "nominal.xyz", np.repeat(flat, 4, axis=0) * 1e3, fmt="%.5f")
    assert main(["-q", "rework", str(tmp_path / "cad.ply"), str(tmp_path / "nominal.xyz"), "--scan-units", "mm",
                 "--placement", "as-measured", "--out", str(again)]) == 0
    assert "nothing to rework" in json.loads((again / "rework.json").read_text())["message"]
    assert not (again / "plan").exists()


def test_rework_refuses_a_target_of_its_own_before_work(tmp_path):
    from swath.cli import main

    assert main(["-q", "rework", "cad.ply", "scan.xyz", "--target-depth", "5um", "--out", str(tmp_path / "o")]) == 2
    assert not (tmp_path / "o").exists()


def test_target_floor_fastest_raises_an_unreachable_target_instead_of_refusing():
    from swath.errors import InfeasibleError
    from swath.feed import optimise_feed
    from swath.feed.spacing import raster_at_offsets
    from swath.feed.targets import TargetMap
    from swath.trajectory import FeedLimit

    tool = Tool(pad_radius=0.02)
    plate = flat_plate(size_x=0.16, size_y=0.12, spacing=4e-3)
    tp = raster_at_offsets(plate, tool, [0.045, 0.075])
    # a target that tapers to nothing across the passes: below what the fastest feed removes
    taper = TargetMap(plate.vertices, 6e-6 * np.clip((plate.vertices[:, 1] - 0.03) / 0.06, 0, 1))
    with pytest.raises(InfeasibleError, match="fastest allowed feed already removes"):
        optimise_feed(tp, tool, [FeedLimit(0.05)], target=taper, tolerance=0.2e-6, boundary_margin=0.0)
    res = optimise_feed(tp, tool, [FeedLimit(0.05)], target=taper, tolerance=0.2e-6, boundary_margin=0.0,
                        target_floor="fastest")
    assert res.metrics["target_raised_max_m"] > 0.2e-6
    assert res.metrics["speed_max_m_per_s"] == pytest.approx(0.05, rel=1e-6)
    with pytest.raises(InputError, match="target_floor"):
        optimise_feed(tp, tool, [FeedLimit(0.05)], target=taper, tolerance=0.2e-6, target_floor="lowest")
