"""The vectorised 1-to-4 halving reproduces trimesh.remesh.subdivide_to_size bit for bit."""

import numpy as np
import pytest
import trimesh

from conftest import shared_mesh
from shapes import sphere_cap
from swath.errors import InputError
from swath.examples import flat_plate, large_panel
from swath.io.mesh import load_mesh
from swath.surface.subdivide import halve_long_edges


def _same_as_trimesh(vertices, faces, max_edge):
    expected_v, expected_f = trimesh.remesh.subdivide_to_size(vertices, faces, max_edge=max_edge, max_iter=20)
    got_v, got_f = halve_long_edges(vertices, faces, max_edge)
    assert got_v.dtype == np.float64 and got_f.dtype == np.int64
    np.testing.assert_array_equal(got_f, expected_f)
    np.testing.assert_array_equal(got_v, expected_v)
    return got_v, got_f


@pytest.mark.parametrize("factor", [1.5, 0.7, 0.3, 0.12])
def test_jittered_plate_same_as_trimesh(rng, factor):
    """Uneven edges: faces with 1, 2 and 3 long edges in the same round, several rounds."""
    plate = flat_plate(size_x=0.12, size_y=0.08, spacing=0.01)
    xyz = plate.vertices + rng.normal(scale=0.002, size=plate.vertices.shape)
    v, f = _same_as_trimesh(xyz, plate.faces, 0.01 * factor)
    lengths = np.linalg.norm(v[f] - v[f[:, [1, 2, 0]]], axis=2)
    assert lengths.max() <= 0.01 * factor
    assert len(f) > len(plate.faces) or factor > 1.4


def test_sphere_cap_and_panel_same_as_trimesh():
    cap = sphere_cap(0.2, 0.6, n=40)
    _same_as_trimesh(cap.vertices, cap.faces, 0.004)
    panel = large_panel(n_faces=4000)
    _same_as_trimesh(panel.vertices, panel.faces, 0.25 * float(np.median(panel.edge_lengths)))


@pytest.mark.parametrize("name", ["bezier_dac_cad.ply", "noether_wavy_mesh_with_hole.ply"])
def test_shared_meshes_same_as_trimesh(name):
    from conftest import SHARED_MESH_UNITS

    surface = load_mesh(shared_mesh(name), units=SHARED_MESH_UNITS[name])
    _same_as_trimesh(surface.vertices, surface.faces, 0.5 * float(np.median(surface.edge_lengths)))


def test_short_edges_untouched_and_surface_uses_it():
    plate = flat_plate(size_x=0.05, size_y=0.05, spacing=0.01)
    v, f = halve_long_edges(plate.vertices, plate.faces, 1.0)
    np.testing.assert_array_equal(v, plate.vertices)
    np.testing.assert_array_equal(f, plate.faces)
    fine = plate.subdivided(0.004, method="halving")
    expected_v, expected_f = trimesh.remesh.subdivide_to_size(plate.vertices, plate.faces, max_edge=0.004, max_iter=20)
    np.testing.assert_array_equal(fine.faces, expected_f)
    np.testing.assert_array_equal(fine.vertices, expected_v)


@pytest.mark.parametrize("bad", [0.0, -1.0, np.nan, np.inf])
def test_bad_max_edge(bad):
    plate = flat_plate(size_x=0.05, size_y=0.05, spacing=0.01)
    with pytest.raises(InputError, match="max_edge"):
        halve_long_edges(plate.vertices, plate.faces, bad)


def test_sliver_cad_mesh_same_as_trimesh():
    """crs_part_5's long CAD slivers need many rounds, each finishing some faces and splitting
    others: the faces set aside as final keep trimesh's order, bit for bit."""
    from conftest import SHARED_MESH_UNITS

    surface = load_mesh(shared_mesh("crs_part_5.stl"), units=SHARED_MESH_UNITS["crs_part_5.stl"])
    v, f = halve_long_edges(surface.vertices, surface.faces, 0.02)
    rounds = int(np.ceil(np.log2(surface.edge_lengths.max() / 0.02)))
    assert rounds >= 5 and len(f) > 10 * len(surface.faces)
    _same_as_trimesh(surface.vertices, surface.faces, 0.02)
