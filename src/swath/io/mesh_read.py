"""Read the raw triangles of a mesh file (STL, PLY, OBJ): vertices, faces, and the file's normals."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from ..errors import InputError


def read_mesh_file(path: Path, ext: str):
    """Raw ``(vertices (n,3) float, faces (m,3) int, per-face file normals (m,3) or None)``."""
    from trimesh.exchange import obj, ply, stl

    data = path.read_bytes()
    if ext == ".stl":
        _sniff_stl(data, path.name)
    elif ext == ".ply" and not data.lstrip()[:3] == b"ply":
        raise InputError(f"{path.name} is not a PLY file (it does not start with 'ply'); check the file")
    elif ext == ".obj" and b"\x00" in data[:65536]:
        raise InputError(f"{path.name} holds binary data, not a text OBJ; check the file or re-export it")
    loader = {".stl": stl.load_stl, ".ply": ply.load_ply, ".obj": obj.load_obj}[ext]
    try:
        kw = loader(io.BytesIO(data))
    except Exception as exc:  # noqa: BLE001 - any parser failure is an unreadable file
        raise InputError(f"could not read {path.name} as {ext[1:].upper()}: {exc}; check the file or "
                         "re-export it") from None
    parts = list(kw["geometry"].values()) if isinstance(kw, dict) and "geometry" in kw else [kw]
    vs, fs, ns = [], [], []
    offset = 0
    for part in parts:
        if not isinstance(part, dict) or part.get("vertices") is None:
            continue
        vv = np.asarray(part["vertices"], dtype=float).reshape(-1, 3)
        ff = _triangulate(part.get("faces"), path.name)
        vn = part.get("vertex_normals")
        vn = None if vn is None else np.asarray(vn, dtype=float)
        if vn is not None and vn.shape != vv.shape:
            vn = None
        vs.append(vv)
        fs.append(ff + offset)
        ns.append(vn)
        offset += len(vv)
    if not vs:
        raise InputError(f"{path.name} holds no geometry; check the file or re-export it")
    v = np.concatenate(vs)
    f = np.concatenate(fs).astype(np.int64)
    face_normals = None
    if all(n is not None for n in ns) and len(f):
        vn = np.concatenate(ns)
        with np.errstate(invalid="ignore", divide="ignore"):
            vn = vn / np.linalg.norm(vn, axis=1, keepdims=True)
        vn = np.nan_to_num(vn, nan=0.0, posinf=0.0, neginf=0.0)
        if f.max() < len(vn) and f.min() >= 0:
            face_normals = vn[f].sum(axis=1)
            if not np.abs(face_normals).sum() > 0:
                face_normals = None
    return v, f, face_normals


def _triangulate(faces, label: str) -> np.ndarray:
    """Polygon faces (m,k) array or ragged list → (t, 3) int triangles (fan)."""
    if faces is None:
        return np.zeros((0, 3), dtype=np.int64)
    try:
        arr = np.asarray(faces, dtype=np.int64)
        rows = None if arr.ndim != 2 else arr
    except (ValueError, TypeError):
        rows = None
    if rows is not None:
        if rows.shape[1] < 3:
            return np.zeros((0, 3), dtype=np.int64)
        k = rows.shape[1]
        idx = np.stack([np.zeros(k - 2, int), np.arange(1, k - 1), np.arange(2, k)], axis=1)
        return rows[:, idx].reshape(-1, 3)
    polys = [np.asarray(p, dtype=np.int64).ravel() for p in faces]
    out = [p[np.stack([np.zeros(len(p) - 2, int), np.arange(1, len(p) - 1), np.arange(2, len(p))], 1)]
           for p in polys if len(p) >= 3]
    return np.concatenate(out) if out else np.zeros((0, 3), dtype=np.int64)


def _sniff_stl(data: bytes, label: str) -> None:
    if len(data) >= 84:
        n = int(np.frombuffer(data[80:84], dtype="<u4")[0])
        if 84 + 50 * n == len(data):
            return
    if data.lstrip()[:5].lower() == b"solid" and b"\x00" not in data[:4096]:
        return
    raise InputError(f"{label} is not an STL file (neither binary, whose size matches its triangle count, "
                     "nor ASCII starting with 'solid'); check the file or re-export it")
