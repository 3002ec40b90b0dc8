"""Read Wavefront OBJ exactly: ``v``/``vn``/``f`` records, polygon faces fan-triangulated, the
``v/vt/vn`` corner forms, negative (relative) indices resolved against the records defined
*before* the face (as the format defines them), line continuations; groups, materials and
texture coordinates are ignored.  A malformed record is refused naming its line."""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .polygons import MAX_INDEX, fan_triangles, unit_rows


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
    f = fan_triangles(idx_v, n_corners)
    face_normals = None
    if len(f) and len(normals) and (idx_n >= 0).all():
        if idx_n.max() >= len(normals):
            raise InputError(f"{label}: a face refers to normal {idx_n.max() + 1} but the file has "
                             f"{len(normals)}; the file is corrupt, re-export it")
        unit = unit_rows(normals)
        per_corner = fan_triangles(np.arange(len(idx_n)), n_corners)
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
        if len(raw) and np.abs(raw).max() <= MAX_INDEX:
            return raw
        if not len(raw):
            return raw.astype(np.int64)
    except (ValueError, OverflowError):
        pass
    for i, ref in enumerate(refs):
        try:
            ok = abs(int(ref)) <= MAX_INDEX
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
