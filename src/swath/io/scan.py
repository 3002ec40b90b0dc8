"""Scans as swath reads them: a point cloud or mesh with its scan rows (a point-laser scan is a sequence of rows), and the test for which files are clouds."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError

log = logging.getLogger(__name__)


#: Point-cloud extensions (a ``.ply`` is a cloud when it has no faces).
CLOUD_EXTENSIONS = (".xyz", ".txt", ".csv", ".pts", ".pcd")


#: Row inference: a new scan row starts where the step to the next point is longer than this
#: many median steps, or where the scan direction turns back (cosine below ROW_TURN_COS).
ROW_JUMP = 3.0


ROW_TURN_COS = -0.7


# --------------------------------------------------------------------------------------------
# scans
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Scan:
    """A loaded scan.

    Attributes
    ----------
    points : (n, 3) float
        Points (a cloud) or vertices (a mesh), m.
    normals : (n, 3) float or None
        Unit normals from the file (clouds) or the mesh's vertex normals; only their side is used.
    faces : (m, 3) int or None
        Triangles of a mesh scan; None for a point cloud.
    name : str
        File stem (or example name).
    """

    points: np.ndarray
    normals: np.ndarray | None
    faces: np.ndarray | None
    name: str

    @property
    def kind(self) -> str:
        """``"mesh"`` or ``"points"``."""
        return "points" if self.faces is None else "mesh"


def ply_face_count(path) -> int:
    """Number of faces declared in a PLY header (0 for a point cloud); -1 if the header is unreadable."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(65536)
    except OSError:
        return -1
    end = head.find(b"end_header")
    if not head.lstrip().startswith(b"ply") or end < 0:
        return -1
    for line in head[:end].decode("ascii", errors="replace").splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[0] == "element" and parts[1] == "face":
            try:
                return int(parts[2])
            except ValueError:
                return -1
    return 0


def is_point_cloud_file(path) -> bool:
    """Whether ``path`` names a point cloud (by extension; a PLY by its header having no faces)."""
    path = Path(path)
    ext = path.suffix.lower()
    if ext in CLOUD_EXTENSIONS:
        return True
    return ext == ".ply" and path.is_file() and ply_face_count(path) == 0


def load_scan(path, *, units: str = "m", side=None, all_pieces: bool = False, force_units: bool = False) -> Scan:
    """Load a scan: a point cloud (:func:`swath.io.points.load_points`) or a mesh (:func:`swath.io.mesh.load_mesh`).

    Parameters
    ----------
    path : str or Path
        ``.xyz .txt .csv .pts .pcd .ply`` (cloud) or ``.stl .obj .ply`` (mesh; a PLY with faces).
    units : str
        The file's length unit (m, mm, cm, in).
    side : str or (3,) float, optional
        For a mesh: the direction the tool comes from (orients the mesh; needed for a closed solid).
    all_pieces : bool
        For a mesh: keep every piece (default the largest).
    force_units : bool
        Accept a size outside 5 mm .. 20 m.

    Returns
    -------
    Scan
    """
    if is_point_cloud_file(path):
        from .points import load_points

        pts, nrm = load_points(path, units=units, force_units=force_units)
        return Scan(pts, nrm, None, Path(path).stem)
    from .mesh import load_mesh

    surface = load_mesh(path, units=units, side=side, all_pieces=all_pieces, force_units=force_units)
    return scan_from_surface(surface)


def scan_from_surface(surface) -> Scan:
    """A :class:`Scan` of a surface's vertices and triangles (``(n, 3)`` m, ``(m, 3)`` int)."""
    return Scan(np.asarray(surface.vertices), np.asarray(surface.normals), np.asarray(surface.faces),
                str(surface.name))


def infer_scan_rows(points) -> np.ndarray:
    """Scan-row ids ``(n,)`` of points stored in scan order, as a point laser records them.

    A new row starts where the step to the next point is longer than ``ROW_JUMP`` median steps
    (the return to the start of the next row) or where the scan turns back (the directions of
    the steps before and after a step have a cosine below ``ROW_TURN_COS``, and neither of them is
    such a jump: a zig-zag scan).

    Parameters
    ----------
    points : (n, 3) float
        Points in scan order, m.

    Returns
    -------
    (n,) int
        Row id of each point, 0, 1, ... in order.
    """
    X = np.asarray(points, float)
    if len(X) < 4:
        return np.zeros(len(X), dtype=np.int64)
    d = np.diff(X, axis=0)                                     # (n-1, 3) steps
    length = np.linalg.norm(d, axis=1)
    h = float(np.median(length))
    if not h > 0:
        raise InputError("consecutive points coincide; the rows of a scan cannot be read off the point order "
                         "(use --parameterization auto)")
    jump = length > ROW_JUMP * h
    unit = d / np.maximum(length, 1e-300)[:, None]
    cos = np.einsum("ij,ij->i", unit[:-2], unit[2:])           # steps j-1 and j+1 around step j
    # a turn next to a jump is the jump's own (a return stroke reverses the steps beside it)
    turn = (cos < ROW_TURN_COS) & ~jump[:-2] & ~jump[2:]
    brk = jump.copy()
    brk[1:-1] |= turn
    return np.concatenate([[0], np.cumsum(brk)]).astype(np.int64)
