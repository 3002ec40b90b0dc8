"""Target depth maps: how much material to remove where.

A :class:`TargetMap` is a depth (m) at points of the part (part frame); :meth:`TargetMap.depth_on`
reads it onto any sampling of the part (the removal kernel's samples) from the nearest point.

File format (``--target-map FILE``)
-----------------------------------
* **CSV**: a header line ``x,y,z,depth`` and one row per point, all in metres (part frame);
  ``#`` lines are comments.  Depths must be finite and >= 0.
* **PLY**: a mesh whose ``vertex`` element carries a scalar property ``depth`` (m); the vertex
  coordinates are read in ``units`` (default m), the depths always in metres.

Scan excess
-----------
:func:`excess_target` places the nominal CAD surface on a scan (:func:`swath.scan.register_rigid`)
and sets the target at every scan vertex to how far the scan sticks out of the CAD surface along the
CAD's normal (toward the tool); points on or below the CAD surface get 0: remove only what sticks out.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..units import length_unit_factor


@dataclass(frozen=True, eq=False)
class TargetMap:
    """Target removal depth at points of the part.

    Attributes
    ----------
    points : (n, 3) float or None
        Positions, m, part frame; None for a uniform depth.
    depth : (n,) float or float
        Depth to remove at each point, m (a single float when ``points`` is None).
    name : str
        Where it came from (for reports).
    """

    points: np.ndarray | None
    depth: np.ndarray | float
    name: str = ""

    def __post_init__(self):
        if self.points is None:
            d = float(self.depth)
            if not (np.isfinite(d) and d >= 0):
                raise InputError(f"a uniform target depth must be finite and >= 0 m, got {self.depth!r}")
            object.__setattr__(self, "depth", d)
            return
        p = np.asarray(self.points, float)
        d = np.asarray(self.depth, float).reshape(-1)
        if p.ndim != 2 or p.shape[1] != 3 or len(p) != len(d) or len(p) == 0:
            raise InputError(f"a target map needs (n, 3) points and (n,) depths, got {p.shape} and {d.shape}")
        if not (np.isfinite(p).all() and np.isfinite(d).all() and (d >= 0).all()):
            raise InputError("target depths must be finite and >= 0 m, at finite points")
        object.__setattr__(self, "points", p)
        object.__setattr__(self, "depth", d)

    def depth_on(self, surface) -> np.ndarray:
        """Depth ``(S,)`` (m) at the vertices of ``surface``: the nearest map point's depth."""
        from scipy.spatial import cKDTree

        if self.points is None:
            return np.full(len(surface.vertices), self.depth)
        _, j = cKDTree(self.points).query(surface.vertices)
        return np.asarray(self.depth)[j]


def uniform_target(depth: float) -> TargetMap:
    """The same depth (m) everywhere."""
    return TargetMap(None, depth, name=f"uniform {depth * 1e6:.3g} um")


def read_target_map(path, *, units: str = "m") -> TargetMap:
    """Read a per-point target depth map from a CSV or PLY file (see the module notes).

    Parameters
    ----------
    path : str or Path
    units : str
        Length unit of the PLY vertex coordinates (``m``, ``mm``, ``cm``, ``in``); CSV is always m.
    """
    path = Path(path)
    if not path.exists():
        raise InputError(f"target map {str(path)!r} does not exist")
    suffix = path.suffix.lower()
    if suffix == ".csv":
        return _read_csv(path)
    if suffix == ".ply":
        import trimesh

        mesh = trimesh.load(path, process=False, force="mesh")
        raw = mesh.metadata.get("_ply_raw", {}).get("vertex", {}).get("data", {})
        if "depth" not in raw:
            raise InputError(f"{path.name}: the PLY vertex element has no 'depth' property; add one (m) per vertex")
        depth = np.asarray(raw["depth"], float).reshape(-1)
        vertices = np.asarray(getattr(mesh, "vertices"), dtype=np.float64)   # a Trimesh (force="mesh")
        return TargetMap(vertices * length_unit_factor(units), depth, name=path.name)
    raise InputError(f"target map {path.name}: expected a .csv (x,y,z,depth in m) or a .ply with a vertex 'depth'")


def _read_csv(path: Path) -> TargetMap:
    text = "\n".join(line for line in path.read_text().splitlines() if line.strip() and not line.lstrip().startswith("#"))
    reader = csv.reader(io.StringIO(text))
    try:
        header = [h.strip().lower() for h in next(reader)]
    except StopIteration:
        raise InputError(f"{path.name} is empty; expected a header x,y,z,depth and one row per point") from None
    need = ["x", "y", "z", "depth"]
    if any(h not in header for h in need):
        raise InputError(f"{path.name}: header {header} lacks one of {need} (metres, part frame)")
    col = [header.index(h) for h in need]
    rows = []
    for k, row in enumerate(reader, start=2):
        try:
            rows.append([float(row[c]) for c in col])
        except (ValueError, IndexError):
            raise InputError(f"{path.name} line {k}: expected four numbers x,y,z,depth, got {row!r}") from None
    if not rows:
        raise InputError(f"{path.name} has a header but no points")
    a = np.asarray(rows)
    return TargetMap(a[:, :3], a[:, 3], name=path.name)


def write_target_map(path, target: TargetMap) -> None:
    """Write a per-point map as CSV (``x,y,z,depth`` in m), atomically."""
    from ..io.atomic import write_text_atomic

    if target.points is None:
        raise InputError("a uniform target has no points to write; give the depth instead")
    lines = ["x,y,z,depth"] + [f"{p[0]:.9g},{p[1]:.9g},{p[2]:.9g},{d:.9g}" for p, d in zip(target.points, np.asarray(target.depth))]
    write_text_atomic(path, "\n".join(lines) + "\n")


def excess_target(scan, cad, *, registration=None, max_depth: float | None = None) -> TargetMap:
    """The material of ``scan`` standing proud of ``cad``: a target on the scan's vertices.

    Parameters
    ----------
    scan : Surface
        The measured part, m (the surface the passes are planned on).
    cad : Surface
        The nominal surface, m, in its own frame (normals toward the tool).
    registration : Registration, optional
        ``cad2scan`` placement; default :func:`swath.scan.register_rigid` (CAD onto scan).
    max_depth : float, optional
        Clip depths above this, m (scan spikes).

    Returns
    -------
    TargetMap
        Depth at each scan vertex: its signed distance from the placed CAD surface along the CAD
        normal, where positive (0 elsewhere), m.
    """
    from ..scan import register_rigid
    from ..surface import Surface

    if registration is None:
        registration = register_rigid(cad, scan)
    placed = Surface(registration.transform(cad.vertices), cad.faces, name=cad.name)
    closest, _, face = placed.closest_points(scan.vertices)
    normal = placed.interpolate_normals(closest, face)
    signed = np.einsum("ij,ij->i", scan.vertices - closest, normal)
    depth = np.clip(signed, 0.0, None if max_depth is None else float(max_depth))
    return TargetMap(np.asarray(scan.vertices, float), depth, name=f"excess of {scan.name} over {cad.name}")
