"""Target depth maps and the feed figures."""

import numpy as np
import pytest

from swath.contact import Tool
from swath.errors import InputError
from swath.examples import flat_plate
from swath.feed import optimise_feed
from swath.feed.spacing import raster_at_offsets
from swath.feed.targets import TargetMap, excess_target, read_target_map, uniform_target, write_target_map
from swath.surface import Surface
from swath.trajectory import FeedLimit


def test_uniform_target_reads_onto_any_sampling():
    plate = flat_plate(size_x=0.1, size_y=0.1, spacing=1e-2)
    np.testing.assert_array_equal(uniform_target(20e-6).depth_on(plate), np.full(len(plate.vertices), 20e-6))
    with pytest.raises(InputError):
        uniform_target(-1e-6)


def test_csv_round_trip_and_nearest_lookup(tmp_path):
    pts = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]])
    write_target_map(tmp_path / "t.csv", TargetMap(pts, [1e-6, 3e-6]))
    back = read_target_map(tmp_path / "t.csv")
    np.testing.assert_allclose(back.depth, [1e-6, 3e-6])
    plate = flat_plate(size_x=0.1, size_y=0.02, spacing=1e-2)
    d = back.depth_on(plate)
    x = plate.vertices[:, 0]
    np.testing.assert_allclose(d[x < 0.049], 1e-6)
    np.testing.assert_allclose(d[x > 0.051], 3e-6)


def test_csv_errors_name_the_line(tmp_path):
    (tmp_path / "bad.csv").write_text("x,y,z,depth\n0,0,0,1e-6\n0,0,oops,1e-6\n")
    with pytest.raises(InputError, match="line 3"):
        read_target_map(tmp_path / "bad.csv")
    (tmp_path / "nohead.csv").write_text("a,b\n1,2\n")
    with pytest.raises(InputError, match="header"):
        read_target_map(tmp_path / "nohead.csv")


def test_ply_vertex_depth_property(tmp_path):
    import trimesh

    plate = flat_plate(size_x=0.02, size_y=0.02, spacing=1e-2)
    mesh = trimesh.Trimesh(plate.vertices * 1e3, plate.faces, process=False)
    depth = np.arange(len(plate.vertices)) * 1e-6          # exact in the 8 decimals of an ASCII PLY
    mesh.vertex_attributes["depth"] = depth
    (tmp_path / "t.ply").write_bytes(trimesh.exchange.ply.export_ply(mesh, encoding="ascii", vertex_normal=False))
    tm = read_target_map(tmp_path / "t.ply", units="mm")
    np.testing.assert_allclose(tm.points, plate.vertices, atol=1e-9)
    np.testing.assert_allclose(tm.depth, depth, rtol=1e-6)


class _Identity:
    """A registration that leaves the CAD where it is (cad2scan = identity)."""

    @staticmethod
    def transform(points):
        return np.asarray(points, float)


def test_excess_target_is_what_sticks_out():
    cad = flat_plate(size_x=0.1, size_y=0.1, spacing=5e-3)
    v = cad.vertices.copy()
    r2 = (v[:, 0] - 0.05) ** 2 + (v[:, 1] - 0.05) ** 2
    v[:, 2] = 50e-6 * np.exp(-r2 / (2 * 0.01**2)) - 10e-6 * (v[:, 0] < 0.02)   # a bump and a dip
    scan = Surface(v, cad.faces, name="scan")
    tm = excess_target(scan, cad, registration=_Identity())
    np.testing.assert_allclose(tm.depth, np.clip(v[:, 2], 0, None), atol=1e-9)
    assert tm.depth.max() == pytest.approx(50e-6, rel=1e-6)


def test_feed_figures_render(tmp_path):
    from swath.report.feed_plots import write_feed_plots

    tool = Tool(pad_radius=0.02)
    plate = flat_plate(size_x=0.16, size_y=0.12, spacing=4e-3)
    tp = raster_at_offsets(plate, tool, [0.045, 0.075])
    res = optimise_feed(tp, tool, [FeedLimit(0.05)], target=6e-6, tolerance=1e-6, boundary_margin=0.0)
    paths = write_feed_plots(tmp_path, res, dpi=50)
    assert set(paths) == {"feed_along_passes", "depth_vs_target", "residual_histogram"}
    for p in paths.values():
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
