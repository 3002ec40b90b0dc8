"""Exact mesh reading: relative OBJ indices, malformed ASCII PLY rows, float64 positions, fin repair, unit names."""

from __future__ import annotations

import logging

import numpy as np
import pytest
from meshfiles import grid, obj_text, plate_with_fin, ply_ascii_lines, ply_binary_bytes

from swath.errors import InputError
from swath.io.mesh import load_mesh, nonmanifold_faces
from swath.io.mesh_repair import face_areas
from swath.io.obj_read import read_obj
from swath.units import canonical_length_unit, length_unit_factor


def sorted_rows(a):
    a = np.asarray(a)
    return a[np.lexsort(a.T[::-1])]


# --------------------------------------------------------------------------------------------
# OBJ
# --------------------------------------------------------------------------------------------
def test_obj_relative_indices_read_every_face(tmp_path):
    v, f = grid(31, 31, size=(0.3, 0.3))                         # 1800 faces, 0.09 m²
    path = tmp_path / "relative.obj"
    path.write_text(obj_text(v, f, relative_groups=30))
    surface = load_mesh(path)
    assert len(surface.faces) == 1800
    assert surface.area == pytest.approx(0.09, rel=1e-12)
    assert len(surface.vertices) == 31 * 31                       # the groups' copies merged back


def test_obj_relative_and_absolute_agree():
    v, f = grid(4, 3)
    absolute = read_obj(obj_text(v, f).encode(), "a.obj")
    relative = read_obj(obj_text(v, f, relative_groups=3).encode(), "r.obj")
    # same triangles by position, whatever the vertex numbering
    assert np.array_equal(sorted_rows(absolute[0][absolute[1]].reshape(len(f), 9)),
                          sorted_rows(relative[0][relative[1]].reshape(len(f), 9)))


def test_obj_corner_forms_continuation_and_normals():
    text = ("v 0 0 0\nv 1 0 0\nv 1 1 0 \\\n\nv 0 1 0\nvt 0 0\nvn 0 0 -1\n"
            "f -4/1/-1 -3//1 -2/1/1 \\\n -1//-1   # a quad, with a continuation line\n")
    v, f, fn = read_obj(text.encode(), "forms.obj")
    assert v.dtype == np.float64 and v.shape == (4, 3)
    assert f.tolist() == [[0, 1, 2], [0, 2, 3]]
    assert np.allclose(fn, [[0, 0, -3], [0, 0, -3]])


@pytest.mark.parametrize("text, message", [
    ("v 0 0 0\nv 1 0 0\nf -1 -2 -3\n", r"bad\.obj, line 3: vertex reference -3 is invalid.*2 vertexs? are defined"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", r"line 4: vertex reference 0 is invalid"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", r"line 4: face refers to vertex 4 but the file has 3 vertices"),
    ("v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n", r"line 2: a 'v' record needs 3 numbers, got 2"),
    ("v 0 0 0\nv 1 zero 0\n", r"line 2: expected 3 numbers after 'v'"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", r"line 4: a face needs at least 3 vertices, got 2"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x/3\n", r"line 4: 'x/3' is not a vertex reference"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999999\n", r"line 4: '9+' is not a vertex reference"),
])
def test_obj_malformed_refused_with_line(tmp_path, text, message):
    path = tmp_path / "bad.obj"
    path.write_text(text)
    with pytest.raises(InputError, match=message):
        load_mesh(path)


# --------------------------------------------------------------------------------------------
# ASCII PLY
# --------------------------------------------------------------------------------------------
def ply_with(lines, tmp_path, name="bad.ply", newline="\n"):
    path = tmp_path / name
    path.write_bytes((newline.join(lines) + newline).encode())
    return path


def test_ply_blank_line_after_header_refused(tmp_path):
    lines = ply_ascii_lines(*grid())                              # 20 vertices, 24 faces; header is 9 lines
    lines.insert(lines.index("end_header") + 1, "")
    with pytest.raises(InputError, match=r"bad\.ply, line 10: the vertex row is blank, expected 3 values"):
        load_mesh(ply_with(lines, tmp_path))


@pytest.mark.parametrize("row, replacement, message", [
    (12, "0.1 0.2", r"line 12: the vertex row has 2 values \('0\.1 0\.2'\), expected 3 values"),
    (12, "0.1 0.2 0 7", r"line 12: the vertex row has 4 values .*expected 3 values"),
    (12, "0.1 abc 0", r"line 12: vertex row '0\.1 abc 0' holds a value that is not a number"),
    (30, "3 0 1", r"line 30: the face row has 3 values \('3 0 1'\), expected 4 values"),
    (31, "3 0 1 2 3", r"line 31: the face row has 5 values .*expected 4 values"),
    (31, "2 0 1", r"line 31: a face has 2 vertices, a face needs at least 3"),
    (32, "3 0 1 20", r"line 32: face refers to vertex 20 but the file has 20 vertices \(0\.\.19\)"),
    (32, "3 0 1 -1", r"line 32: face refers to vertex -1"),
    (32, "3 0 1.5 2", r"line 32: face row '3 0 1\.5 2' holds a value that is not a whole number"),
    (32, "3 0 1 99999999999999999999999", r"line 32: face row '3 0 1 9+' holds a value that is not a whole number"),
])
def test_ply_bad_rows_refused_with_line(tmp_path, row, replacement, message):
    lines = ply_ascii_lines(*grid())
    lines[row - 1] = replacement
    with pytest.raises(InputError, match=message):
        load_mesh(ply_with(lines, tmp_path))


def test_ply_short_normal_row_refused(tmp_path):
    v, f = grid()
    lines = ply_ascii_lines(v, f, normals=np.tile([0.0, 0.0, 1.0], (len(v), 1)))
    lines[13] = "0.05 0 0 0 0"
    with pytest.raises(InputError, match=r"line 14: the vertex row has 5 values .*expected 6 values"):
        load_mesh(ply_with(lines, tmp_path))


def test_ply_truncated_and_extra_rows_refused(tmp_path):
    lines = ply_ascii_lines(*grid())
    with pytest.raises(InputError, match=r"ends at line 50 but element 'face' needs 24 rows from line 30.*truncated"):
        load_mesh(ply_with(lines[:-3], tmp_path))
    with pytest.raises(InputError, match=r"line 54: 1 rows more than the header declares"):
        load_mesh(ply_with(lines + ["3 0 1 2"], tmp_path, "extra.ply"))


def test_ply_crlf_and_trailing_blank_lines_load(tmp_path):
    v, f = grid()
    surface = load_mesh(ply_with(ply_ascii_lines(v, f) + ["", ""], tmp_path, "crlf.ply", newline="\r\n"))
    assert len(surface.faces) == len(f) and surface.area == pytest.approx(0.02)


@pytest.mark.parametrize("writer", ["obj", "ply", "binary_ply"])
def test_nan_and_inf_refused(tmp_path, writer):
    v, f = grid()
    v[3, 1], v[7, 2] = np.nan, -np.inf
    path = tmp_path / f"nan.{'obj' if writer == 'obj' else 'ply'}"
    if writer == "obj":
        path.write_text(obj_text(v, f))
    elif writer == "ply":
        path.write_text("\n".join(ply_ascii_lines(v, f)) + "\n")
    else:
        path.write_bytes(ply_binary_bytes(v, f))
    with pytest.raises(InputError, match=r"2 of 20 vertices have NaN or infinite coordinates"):
        load_mesh(path)


# --------------------------------------------------------------------------------------------
# float64 throughout: a part 1 km from the origin keeps its micrometres
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("writer", ["obj", "ply", "binary_ply"])
def test_far_from_origin_full_precision(tmp_path, writer):
    v, f = grid(11, 11, size=(0.3, 0.3), origin=(1000.0, -1000.0, 1000.0))
    v[:, 2] += 1e-6 * np.arange(len(v))                           # micrometre steps on a 1 km offset
    path = tmp_path / f"far.{'obj' if writer == 'obj' else 'ply'}"
    if writer == "obj":
        path.write_text(obj_text(v, f))
    elif writer == "ply":
        path.write_text("\n".join(ply_ascii_lines(v, f)) + "\n")
    else:
        path.write_bytes(ply_binary_bytes(v, f))
    surface = load_mesh(path)
    assert surface.vertices.dtype == np.float64
    assert np.array_equal(sorted_rows(surface.vertices), sorted_rows(v))      # bit-exact
    assert surface.area == pytest.approx(0.09, rel=1e-6)


# --------------------------------------------------------------------------------------------
# non-manifold repair: keep the surface, drop the fin
# --------------------------------------------------------------------------------------------
def test_fin_dropped_plate_kept(tmp_path, caplog):
    v, f, n_plate = plate_with_fin()                               # 450 plate faces + a 100 x 30 mm fin
    path = tmp_path / "fin.ply"
    path.write_text("\n".join(ply_ascii_lines(v, f)) + "\n")
    with caplog.at_level(logging.WARNING, logger="swath.io"):
        surface = load_mesh(path)
    assert len(surface.faces) == n_plate == 450
    assert surface.area == pytest.approx(0.09, rel=1e-12)
    assert np.abs(surface.vertices[:, 2]).max() == 0.0             # nothing of the fin is left
    assert "5 edges are shared by more than two faces" in caplog.text
    assert "dropped 10 faces branching off it" in caplog.text and "0.003 m²" in caplog.text
    assert "pieces" not in caplog.text                              # the fin went as a whole


@pytest.mark.parametrize("tilt_deg", [30.0, 60.0, 90.0, 150.0])
def test_nonmanifold_choice_keeps_the_flattest_pair(tilt_deg):
    # three faces on the edge (0,0,0)-(1,0,0): two continuing a plane, one flap tilted by tilt_deg
    t = np.radians(tilt_deg)
    v = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -1, 0], [0.5, 3 * np.cos(t), 3 * np.sin(t)]])
    f = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    drop, n_bad, n_edges = nonmanifold_faces(v, f, face_areas(v, f))
    assert (n_bad, n_edges) == (1, 7)
    assert drop.tolist() == [False, False, True]                   # the (larger) flap goes


def test_nonmanifold_crossing_planes_keep_one_plane():
    # four faces on one edge: two planes crossing at 90 degrees; either plane is a flat pair
    v = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -1, 0], [0.5, 0, 2], [0.5, 0, -2]])
    f = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4], [1, 0, 5]])
    drop, n_bad, _ = nonmanifold_faces(v, f, face_areas(v, f))
    assert n_bad == 1
    assert drop.tolist() == [True, True, False, False]              # the larger flat pair (area tie-break)


# --------------------------------------------------------------------------------------------
# unit names
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("text, unit", [
    ("m", "m"), ("M", "m"), ("meter", "m"), ("Metres", "m"), ("metre", "m"), ("METERS", "m"),
    ("mm", "mm"), ("MM", "mm"), ("Mm", "mm"), ("millimetre", "mm"), ("millimeters", "mm"), (" mm ", "mm"),
    ("cm", "cm"), ("centimetres", "cm"), ("in", "in"), ("IN", "in"), ("inch", "in"), ("Inches", "in"),
])
def test_unit_names(text, unit):
    assert canonical_length_unit(text) == unit
    assert length_unit_factor(text) == {"m": 1.0, "mm": 1e-3, "cm": 1e-2, "in": 0.0254}[unit]


@pytest.mark.parametrize("text", ["furlong", "", "mmm", "inchs", "km"])
def test_unknown_unit_refused(text):
    with pytest.raises(InputError, match=r"unknown length unit .*use one of m, mm, cm, in"):
        canonical_length_unit(text)


def test_unit_names_through_load_mesh(tmp_path, caplog):
    v, f = grid(size=(200.0, 100.0))                              # 200 x 100 mm in millimetres
    path = tmp_path / "plate_mm.obj"
    path.write_text(obj_text(v, f))
    for name in ("MM", "millimetres", "Millimeter"):
        assert load_mesh(path, units=name).area == pytest.approx(0.02, rel=1e-12)
    with pytest.raises(InputError, match=r"200 m across when read in m.*pass --units mm"):
        load_mesh(path, units="Metre")
    inch = tmp_path / "plate_in.obj"
    inch.write_text(obj_text(*grid(size=(8.0, 4.0))))
    assert load_mesh(inch, units="inches").area == pytest.approx(32 * 0.0254**2, rel=1e-12)


def test_cli_accepts_unit_names(tmp_path, capsys):
    from swath.cli import main

    bad = tmp_path / "empty.obj"
    bad.write_text("# nothing\n")
    assert main(["--quiet", "plan", "--constant-feed", str(bad), "--units", "Inch", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err == "swath: error: empty.obj holds no vertices; check the file or re-export it\n"   # the unit passed
    assert main(["--quiet", "plan", "--constant-feed", str(bad), "--units", "furlong", "--out", str(tmp_path / "out")]) == 2
    assert "unknown length unit 'furlong'" in capsys.readouterr().err


# --------------------------------------------------------------------------------------------
# the point-cloud loader shares the PLY reader and the unit names
# --------------------------------------------------------------------------------------------
def test_points_ascii_ply_rows_checked_and_unit_names(tmp_path):
    from swath.io import load_points

    rng = np.random.default_rng(7)
    cloud = rng.uniform(0.0, 150.0, (50, 3))                      # mm
    lines = ply_ascii_lines(cloud)
    path = ply_with(lines, tmp_path, "cloud.ply")
    points, normals = load_points(path, units="Millimetres")
    assert normals is None and np.array_equal(points, cloud * 1e-3)
    lines.insert(lines.index("end_header") + 1, "")
    with pytest.raises(InputError, match=r"blank_cloud\.ply, line 8: the vertex row is blank"):
        load_points(ply_with(lines, tmp_path, "blank_cloud.ply"), units="mm")


def test_large_branch_refused_naming_its_share(tmp_path):
    v, f, _ = plate_with_fin(fin_x=(0.0, 0.3), fin_height=0.08)   # a 300 x 80 mm wall on a 300 mm plate
    path = tmp_path / "wall.ply"
    path.write_text("\n".join(ply_ascii_lines(v, f)) + "\n")
    with pytest.raises(InputError, match=r"wall\.ply: 15 edges are shared by more than two faces, and the faces "
                                         r"branching off the surface there carry 21\.1% of the area"):
        load_mesh(path)
