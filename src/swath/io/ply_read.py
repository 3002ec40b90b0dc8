"""Read PLY: ASCII exactly (the header's elements and properties, then exactly one row per element;
a blank, short, long or non-numeric row is refused naming its line), binary with trimesh."""

from __future__ import annotations

import io
import re

import numpy as np

from ..errors import InputError
from .polygons import MAX_INDEX, fan_triangles, triangulate

#: PLY scalar types and their numpy dtypes (both the spec's names and the sized aliases).
_PLY_TYPES = {"char": "i1", "uchar": "u1", "short": "i2", "ushort": "u2", "int": "i4", "uint": "u4",
              "float": "f4", "double": "f8", "int8": "i1", "uint8": "u1", "int16": "i2", "uint16": "u2",
              "int32": "i4", "uint32": "u4", "float32": "f4", "float64": "f8"}
_PLY_FACE_LISTS = ("vertex_indices", "vertex_index")


def read_ply(data: bytes, label: str):
    """Parse a PLY file (ASCII exactly, binary with trimesh).

    Returns
    -------
    vertices : (n, 3) float64
    faces : (m, 3) int64 or None
        Fan-triangulated faces, or None when the file has no face element.
    vertex_normals : (n, 3) float or None
        The ``nx ny nz`` properties when present.
    """
    if data.lstrip()[:3] != b"ply":
        raise InputError(f"{label} is not a PLY file (it does not start with 'ply'); check the file")
    fmt, elements, body_start, n_header_lines = _ply_header(data, label)
    if fmt == "ascii":
        return _read_ascii_ply(data[body_start:], elements, n_header_lines, label)
    return _read_binary_ply(data, label)


def _ply_header(data: bytes, label: str):
    """``(format, [(name, count, [(prop, list_count_type or None)])], body offset, header lines)``."""
    match = re.search(rb"end_header[ \t]*\r?\n", data)
    if match is None:
        match = re.search(rb"end_header\s*$", data) if data.rstrip().endswith(b"end_header") else None
        if match is None:
            raise InputError(f"{label}: the PLY header has no 'end_header' line; the file is truncated or not a PLY")
    header = data[:match.start()].decode("ascii", errors="replace").splitlines()
    fmt = None
    elements: list = []
    for i, line in enumerate(header, start=1):
        tokens = line.split()
        if not tokens or tokens[0] in ("ply", "comment", "obj_info"):
            continue
        if tokens[0] == "format" and len(tokens) >= 2:
            fmt = tokens[1]
        elif tokens[0] == "element" and len(tokens) == 3:
            try:
                count = int(tokens[2])
            except ValueError:
                count = -1
            if count < 0:
                raise InputError(f"{label}, line {i}: element {tokens[1]!r} has count {tokens[2]!r}, expected a "
                                 "whole number >= 0; the file is corrupt")
            elements.append((tokens[1], count, []))
        elif tokens[0] == "property" and elements:
            if len(tokens) == 5 and tokens[1] == "list" and tokens[2] in _PLY_TYPES and tokens[3] in _PLY_TYPES:
                elements[-1][2].append((tokens[4], tokens[2]))
            elif len(tokens) == 3 and tokens[1] in _PLY_TYPES:
                elements[-1][2].append((tokens[2], None))
            else:
                raise InputError(f"{label}, line {i}: cannot read the PLY property {line.strip()[:60]!r}")
        else:
            raise InputError(f"{label}, line {i}: unexpected PLY header line {line.strip()[:60]!r}")
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise InputError(f"{label}: PLY format {fmt!r} is not ascii, binary_little_endian or binary_big_endian")
    return fmt, elements, match.end(), len(header) + 1


def _read_ascii_ply(body: bytes, elements, n_header_lines: int, label: str):
    lines = body.decode("ascii", errors="replace").split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    row = 0
    tables: dict = {}
    for name, count, props in elements:
        if row + count > len(lines):
            raise InputError(f"{label}: the file ends at line {n_header_lines + len(lines)} but element {name!r} "
                             f"needs {count} rows from line {n_header_lines + row + 1}; the file is truncated")
        tables[name] = _ascii_rows(lines[row:row + count], props, n_header_lines + row + 1, name, label)
        row += count
    extra = [i for i in range(row, len(lines)) if lines[i].strip()]
    if extra:
        raise InputError(f"{label}, line {n_header_lines + extra[0] + 1}: {len(extra)} rows more than the header "
                         "declares; the element counts are wrong, re-export the file")
    vertex = tables.get("vertex")
    if vertex is None or not all(c in vertex for c in "xyz"):
        raise InputError(f"{label} has no vertex element with x, y, z properties; check the file")
    v = np.column_stack([vertex[c] for c in "xyz"]).astype(np.float64).reshape(-1, 3)
    normals = None
    if all(c in vertex for c in ("nx", "ny", "nz")):
        normals = np.column_stack([vertex[c] for c in ("nx", "ny", "nz")]).astype(np.float64)
    face = tables.get("face")
    faces = None
    if face is not None:
        key = next((k for k in _PLY_FACE_LISTS if k in face), None)
        if key is not None:
            polys, first_line = face[key], face["_first_line"]
            if "_array" in face:
                counts = np.full(len(face["_array"]), face["_array"].shape[1], dtype=np.int64)
                polys = [face["_array"].ravel()]
            else:
                counts = np.array([len(p) for p in polys], dtype=np.int64)
            small = np.flatnonzero(counts < 3)
            if small.size:
                raise InputError(f"{label}, line {first_line + small[0]}: a face has {counts[small[0]]} vertices, "
                                 "a face needs at least 3; check the file or re-export it")
            corners = np.concatenate(polys) if polys else np.zeros(0, dtype=np.int64)
            bad = np.flatnonzero((corners < 0) | (corners >= len(v)))
            if bad.size:
                face_no = int(np.searchsorted(np.cumsum(counts), bad[0], side="right"))
                raise InputError(f"{label}, line {first_line + face_no}: face refers to vertex {corners[bad[0]]} but "
                                 f"the file has {len(v)} vertices (0..{len(v) - 1}); the file is corrupt, re-export it")
            faces = fan_triangles(corners, counts)
    return v, faces, normals


def _ascii_rows(rows: list[str], props, first_line: int, name: str, label: str) -> dict:
    """Parse ``rows`` of one element: scalar properties -> (count,) float, list properties -> list of int arrays."""
    out: dict = {"_first_line": first_line}
    is_list = [kind is not None for _, kind in props]
    split = [r.split() for r in rows]
    if not any(is_list):
        lens = np.array([len(t) for t in split], dtype=np.int64)
        bad = np.flatnonzero(lens != len(props))
        if bad.size:
            raise InputError(_row_error(label, first_line + bad[0], name, rows[bad[0]], len(props)))
        try:
            table = np.array(split, dtype=np.float64).reshape(len(rows), len(props))
        except ValueError:
            for i, toks in enumerate(split):
                try:
                    [float(t) for t in toks]
                except ValueError:
                    raise InputError(f"{label}, line {first_line + i}: {name} row {rows[i].strip()[:60]!r} holds "
                                     "a value that is not a number; check the file") from None
            raise
        for j, (prop, _) in enumerate(props):
            out[prop] = table[:, j]
        return out
    if len(props) == 1 and rows:
        fast = _uniform_list_rows(split)
        if fast is not None:
            out[props[0][0]] = fast
            out["_array"] = fast
            return out
    columns: list[list] = [[] for _ in props]
    for i, toks in enumerate(split):
        pos = 0
        try:
            for j, (_, kind) in enumerate(props):
                if kind is None:
                    columns[j].append(float(toks[pos]))
                    pos += 1
                else:
                    n = int(toks[pos])
                    if n < 0 or pos + 1 + n > len(toks):
                        raise IndexError
                    indices = [int(t) for t in toks[pos + 1:pos + 1 + n]]
                    if any(abs(k) > MAX_INDEX for k in indices):
                        raise ValueError
                    columns[j].append(np.array(indices, dtype=np.int64))
                    pos += 1 + n
            if pos != len(toks):
                raise IndexError
        except IndexError:
            expected = None
            if len(props) == 1 and toks and toks[0].isdigit():
                expected = 1 + int(toks[0])          # the row's own count, plus the count itself
            raise InputError(_row_error(label, first_line + i, name, rows[i], expected)) from None
        except ValueError:
            raise InputError(f"{label}, line {first_line + i}: {name} row {rows[i].strip()[:60]!r} holds a value "
                             "that is not a whole number (or is too large) where an index is expected; check the file") from None
    for j, (prop, kind) in enumerate(props):
        out[prop] = columns[j] if kind is not None else np.asarray(columns[j], dtype=np.float64)
    return out


def _uniform_list_rows(split: list[list[str]]):
    """(count, k) int64 when every row is ``k i_1 .. i_k`` with the same k; None otherwise (then the
    general, row-by-row parser runs and names any bad row)."""
    width = len(split[0])
    if width < 1 or any(len(t) != width for t in split):
        return None
    try:
        table = np.array(split, dtype=np.int64)
    except (ValueError, OverflowError):
        return None
    if table.ndim != 2 or not (table[:, 0] == width - 1).all():
        return None
    return table[:, 1:]


def _row_error(label: str, line: int, name: str, row: str, expected: int | None) -> str:
    got = len(row.split())
    what = "is blank" if got == 0 else f"has {got} values ({row.strip()[:60]!r})"
    want = (f"{expected} values" if expected is not None else
            "as many values as its properties and list counts say")
    return (f"{label}, line {line}: the {name} row {what}, expected {want}; the file is truncated or corrupt, "
            "re-export it")


def _read_binary_ply(data: bytes, label: str):
    from trimesh.exchange import ply

    try:
        kw = ply.load_ply(io.BytesIO(data))
    except Exception as exc:  # noqa: BLE001 - any parser failure is an unreadable file
        raise InputError(f"could not read {label} as PLY: {exc}; check the file or re-export it") from None
    v = np.asarray(kw.get("vertices", np.zeros((0, 3))), dtype=np.float64).reshape(-1, 3)
    faces = kw.get("faces")
    if faces is not None:
        sizes = np.array([len(p) for p in faces]) if not hasattr(faces, "shape") else np.full(len(faces), faces.shape[-1])
        if (sizes < 3).any():
            raise InputError(f"{label}: {int((sizes < 3).sum())} of {len(sizes)} faces have fewer than 3 vertices; "
                             "the file is corrupt, re-export it")
        faces = triangulate(faces)
    vn = kw.get("vertex_normals")
    vn = None if vn is None else np.asarray(vn, dtype=np.float64)
    if vn is not None and vn.shape != v.shape:
        vn = None
    if faces is not None and len(faces) and (faces.min() < 0 or faces.max() >= len(v)):
        raise InputError(f"{label}: face indices run {faces.min()}..{faces.max()} but there are {len(v)} vertices; "
                         "the file is corrupt, re-export it")
    return v, faces, vn
