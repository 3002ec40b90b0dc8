"""The :class:`Part` record: a part surface with the faces it came from, and what is to be finished.

A CAD part (STEP, IGES) keeps its B-rep faces: every triangle of the tessellation knows the CAD
face it lies on (``face_ids``), and every face its name, colour and surface kind.  A mesh part is
one face.  The selection (the area to finish) and the keep-outs (where the pad must not touch)
are per-triangle masks set by :mod:`swath.segment.select`.

:class:`ExactNormalSurface` is a :class:`~swath.surface.Surface` whose vertex normals are given
(evaluated on the exact CAD geometry) instead of estimated from the facets.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from ..errors import InputError
from ..surface import Surface
from ..surface import geometry as _geometry


class ExactNormalSurface(Surface):
    """A :class:`~swath.surface.Surface` whose smooth normals are given, not estimated.

    The normals are given per triangle corner (each triangle carries the exact normal of its own
    CAD face at its corners); a vertex's normal is the mean of its corners' normals, so a vertex on
    a sharp edge between two faces takes the bevel between them, and the same vertex in a
    :meth:`sub_surface` of one face only takes that face's exact normal.

    Parameters
    ----------
    vertices : (n, 3) float
        Vertex positions, m.
    faces : (m, 3) int
        Triangles; their winding must agree with the normals.
    corner_normals : (m, 3, 3) float
        Unit normal toward the tool at each corner of each triangle, e.g. evaluated on the
        triangle's CAD face at that vertex.
    **kwargs
        As :class:`~swath.surface.Surface`.
    """

    def __init__(self, vertices, faces, *, corner_normals, **kwargs):
        super().__init__(vertices, faces, **kwargs)
        c = np.array(corner_normals, dtype=float)
        if c.shape != (len(self.faces), 3, 3) or not np.isfinite(c).all():
            raise InputError(f"expected finite corner normals of shape ({len(self.faces)}, 3, 3), got {c.shape}")
        c.setflags(write=False)
        self.corner_normals = c

    @cached_property
    def normals(self) -> np.ndarray:
        """(n, 3) exact unit vertex normals: the mean of the vertex's corner normals."""
        acc = np.zeros_like(self.vertices)
        for k in range(3):
            np.add.at(acc, self.faces[:, k], self.corner_normals[:, k])
        n = _geometry.normalize(acc)
        n.setflags(write=False)
        return n

    def sub_surface(self, face_index, *, name: str | None = None) -> ExactNormalSurface:
        """The surface of the triangles ``face_index`` ``(k,) int`` only, keeping their exact normals."""
        face_index = np.asarray(face_index, np.int64)
        faces = self.faces[face_index]
        used, inverse = np.unique(faces, return_inverse=True)
        return ExactNormalSurface(self.vertices[used], inverse.reshape(-1, 3),
                                  corner_normals=self.corner_normals[face_index], name=name or self.name,
                                  normal_smoothing=self.normal_smoothing,
                                  curvature_neighbours=self.curvature_neighbours)

    def subdivided(self, max_edge: float, *, method: str = "long_edges") -> Surface:
        """As :meth:`Surface.subdivided`; a new vertex takes the normal interpolated (barycentric,
        renormalised) between the exact normals of the triangle it lies on."""
        fine = super().subdivided(max_edge, method=method)
        if fine is self:
            return self
        _, _, tri = self.closest_points(fine.vertices)
        normals = self.interpolate_normals(fine.vertices, tri)
        if method == "long_edges":
            normals[:len(self.vertices)] = self.normals
        return ExactNormalSurface(fine.vertices, fine.faces, corner_normals=normals[fine.faces], name=self.name,
                                  normal_smoothing=self.normal_smoothing,
                                  curvature_neighbours=self.curvature_neighbours)


@dataclass(frozen=True)
class PartFace:
    """One face of a part as the CAD file gives it.

    Attributes
    ----------
    id : int
        The face's id, counting from 1 in the order the file's shape lists its faces.
    name : str
        The face's name in the file ('' when it has none).
    kind : str
        The exact surface kind: ``"plane"``, ``"cylinder"``, ``"cone"``, ``"sphere"``, ``"torus"``,
        ``"bspline"``, ``"bezier"``, ``"revolution"``, ``"extrusion"``, ``"offset"``, ``"other"``,
        or ``"mesh"`` for a part read from a mesh.
    colour : str or None
        The face's colour as ``"#rrggbb"`` where the file has one.
    area : float
        The area of its triangles, m².
    """

    id: int
    name: str = ""
    kind: str = "mesh"
    colour: str | None = None
    area: float = 0.0

    def label(self) -> str:
        """``"face 3 'flange_top' (plane)"``: how reports and messages name the face."""
        name = f" {self.name!r}" if self.name else ""
        return f"face {self.id}{name} ({self.kind})"


@dataclass(frozen=True, eq=False)
class Part:
    """A part: its surface, the face each triangle lies on, and the area to finish.

    Attributes
    ----------
    surface : Surface
        The whole part, metres, part frame, normals out of the material (toward the tool).
    face_ids : (m,) int
        The :attr:`PartFace.id` of the face each triangle of ``surface`` lies on.
    faces : tuple of PartFace
        The faces, in id order.
    selected : (m,) bool
        Triangles to finish (all by default).
    keep_out : (m,) bool
        Triangles the pad must not touch (none by default).
    keep_out_margin : float
        Extra clearance (m) the pad keeps from the keep-out triangles beyond its own radius.
    edge_margin : float
        Distance (m) the pad's centre keeps in from the selected area's open edges.
    closed : bool
        Whether the surface is a closed solid (no open boundary).
    source : str
        Where the part came from (a file name or an example), for reports.
    chordal_tolerance : float or None
        The largest distance (m) of the tessellation from the exact faces, for a CAD part.
    """

    surface: Surface
    face_ids: np.ndarray
    faces: tuple[PartFace, ...]
    selected: np.ndarray = None  # type: ignore[assignment]  # None: all (set in __post_init__)
    keep_out: np.ndarray = None  # type: ignore[assignment]  # None: none (set in __post_init__)
    keep_out_margin: float = 0.0
    edge_margin: float = 0.0
    closed: bool = False
    source: str = ""
    chordal_tolerance: float | None = None

    def __post_init__(self):
        m = len(self.surface.faces)
        ids = np.asarray(self.face_ids, dtype=np.int64)
        if ids.shape != (m,):
            raise InputError(f"expected one face id per triangle, shape ({m},), got {ids.shape}")
        known = {f.id for f in self.faces}
        if not set(np.unique(ids).tolist()) <= known:
            raise InputError("every triangle's face id must be one of the part's faces")
        ids.setflags(write=False)
        object.__setattr__(self, "face_ids", ids)
        for key, default in (("selected", True), ("keep_out", False)):
            mask = getattr(self, key)
            mask = np.full(m, default) if mask is None else np.asarray(mask, dtype=bool)
            if mask.shape != (m,):
                raise InputError(f"expected a {key} mask of shape ({m},), got {mask.shape}")
            mask = mask.copy()
            mask.setflags(write=False)
            object.__setattr__(self, key, mask)
        for key in ("keep_out_margin", "edge_margin"):
            value = float(getattr(self, key))
            if not (np.isfinite(value) and value >= 0):
                raise InputError(f"{key.replace('_', '-')} must be a length >= 0 m, got {value!r}")

    @classmethod
    def from_surface(cls, surface: Surface, *, source: str = "") -> Part:
        """A mesh part: one face (id 1, kind ``"mesh"``) holding every triangle."""
        return cls(surface, np.ones(len(surface.faces), np.int64),
                   (PartFace(1, surface.name, "mesh", None, surface.area),), closed=not surface.boundary_loops,
                   source=source or surface.name)

    def face(self, face_id: int) -> PartFace:
        """The face with id ``face_id``."""
        for f in self.faces:
            if f.id == face_id:
                return f
        raise InputError(f"the part has no face {face_id}; its faces are 1..{len(self.faces)}")

    def with_selection(self, *, selected=None, keep_out=None, keep_out_margin: float | None = None,
                       edge_margin: float | None = None) -> Part:
        """A copy with the selection, keep-outs or margins replaced (None keeps the current one)."""
        changes: dict = {}
        if selected is not None:
            changes["selected"] = selected
        if keep_out is not None:
            changes["keep_out"] = keep_out
        if keep_out_margin is not None:
            changes["keep_out_margin"] = keep_out_margin
        if edge_margin is not None:
            changes["edge_margin"] = edge_margin
        return replace(self, **changes)

    @property
    def work_triangles(self) -> np.ndarray:
        """(m,) bool: triangles to finish, the selection minus the keep-outs."""
        return self.selected & ~self.keep_out

    def face_areas(self, mask=None) -> dict[int, float]:
        """Area (m²) per face id of the triangles in ``mask`` (m,) bool (all by default)."""
        areas = self.surface.face_areas if mask is None else np.where(mask, self.surface.face_areas, 0.0)
        per = np.bincount(self.face_ids, weights=areas, minlength=max(f.id for f in self.faces) + 1)
        return {f.id: float(per[f.id]) for f in self.faces}

    def faces_table(self) -> list[dict]:
        """One row per face (id, name, kind, colour, area in m², whether selected / kept out), for
        reports and ``metrics.json``."""
        sel = self.face_areas(self.selected)
        out = self.face_areas(self.keep_out)
        return [{"id": f.id, "name": f.name, "kind": f.kind, "colour": f.colour, "area_m2": f.area,
                 "selected_area_m2": sel[f.id], "keep_out_area_m2": out[f.id]} for f in self.faces]
