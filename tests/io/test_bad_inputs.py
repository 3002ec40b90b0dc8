"""A corpus of bad (and awkward but valid) mesh inputs, generated in code.

Each input either loads correctly or is refused with an InputError of one line, both through
:func:`swath.io.load_mesh` and through the command line (``swath plan``: exit 2, one line on
stderr, nothing left beside the output directory).
"""

from __future__ import annotations

import logging
import re

import numpy as np
import pytest
from meshfiles import (
    box,
    grid,
    obj_text,
    plate_with_fin,
    ply_ascii_lines,
    ply_binary_bytes,
    stl_binary_bytes,
)

from swath.cli import main
from swath.errors import InputError
from swath.io import load_mesh


def _rows(a):
    a = np.asarray(a)
    return a[np.lexsort(a.T[::-1])]


def _ply(path, v, f=None):
    path.write_text("\n".join(ply_ascii_lines(v, f)) + "\n")
    return path


def _fins_everywhere(path):
    v, f = grid(5, 5, size=(0.2, 0.2))
    half = f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    edges, counts = np.unique(np.sort(half, axis=1), axis=0, return_counts=True)
    interior = edges[counts == 2]
    apex = (v[interior[:, 0]] + v[interior[:, 1]]) / 2 + [0, 0, 0.05]
    fins = np.column_stack([interior, len(v) + np.arange(len(interior))])
    return _ply(path, np.vstack([v, apex]), np.vstack([f, fins]))


def _garbage(path, seed):
    path.write_bytes(np.random.default_rng(seed).integers(0, 256, 3000, dtype=np.uint8).tobytes())
    return path


def _dir(path):
    path.mkdir()
    return path


#: name -> (file name, writer(path) -> path, regex the one-line refusal must match)
REFUSED = {
    "empty stl": ("empty.stl", lambda p: (p.write_bytes(b""), p)[1], r"empty\.stl is empty \(0 bytes\)"),
    "empty obj": ("empty.obj", lambda p: (p.write_bytes(b""), p)[1], r"empty\.obj is empty \(0 bytes\)"),
    "blank obj": ("blank.obj", lambda p: (p.write_text("# exported by nothing\n\n"), p)[1],
                  r"blank\.obj holds no vertices"),
    "garbage stl": ("garbage.stl", lambda p: _garbage(p, 1), r"garbage\.stl is not an STL file"),
    "garbage ply": ("garbage.ply", lambda p: _garbage(p, 2), r"garbage\.ply is not a PLY file"),
    "garbage obj": ("garbage.obj", lambda p: _garbage(p, 3), r"garbage\.obj holds binary data, not a text OBJ"),
    "text obj garbage": ("words.obj", lambda p: (p.write_text("hello world\nthis is not\na mesh\n"), p)[1],
                         r"words\.obj holds no vertices"),
    "truncated binary stl": ("cut.stl", lambda p: (p.write_bytes(stl_binary_bytes(*grid())[:-17]), p)[1],
                             r"cut\.stl is not an STL file \(neither binary, whose size matches"),
    "truncated binary ply": ("cut.ply", lambda p: (p.write_bytes(ply_binary_bytes(*grid())[:-5]), p)[1],
                             r"could not read cut\.ply as PLY: .*unexpected length"),
    "truncated ascii ply": ("cut_ascii.ply",
                            lambda p: (p.write_text("\n".join(ply_ascii_lines(*grid())[:-4]) + "\n"), p)[1],
                            r"the file ends at line 49 but element 'face' needs 24 rows"),
    "ply header only": ("header.ply", lambda p: (p.write_text("ply\nformat ascii 1.0\nelement vertex 3\n"), p)[1],
                        r"header\.ply: the PLY header has no 'end_header' line"),
    "nan": ("nan.ply", lambda p: _ply(p, np.where(np.arange(60).reshape(20, 3) == 7, np.nan, grid()[0]), grid()[1]),
            r"1 of 20 vertices have NaN or infinite coordinates"),
    "inf": ("inf.obj", lambda p: (p.write_text(obj_text(np.vstack([grid()[0][:-1], [[np.inf, 0, 0]]]), grid()[1])),
                                  p)[1],
            r"1 of 20 vertices have NaN or infinite coordinates"),
    "face out of range obj": ("range.obj", lambda p: (p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99\n"), p)[1],
                              r"range\.obj, line 4: face refers to vertex 99 but the file has 3 vertices"),
    "face out of range ply": ("range.ply", lambda p: _ply(p, grid()[0], np.where(grid()[1] == 5, 20, grid()[1])),
                              r"range\.ply, line \d+: face refers to vertex 20 but the file has 20 vertices"),
    "all degenerate": ("line.obj",
                       lambda p: (p.write_text("v 0 0 0\nv 0.1 0 0\nv 0.2 0 0\nv 0.3 0 0\nf 1 2 3\nf 2 3 4\nf 1 1 2\n"),
                                  p)[1],
                       r"all 3 faces are degenerate \(zero area\)"),
    "point cloud ply": ("cloud.ply", lambda p: _ply(p, grid()[0]), r"cloud\.ply.*point cloud"),
    "badly non-manifold": ("fins.ply", _fins_everywhere, r"badly broken: \d+ edges .* shared by more than two faces"),
    "closed solid without side": ("box.stl", lambda p: (p.write_bytes(stl_binary_bytes(*box())), p)[1],
                                  r"box\.stl is a closed solid.*--side \+z"),
    "size in wrong unit": ("plate_mm.obj", lambda p: (p.write_text(obj_text(*grid(size=(300.0, 200.0)))), p)[1],
                           r"part is 300 m across when read in m.*--units mm"),
    "wrong extension": ("part.dxf", lambda p: (p.write_text("0\nSECTION\n"), p)[1],
                        r"part\.dxf: unsupported"),
    "stl bytes named ply": ("shape.ply", lambda p: (p.write_bytes(stl_binary_bytes(*grid())), p)[1],
                            r"shape\.ply is not a PLY file"),
    "ply text named stl": ("shape.stl", lambda p: _ply(p, *grid()), r"shape\.stl is not an STL file"),
    "obj text named ply": ("shape2.ply", lambda p: (p.write_text(obj_text(*grid())), p)[1], r"shape2\.ply is not a PLY"),
    "directory": ("folder.stl", _dir, r"folder\.stl is a directory; give the path of a mesh file"),
    "directory no extension": ("folder", _dir, r"folder is a directory; give the path of a mesh file"),
    "missing": ("missing.ply", lambda p: p, r"missing\.ply: no such file"),
}


@pytest.mark.parametrize("case", sorted(REFUSED))
def test_refused_by_load_mesh(tmp_path, case):
    name, write, message = REFUSED[case]
    path = write(tmp_path / name)
    with pytest.raises(InputError, match=message) as info:
        load_mesh(path)
    assert "\n" not in str(info.value)


def test_a_broken_step_file_is_refused_by_the_cli(tmp_path, capsys):
    from swath.cli import main

    (tmp_path / "part.step").write_text("ISO-10303-21;\n")
    assert main(["plan", "--constant-feed", str(tmp_path / "part.step"), "--out", str(tmp_path / "out")]) == 2
    assert "part.step: Open CASCADE could not read it as a STEP file; re-export it" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("case", sorted(REFUSED))
def test_refused_by_the_cli(tmp_path, capsys, case):
    name, write, message = REFUSED[case]
    (tmp_path / "in").mkdir()
    path = write(tmp_path / "in" / name)
    parent = tmp_path / "runs"
    parent.mkdir()
    for argv in (["plan", str(path), "--out", str(parent / "out")],
                 ["--quiet", "plan", str(path), "--out", str(parent / "out")]):
        assert main(argv) == 2
        captured = capsys.readouterr()
        errors = [ln for ln in captured.err.splitlines() if not ln.startswith("[")]   # progress lines start "["
        assert len(errors) == 1 and errors[0].startswith("swath: error: "), captured.err
        assert re.search(message, errors[0]), errors[0]
        assert "Traceback" not in captured.err and captured.out == ""
        assert list(parent.iterdir()) == []                       # nothing left behind
    assert captured.err.count("\n") == 1                           # --quiet: the error line alone


# --------------------------------------------------------------------------------------------
# awkward but valid: each loads, correctly
# --------------------------------------------------------------------------------------------
def test_multi_piece(tmp_path, caplog):
    v1, f1 = grid(size=(0.2, 0.1))
    v2, f2 = grid(size=(0.05, 0.05), origin=(0.5, 0.0, 0.1))
    v3, f3 = grid(size=(0.04, 0.04), origin=(0.0, 0.5, 0.0))
    path = _ply(tmp_path / "three.ply", np.vstack([v1, v2, v3]),
                np.vstack([f1, f2 + len(v1), f3 + len(v1) + len(v2)]))
    with caplog.at_level(logging.WARNING, logger="swath.io"):
        largest = load_mesh(path)
    assert largest.area == pytest.approx(0.02) and "3 pieces" in caplog.text
    every = load_mesh(path, all_pieces=True)
    assert every.area == pytest.approx(0.02 + 0.0025 + 0.0016)


def test_closed_solid_with_side(tmp_path):
    path = tmp_path / "box.stl"
    path.write_bytes(stl_binary_bytes(*box()))
    surface = load_mesh(path, side="+z")
    assert surface.area == pytest.approx(0.2 * 0.1, rel=1e-6)
    assert np.allclose(surface.vertices[:, 2], 0.025, atol=1e-7)
    assert (surface.face_normals[:, 2] > 0.99).all()


def test_single_triangle(tmp_path):
    path = tmp_path / "one.obj"
    path.write_text("v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nf 1 2 3\n")
    surface = load_mesh(path)
    assert len(surface.faces) == 1 and surface.area == pytest.approx(0.005, rel=1e-12)


def test_far_from_origin_loads_exactly(tmp_path):
    v, f = grid(21, 11, size=(0.3, 0.15), origin=(1000.0, 1000.0, 1000.0))   # 1 km from the origin
    path = _ply(tmp_path / "far.ply", v, f)
    surface = load_mesh(path)
    assert np.array_equal(_rows(surface.vertices), _rows(v))
    assert surface.area == pytest.approx(0.045, rel=1e-9)


@pytest.mark.parametrize("name", ["pièce d'essai ü.ply", "with  spaces/part one.obj", "日本語 フォルダ/部品.stl"])
def test_unicode_and_space_paths(tmp_path, name):
    path = tmp_path / name
    path.parent.mkdir(parents=True, exist_ok=True)
    v, f = grid()
    if path.suffix == ".ply":
        _ply(path, v, f)
    elif path.suffix == ".obj":
        path.write_text(obj_text(v, f), encoding="utf-8")
    else:
        path.write_bytes(stl_binary_bytes(v, f))
    surface = load_mesh(path)
    assert surface.area == pytest.approx(0.02, rel=1e-6) and surface.name == path.stem


def test_fin_is_repaired_not_refused(tmp_path):
    v, f, n_plate = plate_with_fin()
    surface = load_mesh(_ply(tmp_path / "fin.ply", v, f), all_pieces=True)
    assert len(surface.faces) == n_plate and surface.area == pytest.approx(0.09)


def test_refusal_on_unicode_path_names_the_file(tmp_path):
    path = tmp_path / "dossier é" / "pièce vide.stl"
    path.parent.mkdir()
    path.write_bytes(b"")
    with pytest.raises(InputError, match=r"pièce vide\.stl is empty"):
        load_mesh(path)
