"""The :class:`Surface` record: a triangulated open surface with normals toward the tool."""

from __future__ import annotations

from functools import cached_property

import numpy as np

from ..errors import InputError
from . import geometry, topology
from .curvature import PrincipalCurvature, principal_curvatures
from .subdivide import halve_long_edges, split_long_edges

#: The methods of :meth:`Surface.subdivided`.
SUBDIVISION_METHODS = ("long_edges", "halving")


class Surface:
    """A part surface to be finished: triangles in the part frame, normals toward the tool side.

    The record is immutable: arrays are copied and made read-only on construction, and every
    derived array is computed once on first use (``cached_property``) by a pure function.

    Parameters
    ----------
    vertices : (n, 3) float
        Vertex positions, metres, part frame.
    faces : (m, 3) int
        Triangles as vertex indices; winding sets the normal (right-hand rule), which must point
        toward the side the tool works on.
    name : str
        A label for reports.
    normal_smoothing : float
        Radius (m) over which vertex normals are averaged to give the smooth normals the tool is
        aligned with (0 = plain area-weighted vertex normals).  Default 2 mm: it removes scan noise
        yet stays far below any pad radius.
    curvature_neighbours : int
        Neighbourhood size (points) of the quadric curvature fit.

    Raises
    ------
    InputError
        On wrong shapes, non-finite coordinates, out-of-range indices or zero total area.
    """

    def __init__(self, vertices, faces, *, name: str = "", normal_smoothing: float = 2e-3,
                 curvature_neighbours: int = 24):
        v = np.array(vertices, dtype=float)
        f = np.array(faces)
        if v.ndim != 2 or v.shape[1] != 3 or len(v) < 3:
            raise InputError(f"expected vertices of shape (n>=3, 3), got {v.shape}")
        if f.ndim != 2 or f.shape[1] != 3 or len(f) < 1:
            raise InputError(f"expected faces of shape (m>=1, 3), got {f.shape}")
        if not np.issubdtype(f.dtype, np.integer):
            if not np.all(np.equal(np.mod(f, 1), 0)):
                raise InputError("face indices must be integers")
        f = f.astype(np.int64)
        if not np.isfinite(v).all():
            bad = int((~np.isfinite(v)).any(axis=1).sum())
            raise InputError(f"{bad} vertices have NaN or infinite coordinates; repair or re-export the mesh")
        if f.min() < 0 or f.max() >= len(v):
            raise InputError(f"face indices must lie in 0..{len(v) - 1}, got {f.min()}..{f.max()}")
        v.setflags(write=False)
        f.setflags(write=False)
        self.vertices = v
        self.faces = f
        self.name = name
        self.normal_smoothing = float(normal_smoothing)
        self.curvature_neighbours = int(curvature_neighbours)
        if not self.area > 0:
            raise InputError("the mesh has no area (all triangles are degenerate)")

    def adopt(self, **derived) -> None:
        """Take derived values computed elsewhere for this very mesh (by a helper process forked
        from this one, :class:`swath.core.beside.Beside`) instead of computing them again here.

        Each keyword names one of the cached per-vertex or per-face properties (``normals``,
        ``curvature``, ...); a value already computed here is kept.  Only values computed from this
        surface's own vertices and faces (as the property would) may be given.
        """
        for name, value in derived.items():
            if not isinstance(getattr(type(self), name, None), cached_property):
                raise TypeError(f"Surface.{name} is not a derived (cached) property")
            if isinstance(value, np.ndarray):
                value = _ro(value)          # as the property itself returns it
            self.__dict__.setdefault(name, value)

    def memo(self, key, build, *, lasting: bool = False):
        """``build()`` for this surface, computed once per ``key`` (hashable) and kept with the
        surface: a model that several calls on the same part share (the uniform planner's working
        mesh and distance solver), instead of each building it again.  Kept for the surface's
        lifetime, never pickled (a copy sent to another process builds its own), and released
        by :meth:`forget`.  ``build`` must depend only on this surface and what ``key`` names.

        ``lasting``: kept through :meth:`forget` too (which releases the planners' large models):
        the small derived data every later stage reads again, such as the removal simulation's
        samples (:func:`swath.simulate.removal.simulate_removal` runs five to ten times a job)."""
        memos = self.__dict__.setdefault("_lasting" if lasting else "_memos", {})
        if key not in memos:
            memos[key] = build()
        return memos[key]

    def forget(self, kind=None) -> None:
        """Drop the values of :meth:`memo` (those whose key is a tuple starting with ``kind``, or all)."""
        memos = self.__dict__.get("_memos", {})
        for key in [k for k in memos if kind is None or (isinstance(k, tuple) and k[:1] == (kind,))]:
            del memos[key]

    def __getstate__(self) -> dict:
        # The closest-point tree is a libigl object that cannot be pickled; it is rebuilt on use.
        # The memos (a distance solver in C++) stay with this process.
        state = dict(self.__dict__)
        state.pop("_closest_point_tree", None)
        state.pop("_memos", None)
        state.pop("_lasting", None)
        return state

    def __repr__(self) -> str:
        return f"Surface({self.name!r}, {len(self.vertices)} vertices, {len(self.faces)} faces, area={self.area:.4g} m²)"

    # --- per-face -----------------------------------------------------------------------------
    @cached_property
    def _face_normals_areas(self):
        return geometry.face_normals_and_areas(self.vertices, self.faces)

    @cached_property
    def face_normals(self) -> np.ndarray:
        """(m, 3) unit facet normals, toward the tool."""
        return _ro(self._face_normals_areas[0])

    @cached_property
    def face_areas(self) -> np.ndarray:
        """(m,) facet areas, m²."""
        return _ro(self._face_normals_areas[1])

    @cached_property
    def area(self) -> float:
        """Total area, m²."""
        return float(self.face_areas.sum())

    # --- per-vertex ---------------------------------------------------------------------------
    @cached_property
    def vertex_areas(self) -> np.ndarray:
        """(n,) area attributed to each vertex (a third of each incident face), m²."""
        return _ro(geometry.vertex_areas(len(self.vertices), self.faces, self.face_areas))

    @cached_property
    def vertex_normals(self) -> np.ndarray:
        """(n, 3) area-weighted unit vertex normals (unsmoothed)."""
        return _ro(geometry.vertex_normals(len(self.vertices), self.faces, self.face_normals, self.face_areas))

    @cached_property
    def normals(self) -> np.ndarray:
        """(n, 3) smooth unit vertex normals toward the tool: vertex normals averaged over
        ``normal_smoothing`` metres.  Tool z is aligned with minus these (interpolated)."""
        return _ro(geometry.smooth_vertex_normals(self.vertices, self.vertex_normals, self.vertex_areas,
                                                  self.normal_smoothing, self.kdtree))

    @cached_property
    def curvature(self) -> PrincipalCurvature:
        """Principal curvatures (1/m, positive = convex toward the tool) and directions per vertex."""
        return principal_curvatures(self.vertices, self.normals, neighbours=self.curvature_neighbours,
                                    tree=self.kdtree)

    # --- topology and bounds --------------------------------------------------------------------
    @cached_property
    def boundary_loops(self) -> list[np.ndarray]:
        """Closed boundary loops (vertex indices), longest first; empty for a closed surface."""
        return topology.boundary_loops(self.faces)

    def farther_from_boundary(self, margin: float) -> np.ndarray:
        """(n,) bool: vertices farther than ``margin`` (m) from the open boundary's vertices
        (:func:`farther_from_boundary`)."""
        return farther_from_boundary(self.vertices, self, margin)

    @cached_property
    def edge_lengths(self) -> np.ndarray:
        """(3m,) length of each face edge (shared edges appear twice), m."""
        tri = self.vertices[self.faces]
        return np.linalg.norm(tri - np.roll(tri, -1, axis=1), axis=2).ravel()

    @cached_property
    def bounds(self) -> np.ndarray:
        """(2, 3) axis-aligned bounding box corners, m."""
        return _ro(np.array([self.vertices.min(axis=0), self.vertices.max(axis=0)]))

    @cached_property
    def principal_axes(self) -> tuple[np.ndarray, np.ndarray]:
        """Area centroid ``(3,)`` and principal axes ``(3, 3)``, rows, largest spread first (exact
        triangle moments, independent of the triangulation)."""
        return geometry.area_principal_axes(self.vertices, self.faces)

    # --- queries --------------------------------------------------------------------------------
    @cached_property
    def kdtree(self):
        """A ``scipy.spatial.cKDTree`` over the vertices."""
        from scipy.spatial import cKDTree

        return cKDTree(self.vertices)

    @cached_property
    def trimesh(self):
        """A ``trimesh.Trimesh`` view (no processing) for proximity and slicing queries."""
        import trimesh

        return trimesh.Trimesh(self.vertices, self.faces, process=False, validate=False)

    @cached_property
    def _closest_point_tree(self):
        """A libigl AABB tree over the triangles, with the vertices it was built on.

        The vertices are shifted to their centroid first, so coordinates far from the origin (a
        part placed in a robot cell) keep their precision.  libigl answers closest-point queries
        25-50x faster than trimesh's rtree search, most of all for points far off the surface
        (air-move clearance checks).
        """
        import igl

        origin = self.vertices.mean(axis=0)
        V = np.ascontiguousarray(self.vertices - origin, dtype=np.float64)
        F = np.ascontiguousarray(self.faces, dtype=np.int64)
        tree = igl.AABB()
        tree.init(V, F)
        return origin, V, F, tree

    def build_closest_point_tree(self) -> None:
        """Build the tree :meth:`closest_points` searches now, if not built yet.  Called before
        forking worker processes that will query the surface: they inherit it instead of each
        building it, and so does this process's own later query."""
        _ = self._closest_point_tree

    def closest_points(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Closest points on the surface to ``points`` ``(k, 3)``.

        Returns
        -------
        closest : (k, 3) float
            The nearest surface points, m.
        distance : (k,) float
            Distances, m.
        face : (k,) int
            The face each closest point lies on.
        """
        origin, V, F, tree = self._closest_point_tree
        q = np.ascontiguousarray(np.asarray(points, float).reshape(-1, 3) - origin)
        if len(q) == 0:
            return np.zeros((0, 3)), np.zeros(0), np.zeros(0, dtype=np.int64)
        d2, face, closest = tree.squared_distance(V, F, q)
        return closest + origin, np.sqrt(np.maximum(d2, 0.0)), face.astype(np.int64)

    def interpolate_normals(self, points: np.ndarray, face: np.ndarray) -> np.ndarray:
        """Smooth unit normals ``(k, 3)`` at ``points`` lying on faces ``face``: barycentric
        interpolation of :attr:`normals` between the face's vertices."""
        import trimesh

        tri = self.vertices[self.faces[face]]
        bary = trimesh.triangles.points_to_barycentric(tri, points)
        bary = np.clip(bary, 0.0, None)
        bary /= np.maximum(bary.sum(axis=1, keepdims=True), 1e-300)
        n = np.einsum("ki,kij->kj", bary, self.normals[self.faces[face]])
        return geometry.normalize(n)

    def face_pieces(self) -> list[np.ndarray]:
        """Face indices ``(k,) int`` of each connected piece (faces sharing vertices), largest first
        (read-only arrays, computed once: every candidate direction of a plan asks again)."""
        return list(self._face_pieces)

    @cached_property
    def _face_pieces(self) -> tuple[np.ndarray, ...]:
        n, label = topology.vertex_components(len(self.vertices), self.faces)
        face_label = label[self.faces[:, 0]]
        groups = [np.flatnonzero(face_label == i) for i in range(n)]
        groups = [g for g in groups if len(g)]
        groups.sort(key=lambda g: -float(self.face_areas[g].sum()))
        return tuple(_ro(g) for g in groups)

    def sub_surface(self, face_index, *, name: str | None = None) -> Surface:
        """The surface made of the faces ``face_index`` ``(k,) int`` only (vertices renumbered)."""
        faces = self.faces[np.asarray(face_index, np.int64)]
        used, inverse = np.unique(faces, return_inverse=True)
        return Surface(self.vertices[used], inverse.reshape(-1, 3), name=name or self.name,
                       normal_smoothing=self.normal_smoothing, curvature_neighbours=self.curvature_neighbours)

    def subdivided(self, max_edge: float, *, method: str = "long_edges") -> Surface:
        """A copy whose edges are all at most ``max_edge`` metres (same shape, finer sampling).

        Parameters
        ----------
        max_edge : float
            Longest edge allowed, m.
        method : {"long_edges", "halving"}
            ``"long_edges"``: split only the edges longer than ``max_edge``
            (:func:`swath.surface.subdivide.split_long_edges`), so long slivers are cut across, not
            also along, and each edge ends in equal pieces just under ``max_edge``; the vertices of
            this surface are kept, first and in order.  ``"halving"``: the earlier 1-to-4 split of
            every face with a long edge (:func:`swath.surface.subdivide.halve_long_edges`, the same
            mesh as ``trimesh.remesh.subdivide_to_size``), up to about twice as
            many vertices per direction; kept for results that must not change.

        Returns
        -------
        Surface
            ``self`` when no edge is longer than ``max_edge``.
        """
        if method not in SUBDIVISION_METHODS:
            raise InputError(f"subdivision method must be one of {', '.join(SUBDIVISION_METHODS)}, got {method!r}")
        if self.edge_lengths.max() <= max_edge:
            return self
        if method == "halving":
            v, f = halve_long_edges(self.vertices, self.faces, max_edge)
        else:
            v, f = split_long_edges(self.vertices, self.faces, max_edge)
        return Surface(v, f, name=self.name, normal_smoothing=self.normal_smoothing,
                       curvature_neighbours=self.curvature_neighbours)


def farther_from_boundary(points: np.ndarray, surface: Surface, margin: float, step: float | None = None) -> np.ndarray:
    """(k,) bool: ``points`` ``(k, 3)`` (m) farther than ``margin`` (m), in space, from the open
    boundary of ``surface``: the part's inside, where a pad of radius ``margin`` never hangs over
    the edge.  All True on a closed surface or for ``margin <= 0``.

    The distance is to the boundary's vertices, or with ``step`` (m) to points no more than
    ``step`` apart along its edges (for points on a finer sampling than the surface's own mesh).
    """
    from scipy.spatial import cKDTree

    from .polyline import densify

    loops = surface.boundary_loops
    if not loops or margin <= 0:
        return np.ones(len(points), bool)
    if step is None:
        boundary = surface.vertices[np.unique(np.concatenate(loops))]
    else:
        boundary = np.vstack([densify(surface.vertices[np.append(loop, loop[0])], step)[0] for loop in loops])
    d, _ = cKDTree(boundary).query(points, distance_upper_bound=margin)
    return ~np.isfinite(d)


def _ro(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a
