"""Slice a triangle mesh with parallel planes into clean polylines, and resample them on the surface.

The slicer is topological, not geometric, which is what makes it unable to hang or to chain the
wrong points together:

* every vertex is classed *below* a plane (signed height ``h < d``) or *not below* (``h >= d``) —
  a vertex exactly on the plane counts as above (a symbolic perturbation of the plane), so a plane
  through vertices or along edges needs no special case;
* a face is cut when its vertices are not all on one side; it is then cut on exactly two of its
  edges, and contributes one segment joining the two *edge crossings*;
* a crossing is identified by (plane, undirected edge), so the two faces sharing an edge share
  the crossing exactly — chaining is a graph walk over these ids, with no distance tolerance;
* every crossing on an interior manifold edge has two segments, on a boundary edge one (the chain
  ends where the slice leaves the surface or crosses a hole), on a non-manifold edge more: the
  chain is split there (a branch point).

Positions come last: a crossing on edge ``(a, b)`` is ``a + t (b − a)`` (exactly ``a`` or ``b``
when the plane passes through it).  Several crossings can then coincide (a plane through a vertex
gives one crossing per edge at that vertex); the zero-length segments between them are dropped
after chaining.  Each remaining segment lies in one face, so any point interpolated along it lies
exactly on the mesh, in that face.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..surface.cells import jit
from ..surface.topology import mesh_edges

log = logging.getLogger("swath.plan")

#: Segments shorter than this (m) are merged away after chaining: far below any feature that
#: matters to a pad, far above the round-off of metre-scale coordinates.
MERGE_TOLERANCE = 1e-7


@dataclass(frozen=True, eq=False)
class SlicePolyline:
    """One chained piece of a plane's intersection with a mesh.

    Attributes
    ----------
    points : (k, 3) float
        Crossing points in order along the slice, m, k >= 2; consecutive points are more than
        the merge tolerance apart.  A closed polyline repeats its first point at the end.
    faces : (k - 1,) int
        The face each segment ``points[i] → points[i + 1]`` lies in.
    values : (k, q) float or None
        Per-vertex values (e.g. smooth normals) interpolated linearly along the mesh edges to
        the points; linear interpolation along a segment then equals barycentric interpolation
        in its face.
    plane : int
        Index of the cutting plane in the ``offsets`` given to :func:`slice_mesh`.
    closed : bool
        True when the slice is a closed loop on the surface.
    """

    points: np.ndarray
    faces: np.ndarray
    values: np.ndarray | None
    plane: int
    closed: bool

    @property
    def length(self) -> float:
        """Polyline length, m."""
        return float(np.linalg.norm(np.diff(self.points, axis=0), axis=1).sum())

    def reversed(self) -> SlicePolyline:
        """The same polyline run the other way."""
        vals = None if self.values is None else self.values[::-1].copy()
        return SlicePolyline(self.points[::-1].copy(), self.faces[::-1].copy(), vals, self.plane, self.closed)

    def rolled(self, start: int) -> SlicePolyline:
        """A closed polyline restarted at point ``start`` (same loop, same direction)."""
        if not self.closed:
            raise InputError("only a closed polyline can be restarted at another point")
        k = len(self.points) - 1
        idx = (np.arange(k + 1) + start) % k
        vals = None if self.values is None else self.values[idx]
        return SlicePolyline(self.points[idx], self.faces[(np.arange(k) + start) % k], vals, self.plane, True)


@dataclass(frozen=True, eq=False)
class SurfaceSamples:
    """Points on a mesh with the face each lies in.

    Attributes
    ----------
    points : (k, 3) float
        Positions, m.
    faces : (k,) int
        Face containing each point.
    values : (k, q) float or None
        Interpolated per-vertex values at the points.
    """

    points: np.ndarray
    faces: np.ndarray
    values: np.ndarray | None


def slice_mesh(vertices: np.ndarray, faces: np.ndarray, normal, offsets, *, values: np.ndarray | None = None,
               merge_tolerance: float = MERGE_TOLERANCE, edges=None) -> list[SlicePolyline]:
    """Intersect a triangle mesh with the planes ``x · normal = offset`` and chain the result.

    Parameters
    ----------
    vertices : (n, 3) float
        Mesh vertices, m.
    faces : (m, 3) int
        Triangles.
    normal : (3,) float
        Common plane normal (any length, not zero).
    offsets : (p,) float
        Plane offsets along the unit normal, m (any order; may repeat).
    values : (n, q) float, optional
        Per-vertex values to interpolate to the slice points (e.g. smooth normals).
    merge_tolerance : float
        Segments this short or shorter (m) are merged into their neighbours after chaining.
    edges : tuple, optional
        ``mesh_edges(faces)``, when the caller slices one mesh many times (see :func:`level_sets`).

    Returns
    -------
    list of SlicePolyline
        Ordered by plane index, each with at least one segment longer than ``merge_tolerance``.
        Chains are split at boundary edges (holes, the surface border) and at non-manifold edges.

    Raises
    ------
    InputError
        On malformed arrays or a zero normal.

    Notes
    -----
    Fully vectorised over planes and faces; the cost is ``O(m log m)`` plus the number of cut
    faces.  It never iterates to convergence, so it cannot hang.
    """
    V = np.asarray(vertices, float)
    F = np.asarray(faces, np.int64)
    if V.ndim != 2 or V.shape[1] != 3 or F.ndim != 2 or F.shape[1] != 3:
        raise InputError(f"expected vertices (n, 3) and faces (m, 3), got {V.shape} and {F.shape}")
    c = np.asarray(normal, float).reshape(-1)
    if c.shape != (3,) or not np.isfinite(c).all() or np.linalg.norm(c) == 0:
        raise InputError(f"the plane normal must be a finite, non-zero 3-vector, got {normal!r}")
    c = c / np.linalg.norm(c)
    off = np.asarray(offsets, float).reshape(-1)
    if not np.isfinite(off).all():
        raise InputError("plane offsets must be finite")
    vals = None
    if values is not None:
        vals = np.asarray(values, float)
        vals = vals.reshape(len(vals), -1)
        if len(vals) != len(V):
            raise InputError(f"values must have one row per vertex ({len(V)}), got {len(vals)}")
    if len(F) == 0 or len(off) == 0:
        return []

    return level_sets(V, F, V @ c, off, values=vals, merge_tolerance=merge_tolerance, edges=edges)


def level_sets(vertices: np.ndarray, faces: np.ndarray, field: np.ndarray, levels, *,
               values: np.ndarray | None = None, face_mask: np.ndarray | None = None,
               merge_tolerance: float = MERGE_TOLERANCE, edges=None, rows=None) -> list[SlicePolyline]:
    """Level sets ``field = level`` of a per-vertex scalar field, chained into polylines.

    The field is interpolated linearly over each triangle; a plane slice is the level set of
    ``field = x · normal`` (:func:`slice_mesh`), a geodesic-parallel pass the level set of a distance
    field.  The same topological rules apply (see the module notes), so it cannot hang.

    Parameters
    ----------
    vertices : (n, 3) float
    faces : (m, 3) int
    field : (n,) float
        Scalar value at each vertex.
    levels : (p,) float
        Levels to extract (the ``plane`` index of each polyline refers to this array).
    values : (n, q) float, optional
        Per-vertex values interpolated to the points.
    face_mask : (m,) bool, optional
        Only faces where this is true are cut (the level set stops at the mask's border).
    merge_tolerance : float
        Segments this short or shorter (m) are merged away.
    edges : tuple, optional
        ``mesh_edges(faces)`` if the caller extracts many level sets of one mesh (not with
        ``face_mask``).
    rows : (k,) int, optional
        With one level, no ``face_mask`` and ``edges``: increasing indices of the faces that may be
        cut, including every face the level cuts (:class:`PlaneSlicer`); the others are not looked
        at, and the answer is the one of looking at all.

    Returns
    -------
    list of SlicePolyline
    """
    V = np.asarray(vertices, float)
    F = np.asarray(faces, np.int64)
    h = np.asarray(field, float).reshape(-1)
    if len(h) != len(V) or not np.isfinite(h).all():
        raise InputError(f"the field must hold one finite value per vertex ({len(V)}), got shape {h.shape}")
    off = np.asarray(levels, float).reshape(-1)
    vals = None if values is None else np.asarray(values, float).reshape(len(V), -1)
    if face_mask is not None:
        keep_faces = np.flatnonzero(np.asarray(face_mask, bool))
        F = F[keep_faces]
    if len(F) == 0 or len(off) == 0:
        return []
    plane_order = np.argsort(off, kind="stable")
    d_sorted = off[plane_order]
    edges, face_edges = mesh_edges(F) if (edges is None or face_mask is not None) else edges
    n_edges = len(edges)

    # --- (face, plane) pairs: plane d cuts face f iff min h < d <= max h ----------------------------
    if len(d_sorted) == 1:
        # One level (a pass of the uniform planner, a touch-up slice): a face is cut iff some corner
        # lies below the level and some does not, the same test on vertex flags, and no per-face
        # minimum, maximum or search.
        under = h < d_sorted[0]
        if rows is not None and face_mask is None:
            Fr = F[rows]
            u0, u1, u2 = under[Fr[:, 0]], under[Fr[:, 1]], under[Fr[:, 2]]
            pair_face = np.asarray(rows, np.int64)[(u0 | u1 | u2) & ~(u0 & u1 & u2)]
        else:
            u0, u1, u2 = under[F[:, 0]], under[F[:, 1]], under[F[:, 2]]
            pair_face = np.flatnonzero((u0 | u1 | u2) & ~(u0 & u1 & u2))
        total = len(pair_face)
        if total == 0:
            return []
        pair_plane = np.zeros(total, np.int64)
    else:
        hf = h[F]
        # min / max over the three corners as two elementwise passes: the same values as
        # ``hf.min(axis=1)``, without NumPy's slow reduction over a length-3 axis (30x faster).
        h0, h1, h2 = hf[:, 0], hf[:, 1], hf[:, 2]
        j0 = np.searchsorted(d_sorted, np.minimum(np.minimum(h0, h1), h2), side="right")
        j1 = np.searchsorted(d_sorted, np.maximum(np.maximum(h0, h1), h2), side="right")
        count = j1 - j0
        total = int(count.sum())
        if total == 0:
            return []
        pair_face = np.repeat(np.arange(len(F)), count)
        first = np.repeat(np.cumsum(count) - count, count)
        pair_plane = j0[pair_face] + (np.arange(total) - first)          # index into d_sorted
    d = d_sorted[pair_plane]
    below = h[F[pair_face]] < d[:, None]                              # (P, 3)
    cut = below != np.roll(below, -1, axis=1)                         # edge slot e = (v_e, v_e+1)
    slot = np.nonzero(cut)[1].reshape(-1, 2)                          # exactly two cut edges per face
    edge_id = face_edges[pair_face[:, None], slot]                    # (P, 2)

    # --- crossing nodes: unique (plane, edge) ------------------------------------------------------
    key = pair_plane[:, None] * np.int64(n_edges) + edge_id
    node_key, ends = np.unique(key.ravel(), return_inverse=True)
    ends = ends.reshape(-1, 2)
    node_plane = node_key // n_edges
    node_edge = node_key % n_edges
    a, b = edges[node_edge, 0], edges[node_edge, 1]
    dn = d_sorted[node_plane]
    t = (dn - h[a]) / (h[b] - h[a])                                   # one end below, one not: h[a] != h[b]
    t = np.clip(t, 0.0, 1.0)
    pts = V[a] + t[:, None] * (V[b] - V[a])
    pts = np.where((t == 0.0)[:, None], V[a], np.where((t == 1.0)[:, None], V[b], pts))
    node_vals = None if vals is None else vals[a] + t[:, None] * (vals[b] - vals[a])

    # --- segments: drop duplicates (duplicate faces), split at branch nodes ------------------------
    seg_face = pair_face
    _, keep = np.unique(ends.min(axis=1) * np.int64(len(node_key)) + ends.max(axis=1), return_index=True)
    keep.sort()
    ends, seg_face = ends[keep], seg_face[keep]
    n_nodes = len(node_key)
    degree = np.bincount(ends.ravel(), minlength=n_nodes)
    branch = degree[ends] > 2
    node_src = np.arange(n_nodes)
    if branch.any():
        new = n_nodes + np.arange(int(branch.sum()))
        node_src = np.concatenate([node_src, ends[branch]])
        ends = ends.copy()
        ends[branch] = new
        n_nodes = len(node_src)
        log.debug("slice: split chains at %d branch crossings (non-manifold edges)", int(branch.sum()))

    if face_mask is not None:
        seg_face = keep_faces[seg_face]
    chains, closed, chain_faces = _chain(ends, seg_face, n_nodes)

    # --- positions, tiny-segment merging, records --------------------------------------------------
    out = []
    for nodes, is_closed, sf in zip(chains, closed, chain_faces):
        src = node_src[nodes]
        p = pts[src]
        seg_len = np.linalg.norm(np.diff(p, axis=0), axis=1)
        long = seg_len > merge_tolerance
        if not long.any():
            continue
        keep_pt = np.concatenate([[True], long])
        plane = int(plane_order[node_plane[src[0]]])
        v = None if node_vals is None else node_vals[src][keep_pt]
        out.append(SlicePolyline(p[keep_pt], sf[long], v, plane, bool(is_closed)))
    out.sort(key=lambda pl: pl.plane)
    return out


class PlaneSlicer:
    """One mesh cut by single planes of one normal, again and again (the fill passes of a plan).

    ``slicer(offset)`` is ``slice_mesh(vertices, faces, normal, [offset], values=values, edges=edges)``,
    the same polylines bit for bit, found among the faces the plane can cut only: the faces sorted
    by their lowest corner height, those whose lowest corner lies less than the tallest face's
    height span below the plane are tested as :func:`level_sets` tests them.

    Parameters
    ----------
    vertices : (n, 3) float
        m.
    faces : (m, 3) int
    normal : (3,) float
        The planes' common normal (any length, not zero).
    values : (n, q) float, optional
        Per-vertex values interpolated to the points.
    edges : tuple, optional
        ``mesh_edges(faces)``, when the caller has it.
    """

    def __init__(self, vertices, faces, normal, *, values=None, edges=None):
        self.vertices = np.asarray(vertices, float)
        self.faces = np.asarray(faces, np.int64)
        if self.vertices.ndim != 2 or self.vertices.shape[1] != 3 or self.faces.ndim != 2 or self.faces.shape[1] != 3:
            raise InputError(f"expected vertices (n, 3) and faces (m, 3), got {self.vertices.shape} and "
                             f"{self.faces.shape}")
        c = np.asarray(normal, float).reshape(-1)
        if c.shape != (3,) or not np.isfinite(c).all() or np.linalg.norm(c) == 0:
            raise InputError(f"the plane normal must be a finite, non-zero 3-vector, got {normal!r}")
        c = c / np.linalg.norm(c)                          # as slice_mesh takes it
        self.heights = self.vertices @ c
        self.values = values
        self.edges = mesh_edges(self.faces) if edges is None else edges
        hf = self.heights[self.faces]
        low = np.minimum(np.minimum(hf[:, 0], hf[:, 1]), hf[:, 2])
        high = np.maximum(np.maximum(hf[:, 0], hf[:, 1]), hf[:, 2])
        self._order = np.argsort(low, kind="stable")
        self._low = low[self._order]
        # a face the plane d cuts has low < d <= high, so low >= d - span: the slack covers the rounding
        self._span = float((high - low).max()) * (1.0 + 1e-9) + 1e-12 if len(low) else 0.0

    def __call__(self, offset: float) -> list[SlicePolyline]:
        d = float(offset)
        if not np.isfinite(d):
            raise InputError("plane offsets must be finite")
        if len(self.faces) == 0:
            return []
        a = int(np.searchsorted(self._low, d - self._span, side="left"))
        b = int(np.searchsorted(self._low, d, side="left"))             # low < d
        rows = np.sort(self._order[a:b])
        return level_sets(self.vertices, self.faces, self.heights, [d], values=self.values, edges=self.edges,
                          rows=rows)


def _chain(ends: np.ndarray, seg_face: np.ndarray, n_nodes: int):
    """Order the segments of a graph whose nodes have degree <= 2 into chains.

    Returns lists of node sequences, closed flags and per-segment faces.  A chain starts at its
    lowest-numbered open end; a closed loop is cut at its lowest-numbered segment (which becomes
    the closing segment) and starts at that segment's first node.  Chains come in the order of
    their first nodes.  One compiled walk along the segments (:func:`_walk_chains`); the same
    chains, in the same order, as sparse graph searches find them (components, then one depth-first
    traversal), which cost more than the walk on a slice of a few hundred segments.
    """
    ends = np.ascontiguousarray(ends, np.int64)
    if len(ends) == 0:
        return [], [], []
    nodes, node_start, seg, closed = _walk_chains(ends, int(n_nodes))
    faces = np.asarray(seg_face)[seg]
    chains, faces_out = [], []
    for i in range(len(node_start) - 1):
        a, b = node_start[i], node_start[i + 1]
        chains.append(nodes[a:b])
        faces_out.append(faces[a - i:b - i - 1])
    return chains, [bool(c) for c in closed], faces_out


@jit()
def _walk_chains(ends, n_nodes):   # pragma: no cover - compiled
    """The chains of a graph of segments ``ends`` (S, 2) on ``n_nodes`` nodes of degree <= 2 (see
    :func:`_chain`): the nodes of every chain one after another, where each chain's nodes start
    ``(c + 1,)``, the segment of each step (``len(nodes) - c``, chain after chain) and the closed flags."""
    S = len(ends)
    nbr = np.full((n_nodes, 2), -1, np.int64)          # the (up to) two segments at each node
    degree = np.zeros(n_nodes, np.int64)
    for s in range(S):
        for e in range(2):
            v = ends[s, e]
            if degree[v] < 2:
                nbr[v, degree[v]] = s
            degree[v] += 1
    # each component's start node and, for a loop, the segment it is cut at
    seen = np.zeros(n_nodes, np.bool_)
    start = np.full(n_nodes, -1, np.int64)
    cut = np.full(n_nodes, -1, np.int64)              # indexed by start node
    n_chains = 0
    stack = np.empty(n_nodes, np.int64)
    for v0 in range(n_nodes):
        if seen[v0] or degree[v0] == 0:
            continue
        # the component of v0: its lowest open end and its lowest segment
        top = 0
        stack[top] = v0
        seen[v0] = True
        low_open = -1
        low_seg = S
        while top >= 0:
            v = stack[top]
            top -= 1
            if degree[v] == 1 and (low_open < 0 or v < low_open):
                low_open = v
            for j in range(min(degree[v], 2)):
                s = nbr[v, j]
                if s < low_seg:
                    low_seg = s
                w = ends[s, 1] if ends[s, 0] == v else ends[s, 0]
                if not seen[w]:
                    seen[w] = True
                    top += 1
                    stack[top] = w
        if low_open >= 0:
            start[n_chains] = low_open
            cut[n_chains] = -1
        else:
            start[n_chains] = ends[low_seg, 0]
            cut[n_chains] = low_seg
        n_chains += 1
    order = np.argsort(start[:n_chains], kind="mergesort")
    nodes = np.empty(S + 2 * n_chains, np.int64)
    seg = np.empty(S + n_chains, np.int64)
    node_start = np.empty(n_chains + 1, np.int64)
    closed = np.zeros(n_chains, np.bool_)
    used = np.zeros(S, np.bool_)
    k = 0
    m = 0
    for i in range(n_chains):
        c = order[i]
        v = start[c]
        node_start[i] = k
        if cut[c] >= 0:
            used[cut[c]] = True
            closed[i] = True
        nodes[k] = v
        k += 1
        while True:
            nxt = -1
            for j in range(min(degree[v], 2)):
                s = nbr[v, j]
                if not used[s]:
                    nxt = s
                    break
            if nxt < 0:
                break
            used[nxt] = True
            seg[m] = nxt
            m += 1
            v = ends[nxt, 1] if ends[nxt, 0] == v else ends[nxt, 0]
            nodes[k] = v
            k += 1
        if cut[c] >= 0:                                 # the loop closes over its cut segment
            seg[m] = cut[c]
            m += 1
            nodes[k] = start[c]
            k += 1
    node_start[n_chains] = k
    return nodes[:k], node_start, seg[:m], closed


def resample(polyline: SlicePolyline, spacing: float) -> SurfaceSamples:
    """Resample a slice polyline at uniform arc length, keeping every point on the mesh.

    Parameters
    ----------
    polyline : SlicePolyline
    spacing : float
        Largest arc-length step, m; the step used is ``length / ceil(length / spacing)``.

    Returns
    -------
    SurfaceSamples
        ``ceil(length / spacing) + 1`` points from the first point to the last (both kept exactly),
        each interpolated along a slice segment and tagged with that segment's face, so it lies on
        the mesh; values are interpolated the same way.
    """
    if not (np.isfinite(spacing) and spacing > 0):
        raise InputError(f"resampling spacing must be positive and finite, got {spacing!r} m")
    p = polyline.points
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    length = cum[-1]
    n = max(int(np.ceil(length / spacing)), 1) + 1
    s = np.linspace(0.0, length, n)
    i = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.clip(np.where(seg[i] > 0, (s - cum[i]) / seg[i], 0.0), 0.0, 1.0)
    pts = p[i] + u[:, None] * (p[i + 1] - p[i])
    pts[0], pts[-1] = p[0], p[-1]
    vals = None
    if polyline.values is not None:
        w = polyline.values
        vals = w[i] + u[:, None] * (w[i + 1] - w[i])
        vals[0], vals[-1] = w[0], w[-1]
    return SurfaceSamples(pts, polyline.faces[i], vals)
