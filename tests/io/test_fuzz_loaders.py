"""Bounded fuzz of the loaders: random bytes and mutated valid files either load or raise InputError."""

from __future__ import annotations

import logging
import tempfile
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from meshfiles import (
    grid,
    obj_text,
    plate_with_fin,
    ply_ascii_lines,
    ply_binary_bytes,
    stl_binary_bytes,
)

from swath.errors import InputError
from swath.io import load_mesh, load_points
from swath.surface import Surface

FUZZ = settings(max_examples=100, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def _seeds() -> dict[str, bytes]:
    v, f = grid(6, 5, size=(0.2, 0.1))
    fin_v, fin_f, _ = plate_with_fin(n=6, size=0.3, fin_y=0.12, fin_x=(0.06, 0.18), fin_height=0.03)
    normals = np.tile([0.0, 0.0, 1.0], (len(v), 1))
    ascii_stl = "solid s\n" + "".join(
        "facet normal 0 0 1\nouter loop\n" + "".join(f"vertex {a!r} {b!r} {c!r}\n" for a, b, c in t.tolist())
        + "endloop\nendfacet\n" for t in v[f]) + "endsolid s\n"
    return {
        ".obj": obj_text(v, f, relative_groups=3).encode(),
        ".ply": ("\n".join(ply_ascii_lines(v, f, normals=normals)) + "\n").encode(),
        ".ply ": ply_binary_bytes(fin_v, fin_f),                    # (key with a space: a second .ply seed)
        ".stl": stl_binary_bytes(v, f),
        ".stl ": ascii_stl.encode(),
    }


SEEDS = _seeds()


@st.composite
def mutated(draw):
    key = draw(st.sampled_from(sorted(SEEDS)))
    data = bytearray(SEEDS[key])
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["flip", "truncate", "insert", "delete_line", "duplicate_line", "digit"]))
        if not data:
            break
        at = draw(st.integers(0, len(data) - 1))
        if kind == "flip":
            data[at] = draw(st.integers(0, 255))
        elif kind == "truncate":
            del data[at:]
        elif kind == "insert":
            data[at:at] = draw(st.binary(min_size=1, max_size=12))
        elif kind == "digit":
            data[at:at + 1] = draw(st.sampled_from([b"-", b"9", b"nan", b"e99", b" ", b"\n", b"/", b"-1"]))
        else:
            lines = bytes(data).split(b"\n")
            i = at % len(lines)
            if kind == "delete_line":
                del lines[i]
            else:
                lines.insert(i, lines[i])
            data = bytearray(b"\n".join(lines))
    return key.strip(), bytes(data)


def _load(ext: str, data: bytes, loader):
    io_log = logging.getLogger("swath.io")
    level = io_log.level
    io_log.setLevel(logging.CRITICAL)             # the repairs' warnings are not under test here
    try:
        return _load_file(ext, data, loader)
    finally:
        io_log.setLevel(level)


def _load_file(ext: str, data: bytes, loader):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"fuzz{ext}"
        path.write_bytes(data)
        try:
            return loader(path)
        except InputError as exc:
            assert "\n" not in str(exc)
            return exc


@FUZZ
@given(ext=st.sampled_from([".stl", ".ply", ".obj"]), data=st.binary(max_size=3000))
def test_random_bytes_load_or_refuse(ext, data):
    result = _load(ext, data, load_mesh)
    assert isinstance(result, (Surface, InputError))


@FUZZ
@given(case=mutated())
def test_mutated_files_load_or_refuse(case):
    ext, data = case
    result = _load(ext, data, lambda p: load_mesh(p, all_pieces=True))
    if isinstance(result, Surface):
        assert np.isfinite(result.vertices).all() and result.area > 0
        assert result.faces.min() >= 0 and result.faces.max() < len(result.vertices)
    else:
        assert isinstance(result, InputError)


@FUZZ
@given(ext=st.sampled_from([".ply", ".xyz", ".pcd"]), data=st.one_of(st.binary(max_size=2000),
                                                                     mutated().map(lambda c: c[1])))
def test_points_loader_loads_or_refuses(ext, data):
    result = _load(ext, data, load_points)
    assert isinstance(result, (tuple, InputError))
