"""Passes that wrap around a closed part (a tube, a handle) about an axis, with no seam.

:func:`wrap` lays one continuous helix around the axis (``mode="helix"``, the default): a flat turn
at each end and a helix of pitch ``spacing`` between them, so the pad never lifts where a raster
would restart; or rings (``mode="rings"``), one closed pass per axial station, run alternately one
way round and the other (a positioner then never turns more than about a turn and a half).

Every path point is where a ray from outside, pointing at the axis, first meets the surface: the
outermost surface around the axis.  The pad is a flat disc tangent there, so a station is kept only
where no part of the surface within one pad radius along the axis stands proud of the pad face (a
flange next to a tube): the path stops one pad radius (and :data:`RIM_CLEARANCE`, 50 µm) short of
a taller neighbour, and the pad's rim runs along the foot of it.
"""

from __future__ import annotations

import math

import numpy as np

from ..core import Pass, ToolPath
from ..errors import InputError
from .common import log, positive

__all__ = ["wrap", "principal_axis"]

_MODES = ("helix", "rings")

#: How far the pad's rim stays from a taller neighbour (a flange), m: 50 µm, so that the pad never
#: reaches over the neighbour's face (under the contact model it would press it sideways); the foot
#: line itself is left to the neighbour's own finishing.
RIM_CLEARANCE = 5e-5


def principal_axis(vertices) -> tuple[np.ndarray, np.ndarray]:
    """The line of largest spread of ``vertices`` (n, 3): its centroid (3,) and unit direction (3,)."""
    v = np.asarray(vertices, dtype=float)
    c = v.mean(axis=0)
    _, _, vt = np.linalg.svd(v - c, full_matrices=False)
    d = vt[0] / np.linalg.norm(vt[0])
    return c, d if d[np.argmax(np.abs(d))] > 0 else -d


def _frame(direction) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (3,) orthogonal to ``direction`` and to each other (e1, e2 = a × e1)."""
    a = np.asarray(direction, dtype=float)
    ref = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = ref - np.dot(ref, a) * a
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(a, e1)


def _hits(surface, origin, axis, s, phi):
    """Outermost surface points at axial stations ``s`` (k,) and angles ``phi`` (k,) about the axis.

    The surface's outward-facing triangles are mapped to (axial position, angle about the axis) and
    binned on a grid; each query takes, among the triangles whose (s, φ) image contains it, the one
    farthest from the axis (what a ray from outside toward the axis meets first), and the point on
    that facet with the same barycentric coordinates.

    Returns ``points (k, 3)``, ``normals (k, 3)`` (toward the tool: a CAD part's exact normals of the
    facet's own face at its corners, else the vertex normals, interpolated) and
    ``ok (k,)`` (a hit whose normal faces away from the axis).
    """
    k = len(s)
    points = np.full((k, 3), np.nan)
    normals = np.full((k, 3), np.nan)
    tris = _triangles(surface, origin, axis)
    if tris is None:
        return points, normals, np.zeros(k, bool)
    ts, tphi, cell_start, cell_tris, ds, dphi, s0, n_s, n_phi, faces, face_index = tris
    phi = np.mod(phi, 2 * math.pi)
    i_s = np.clip(np.floor((s - s0) / ds).astype(int), 0, n_s - 1)
    i_p = np.floor(phi / dphi).astype(int) % n_phi
    cell = i_s * n_phi + i_p
    counts = cell_start[cell + 1] - cell_start[cell]
    q = np.repeat(np.arange(k), counts)
    offs = np.arange(len(q)) - np.repeat(np.cumsum(counts) - counts, counts)
    cand = cell_tris[np.repeat(cell_start[cell], counts) + offs]
    # the query's angle in the triangle's own unwrapped range
    pq = phi[q] + 2 * math.pi * np.round((tphi[cand, 0] - phi[q]) / (2 * math.pi))
    a = np.column_stack([ts[cand, 0], tphi[cand, 0]])
    e1 = np.column_stack([ts[cand, 1], tphi[cand, 1]]) - a
    e2 = np.column_stack([ts[cand, 2], tphi[cand, 2]]) - a
    d = np.column_stack([s[q], pq]) - a
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    det = np.where(np.abs(det) > 1e-300, det, np.nan)
    w1 = (d[:, 0] * e2[:, 1] - d[:, 1] * e2[:, 0]) / det
    w2 = (e1[:, 0] * d[:, 1] - e1[:, 1] * d[:, 0]) / det
    eps = 1e-9
    inside = (w1 >= -eps) & (w2 >= -eps) & (w1 + w2 <= 1 + eps)
    q, cand, w1, w2 = q[inside], cand[inside], w1[inside], w2[inside]
    v = np.asarray(surface.vertices)[faces[cand]]
    p3 = (1 - w1 - w2)[:, None] * v[:, 0] + w1[:, None] * v[:, 1] + w2[:, None] * v[:, 2]
    rel = p3 - origin
    rad = np.linalg.norm(rel - (rel @ axis)[:, None] * axis, axis=1)
    order = np.lexsort((-rad, q))              # per query, the farthest from the axis first
    first = np.ones(len(order), bool)
    first[1:] = q[order][1:] != q[order][:-1]
    pick = order[first]
    qq = q[pick]
    points[qq] = p3[pick]
    corner = getattr(surface, "corner_normals", None)          # a CAD part: each face's exact normal
    nv = corner[face_index[cand[pick]]] if corner is not None else np.asarray(surface.normals)[faces[cand[pick]]]
    w = np.column_stack([1 - w1[pick] - w2[pick], w1[pick], w2[pick]])
    n = np.einsum("ij,ijk->ik", w, nv)
    normals[qq] = n / np.linalg.norm(n, axis=1, keepdims=True)
    e_1, e_2 = _frame(axis)
    radial = np.cos(phi)[:, None] * e_1 + np.sin(phi)[:, None] * e_2
    ok = np.isfinite(points[:, 0]) & (np.einsum("ij,ij->i", np.nan_to_num(normals), radial) > _FACING)
    return points, normals, ok


def _triangles(surface, origin, axis):
    """The outward-facing triangles in (s, φ) and a grid of them (the last one cached)."""
    key = (tuple(np.round(origin, 12)), tuple(np.round(axis, 12)))
    if _CACHE and _CACHE[0] is surface and _CACHE[1] == key:
        return _CACHE[2]
    v = np.asarray(surface.vertices) - origin
    f = np.asarray(surface.faces)
    e1, e2 = _frame(axis)
    sv = v @ axis
    pv = np.arctan2(v @ e2, v @ e1)
    centre = v[f].mean(axis=1)
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-300)
    radial = centre - (centre @ axis)[:, None] * axis
    rnorm = np.linalg.norm(radial, axis=1)
    face_index = np.flatnonzero((np.einsum("ij,ij->i", fn, radial) > 0.05 * rnorm) & (rnorm > 0))
    faces = f[face_index]
    result = None
    if len(faces):
        ts = sv[faces]
        tphi = pv[faces]
        tphi = tphi[:, :1] + np.mod(tphi - tphi[:, :1] + math.pi, 2 * math.pi) - math.pi   # unwrapped per triangle
        size_s = float(np.median(np.ptp(ts, axis=1))) + 1e-9
        size_p = float(np.median(np.ptp(tphi, axis=1))) + 1e-9
        s0 = float(ts.min())
        n_s = max(1, int(math.ceil((ts.max() - s0) / (2 * size_s))))
        ds = (float(ts.max()) - s0) / n_s + 1e-12
        n_phi = max(1, min(2048, int(2 * math.pi / (2 * size_p))))
        dphi = 2 * math.pi / n_phi
        lo_s = np.clip(np.floor((ts.min(axis=1) - s0) / ds).astype(int), 0, n_s - 1)
        hi_s = np.clip(np.floor((ts.max(axis=1) - s0) / ds).astype(int), 0, n_s - 1)
        lo_p = np.floor(tphi.min(axis=1) / dphi).astype(int)
        hi_p = np.floor(tphi.max(axis=1) / dphi).astype(int)
        tri_ids, cells = [], []
        for j in range(int((hi_s - lo_s).max()) + 1):
            for i in range(min(n_phi, int((hi_p - lo_p).max()) + 1)):
                idx = np.flatnonzero((lo_s + j <= hi_s) & (lo_p + i <= hi_p))
                tri_ids.append(idx)
                cells.append((lo_s[idx] + j) * n_phi + (lo_p[idx] + i) % n_phi)
        tri_all, cell_all = np.concatenate(tri_ids), np.concatenate(cells)
        order = np.argsort(cell_all, kind="stable")
        cell_start = np.searchsorted(cell_all[order], np.arange(n_s * n_phi + 1))
        result = (ts, tphi, cell_start, tri_all[order], ds, dphi, s0, n_s, n_phi, faces, face_index)
    _CACHE[:] = [surface, key, result]
    return result


_CACHE: list = []

#: A path point's normal must be within 60° of the direction away from the axis (cos 60° = 0.5):
#: steeper skin (the rounded end of a handle, a chamfer) is left to the neighbouring turns.
_FACING = 0.5


def _band(surface, origin, axis, pad_radius, tolerance, n_angles=24):
    """The longest axial range where the pad, a flat disc tangent to the outermost surface all round,
    has no surface standing proud of its face within its radius: ``(s_lo, s_hi, radius, open_lo,
    open_hi)`` (m; ``radius`` the median distance of the skin from the axis; ``open_*`` True where the
    range ends with the surface rather than at a taller neighbour)."""
    v = np.asarray(surface.vertices, dtype=float)
    s_v = (v - origin) @ axis
    order = np.argsort(s_v)
    v_sorted, s_sorted = v[order], s_v[order]
    lo, hi = float(s_v.min()), float(s_v.max())
    phi = np.linspace(0, 2 * math.pi, n_angles, endpoint=False)

    def fit(s_i: float) -> int:
        """0: the pad fits all round at station ``s_i`` (every angle has a skin facing out, and no vertex
        within one pad radius of the contact, in the pad's plane, stands more than ``tolerance`` proud of
        it); 1: some angle has no skin facing out (the part ends); 2: a neighbour stands proud."""
        pts, nrm, ok = _hits(surface, origin, axis, np.full(n_angles, s_i), phi)
        if not ok.all():
            return 1
        a, b = np.searchsorted(s_sorted, [s_i - pad_radius, s_i + pad_radius])
        near = v_sorted[a:b]
        if not len(near):
            return 0
        rel = near[None, :, :] - pts[:, None, :]                     # (angles, m, 3)
        h = np.einsum("amk,ak->am", rel, nrm)                         # height above the pad face
        d2 = np.einsum("amk,amk->am", rel, rel) - h * h               # squared distance in the pad plane
        return 2 if np.any((h > tolerance) & (d2 < pad_radius * pad_radius)) else 0

    # stations an eighth of a pad radius apart: a proud neighbour is seen from several (the ends are refined)
    s = np.linspace(lo, hi, int(min(400, max(8, math.ceil((hi - lo) / (pad_radius / 8))))) + 1)
    why = np.array([fit(si) for si in s])
    admissible = why == 0
    if not admissible.any():
        raise InputError("the wrap planner found no axial station where the pad can go all round the part: the "
                         "surface is not closed about the axis, or a taller neighbour is within one pad radius "
                         "everywhere; give the axis (axis=(point, direction)) or plan with another planner")
    runs, start = [], None
    for i, a in enumerate(np.append(admissible, False)):
        if a and start is None:
            start = i
        elif not a and start is not None:
            runs.append((start, i - 1))
            start = None
    i0, i1 = max(runs, key=lambda r: s[r[1]] - s[r[0]])

    def edge(inside: float, outside: float) -> float:
        """The admissible station nearest ``outside``, by bisection (to 10 µm), moved RIM_CLEARANCE inward."""
        while abs(outside - inside) > 1e-5:
            mid = 0.5 * (inside + outside)
            inside, outside = (mid, outside) if fit(mid) == 0 else (inside, mid)
        return inside + math.copysign(RIM_CLEARANCE, inside - outside)

    open_lo = i0 == 0 or why[i0 - 1] == 1
    open_hi = i1 == len(s) - 1 or why[i1 + 1] == 1
    s_lo = s[i0] if i0 == 0 else edge(s[i0], s[i0 - 1])
    s_hi = s[i1] if i1 == len(s) - 1 else edge(s[i1], s[i1 + 1])
    mid_pts, _, mid_ok = _hits(surface, origin, axis, np.repeat(s[i0:i1 + 1], n_angles),
                               np.tile(phi, i1 - i0 + 1))
    rel = mid_pts[mid_ok] - origin
    radius = float(np.median(np.linalg.norm(rel - (rel @ axis)[:, None] * axis, axis=1)))
    return s_lo, s_hi, radius, bool(open_lo), bool(open_hi)


def wrap(surface, tool, *, spacing: float | None = None, axis=None, mode: str = "helix",
         point_spacing: float = 1e-3, around=None, progress=None) -> ToolPath:
    """Cover a closed part all round its axis with a continuous helix (or rings).

    Parameters
    ----------
    surface : Surface
        The part (normals toward the tool, i.e. out of the solid).
    tool : Tool
        The pad: its radius sets the clearance to taller neighbours and, with the contact model, the
        default spacing.
    spacing : float, optional
        Helix pitch or ring spacing along the axis, m.  Default: the largest equal spacing of planes
        normal to the axis that covers the band under the contact model
        (:func:`swath.contact.widths.raster_spacing`, as the raster planner chooses it), made to fit
        the band in whole turns.
    axis : (point (3,), direction (3,)), optional
        The axis in the part frame, m.  Default: the line of largest spread of the vertices
        (:func:`principal_axis`); a positioner's axis in the part frame when planned for one.
    mode : str
        ``helix`` (one continuous pass) or ``rings`` (one closed pass per station, alternating).
    point_spacing : float
        Arc-length step between pass points, m (default 1 mm).
    around : Surface, optional
        The whole part ``surface`` belongs to (the same frame): the band the pad can go round and its
        clearance to taller neighbours are found on it, so a flange that is not to be finished still
        keeps the pad off.  Default: ``surface``.
    progress : callable, optional
        ``progress(stage, done, total)``.

    Returns
    -------
    ToolPath
        ``planner="wrap"``; metadata ``axis_point_m``, ``axis_direction``, ``spacing_m``,
        ``band_m`` (axial range of the pad centre), ``radius_m`` (median outer radius), ``mode``,
        ``n_turns``.
    """
    if mode not in _MODES:
        raise InputError(f"wrap mode must be one of {', '.join(_MODES)}, got {mode!r}")
    point_spacing = positive("point_spacing", point_spacing)
    if axis is None:
        origin, direction = principal_axis((surface if around is None else around).vertices)
    else:
        try:
            origin, direction = (np.asarray(a, dtype=float).reshape(3) for a in axis)
        except (TypeError, ValueError):
            raise InputError(f"axis must be (point, direction), each three numbers in the part frame, got {axis!r}") \
                from None
        if not (np.isfinite(origin).all() and np.isfinite(direction).all() and np.linalg.norm(direction) > 0):
            raise InputError(f"axis must be a finite point and a non-zero direction, got {axis!r}")
        direction = direction / np.linalg.norm(direction)
    say = progress or (lambda stage, done, total: None)
    say("wrap: finding the band the pad can go round", 0, 1)
    tol = max(2.0 * tool.flat_depression, 5e-4)
    whole = surface if around is None else around
    s_lo, s_hi, radius, open_lo, open_hi = _band(whole, origin, direction, tool.pad_radius, tol)
    if spacing is None:
        from ..contact.widths import raster_spacing

        spacing = raster_spacing(_band_surface(surface, origin, direction, s_lo, s_hi), tool, direction).spacing
    spacing = positive("spacing", spacing)
    # pad centres: a quarter spacing in from an open end (the pad overhangs it), at the band's end
    # beside a taller neighbour (one pad radius from it); no further apart than the spacing
    inset = min(0.25 * spacing, 0.25 * (s_hi - s_lo))
    a, b = s_lo + (inset if open_lo else 0.0), s_hi - (inset if open_hi else 0.0)
    n_gaps = max(1, math.ceil((b - a) / spacing - 1e-9))
    pitch = (b - a) / n_gaps
    per_turn = max(36, math.ceil(2 * math.pi * radius / point_spacing))
    passes = []
    if mode == "helix":
        # a flat turn, n_gaps turns of helix, a flat turn: one continuous curve
        u = np.arange((n_gaps + 2) * per_turn + 1) / per_turn          # turns done
        s = np.clip(a + (u - 1.0) * pitch, a, b)
        phi = 2 * math.pi * u
        segs = [(s, phi, 0)]
    else:
        segs = []
        for i in range(n_gaps + 1):
            u = np.arange(per_turn + 1) / per_turn
            sign = 1 if i % 2 == 0 else -1
            segs.append((np.full(len(u), a + i * pitch), sign * 2 * math.pi * u, i))
    for s, phi, level in segs:
        pts, nrm, ok = _hits(surface, origin, direction, s, phi)
        for lo, hi in _ok_runs(ok):
            if hi - lo >= 2:
                passes.append(Pass(points=pts[lo:hi], normals=nrm[lo:hi], level=level))
    if not passes:
        raise InputError("the wrap planner found no surface around the axis; check the axis and the part")
    n_missed = sum(len(s) for s, _, _ in segs) - sum(len(p.points) for p in passes)
    if n_missed:
        log.warning("wrap: %d path points found no outward surface around the axis; the path is split there "
                    "[W-WRAP-SPLIT]", n_missed)
    say("wrap: done", 1, 1)
    meta = {"axis_point_m": [float(v) for v in origin], "axis_direction": [float(v) for v in direction],
            "spacing_m": float(pitch), "band_m": [float(a), float(b)], "radius_m": radius, "mode": mode,
            "n_turns": float(n_gaps + 2 if mode == "helix" else n_gaps + 1)}
    return ToolPath(surface=surface, passes=tuple(passes), planner="wrap", metadata=meta)


def _band_surface(surface, origin, axis, s_lo, s_hi):
    """The triangles of ``surface`` in the band (centroid between ``s_lo`` and ``s_hi`` along the axis)
    whose normal is within 45° of the radial direction: what the default spacing is chosen on."""
    c = np.asarray(surface.vertices)[np.asarray(surface.faces)].mean(axis=1) - origin
    sc = c @ axis
    radial = c - sc[:, None] * axis
    radial /= np.maximum(np.linalg.norm(radial, axis=1, keepdims=True), 1e-300)
    keep = (sc >= s_lo) & (sc <= s_hi) & (np.einsum("ij,ij->i", surface.face_normals, radial) > math.sqrt(0.5))
    return surface.sub_surface(np.flatnonzero(keep)) if keep.sum() >= 8 else surface


def _ok_runs(ok) -> list[tuple[int, int]]:
    """``[start, stop)`` runs of True in ``ok``."""
    edges = np.diff(np.concatenate([[0], ok.astype(int), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)))
