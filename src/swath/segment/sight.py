"""Line of sight: which triangles of a part a tool coming from a direction can see.

A triangle is *visible* from a direction ``d`` when the ray from its centroid along ``d`` leaves
the part without crossing another of its triangles.  The rays of one direction are parallel, so
the test is a 2-D one in the plane across ``d``: the ray of a point is blocked by a triangle whose
projection contains the point's projection and which lies farther along ``d`` at that spot.  The
triangles' projections are binned on a grid of about their own size, so each ray is tested only
against the few triangles over its cell (no ray-tracing library needed).
"""

from __future__ import annotations

import numpy as np

from ..surface import Surface

#: Largest number of (ray, triangle) pairs tested at once (memory bound).
PAIR_CHUNK = 2_000_000


def visible(surface: Surface, direction, which=None, *, tolerance: float | None = None,
            closed: bool = False) -> np.ndarray:
    """(m,) bool: triangles whose centroid's ray along ``direction`` meets no other triangle.

    The triangles' winding gives their outward side (``surface.face_normals``).

    Parameters
    ----------
    surface : Surface
        The part, m.
    direction : (3,) float
        The direction the tool comes from (the ray runs from the triangle toward it), part frame.
    which : (m,) bool, optional
        Test only these triangles (the others come out False); default all.
    tolerance : float, optional
        The ray starts this far (m) off the centroid along the triangle's normal, and a triangle
        less than this ahead of that start does not block it (default 1e-6 × the part's extent).
    closed : bool
        The surface is a closed solid wound outward: a triangle facing away from the ray is hidden
        (the ray runs into the material), and a ray from one facing it meets the part first where
        it enters the material, through a triangle facing against it, so only those are tested.

    Returns
    -------
    (m,) bool
    """
    d = np.asarray(direction, float)
    d = d / np.linalg.norm(d)
    V, F = surface.vertices, surface.faces
    m = len(F)
    which = np.ones(m, bool) if which is None else np.asarray(which, bool)
    out = np.zeros(m, bool)
    if closed:
        # a ray from a triangle facing away from it runs straight into the material
        which = which & (surface.face_normals @ (np.asarray(direction, float)) >= 0)
    queries = np.flatnonzero(which)
    if len(queries) == 0:
        return out
    extent = float(np.ptp(V, axis=0).max())
    tol = 1e-6 * extent if tolerance is None else float(tolerance)
    # coordinates across d (u, v) and along it (h)
    a = np.cross(d, np.eye(3)[int(np.argmin(np.abs(d)))])
    a /= np.linalg.norm(a)
    axes = np.array([a, np.cross(d, a)])
    uv = V @ axes.T                                     # (n, 2)
    h = V @ d                                           # (n,)
    tri_uv = uv[F]                                      # (m, 3, 2)
    tri_h = h[F]                                        # (m, 3)
    e1 = tri_uv[:, 1] - tri_uv[:, 0]
    e2 = tri_uv[:, 2] - tri_uv[:, 0]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]    # twice the projected signed area
    # an edge-on triangle blocks nothing its neighbours do not
    blocking = np.abs(det) > 1e-12 * extent ** 2
    if closed:
        blocking &= surface.face_normals @ d < 0
    blocking = np.flatnonzero(blocking)
    if len(blocking) == 0:
        out[queries] = True
        return out
    # the ray starts a tolerance off the triangle, along its normal: a face edge-on to the rays
    # is then not grazed by the neighbours it meets at an edge
    start_point = V[F[queries]].mean(axis=1) + tol * surface.face_normals[queries]
    q_uv = start_point @ axes.T
    q_h = start_point @ d

    lo = tri_uv[blocking].min(axis=1)
    hi = tri_uv[blocking].max(axis=1)
    origin = uv.min(axis=0)
    # cells about a triangle's projected size (slivers then span several), coarser while the
    # entries would exceed a budget
    cell = max(float(np.median(np.sqrt(np.abs(det[blocking])))), 1e-4 * extent, 1e-12)
    while True:                                         # coarser cells when big triangles span too many
        i0 = np.floor((lo - origin) / cell).astype(np.int64)
        i1 = np.floor((hi - origin) / cell).astype(np.int64)
        span = i1 - i0 + 1
        count = span[:, 0] * span[:, 1]
        if count.sum() <= 24 * len(blocking) + 1000:
            break
        cell *= 1.5
    width = int(np.floor((uv.max(axis=0) - origin)[1] / cell)) + 2
    # every (cell, triangle) entry of the triangles' bounding boxes
    tri_of_entry = np.repeat(np.arange(len(blocking)), count)
    k = np.arange(len(tri_of_entry)) - np.repeat(np.cumsum(count) - count, count)
    cu = i0[tri_of_entry, 0] + k // span[tri_of_entry, 1]
    cv = i0[tri_of_entry, 1] + k % span[tri_of_entry, 1]
    entry_cell = cu * width + cv
    order = np.argsort(entry_cell, kind="stable")
    entry_cell, entry_tri = entry_cell[order], blocking[tri_of_entry[order]]

    q_cell_uv = np.floor((q_uv - origin) / cell).astype(np.int64)
    q_cell = q_cell_uv[:, 0] * width + q_cell_uv[:, 1]
    start = np.searchsorted(entry_cell, q_cell, side="left")
    stop = np.searchsorted(entry_cell, q_cell, side="right")
    n_pairs = stop - start
    blocked = np.zeros(len(queries), bool)
    bounds = np.concatenate([[0], np.cumsum(n_pairs)])
    q_start = 0
    while q_start < len(queries):
        q_stop = int(np.searchsorted(bounds, bounds[q_start] + PAIR_CHUNK, side="right")) - 1
        q_stop = min(max(q_stop, q_start + 1), len(queries))
        sl = slice(q_start, q_stop)
        counts = n_pairs[sl]
        qi = np.repeat(np.arange(q_start, q_stop), counts)
        offset = np.arange(len(qi)) - np.repeat(np.cumsum(counts) - counts, counts)
        ti = entry_tri[np.repeat(start[sl], counts) + offset]
        keep = ti != queries[qi]
        qi, ti = qi[keep], ti[keep]
        p = q_uv[qi] - tri_uv[ti, 0]
        b1 = (p[:, 0] * e2[ti, 1] - p[:, 1] * e2[ti, 0]) / det[ti]
        b2 = (e1[ti, 0] * p[:, 1] - e1[ti, 1] * p[:, 0]) / det[ti]
        b0 = 1.0 - b1 - b2
        eps = -1e-9
        inside = (b0 >= eps) & (b1 >= eps) & (b2 >= eps)
        depth = b0 * tri_h[ti, 0] + b1 * tri_h[ti, 1] + b2 * tri_h[ti, 2]
        hit = inside & (depth > q_h[qi] + tol)
        blocked[np.unique(qi[hit])] = True
        q_start = q_stop
    out[queries] = ~blocked
    return out
