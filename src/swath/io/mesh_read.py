"""Read the raw triangles of a mesh file (STL, PLY, OBJ): vertices, faces and the file's normals.

The text formats are parsed here, exactly, so that a malformed row is refused with its line
number instead of being skipped or misread:

- OBJ: ``v``/``vn``/``f`` records, polygon faces fan-triangulated, ``v/vt/vn`` corner forms,
  negative (relative) indices resolved against the vertices defined *before* the face (as the
  OBJ format defines them), line continuations (``\\``); groups, materials and texture
  coordinates are ignored.
- ASCII PLY: the header's elements and properties, then exactly one row per element; a blank,
  short, long or non-numeric row is refused naming its line.

Binary PLY and STL (binary and ASCII) are read with trimesh's parsers, after checking the file is
what its extension says.  Positions are returned as float64, as written in the file.
"""

from __future__ import annotations

import io
import re
from pathlib import Path

import numpy as np

from ..errors import InputError

#: PLY scalar types and their numpy dtypes (both the spec's names and the sized aliases).
_PLY_TYPES = {"char": "i1", "uchar": "u1", "short": "i2", "ushort": "u2", "int": "i4", "uint": "u4",
              "float": "f4", "double": "f8", "int8": "i1", "uint8": "u1", "int16": "i2", "uint16": "u2",
              "int32": "i4", "uint32": "u4", "float32": "f4", "float64": "f8"}
_PLY_FACE_LISTS = ("vertex_indices", "vertex_index")
#: Larger indices than this are refused as corrupt (they could not be stored as int64 arrays).
_MAX_INDEX = 2**62


def read_mesh_file(path: Path, ext: str):
    """The raw triangles of a mesh file.

    Parameters
    ----------
    path : Path
        The file.
    ext : str
        Its lower-case extension, ``.stl``, ``.ply`` or ``.obj``.

    Returns
    -------
    vertices : (n, 3) float64
        Positions in the file's unit.
    faces : (m, 3) int64
        Triangles (polygons fan-triangulated); indices in ``0..n-1``.
    face_normals : (m, 3) float or None
        Per face, the sum of the file's unit normals at its corners (None when the file has none).

    Raises
    ------
    InputError
        When the file is not what its extension says, is malformed (naming the line for the text
        formats), or its faces refer to vertices it does not have.
    """
    data = path.read_bytes()
    label = path.name
    if ext == ".obj":
        return read_obj(data, label)
    if ext == ".ply":
        v, f, vn = read_ply(data, label)
        if f is None:
            f = np.zeros((0, 3), dtype=np.int64)
        return v, f, _face_normals_from_vertex_normals(f, vn)
    return _read_stl(data, label)


# --------------------------------------------------------------------------------------------
# OBJ
# --------------------------------------------------------------------------------------------
def read_obj(data: bytes, label: str):
    """Parse a Wavefront OBJ; returns ``(vertices (n,3) float64, faces (m,3) int64, face normals or None)``.

    Negative indices count back from the last ``v`` (or ``vn``) record before the face, so
    ``f -3 -2 -1`` is the triangle of the three vertices just defined.
    """
    if b"\x00" in data[:65536]:
        raise InputError(f"{label} holds binary data, not a text OBJ; check the file or re-export it")
    text = data.decode("utf-8-sig", errors="replace")
    lines = text.splitlines()
    records: dict[str, list] = {"v": [], "vn": []}       # the 3 number strings of each v / vn record
    record_lines: dict[str, list] = {"v": [], "vn": []}
    corner_v: list[str] = []         # vertex reference of each face corner, flattened, as written
    corner_n: list[str] = []         # normal reference of each corner, "0" when the corner has none
    counts: list[int] = []           # corners per face
    face_lines: list[int] = []       # 1-based line of each face
    defined_v: list[int] = []        # vertices defined before each face (for relative indices)
    defined_n: list[int] = []
    lineno, n_lines = 0, len(lines)
    while lineno < n_lines:
        start = lineno
        line = lines[lineno]
        lineno += 1
        while line.endswith("\\") and lineno < n_lines:      # continuation
            line = line[:-1] + " " + lines[lineno]
            lineno += 1
        tokens = line.split("#", 1)[0].split()
        if not tokens:
            continue
        key = tokens[0]
        if key == "v" or key == "vn":
            if len(tokens) < 4:
                raise InputError(f"{label}, line {start + 1}: a '{key}' record needs 3 numbers, got "
                                 f"{len(tokens) - 1} ({line.strip()[:60]!r}); check the file or re-export it")
            records[key].append(tokens[1:4])
            record_lines[key].append(start + 1)
        elif key == "f":
            k = len(tokens) - 1
            if k < 3:
                raise InputError(f"{label}, line {start + 1}: a face needs at least 3 vertices, got "
                                 f"{k}; check the file or re-export it")
            if "/" in line:
                for tok in tokens[1:]:
                    parts = tok.split("/")
                    corner_v.append(parts[0])
                    corner_n.append(parts[2] if len(parts) > 2 and parts[2] else "0")
            else:
                corner_v.extend(tokens[1:])
                corner_n.extend(["0"] * k)
            counts.append(k)
            face_lines.append(start + 1)
            defined_v.append(len(records["v"]))
            defined_n.append(len(records["vn"]))
    v = _obj_numbers(records["v"], record_lines["v"], "v", label)
    normals = _obj_numbers(records["vn"], record_lines["vn"], "vn", label)
    n_corners = np.asarray(counts, dtype=np.int64)
    corner_face = np.repeat(np.arange(len(counts)), n_corners)
    raw_v = _obj_references(corner_v, corner_face, face_lines, lines, label)
    raw_n = _obj_references(corner_n, corner_face, face_lines, lines, label)
    idx_v = _obj_resolve(raw_v, np.repeat(np.asarray(defined_v, dtype=np.int64), n_corners), corner_face,
                         face_lines, "vertex", label)
    too_far = np.flatnonzero(idx_v >= len(v))
    if too_far.size:
        raise InputError(f"{label}, line {face_lines[corner_face[too_far[0]]]}: face refers to vertex "
                         f"{idx_v[too_far[0]] + 1} but the file has {len(v)} vertices; the file is corrupt, re-export it")
    has_n = raw_n != 0
    idx_n = np.full(len(raw_n), -1, dtype=np.int64)
    if has_n.any():
        idx_n[has_n] = _obj_resolve(raw_n[has_n], np.repeat(np.asarray(defined_n, dtype=np.int64), n_corners)[has_n],
                                    corner_face[has_n], face_lines, "normal", label)
    f = _fan(idx_v, n_corners)
    face_normals = None
    if len(f) and len(normals) and (idx_n >= 0).all():
        if idx_n.max() >= len(normals):
            raise InputError(f"{label}: a face refers to normal {idx_n.max() + 1} but the file has "
                             f"{len(normals)}; the file is corrupt, re-export it")
        unit = _unit_rows(normals)
        per_corner = _fan(np.arange(len(idx_n)), n_corners)
        face_normals = unit[idx_n[per_corner]].sum(axis=1)
        if not np.abs(face_normals).sum() > 0:
            face_normals = None
    return v, f, face_normals


def _obj_numbers(rows: list, row_lines: list, key: str, label: str) -> np.ndarray:
    """(n, 3) float64 of the ``v`` / ``vn`` records' number strings; a bad one is refused naming its line."""
    try:
        return np.array(rows, dtype=np.float64).reshape(-1, 3)
    except ValueError:
        for tokens, line in zip(rows, row_lines, strict=True):
            try:
                [float(t) for t in tokens]
            except ValueError:
                raise InputError(f"{label}, line {line}: expected 3 numbers after '{key}', got "
                                 f"{' '.join(tokens)[:60]!r}; check the file or re-export it") from None
        raise


def _obj_references(refs: list, corner_face: np.ndarray, face_lines: list, lines: list, label: str) -> np.ndarray:
    """int64 of reference strings as written (1-based or negative); a bad one is refused naming its line."""
    try:
        raw = np.array(refs, dtype=np.int64)
        if len(raw) and np.abs(raw).max() <= _MAX_INDEX:
            return raw
        if not len(raw):
            return raw.astype(np.int64)
    except (ValueError, OverflowError):
        pass
    for i, ref in enumerate(refs):
        try:
            ok = abs(int(ref)) <= _MAX_INDEX
        except ValueError:
            ok = False
        if not ok:
            line = face_lines[corner_face[i]]
            token = next((t for t in lines[line - 1].split()[1:] if ref in t.split("/")), ref)
            raise InputError(f"{label}, line {line}: {token!r} is not a vertex reference such as '7', '7/3', "
                             "'7//2' or '-1'; check the file or re-export it")
    raise AssertionError("unreachable: a reference failed to convert but none is bad")


def _obj_resolve(raw: np.ndarray, defined: np.ndarray, corner_face: np.ndarray, face_lines: list, what: str,
                 label: str) -> np.ndarray:
    """0-based indices of OBJ references: ``k > 0`` is the k-th record of the file (forward references
    are tolerated and checked against the final count), ``-k`` the k-th last defined before the face."""
    index = np.where(raw > 0, raw - 1, defined + raw)
    bad = np.flatnonzero((raw == 0) | (index < 0))
    if bad.size:
        i = bad[0]
        raise InputError(f"{label}, line {face_lines[corner_face[i]]}: {what} reference {raw[i]} is invalid (OBJ "
                         f"indices start at 1; -k means the k-th last, and {defined[i]} {what}s are defined before "
                         "this line); the file is corrupt, re-export it")
    return index


def _fan(corners: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Fan triangles (t, 3) of polygons given as flattened ``corners`` with ``counts`` corners each."""
    if len(counts) == 0:
        return np.zeros((0, 3), dtype=np.int64)
    start = np.r_[0, np.cumsum(counts)[:-1]]
    n_tri = counts - 2
    first = np.repeat(start, n_tri)
    step = np.arange(int(n_tri.sum())) - np.repeat(np.r_[0, np.cumsum(n_tri)[:-1]], n_tri)
    return np.stack([corners[first], corners[first + step + 1], corners[first + step + 2]], axis=1)


# --------------------------------------------------------------------------------------------
# PLY
# --------------------------------------------------------------------------------------------
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
        if data.rstrip().endswith(b"end_header"):
            match = re.search(rb"end_header\s*$", data)
        else:
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
            faces = _fan(corners, counts)
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
                    if any(abs(k) > _MAX_INDEX for k in indices):
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
        faces = _triangulate(faces)
    vn = kw.get("vertex_normals")
    vn = None if vn is None else np.asarray(vn, dtype=np.float64)
    if vn is not None and vn.shape != v.shape:
        vn = None
    if faces is not None and len(faces) and (faces.min() < 0 or faces.max() >= len(v)):
        raise InputError(f"{label}: face indices run {faces.min()}..{faces.max()} but there are {len(v)} vertices; "
                         "the file is corrupt, re-export it")
    return v, faces, vn


# --------------------------------------------------------------------------------------------
# STL
# --------------------------------------------------------------------------------------------
def _read_stl(data: bytes, label: str):
    from trimesh.exchange import stl

    _sniff_stl(data, label)
    try:
        kw = stl.load_stl(io.BytesIO(data))
    except Exception as exc:  # noqa: BLE001 - any parser failure is an unreadable file
        raise InputError(f"could not read {label} as STL: {exc}; check the file or re-export it") from None
    if not isinstance(kw, dict) or kw.get("vertices") is None:
        raise InputError(f"{label} holds no triangles; check the file or re-export it")
    v = np.asarray(kw["vertices"], dtype=np.float64).reshape(-1, 3)
    f = _triangulate(kw.get("faces"))
    if len(f) and (f.min() < 0 or f.max() >= len(v)):
        raise InputError(f"could not read {label} as STL: its triangles are inconsistent; re-export it")
    return v, f, None


def _sniff_stl(data: bytes, label: str) -> None:
    if len(data) >= 84:
        n = int(np.frombuffer(data[80:84], dtype="<u4")[0])
        if 84 + 50 * n == len(data):
            return
    if data.lstrip()[:5].lower() == b"solid" and b"\x00" not in data[:4096]:
        return
    raise InputError(f"{label} is not an STL file (neither binary, whose size matches its triangle count, "
                     "nor ASCII starting with 'solid'); check the file or re-export it")


# --------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------
def _triangulate(faces) -> np.ndarray:
    """Polygon faces, a (m, k) array or a ragged list, as (t, 3) int64 fan triangles; rows of < 3 dropped."""
    if faces is None:
        return np.zeros((0, 3), dtype=np.int64)
    try:
        rows = np.asarray(faces, dtype=np.int64)
    except (ValueError, TypeError):
        rows = None
    if rows is not None and rows.ndim == 2:
        if rows.shape[1] < 3:
            return np.zeros((0, 3), dtype=np.int64)
        return _fan(rows.ravel(), np.full(len(rows), rows.shape[1], dtype=np.int64))
    polys = [np.asarray(p, dtype=np.int64).ravel() for p in faces]
    polys = [p for p in polys if len(p) >= 3]
    if not polys:
        return np.zeros((0, 3), dtype=np.int64)
    return _fan(np.concatenate(polys), np.array([len(p) for p in polys], dtype=np.int64))


def _unit_rows(a: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        unit = a / np.linalg.norm(a, axis=1, keepdims=True)
    return np.nan_to_num(unit, nan=0.0, posinf=0.0, neginf=0.0)


def _face_normals_from_vertex_normals(faces: np.ndarray, vertex_normals):
    """Per face, the sum of its corners' unit vertex normals; None without usable normals."""
    if vertex_normals is None or len(faces) == 0:
        return None
    face_normals = _unit_rows(vertex_normals)[faces].sum(axis=1)
    return face_normals if np.abs(face_normals).sum() > 0 else None
