"""Tests of the io stage: loading meshes and point clouds, refusals, repairs, saving."""

from __future__ import annotations

import logging
import struct

import numpy as np
import pytest
from meshfiles import ply_ascii_lines

from conftest import SHARED_MESH_UNITS, shared_mesh
from swath.errors import InputError
from swath.io import likely_unit, load_mesh, load_points, parse_side, save_surface_ply
from swath.io.mesh import edge_table, merge_vertices, orient_faces


# --------------------------------------------------------------------------------------------
# small writers for synthetic files
# --------------------------------------------------------------------------------------------
def write_ply(path, vertices, faces=None, normals=None):
    """ASCII PLY with optional faces and per-vertex normals."""
    path.write_text("\n".join(ply_ascii_lines(vertices, faces, normals)) + "\n")
    return path


def write_obj(path, vertices, faces):
    lines = [f"v {x:.17g} {y:.17g} {z:.17g}" for x, y, z in np.asarray(vertices, float).tolist()]
    lines += ["f " + " ".join(str(int(i) + 1) for i in f) for f in faces]
    path.write_text("\n".join(lines) + "\n")
    return path


def write_binary_stl(path, vertices, faces):
    tri = np.asarray(vertices, float)[np.asarray(faces)]
    rec = np.zeros(len(tri), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["v"] = tri
    path.write_bytes(b"\0" * 80 + struct.pack("<I", len(tri)) + rec.tobytes())
    return path


def grid(nx=5, ny=4, size=(0.2, 0.1), origin=(0.0, 0.0, 0.0)):
    """A flat grid in z = const, faces wound +z: (vertices, faces)."""
    x, y = np.meshgrid(np.linspace(0, size[0], nx), np.linspace(0, size[1], ny), indexing="ij")
    v = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1) + origin
    idx = np.arange(nx * ny).reshape(nx, ny)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    f = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return v, f


def box(extents=(0.2, 0.1, 0.05)):
    """Closed box centred at the origin, outward winding, 8 vertices, 12 faces."""
    import trimesh

    m = trimesh.creation.box(extents=extents)
    return np.asarray(m.vertices), np.asarray(m.faces)


def interior_edges_consistent(faces):
    """True when every edge shared by two faces is used once in each direction."""
    edge_of, counts, forward = edge_table(faces)
    shared = counts[edge_of] == 2
    per_edge = np.bincount(edge_of[shared], weights=forward[shared], minlength=len(counts))
    return bool(np.all(per_edge[counts == 2] == 1)) and counts.max() <= 2


# --------------------------------------------------------------------------------------------
# shared real meshes
# --------------------------------------------------------------------------------------------
# faces / vertices after loading (SOURCES.md counts after merging; bezier_dac_scan keeps its
# largest of 12 pieces) and the largest extent in metres.
SHARED_EXPECTED = {
    "snp_part_scan.ply": (7052, 3627, 0.470),
    "noether_raw_mesh.ply": (56884, 29768, 1.277),
    "bezier_dac_cad.ply": (2570, 1475, 0.432),
    "bezier_dac_scan.ply": (142063, 72292, 0.758),
    "noether_wavy_mesh_with_hole.ply": (1347, 757, 10.5 * 0.0254),
    "bezier_complex_shape.ply": (2048, 1089, 0.722),
    "crs_part_5.stl": (997, 548, 1.972),
}


@pytest.mark.parametrize("name", sorted(SHARED_MESH_UNITS))
def test_shared_mesh_loads(name):
    surface = load_mesh(shared_mesh(name), units=SHARED_MESH_UNITS[name])
    n_faces, n_vertices, extent = SHARED_EXPECTED[name]
    assert len(surface.faces) == n_faces
    assert len(surface.vertices) == n_vertices
    assert np.ptp(surface.vertices, axis=0).max() == pytest.approx(extent, abs=1e-3)
    assert surface.name == name.rsplit(".", 1)[0]
    assert interior_edges_consistent(surface.faces)
    assert len(surface.boundary_loops) >= 1          # every shared part is an open surface


def test_shared_scan_pieces(caplog):
    path = shared_mesh("bezier_dac_scan.ply")
    with caplog.at_level(logging.WARNING, logger="swath.io"):
        kept = load_mesh(path)
    assert "12 pieces" in caplog.text
    everything = load_mesh(path, all_pieces=True)
    assert (len(everything.faces), len(everything.vertices)) == (179041, 91499)
    assert kept.area == pytest.approx(0.3725, abs=5e-4)
    assert everything.area == pytest.approx(kept.area + 0.0936, abs=5e-4)


def test_wavy_mesh_agrees_with_file_normals():
    import trimesh

    path = shared_mesh("noether_wavy_mesh_with_hole.ply")
    surface = load_mesh(path, units="in")
    file_normals = trimesh.load(path, process=False).vertex_normals
    assert np.mean(np.einsum("ij,ij->i", surface.vertex_normals, file_normals) > 0.5) > 0.99


def test_wavy_mesh_units_a_slip_is_refused_not_warned(caplog):
    """FORMATS.md: a guessed unit is refused (unless forced) — read in mm (10.5 mm) or in m (10.5 m)
    the wavy scan is a unit slip that another unit (inches, 0.267 m) makes a comfortable size."""
    path = shared_mesh("noether_wavy_mesh_with_hole.ply")
    inches = load_mesh(path, units="in")
    assert np.ptp(inches.vertices, axis=0).max() == pytest.approx(0.2667, rel=1e-3)
    for units, size in (("mm", "0.0105 m"), ("m", "10.5 m")):
        with pytest.raises(InputError, match=f"part is {size} across when read in {units}.*--units in"):
            load_mesh(path, units=units)
    with caplog.at_level(logging.WARNING, logger="swath.io"):
        mm = load_mesh(path, units="mm", force_units=True)
    assert "may not be in mm" in caplog.text
    np.testing.assert_allclose(mm.vertices, inches.vertices / 25.4, rtol=1e-12, atol=1e-15)


# --------------------------------------------------------------------------------------------
# units and size
# --------------------------------------------------------------------------------------------
def test_units_convert_to_metres(tmp_path):
    v, f = grid(size=(200.0, 100.0))
    surface = load_mesh(write_ply(tmp_path / "plate.ply", v, f), units="mm")
    np.testing.assert_allclose(surface.bounds, [[0, 0, 0], [0.2, 0.1, 0]], atol=1e-15)
    assert surface.area == pytest.approx(0.02, rel=1e-12)


def test_size_limits(tmp_path):
    v, f = grid(size=(3000.0, 1000.0))
    path = write_ply(tmp_path / "big.ply", v, f)
    assert np.ptp(load_mesh(path, units="mm").vertices, axis=0).max() == pytest.approx(3.0)
    with pytest.raises(InputError, match=r"3000 m across.*--units mm.*--force-units"):
        load_mesh(path, units="m")
    forced = load_mesh(path, units="m", force_units=True)
    assert np.ptp(forced.vertices, axis=0).max() == pytest.approx(3000.0)
    tiny = write_ply(tmp_path / "tiny.ply", *grid(size=(2.0, 1.0)))
    with pytest.raises(InputError, match=r"0\.002 m across when read in mm.*--units m\b"):
        load_mesh(tiny, units="mm")


def test_likely_unit():
    assert likely_unit(10.5, exclude="m") == "in"         # 0.267 m preferred over 10.5 mm
    assert likely_unit(3000.0) == "mm"
    assert likely_unit(0.5) == "m"
    assert likely_unit(100.0) == "mm"                      # 0.1 m (mm) before 2.54 m (in)
    assert likely_unit(1e6) is None


# --------------------------------------------------------------------------------------------
# refusals
# --------------------------------------------------------------------------------------------
def test_missing_empty_unsupported(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        load_mesh(tmp_path / "nothing.stl")
    (tmp_path / "empty.ply").write_bytes(b"")
    with pytest.raises(InputError, match="empty"):
        load_mesh(tmp_path / "empty.ply")
    (tmp_path / "part.step").write_text("ISO-10303-21;")
    with pytest.raises(InputError, match=r"unsupported.*'\.step'.*\.stl, \.ply, \.obj"):
        load_mesh(tmp_path / "part.step")


@pytest.mark.parametrize("ext", [".stl", ".ply", ".obj"])
def test_garbage_bytes(tmp_path, rng, ext):
    path = tmp_path / f"garbage{ext}"
    path.write_bytes(rng.integers(0, 256, 2000, dtype=np.uint8).tobytes())
    with pytest.raises(InputError, match=r"garbage\.\w+.*(not an? \w+ file|binary data|could not read).*check"):
        load_mesh(path)


def test_nan_vertex(tmp_path):
    v, f = grid()
    v[3, 1] = np.nan
    v[7, 2] = np.inf
    with pytest.raises(InputError, match=r"2 of 20 vertices have NaN or infinite"):
        load_mesh(write_ply(tmp_path / "nan.ply", v, f))


def test_zero_area_and_point_cloud(tmp_path):
    v = np.array([[0, 0, 0], [0.1, 0, 0], [0.2, 0, 0], [0.3, 0, 0]])
    with pytest.raises(InputError, match="degenerate"):
        load_mesh(write_obj(tmp_path / "line.obj", v, [[0, 1, 2], [1, 2, 3]]))
    with pytest.raises(InputError, match=r"no faces.*swath fit"):
        load_mesh(write_ply(tmp_path / "cloud.ply", v))


def test_bad_face_index(tmp_path):
    v, f = grid()
    f[0, 0] = 99
    with pytest.raises(InputError, match=r"bad\.ply, line 30: face refers to vertex 99 but the file has 20 vertices"):
        load_mesh(write_ply(tmp_path / "bad.ply", v, f))


# --------------------------------------------------------------------------------------------
# closed solids and side
# --------------------------------------------------------------------------------------------
def test_closed_box_needs_side(tmp_path):
    path = write_binary_stl(tmp_path / "box.stl", *box())
    with pytest.raises(InputError, match=r"closed solid.*--side \+z"):
        load_mesh(path)


def test_closed_box_top_face(tmp_path):
    v, f = box((0.2, 0.1, 0.05))
    path = write_binary_stl(tmp_path / "box.stl", v, f[:, ::-1])    # inward winding in the file
    top = load_mesh(path, side="+z")
    assert len(top.faces) == 2 and len(top.vertices) == 4
    assert top.area == pytest.approx(0.02, rel=1e-6)
    np.testing.assert_allclose(top.face_normals, [[0, 0, 1]] * 2, atol=1e-7)
    np.testing.assert_allclose(top.normals, [[0, 0, 1]] * 4, atol=1e-7)
    np.testing.assert_allclose(top.vertices[:, 2], 0.025, atol=1e-7)
    side = load_mesh(path, side="-x")
    assert side.area == pytest.approx(0.1 * 0.05, rel=1e-6)
    np.testing.assert_allclose(side.face_normals, [[-1, 0, 0]] * 2, atol=1e-7)
    corner = load_mesh(path, side=[1, 0, 1])                        # top and +x faces, joined
    assert corner.area == pytest.approx(0.02 + 0.005, rel=1e-6)


def step_solid():
    """A closed L-shaped prism: profile in xz, 0.1 m deep along y; its +z faces are two steps,
    0.1 x 0.1 m at z = 0.1 and 0.15 x 0.1 m at z = 0.05.  Faces deliberately wound at random."""
    prof = np.array([[0, 0], [0.25, 0], [0.25, 0.05], [0.1, 0.05], [0.1, 0.1], [0, 0.1]])
    v = np.vstack([np.column_stack([prof[:, 0], np.full(6, y), prof[:, 1]]) for y in (0.0, 0.1)])
    cap = np.array([[3, 4, 5], [3, 5, 0], [3, 0, 1], [3, 1, 2]])  # fan from the reflex corner
    i = np.arange(6)
    j = (i + 1) % 6
    walls = np.concatenate([np.stack([i, j, j + 6], 1), np.stack([i, j + 6, i + 6], 1)])
    f = np.vstack([cap, cap[:, ::-1] + 6, walls])
    flip = np.random.default_rng(7).random(len(f)) < 0.5
    return v, np.where(flip[:, None], f[:, ::-1], f)


def test_closed_solid_side_pieces(tmp_path, caplog):
    path = write_ply(tmp_path / "step.ply", *step_solid())
    with caplog.at_level(logging.WARNING, logger="swath.io"):
        top = load_mesh(path, side="+z")
    assert "form 2 pieces" in caplog.text
    assert top.area == pytest.approx(0.015)
    np.testing.assert_allclose(top.vertices[:, 2], 0.05)
    np.testing.assert_allclose(top.face_normals[:, 2], 1.0)
    both = load_mesh(path, side="+z", all_pieces=True)
    assert both.area == pytest.approx(0.025)
    np.testing.assert_allclose(both.face_normals[:, 2], 1.0)
    under = load_mesh(path, side="-z")
    assert under.area == pytest.approx(0.025) and np.allclose(under.face_normals[:, 2], -1.0)


def test_open_surface_oriented_toward_side(tmp_path, rng):
    v, f = grid(6, 6)
    flip = rng.random(len(f)) < 0.3                                  # inconsistent winding in the file
    f = np.where(flip[:, None], f[:, ::-1], f)
    path = write_ply(tmp_path / "mixed.ply", v, f)
    kept = load_mesh(path)                                            # majority (+z) wins
    np.testing.assert_allclose(kept.face_normals[:, 2], 1.0)
    down = load_mesh(path, side="-z")
    np.testing.assert_allclose(down.face_normals[:, 2], -1.0)
    assert interior_edges_consistent(down.faces)


def test_file_vertex_normals_decide_orientation(tmp_path):
    v, f = grid()
    normals = np.tile([0.0, 0.0, 1.0], (len(v), 1))
    path = write_ply(tmp_path / "normals.ply", v, f[:, ::-1], normals=normals)  # winding says -z
    surface = load_mesh(path)
    np.testing.assert_allclose(surface.face_normals[:, 2], 1.0)


# --------------------------------------------------------------------------------------------
# pieces, non-manifold, non-orientable
# --------------------------------------------------------------------------------------------
def test_two_pieces(tmp_path, caplog):
    v1, f1 = grid(size=(0.2, 0.1))
    v2, f2 = grid(size=(0.05, 0.05), origin=(0.5, 0.0, 0.0))
    path = write_ply(tmp_path / "two.ply", np.vstack([v1, v2]), np.vstack([f1, f2 + len(v1)]))
    with caplog.at_level(logging.WARNING, logger="swath.io"):
        kept = load_mesh(path)
    assert kept.area == pytest.approx(0.02)
    assert kept.vertices[:, 0].max() == pytest.approx(0.2)
    assert "2 pieces" in caplog.text and "0.02 m²" in caplog.text and "0.0025 m²" in caplog.text
    both = load_mesh(path, all_pieces=True)
    assert both.area == pytest.approx(0.0225)
    assert len(both.vertices) == len(v1) + len(v2)


def test_nonmanifold_fin_dropped(tmp_path, caplog):
    v, f = grid(5, 5, size=(0.2, 0.2))
    a, b = f[0, 0], f[0, 2]                                           # an interior diagonal edge
    apex = (v[a] + v[b]) / 2 + [0, 0, 0.01]
    fin = [[a, b, len(v)]]
    path = write_ply(tmp_path / "fin.ply", np.vstack([v, apex]), np.vstack([f, fin]))
    with caplog.at_level(logging.WARNING, logger="swath.io"):
        surface = load_mesh(path)
    assert "1 edges are shared by more than two faces" in caplog.text and "dropped 1 faces" in caplog.text
    assert len(surface.faces) == len(f) and surface.area == pytest.approx(0.04)


def test_badly_nonmanifold_refused(tmp_path):
    v, f = grid(5, 5, size=(0.2, 0.2))
    edge_of, counts, _ = edge_table(f)
    half = f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    interior = np.unique(np.sort(half[counts[edge_of] == 2], axis=1), axis=0)
    apex = (v[interior[:, 0]] + v[interior[:, 1]]) / 2 + [0, 0, 0.05]   # a tall fin on every edge
    fins = np.column_stack([interior, len(v) + np.arange(len(interior))])
    path = write_ply(tmp_path / "fins.ply", np.vstack([v, apex]), np.vstack([f, fins]))
    with pytest.raises(InputError, match=r"badly broken.*more than two faces.*repair"):
        load_mesh(path)


def mobius(n=40, radius=0.1, half_width=0.02):
    """A Möbius strip (non-orientable): (vertices (2n, 3), faces (2n, 3))."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    rims = []
    for s in (-half_width, half_width):
        r = radius + s * np.cos(t / 2)
        rims.append(np.stack([r * np.cos(t), r * np.sin(t), s * np.sin(t / 2)], axis=1))
    i = np.arange(n)                                                  # 0..n-1 one rim, n..2n-1 the other
    j = (i + 1) % n
    nxt_lo = np.where(j == 0, n + j, j)                               # the half twist swaps the rims
    nxt_hi = np.where(j == 0, j, j + n)
    faces = np.concatenate([np.stack([i, nxt_lo, nxt_hi], 1), np.stack([i, nxt_hi, i + n], 1)])
    return np.vstack(rims), faces


def test_mobius_refused(tmp_path):
    with pytest.raises(InputError, match="non-orientable.*Möbius.*repair"):
        load_mesh(write_ply(tmp_path / "mobius.ply", *mobius()))


def test_small_nonorientable_piece_dropped(tmp_path, caplog):
    vg, fg = grid()
    vm, fm = mobius(radius=0.01, half_width=0.002)                    # about 2.5e-4 m², 1% of the total
    path = write_ply(tmp_path / "plate_and_twist.ply", np.vstack([vg, vm + [0.5, 0, 0]]),
                     np.vstack([fg, fm + len(vg)]))
    with caplog.at_level(logging.WARNING, logger="swath.io"):
        surface = load_mesh(path, all_pieces=True)
    assert "non-orientable" in caplog.text
    assert surface.area == pytest.approx(0.02) and len(surface.faces) == len(fg)


def test_orient_faces_keeps_consistent_winding():
    v, f = grid()
    flip, piece, orientable = orient_faces(f[:, ::-1].copy(), np.ones(len(f)))
    assert not flip.any() and orientable.tolist() == [True] and (piece == 0).all()


def test_duplicates_and_degenerate_faces_cleaned(tmp_path):
    v, f = box()
    path = write_binary_stl(tmp_path / "soup.stl", v, f)             # STL repeats each vertex
    top = load_mesh(path, side="+z")
    assert len(top.vertices) == 4
    vg, fg = grid()
    extra = np.array([[0, 0, 1], fg[0], fg[0][::-1]])                 # repeated index + duplicate faces
    surface = load_mesh(write_obj(tmp_path / "dup.obj", vg, np.vstack([fg, extra])))
    assert len(surface.faces) == len(fg)
    vm, fm = merge_vertices(np.array([[0, 0, 0], [1, 0, 0], [0, 0, 0], [1, 1e-12, 0]]),
                            np.array([[0, 1, 2], [2, 3, 1]]), tolerance=1e-9)
    assert len(vm) == 2 and fm.tolist() == [[0, 1, 0], [0, 1, 1]]


def test_ascii_stl(tmp_path):
    v, f = grid()
    tri = v[f]
    body = "".join("facet normal 0 0 1\nouter loop\n" + "".join(f"vertex {a:.17g} {b:.17g} {c:.17g}\n"
                                                              for a, b, c in t.tolist()) + "endloop\nendfacet\n"
                   for t in tri)
    path = tmp_path / "plate.stl"
    path.write_text("solid plate\n" + body + "endsolid plate\n")
    surface = load_mesh(path)
    assert (len(surface.faces), len(surface.vertices)) == (len(f), len(v))
    assert surface.area == pytest.approx(0.02)


def test_obj_quads(tmp_path):
    v = np.array([[0, 0, 0], [0.1, 0, 0], [0.1, 0.1, 0], [0, 0.1, 0]])
    surface = load_mesh(write_obj(tmp_path / "quad.obj", v, [[0, 1, 2, 3]]))
    assert len(surface.faces) == 2 and surface.area == pytest.approx(0.01)


# --------------------------------------------------------------------------------------------
# side parsing and saving
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("text, expected", [
    ("+z", [0, 0, 1]), ("-x", [-1, 0, 0]), ("y", [0, 1, 0]), (" -Z ", [0, 0, -1]),
    ("0,0,2", [0, 0, 1]), ("3 4 0", [0.6, 0.8, 0]), ("[1, 0, 0]", [1, 0, 0]), ((0, -2, 0), [0, -1, 0]),
])
def test_parse_side(text, expected):
    np.testing.assert_allclose(parse_side(text), expected)


@pytest.mark.parametrize("text", ["up", "+w", "0,0,0", "1,2", "1,2,nan", ""])
def test_parse_side_refuses(text):
    with pytest.raises(InputError, match="side"):
        parse_side(text)


def test_save_surface_ply_round_trip(tmp_path):
    from trimesh.exchange import ply

    v, f = box()
    original = load_mesh(write_binary_stl(tmp_path / "box.stl", v, f), side=[0.2, 0.1, 1.0])
    out = tmp_path / "out" / "surface.ply"
    save_surface_ply(original, out)
    assert sorted(p.name for p in out.parent.iterdir()) == ["surface.ply"]
    with open(out, "rb") as fh:
        raw = ply.load_ply(fh)
    np.testing.assert_array_equal(raw["vertices"], original.vertices)
    np.testing.assert_array_equal(raw["faces"], original.faces)
    np.testing.assert_allclose(raw["vertex_normals"], original.normals, atol=1e-7)
    again = load_mesh(out)
    np.testing.assert_array_equal(again.faces, original.faces)
    np.testing.assert_allclose(again.face_normals, original.face_normals, atol=1e-12)


# --------------------------------------------------------------------------------------------
# point clouds
# --------------------------------------------------------------------------------------------
@pytest.fixture
def cloud(rng):
    """A noisy patch of z = 0.1 x² with upward unit normals, 50 points."""
    xy = rng.uniform(-0.1, 0.1, (50, 2))
    pts = np.column_stack([xy, 0.1 * xy[:, 0] ** 2])
    n = np.column_stack([-0.2 * xy[:, 0], np.zeros(50), np.ones(50)])
    return pts, n / np.linalg.norm(n, axis=1, keepdims=True)


def test_points_xyz_and_csv(tmp_path, cloud):
    pts, nrm = cloud
    np.savetxt(tmp_path / "a.xyz", pts * 1000, header="scan in mm")
    p, n = load_points(tmp_path / "a.xyz", units="mm")
    np.testing.assert_allclose(p, pts, atol=1e-12)
    assert n is None
    np.savetxt(tmp_path / "b.csv", np.hstack([pts, nrm]), delimiter=",", header="x,y,z,nx,ny,nz", comments="")
    p, n = load_points(tmp_path / "b.csv")
    np.testing.assert_allclose(p, pts, atol=1e-15)
    np.testing.assert_allclose(n, nrm, atol=1e-15)
    np.savetxt(tmp_path / "c.txt", np.hstack([pts, nrm]))             # no header: unit columns 4-6
    np.testing.assert_allclose(load_points(tmp_path / "c.txt")[1], nrm, atol=1e-15)
    colours = np.full((50, 3), 200.0)
    np.savetxt(tmp_path / "d.txt", np.hstack([pts, colours]))         # x y z r g b: no normals
    assert load_points(tmp_path / "d.txt")[1] is None


def test_points_ply(tmp_path, cloud):
    pts, nrm = cloud
    p, n = load_points(write_ply(tmp_path / "c.ply", pts, normals=nrm))
    np.testing.assert_allclose(p, pts, atol=1e-15)
    np.testing.assert_allclose(n, nrm, atol=1e-15)
    v, f = grid()
    p, n = load_points(write_ply(tmp_path / "m.ply", v, f))           # a mesh: its vertices
    np.testing.assert_allclose(p, v)
    assert n is None


def _pcd_header(n, kind, fields="x y z normal_x normal_y normal_z", width=None, height=1):
    k = len(fields.split())
    return (f"# .PCD v0.7\nVERSION 0.7\nFIELDS {fields}\nSIZE {' '.join(['4'] * k)}\n"
            f"TYPE {' '.join(['F'] * k)}\nCOUNT {' '.join(['1'] * k)}\nWIDTH {width or n}\nHEIGHT {height}\n"
            f"VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA {kind}\n")


def test_points_pcd(tmp_path, cloud):
    pts, nrm = cloud
    table = np.hstack([pts, nrm]).astype(np.float32)
    ascii_path = tmp_path / "a.pcd"
    ascii_path.write_text(_pcd_header(50, "ascii") + "\n".join(" ".join(repr(float(x)) for x in r) for r in table))
    p, n = load_points(ascii_path)
    np.testing.assert_allclose(p, table[:, :3], atol=1e-7)
    np.testing.assert_allclose(n, nrm, atol=1e-6)
    binary_path = tmp_path / "b.pcd"
    binary_path.write_bytes(_pcd_header(50, "binary").encode() + table.astype("<f4").tobytes())
    p, n = load_points(binary_path)
    np.testing.assert_array_equal(p, table[:, :3].astype(float))
    np.testing.assert_allclose(n, nrm, atol=1e-6)
    organised = table[:, :3].copy()
    organised[[4, 9]] = np.nan                                        # no-return pixels
    org_path = tmp_path / "o.pcd"
    org_path.write_bytes(_pcd_header(50, "binary", "x y z", width=10, height=5).encode() + organised.tobytes())
    p, n = load_points(org_path)
    assert len(p) == 48 and n is None
    compressed = tmp_path / "c.pcd"
    compressed.write_bytes(_pcd_header(50, "binary_compressed").encode() + b"\0" * 64)
    with pytest.raises(InputError, match="binary_compressed is not supported"):
        load_points(compressed)


def test_points_refusals(tmp_path, cloud):
    pts, _ = cloud
    bad = pts.copy()
    bad[5, 0] = np.nan
    np.savetxt(tmp_path / "nan.xyz", bad)
    with pytest.raises(InputError, match="1 of 50 points have NaN"):
        load_points(tmp_path / "nan.xyz")
    np.savetxt(tmp_path / "few.xyz", pts[:9])
    with pytest.raises(InputError, match="9 points; at least 10"):
        load_points(tmp_path / "few.xyz")
    np.savetxt(tmp_path / "huge.xyz", pts * 30000)
    with pytest.raises(InputError, match="--units mm"):
        load_points(tmp_path / "huge.xyz")
    (tmp_path / "empty.xyz").write_text("")
    with pytest.raises(InputError, match="empty"):
        load_points(tmp_path / "empty.xyz")
    (tmp_path / "words.txt").write_text("x y z\n1 2 three\n")
    with pytest.raises(InputError, match="could not read"):
        load_points(tmp_path / "words.txt")
    (tmp_path / "scan.las").write_bytes(b"LASF")
    with pytest.raises(InputError, match=r"unsupported.*\.xyz"):
        load_points(tmp_path / "scan.las")
