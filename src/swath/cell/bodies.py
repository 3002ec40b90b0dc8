"""Collision bodies of the cell: boxes, cylinders, capsules and triangle meshes, each with a pose.

A body's pose ``body2frame`` places its own frame in the frame it belongs to (the robot base for
the table and fixtures, the flange for the tool).  Boxes, cylinders and capsules are centred on
their frame's origin with their axis (cylinder, capsule) along its z, as in coal.  Each body is
also covered by a few spheres (:meth:`Body.cover_spheres`), which the collision check uses to cull
pairs that cannot touch before asking coal.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from .frames import check_transform, format_pose


@dataclass(frozen=True, eq=False)
class Box:
    """A box of edge lengths ``size`` (3,) along its x, y, z, m."""

    size: tuple

    def __post_init__(self):
        s = np.asarray(self.size, dtype=float)
        if s.shape != (3,) or not np.all(np.isfinite(s)) or np.any(s <= 0):
            raise InputError(f"a box needs three positive edge lengths, got {self.size!r}")
        object.__setattr__(self, "size", tuple(float(v) for v in s))

    def coal(self):
        import coal

        return coal.Box(*self.size)

    def cover(self):
        """Sphere centres (k, 3) in the body frame and radii (k,), m."""
        s = np.array(self.size)
        long = int(np.argmax(s))
        short = np.delete(s, long)
        k = max(1, math.ceil(s[long] / max(short.max(), 1e-9)))
        step = s[long] / k
        centres = np.zeros((k, 3))
        centres[:, long] = -s[long] / 2 + step * (np.arange(k) + 0.5)
        radius = 0.5 * math.sqrt(step ** 2 + short[0] ** 2 + short[1] ** 2)
        return centres, np.full(k, radius)

    def describe(self) -> str:
        return "box " + " x ".join(f"{v * 1e3:.0f}" for v in self.size) + " mm"


@dataclass(frozen=True, eq=False)
class Cylinder:
    """A cylinder of ``radius`` and ``length`` (along its z), m."""

    radius: float
    length: float

    def __post_init__(self):
        if not (self.radius > 0 and self.length > 0 and math.isfinite(self.radius) and math.isfinite(self.length)):
            raise InputError(f"a cylinder needs a positive radius and length, got {self.radius!r}, {self.length!r}")

    def coal(self):
        import coal

        return coal.Cylinder(self.radius, self.length)

    def cover(self):
        k = max(1, math.ceil(self.length / self.radius))
        step = self.length / k
        centres = np.zeros((k, 3))
        centres[:, 2] = -self.length / 2 + step * (np.arange(k) + 0.5)
        return centres, np.full(k, math.hypot(self.radius, step / 2))

    def describe(self) -> str:
        return f"cylinder Ø{2e3 * self.radius:.0f} x {1e3 * self.length:.0f} mm"


@dataclass(frozen=True, eq=False)
class Capsule:
    """A capsule: the points within ``radius`` of a segment of ``length`` along its z, m."""

    radius: float
    length: float

    def coal(self):
        import coal

        return coal.Capsule(self.radius, self.length)

    def cover(self):
        k = max(1, math.ceil(self.length / self.radius))
        if k == 1:
            return np.zeros((1, 3)), np.array([self.radius + self.length / 2])
        centres = np.zeros((k + 1, 3))
        centres[:, 2] = np.linspace(-self.length / 2, self.length / 2, k + 1)
        return centres, np.full(k + 1, math.hypot(self.radius, self.length / k / 2))

    def describe(self) -> str:
        return f"capsule r {1e3 * self.radius:.0f} mm, {1e3 * self.length:.0f} mm long"


@dataclass(frozen=True, eq=False)
class Mesh:
    """A triangle mesh: ``vertices`` (n, 3) in the body frame, m, and ``faces`` (m, 3) int."""

    vertices: np.ndarray
    faces: np.ndarray

    def __post_init__(self):
        v = np.ascontiguousarray(self.vertices, dtype=np.float64)
        f = np.ascontiguousarray(self.faces, dtype=np.int32)
        if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or not len(f):
            raise InputError(f"a mesh body needs (n, 3) vertices and (m, 3) faces, got {v.shape} and {f.shape}")
        if f.min() < 0 or f.max() >= len(v):
            raise InputError("a mesh body's faces index vertices it does not have")
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "faces", f)

    def coal(self):
        import coal

        bvh = coal.BVHModelOBBRSS()
        bvh.beginModel(len(self.faces), len(self.vertices))
        bvh.addVertices(self.vertices)
        bvh.addTriangles(self.faces)
        bvh.endModel()
        return bvh

    def max_edge(self) -> float:
        tri = self.vertices[self.faces]
        return float(np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max())

    def cover(self):
        lo, hi = self.vertices.min(axis=0), self.vertices.max(axis=0)
        return ((lo + hi) / 2)[None], np.array([np.linalg.norm(hi - lo) / 2])

    def describe(self) -> str:
        return f"mesh of {len(self.faces)} triangles"


Shape = Box | Cylinder | Capsule | Mesh


@dataclass(frozen=True, eq=False)
class Body:
    """A named collision body.

    Attributes
    ----------
    name : str
        How messages name it (``"fixture 'clamp'"``, ``"tool spindle"``).
    shape : Box, Cylinder, Capsule or Mesh
    body2frame : (4, 4) float
        The body's pose in the frame it belongs to (base or flange), m.
    """

    name: str
    shape: Shape
    body2frame: np.ndarray = field(default_factory=lambda: np.eye(4))

    def __post_init__(self):
        object.__setattr__(self, "body2frame", check_transform(self.body2frame, name=f"{self.name} pose"))

    def aabb(self) -> tuple[np.ndarray, np.ndarray]:
        """(3,) lower and upper corners of the body's bounding box in its parent frame, m."""
        if isinstance(self.shape, Mesh):
            p = self.shape.vertices @ self.body2frame[:3, :3].T + self.body2frame[:3, 3]
            return p.min(axis=0), p.max(axis=0)
        c, r = self.shape.cover()
        p = c @ self.body2frame[:3, :3].T + self.body2frame[:3, 3]
        return (p - r[:, None]).min(axis=0), (p + r[:, None]).max(axis=0)

    def as_record(self) -> dict:
        return {"name": self.name, "shape": self.shape.describe(), "pose": format_pose(self.body2frame)}


@dataclass(frozen=True, eq=False)
class Table:
    """The table the part stands on: a box whose top face is at height ``top_z`` in the base frame.

    Attributes
    ----------
    top_z : float
        Height of the table top in the robot base frame, m.
    centre_xy : (2,) float
        Centre of the top face in the base frame's x, y, m.
    size_xy : (2,) float
        Edge lengths along the base frame's x and y, m.
    thickness : float
        m.
    assumed : bool
        True when swath chose the table (no cell file said where it is).
    """

    top_z: float
    centre_xy: tuple = (0.0, 0.0)
    size_xy: tuple = (2.0, 2.0)
    thickness: float = 0.04
    assumed: bool = False

    def body(self) -> Body:
        pose = np.eye(4)
        pose[:3, 3] = (*self.centre_xy, self.top_z - self.thickness / 2)
        return Body("table", Box((*self.size_xy, self.thickness)), pose)

    def as_record(self) -> dict:
        return {"top_z_m": float(self.top_z), "centre_xy_m": [float(v) for v in self.centre_xy],
                "size_xy_m": [float(v) for v in self.size_xy], "thickness_m": float(self.thickness),
                "assumed": bool(self.assumed)}


def default_table(part_vertices_base, reach: float, *, margin: float = 0.2) -> Table:
    """The table assumed when no cell file describes one: its top at the part's lowest point,
    a square under the robot's whole reach (centred on the base axis, edge ``2 (reach + margin)``).

    Parameters
    ----------
    part_vertices_base : (n, 3) float
        The part's vertices in the robot base frame, m.
    reach : float
        The robot's reach, m.
    margin : float
        Extra table beyond the reach on every side, m.
    """
    z = float(np.asarray(part_vertices_base)[:, 2].min())
    side = 2.0 * (reach + margin)
    return Table(top_z=z, centre_xy=(0.0, 0.0), size_xy=(side, side), assumed=True)
