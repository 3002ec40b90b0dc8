"""Read the raw triangles of a mesh file (STL, PLY, OBJ): vertices, faces and the file's normals.

The text formats are parsed exactly (:mod:`~swath.io.obj_read`, :mod:`~swath.io.ply_read`),
so that a malformed row is refused with its line number instead of being skipped or misread:

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
from pathlib import Path

import numpy as np

from ..errors import InputError
from .obj_read import read_obj
from .ply_read import read_ply
from .polygons import triangulate, unit_rows


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
    f = triangulate(kw.get("faces"))
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


def _face_normals_from_vertex_normals(faces: np.ndarray, vertex_normals):
    """Per face, the sum of its corners' unit vertex normals; None without usable normals."""
    if vertex_normals is None or len(faces) == 0:
        return None
    face_normals = unit_rows(vertex_normals)[faces].sum(axis=1)
    return face_normals if np.abs(face_normals).sum() > 0 else None
