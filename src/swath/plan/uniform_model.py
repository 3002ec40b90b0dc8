"""The uniform planner's working mesh: the subdivided surface with its distance solver (heat method, or a narrow-band fast marching), gradient operator, contact-model width model and pad-touch test, shared by all candidate directions."""

from __future__ import annotations

import copy
import functools
import logging
import math
import time
from collections.abc import Callable

import numpy as np

from ..contact.kernels import default_cell, sample_grid, touched_samples
from ..contact.widths import unique_patches, widths_across
from ..core.beside import Beside
from ..errors import InputError
from ..surface.cells import jit
from ..surface.curvature import PrincipalCurvature
from ..surface.geodesic import BandDistance, FaceGradient, heat_solver
from ..surface.geometry import normalize
from ..surface.topology import mesh_edges

log = logging.getLogger(__name__)


#: About this many working-mesh vertices at most (the default working edge is coarsened to stay near
#: it, never past R/4).  Every distance solve of the heat method costs time in proportion to the
#: vertices (0.13 s a solve at 308,365, about 50 solves a direction).  Of the built-in and shared
#: parts only crs_part_5 (2.96 m², its CAD triangles halved to 308,365 vertices at 6.8 mm) is over
#: it: at 169,820 vertices (R/4, 9.5 mm) its uniform job planned in 27 s instead of 37 s, and its
#: passes removed with an interior CoV of 0.207 at constant feed instead of 0.206.
MAX_WORK_VERTICES = 150_000

#: The progress stage of a working mesh's set-up (:class:`_Context`), said with its vertex count and
#: an estimate of its time (:func:`setup_estimate_s`).
SETUP_STAGE = "planning (uniform): setting up the working mesh"

#: The set-up's time once the working mesh is made (its solver and, beside it, its width model), on
#: the 2-core reference machine, for the progress line's estimate only: 5.7 s for crs_part_5's
#: 308,365 vertices, growing as the vertex count to the power 1.1 (snp_part_scan's 75,668
#: vertices: 1.2 s predicted, 1.15 s measured; the blade's 89,383, whose Delaunay mesh needs no
#: intrinsic triangulation: 1.5 s predicted, 1.07 s measured).
SETUP_REFERENCE_S, SETUP_REFERENCE_VERTICES, SETUP_EXPONENT = 5.7, 308_365, 1.1


def setup_estimate_s(n_vertices: int) -> float:
    """About how long (s) a working mesh of ``n_vertices`` takes to set up once made (:data:`SETUP_REFERENCE_S`)."""
    return SETUP_REFERENCE_S * (max(int(n_vertices), 0) / SETUP_REFERENCE_VERTICES) ** SETUP_EXPONENT


#: Distance solvers of :meth:`_Context.distance`: ``"band"`` the narrow-band fast marching
#: (:class:`swath.surface.geodesic.BandDistance`), ``"heat"`` potpourri3d's heat method on the whole
#: working mesh (its factorisation built with the working mesh).
DISTANCE_METHODS = ("band", "heat")

#: The method the uniform planner uses when none is given.  The band solve is 10-100x faster per
#: generation, but the plans it lays differ from the heat method's, and on the demo, crs_part_5 and
#: the panel the default job's interior CoV came out worse (docs/guide/narrow-band-distance.md):
#: the heat method stays the default until that is resolved.
DEFAULT_DISTANCE_METHOD = "heat"


def load_touch_kernel(tool) -> None:
    """Load the compiled pad-touch test (:func:`swath.contact.kernels.touched_samples`) from
    numba's cache now, with the argument types :meth:`_Context.touched_at` passes it, on a grid of
    three samples: about 0.15 s the first candidate would otherwise spend, done while nothing else
    needs this process (see ``while_building`` of :class:`_Context`).  Changes no state but numba's."""
    pts = np.array([[0.0, 0.0, 0.0], [1e-3, 0.0, 0.0], [0.0, 1e-3, 0.0]])
    grid = sample_grid(pts, np.tile([0.0, 0.0, 1.0], (3, 1)), np.full(3, 1e-7), cell=default_cell(tool))
    touched_samples(grid, np.zeros((1, 3)), np.array([[0.0, 0.0, -1.0]]), tool, max_sink=np.array([1e-3]))


class WidthModel:
    """Swath widths from the local contact model at the vertices of a working mesh.

    The contact patch is solved once per distinct (rounded) curvature pair; widths across any
    feed direction are then read from it.
    """

    def __init__(self, curvature: PrincipalCurvature, normals: np.ndarray, tool):
        self.curvature = curvature
        self.normals = normals
        self.patch, self.inverse = unique_patches(curvature.k1, curvature.k2, tool, 180)
        # An upper bound of the width at each vertex over every direction, m: no chord of the
        # patch is longer than twice its farthest ray (NaN where a patch holds NaN).
        reach = np.maximum(np.abs(self.patch.rho_out), np.abs(self.patch.rho_in))
        self.max_width = (2.0 * reach.max(axis=1))[self.inverse]
        # And a lower bound: across any direction ψ the ray nearest ψ (within half the widest gap Δ
        # between rays) reaches at least rho_out cos Δ ahead and the ray nearest ψ + π as far
        # behind, so the width is at least 2 min(rho_out) cos Δ, less a relative 1e-6 for
        # rounding; 0 where some ray has no contact (or holds NaN).
        phi = np.sort(np.asarray(self.patch.phi, float))
        gaps = np.diff(np.concatenate([phi, [phi[0] + 2 * np.pi]]))
        half_gap = 0.5 * float(gaps.max())
        every_ray = np.all(self.patch.rho_out > self.patch.rho_in, axis=1)
        low = 2.0 * self.patch.rho_out.min(axis=1) * math.cos(half_gap) * (1.0 - 1e-6)
        ok = every_ray & np.isfinite(low) & (half_gap < 0.5 * np.pi)
        self.min_width = np.where(ok, np.maximum(low, 0.0), 0.0)[self.inverse]

    def across(self, idx: np.ndarray, feed: np.ndarray) -> np.ndarray:
        """Width (m) of the swath at vertices ``idx`` ``(k,)`` for feed directions ``feed`` ``(k, 3)``."""
        n = self.normals[idx]
        t = feed - np.einsum("ij,ij->i", feed, n)[:, None] * n
        cross = np.cross(n, normalize(t))
        psi = np.arctan2(np.einsum("ij,ij->i", cross, self.curvature.d2[idx]),
                         np.einsum("ij,ij->i", cross, self.curvature.d1[idx]))
        return widths_across(self.patch, self.inverse[idx], psi)


def working_mesh(surface, pad_radius: float, work_spacing: float | None = None):
    """The mesh the uniform planner's distance fields are solved on: ``surface`` with its long
    edges halved down to ``work_spacing`` (m); ``(Surface, spacing m)``.

    By default the spacing follows the part's area (about 150,000 vertices of an even mesh),
    between R/12 and R/4 of the pad radius ``pad_radius`` (m).  Halving long thin CAD triangles
    makes far more vertices than an even mesh of the same edge length, so the spacing is then
    coarsened until the mesh is within 1.3 times :data:`MAX_WORK_VERTICES` (never past R/4,
    where the swath widths would blur).  A given ``work_spacing`` is used as it is."""
    R = float(pad_radius)
    given = work_spacing is not None
    spacing = float(work_spacing) if work_spacing is not None else \
        float(np.clip(np.sqrt(surface.area / 150_000.0), R / 12.0, R / 4.0))
    work = surface.subdivided(spacing, method="halving")
    while not given and len(work.vertices) > 1.3 * MAX_WORK_VERTICES and spacing < R / 4.0:
        spacing = min(spacing * math.sqrt(len(work.vertices) / MAX_WORK_VERTICES), R / 4.0)
        work = surface.subdivided(spacing, method="halving")
    if len(np.unique(work.faces)) < len(work.vertices):
        # vertices no face uses (a hole cut out of a grid): the distance solver refuses them
        work = work.sub_surface(np.arange(len(work.faces)))
    return work, spacing


def _normals_and_widths(surface, W, tool) -> tuple[np.ndarray, WidthModel]:
    """The smooth normals ``(n, 3)`` of the working mesh ``W`` and its :class:`WidthModel`, with
    curvature from the part's own vertices (the nearest one to each working vertex): vertices
    added on flat facets by the subdivision would read the faceting, not the surface."""
    nearest = surface.kdtree.query(W.vertices)[1]
    c = surface.curvature
    widths = WidthModel(PrincipalCurvature(c.k1[nearest], c.k2[nearest], c.d1[nearest], c.d2[nearest]), W.normals, tool)
    return W.normals, widths


def _beside_solver(surface, W, tool) -> dict:
    """Everything the set-up needs that the distance solver does not: the part's smooth normals
    and curvature, the working mesh's smooth normals and boundary loops, the width model, the
    mesh's edges and its gradient operator.  Run beside the solver's factorisation
    (:class:`_Context`); the values are exactly those the cached properties compute here.
    Returns ``{"part": {...}, "work": {...}, "widths": WidthModel, "edges": (edges, face edges)
    of :func:`swath.surface.topology.mesh_edges`, "gradient": FaceGradient}``, the first two
    keyed by :class:`swath.surface.Surface` property names (for ``Surface.adopt``)."""
    normals, widths = _normals_and_widths(surface, W, tool)
    gradient = FaceGradient(W.vertices, W.faces)
    _ = gradient.stacked_basis          # built once here, not in every worker's first candidate
    return {"part": {"normals": surface.normals, "curvature": surface.curvature},
            "work": {"normals": normals, "boundary_loops": W.boundary_loops}, "widths": widths,
            "edges": mesh_edges(np.asarray(W.faces, np.int64)), "gradient": gradient}


class _Context:
    """The working mesh, its distance solver and width model, shared by all candidate directions."""

    def __init__(self, surface, tool, work_spacing, max_turn_curvature=math.inf, *, beside: bool = True,
                 while_building: Callable[[], object] | None = None, distance_method: str | None = None,
                 progress=None):
        """``beside``: build the working mesh's smooth normals and the width model in a forked child
        process while the distance solver is built here (:class:`swath.core.beside.Beside`; the same
        arrays either way), where forking is possible and two CPUs are free.  ``while_building()``,
        if given, runs here after the distance solver is built and before the child's answer is
        read: work that needs none of the context (imports, loading compiled kernels) fills the
        time this process would otherwise wait for the child.  ``distance_method``: one of
        :data:`DISTANCE_METHODS` (default :data:`DEFAULT_DISTANCE_METHOD`).  ``progress(stage, done,
        total)``, if given, hears :data:`SETUP_STAGE` with the working mesh's vertex count and an
        estimate of the set-up's time once the mesh is made, before its solver is built."""
        distance_method = DEFAULT_DISTANCE_METHOD if distance_method is None else distance_method
        if distance_method not in DISTANCE_METHODS:
            raise InputError(f"distance_method must be one of {', '.join(DISTANCE_METHODS)}, got {distance_method!r}")
        t0 = time.perf_counter()
        self.surface = surface
        self.tool = tool
        self.max_turn_curvature = float(max_turn_curvature)   # 1/m, in the tangent plane
        self.work, self.work_spacing = working_mesh(surface, tool.pad_radius, work_spacing)
        W = self.work
        if progress is not None:
            progress(f"{SETUP_STAGE} ({len(W.vertices):,} vertices, about {setup_estimate_s(len(W.vertices)):.0f} s)",
                     0, 1)
        # The two halves of the set-up need nothing from each other: the distance solver (with the
        # heat method its factorisation, C++ holding the GIL) is built here while a forked child
        # builds the part's normals and curvature, the working mesh's normals and boundary loops,
        # the width model, the edges and the gradient operator (numpy); this process adopts them,
        # so later stages find them computed.
        beside_work = Beside(_beside_solver, surface, W, tool, allowed=beside)
        self.distance_method = distance_method
        _ = self.solver if distance_method == "heat" else self.band
        if while_building is not None:
            while_building()
        built = beside_work.result()
        surface.adopt(**built["part"])
        W.adopt(**built["work"])
        self.widths = built["widths"]
        self.edges = built["edges"]
        self.gradient = built["gradient"]                     # direction of the distance field
        # the longest working edge, m: a face's corners lie within it of each other in distance
        self.max_edge = float(np.linalg.norm(W.vertices[self.edges[0][:, 0]] - W.vertices[self.edges[0][:, 1]],
                                             axis=1).max()) if len(self.edges[0]) else 0.0
        self.tree = W.kdtree
        # Pad queries on a cell grid of the working vertices, built once (compiled contact model,
        # float64), relative to the part's centre.
        self._origin = 0.5 * (W.vertices.min(axis=0) + W.vertices.max(axis=0))
        self._grid = sample_grid(W.vertices - self._origin, W.normals, W.vertex_areas, cell=default_cell(tool))
        log.info("uniform: working mesh %d vertices (edges <= %.1f mm), set up in %.2f s", len(W.vertices),
                 1e3 * self.work_spacing, time.perf_counter() - t0)

    @functools.cached_property
    def band(self) -> BandDistance:
        """The narrow-band fast marching on the working mesh (``distance_method="band"`` only)."""
        return BandDistance(self.work.vertices, self.work.faces)

    @functools.cached_property
    def solver(self):
        """potpourri3d's heat-method solver on the working mesh (``distance_method="heat"`` only)."""
        return heat_solver(self.work.vertices, self.work.faces)

    def distance(self, sources: np.ndarray, stop: float = math.inf) -> np.ndarray:
        """Geodesic distance ``(n,)`` (m) from the vertex set ``sources`` ``(s,)`` to the working vertices.

        With the band method only vertices within ``stop`` (m) of the sources get a distance, the
        others ``inf``, and the solve costs in proportion to that band.  The heat method (the
        default, :data:`DEFAULT_DISTANCE_METHOD`) solves on the whole mesh whatever ``stop``; it recovers distance up to a constant,
        fixed so the sources sit at 0 (their median), and the field is clipped at 0.
        """
        src = np.unique(sources)
        if self.distance_method == "band":
            return self.band(src, stop=stop)
        d = np.asarray(self.solver.compute_distance_multisource(src.tolist()), float)
        return np.maximum(d - np.median(d[src]), 0.0)

    def band_stop(self, reach: float) -> float:
        """The stop distance (m) a generation of passes laid ``reach`` local widths beyond the
        covered edge needs: the band ``d <= 2.5 R`` where the widths are read, and the level
        ``d = reach * w`` the pass is cut at (``w`` at most the widest swath, or ``2R`` off the
        band), plus two of the longest working edges so that every face the level cuts, and
        every face round a band vertex, has all its corners' distances."""
        R = self.tool.pad_radius
        widest = max(2.0 * R, float(np.nanmax(self.widths.max_width)) if len(self.widths.max_width) else 0.0)
        return max(2.5 * R, reach * widest) + 2.0 * self.max_edge

    def frontier(self, covered: np.ndarray) -> np.ndarray:
        """Covered vertices with an uncovered neighbour: the edge of the covered region."""
        flags = np.zeros(len(self.work.vertices), np.bool_)
        _frontier_flags(np.ascontiguousarray(self.work.faces, np.int64), np.ascontiguousarray(covered, np.bool_), flags)
        return np.flatnonzero(flags)

    def gradient_directions(self, d: np.ndarray, idx: np.ndarray | None = None) -> np.ndarray:
        """Unit tangent direction of increasing ``d`` ``(n,)`` (m) at each vertex ``(n, 3)``, or at
        the vertices ``idx`` ``(k,)`` only ``(k, 3)`` (the same values as ``[idx]`` of the whole)."""
        return _vertex_gradient_directions(self.gradient, d, self.work.normals, idx)

    def nearest_vertices(self, points: np.ndarray) -> np.ndarray:
        return self.tree.query(points)[1]

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Points ``(k, 3)`` dropped onto the tangent plane of their nearest working vertex, and that
        vertex's smooth normal: within a micrometre of the surface for points already near it (the
        working mesh is finer than R/4), and far cheaper than an exact closest-point query."""
        idx = self.nearest_vertices(points)
        n = self.work.normals[idx]
        off = np.einsum("ij,ij->i", points - self.work.vertices[idx], n)
        return points - off[:, None] * n, n

    def warm(self) -> None:
        """Load the compiled kernels every candidate direction calls (pad touch test, widths across a
        direction, vertex gradient directions, the band distance) now, from numba's cache, with the argument types the
        planner passes them, and build the part's closest-point tree.  Worker processes forked
        afterwards inherit them, instead of each loading and building them again on its first
        candidate (about 0.06 s of CPU per worker for each).  No state of the context changes
        (the tree is a cached property of the part)."""
        first = np.zeros(1, np.int64)
        # the part's closest-point tree: every candidate's resampling on the surface queries it,
        # and so does this process's resampling of the winner afterwards
        self.surface.build_closest_point_tree()
        self.touched_at(self.work.vertices[:1])
        self.widths.across(first, np.asarray(self.widths.curvature.d1[:1], float))
        self.gradient_directions(np.zeros(len(self.work.vertices)), first)
        self.frontier(np.zeros(len(self.work.vertices), bool))
        if self.distance_method == "band":
            self.band(first, stop=0.0)

    def touched(self, pts: np.ndarray) -> np.ndarray:
        """(n,) bool: working vertices the pressed pad touches along the pass ``pts`` ``(k, 3)``,
        at poses at most R/8 apart (see :meth:`touched_at`)."""
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        n = max(int(np.ceil(cum[-1] / (self.tool.pad_radius / 8))), 1) + 1
        idx = np.unique(np.searchsorted(cum, np.linspace(0, cum[-1], n)).clip(0, len(pts) - 1))
        return self.touched_at(pts[idx])

    def touched_at(self, poses: np.ndarray) -> np.ndarray:
        """(n,) bool: working vertices the pressed pad touches at the pad centres ``poses`` ``(k, 3)``.

        The mesh contact model (:func:`swath.contact.mesh_contact`), with the pad-face depth capped at
        that of the local contact model (principal curvatures at the pose): where the pad overhangs
        the part's edge the real pad sinks deeper and reaches farther, and passes laid along that
        wider edge would bow outward more with every generation.  The cap only ever shrinks the
        region counted as covered, so the simulator agrees with it.
        """
        if len(poses) == 0:
            return np.zeros(len(self.work.vertices), bool)
        closest, normals = self.project(poses)
        cap = self.widths.patch.sink[self.widths.inverse[self.nearest_vertices(closest)]]
        return touched_samples(self._grid, closest - self._origin, -normals, self.tool, max_sink=cap)


def shared_context(surface, tool, work_spacing, *, max_turn_curvature: float = math.inf, beside: bool = True,
                   while_building: Callable[[], object] | None = None,
                   distance_method: str | None = None, progress=None) -> _Context:
    """The :class:`_Context` of ``surface`` for ``tool`` and ``work_spacing``, built once and kept
    on the surface (:meth:`swath.surface.Surface.memo`): the default job plans the same part
    several times (the curvature probe, the re-plan at the chosen spacing and lead, the
    length-budget re-plans, the plain plan compared with it), and the working mesh, its
    distance solver's factorisation, width model and gradient operator depend on none of what
    changes between them (the overlap, the seed, the candidate direction).  A call with another
    ``max_turn_curvature`` (the feed or angular limit) gets a shallow copy with it set.  The
    plans are the same as with a context built for each call: nothing in the context changes
    after it is built.  ``beside``, ``while_building``, ``distance_method`` and ``progress`` as for
    :class:`_Context` (all but ``distance_method`` used only when it is built).  ``surface.forget("uniform
    model")`` releases it."""
    distance_method = DEFAULT_DISTANCE_METHOD if distance_method is None else distance_method
    key = ("uniform model", tool, None if work_spacing is None else float(work_spacing), distance_method)
    built: list = []

    def build():
        built.append(True)
        return _Context(surface, tool, work_spacing, max_turn_curvature=max_turn_curvature, beside=beside,
                        while_building=while_building, distance_method=distance_method, progress=progress)

    ctx = surface.memo(key, build)
    if not built:
        log.info("uniform: working mesh of %s reused (%d vertices)", surface.name or "the part", len(ctx.work.vertices))
    if ctx.max_turn_curvature == float(max_turn_curvature):
        return ctx
    other = copy.copy(ctx)
    other.max_turn_curvature = float(max_turn_curvature)
    return other


def _vertex_gradient_directions(gradient: FaceGradient, field: np.ndarray, normals: np.ndarray,
                                idx: np.ndarray | None = None) -> np.ndarray:
    """``gradient.vertex_directions(field, normals)`` ``(n, 3)`` (or its rows ``idx`` ``(k,)``:
    ``(k, 3)``), the face gradients and their per-vertex sums in one compiled loop over the faces.

    The arithmetic is that of :meth:`FaceGradient.vertex_directions` term by term and in the same
    order (each face's gradient as ``((0 + f0 b0) + f1 b1) + f2 b2`` times its area; each vertex's sum
    over its faces in face order, once per corner slot, the three slot sums added in slot order), so
    the directions are the same bit for bit, without the nine weighted ``bincount`` passes.  With
    ``idx`` only the faces round those vertices are visited (each vertex still gets all its faces,
    in the same order).
    """
    basis = gradient.stacked_basis                                             # (3, m, 3)
    n = gradient.n_vertices
    if idx is None:
        rows, k = np.arange(n, dtype=np.int64), n
    else:
        idx = np.asarray(idx, np.int64)
        rows = np.full(n, -1, np.int64)
        rows[idx] = np.arange(len(idx))
        k = len(idx)
        normals = normals[idx]
    acc = _gradient_vertex_sums(np.ascontiguousarray(gradient.faces, np.int64), np.ascontiguousarray(field, float),
                                basis, np.ascontiguousarray(gradient.face_areas, float), rows, k)
    acc -= np.einsum("ij,ij->i", acc, normals)[:, None] * normals
    return normalize(acc)


@jit()
def _frontier_flags(faces, covered, flags):   # pragma: no cover - compiled
    """Set ``flags[v]`` for each covered corner ``v`` of a face with covered and uncovered corners
    (:meth:`_Context.frontier` in one pass over the faces, without the ``(m, 3)`` gathers and the sort)."""
    for f in range(len(faces)):
        a = covered[faces[f, 0]]
        b = covered[faces[f, 1]]
        c = covered[faces[f, 2]]
        if (a or b or c) and not (a and b and c):
            if a:
                flags[faces[f, 0]] = True
            if b:
                flags[faces[f, 1]] = True
            if c:
                flags[faces[f, 2]] = True


@jit()
def _gradient_vertex_sums(faces, field, basis, face_areas, rows, k):   # pragma: no cover - compiled
    """Per-vertex sums of area-weighted face gradients into ``rows[v]`` (``-1``: not wanted), ``(k, 3)``."""
    slots = np.zeros((3, k, 3))
    for f in range(len(faces)):
        r0, r1, r2 = rows[faces[f, 0]], rows[faces[f, 1]], rows[faces[f, 2]]
        if r0 < 0 and r1 < 0 and r2 < 0:
            continue
        a = field[faces[f, 0]]
        b = field[faces[f, 1]]
        c = field[faces[f, 2]]
        for j in range(3):
            g = (((0.0 + a * basis[0, f, j]) + b * basis[1, f, j]) + c * basis[2, f, j]) * face_areas[f]
            if r0 >= 0:
                slots[0, r0, j] += g
            if r1 >= 0:
                slots[1, r1, j] += g
            if r2 >= 0:
                slots[2, r2, j] += g
    acc = np.zeros((k, 3))
    for i in range(3):
        for v in range(k):
            for j in range(3):
                acc[v, j] += slots[i, v, j]
    return acc
