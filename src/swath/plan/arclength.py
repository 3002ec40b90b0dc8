"""Equidistant passes on a B-spline patch by arc-length parameterisation (Amersdorfer & Meurer).

On a parametric patch ``S(u, v)`` iso-parametric passes ``v = const`` are not equidistant: the
distance between ``v`` and ``v + Δv`` is ``∫ sqrt(G) dv``, which varies along the pass and from pass
to pass.  The method replaces the parameters by arc lengths:

* ``a`` is the parameter the passes run along (``u`` or ``v``), ``b`` the other one;
* ``τ(a, b) = ∫_{b0}^{b} |S_b(a, β)| dβ`` — arc length along the ``b`` iso-curve through ``a``
  (the first fundamental form integrated along the iso-line: ``|S_b| = sqrt(G)`` for ``b = v``);
* ``σ(a) = ∫_{a0}^{a} |S_a(α, b_mid)| dα`` — arc length along the middle ``a`` iso-curve, so that
  the ``(σ, τ)`` domain has the part's proportions in metres.

Both integrals are tabulated with Gauss–Legendre quadrature on every knot span (cut into equal
sub-intervals); the inverse maps ``a(σ)`` and ``b(a, τ)`` are cubic-spline interpolants of the
tables with the roles of abscissa and ordinate swapped (*inverse interpolation*, scipy
``CubicSpline`` per iso-curve, then a bicubic spline across them).  The region to cover — the
patch's own boundary, or a polygon the user gives in part coordinates (projected onto the patch
with :meth:`BSplinePatch.project`) — is mapped into ``(σ, τ)`` and clipped with shapely; the
passes are the lines ``τ = τ_min + (k + ½) d`` inside it, which are exactly ``d`` apart measured
along every ``b`` iso-curve whatever the curvature; they are mapped back to parameters and
evaluated exactly on the patch.  Consecutive passes are joined by *interconnection paths* that run
along the region's boundary between the end of one line and the start of the next (the paper's
zig-zag coverage path), when that boundary arc is short.

Where the ``b`` iso-curves cross the passes at right angles and are geodesics (a cylinder, any
surface of revolution or extrusion with ``b`` along the generator's profile) the passes are also
geodesically equidistant; elsewhere ``d`` is the distance along the iso-curves.
"""

from __future__ import annotations

import logging
import math
import time

import numpy as np

from ..contact.widths import SPACING_PERCENTILE, area_percentile, patch_widths
from ..core import Pass, ToolPath
from ..errors import InfeasibleError, InputError
from ..surface.curvature import PrincipalCurvature
from .arclength_map import ArcLengthMap
from .common import MIN_PASS_FRACTION
from .common import is_number as _is_number
from .common import positive as _positive

log = logging.getLogger("swath.plan")

#: A boundary point farther than this from the patch after projection is refused (m).
BOUNDARY_TOLERANCE = 5e-3


# ----------------------------------------------------------------------------------------------
# the planner
# ----------------------------------------------------------------------------------------------
def equidistant_patch(patch, tool, *, spacing: float | None = None, boundary=None, along: str = "auto",
                      point_spacing: float = 1e-3, min_pass_length: float | None = None, connect: bool = True,
                      max_link: float | None = None, surface_spacing: float | None = None) -> ToolPath:
    """Equidistant passes on a B-spline patch by arc-length parameterisation, joined into a zig-zag.

    Parameters
    ----------
    patch : BSplinePatch
        The part; its normal side (``S_u × S_v``) is the tool side.
    tool : Tool
    spacing : float, optional
        Distance between neighbouring passes along the cross iso-curves, m.  Default: the
        full-coverage spacing — the 0.2 % area-percentile of the contact chord across the pass
        direction, from the local contact model with the patch's exact curvature on a 60 × 60
        parameter grid inside the region.
    boundary : (k, 3) float, optional
        Closed polygon in the part frame (m; the last point need not repeat the first) bounding
        the region to cover.  It is densified, projected onto the patch, mapped to ``(σ, τ)`` and
        intersected with the patch.  Default: the whole patch.
    along : {"auto", "u", "v"}
        The parameter the passes run along; ``auto`` takes the direction whose middle iso-curve
        is longer (fewer, longer passes, like raster's feed along the largest spread).
    point_spacing : float
        Arc-length step between pass points, m.
    min_pass_length : float, optional
        Clipped lines shorter than this (m) are dropped; default ``R/4``.
    connect : bool
        Join consecutive lines into one pass by an interconnection path along the region's
        boundary, when the boundary arc between them is at most ``max_link``.
    max_link : float, optional
        Longest interconnection path in ``(σ, τ)``, m; default ``3 × spacing``.
    surface_spacing : float, optional
        Vertex spacing of the triangulated surface the tool path refers to, m (default: the
        patch's :meth:`~BSplinePatch.to_surface` default).

    Returns
    -------
    ToolPath
        Planner ``"equidistant"`` on ``patch.to_surface(...)``; points exactly on the patch,
        normals the patch's exact unit normals.  ``metadata``: spacing_m, spacing_rule,
        predicted_gap_fraction (default spacing), method ``"arc-length"``, along, n_lines,
        line_tau_m, n_passes, n_links, link_length_m, dropped_fragments, dropped_length_m,
        point_spacing_m, min_pass_length_m, region_area_m2 (in ``(σ, τ)``), and, without
        ``connect`` (unconnected lines carry their line index as ``Pass.level``).

    Raises
    ------
    InputError
        On bad numbers, a boundary that is not a (k >= 3, 3) polygon on the patch, or one that
        does not overlap it.
    InfeasibleError
        When no line inside the region is long enough.
    """
    import shapely
    from shapely.geometry import LineString, Polygon

    t_start = time.perf_counter()
    point_spacing = _positive("point_spacing", point_spacing)
    if spacing is not None:
        spacing = _positive("spacing", spacing)
    R = tool.pad_radius
    if min_pass_length is None:
        min_pass_length = MIN_PASS_FRACTION * R
    elif not (_is_number(min_pass_length) and math.isfinite(min_pass_length) and min_pass_length >= 0):
        raise InputError(f"min_pass_length must be a finite length >= 0 m, got {min_pass_length!r}")
    if along not in ("auto", "u", "v"):
        raise InputError(f"along must be 'auto', 'u' or 'v', got {along!r}")
    if along == "auto":
        along = _longer_direction(patch)
    amap = ArcLengthMap(patch, along=along)

    # --- region in (σ, τ) ---------------------------------------------------------------------
    region = Polygon(amap.domain_polygon())
    if boundary is not None:
        poly = _boundary_polygon(amap, boundary, point_spacing)
        region = region.intersection(poly)
        if region.is_empty or region.area <= 0:
            raise InputError("the boundary polygon does not overlap the patch")
        if region.geom_type == "MultiPolygon":
            region = max(region.geoms, key=lambda g: g.area)
            log.warning("equidistant_patch: the boundary cuts the patch into several regions; planning the largest")
    region = shapely.make_valid(region) if not region.is_valid else region

    gap = None
    if spacing is None:
        spacing, gap, rule = _patch_spacing(amap, region, tool)
    else:
        rule = "given"
    if max_link is None:
        max_link = 3.0 * spacing
    _, tau_lo, _, tau_hi = region.bounds
    n_lines = max(int(math.ceil((tau_hi - tau_lo) / spacing - 0.5)), 0)
    if n_lines > 20000:
        raise InputError(f"spacing {spacing * 1e3:.4g} mm would need {n_lines} lines; is the spacing in metres?")
    taus = tau_lo + spacing * (np.arange(n_lines) + 0.5)

    # --- clip lines, map to 3D ----------------------------------------------------------------
    s_lo, _, s_hi, _ = region.bounds
    pieces: list[tuple] = []             # (line index, σ start, σ end) in travel order
    for k, tau in enumerate(taus):
        cut = region.intersection(LineString([(s_lo - 1.0, tau), (s_hi + 1.0, tau)]))
        segs = [g for g in getattr(cut, "geoms", [cut]) if g.geom_type == "LineString" and g.length > 0]
        ivals = sorted((min(g.coords[0][0], g.coords[-1][0]), max(g.coords[0][0], g.coords[-1][0])) for g in segs)
        if k % 2 == 1:
            ivals = [(b, a) for a, b in ivals[::-1]]
        pieces.extend((k, a, b) for a, b in ivals)
    # Ends on the patch's far edge τ = L(a): the polygon there is a chain of chords; put them on the edge.
    if pieces:
        ends = np.array([[a, b] for _, a, b in pieces])
        tk = taus[[k for k, _, _ in pieces]]
        for j in (0, 1):
            miss = amap.tau_length(amap.a_of_sigma(ends[:, j])) - tk
            near = np.abs(miss) < 1e-4 * max(spacing, 1e-3)
            if near.any():
                ends[near, j] = amap.top_crossing(ends[near, j], tk[near])
        pieces = [(k, float(e[0]), float(e[1])) for (k, _, _), e in zip(pieces, ends)]
    mapped, dropped, dropped_length = [], 0, 0.0
    for k, a, b in pieces:
        pts, nrm = _map_polyline(amap, np.array([[a, taus[k]], [b, taus[k]]]), point_spacing)
        length = float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())
        if length < min_pass_length or len(pts) < 2:
            dropped += 1
            dropped_length += length
            continue
        mapped.append((k, np.array([a, taus[k]]), np.array([b, taus[k]]), pts, nrm))
    if not mapped:
        raise InfeasibleError(f"equidistant_patch found no line longer than min_pass_length={min_pass_length * 1e3:.1f} mm "
                              f"at spacing {spacing * 1e3:.1f} mm; lower the spacing or min_pass_length")

    # --- interconnection paths ------------------------------------------------------------------
    rings = [np.asarray(region.exterior.coords)] + [np.asarray(r.coords) for r in region.interiors]
    passes = []
    cur_pts, cur_nrm = [mapped[0][3]], [mapped[0][4]]
    n_links, link_length = 0, 0.0
    for prev, nxt in zip(mapped[:-1], mapped[1:]):
        link = None
        if connect and nxt[0] == prev[0] + 1:
            link = _boundary_arc(rings, prev[2], nxt[1], max_link)
        if link is not None:
            lp, ln = _map_polyline(amap, link, point_spacing)
            cur_pts += [lp[1:], nxt[3][1:]]
            cur_nrm += [ln[1:], nxt[4][1:]]
            n_links += 1
            link_length += float(np.linalg.norm(np.diff(lp, axis=0), axis=1).sum())
        else:
            passes.append(Pass(np.concatenate(cur_pts), np.concatenate(cur_nrm), level=-1 if connect else prev[0]))
            cur_pts, cur_nrm = [nxt[3]], [nxt[4]]
    passes.append(Pass(np.concatenate(cur_pts), np.concatenate(cur_nrm), level=-1 if connect else mapped[-1][0]))

    surface = patch.to_surface(spacing=surface_spacing)
    metadata = dict(
        spacing_m=float(spacing), spacing_rule=rule, method="arc-length", along=along, n_lines=int(n_lines),
        line_tau_m=[float(t) for t in taus], n_passes=len(passes), n_links=int(n_links),
        link_length_m=float(link_length), dropped_fragments=int(dropped), dropped_length_m=float(dropped_length),
        point_spacing_m=float(point_spacing), min_pass_length_m=float(min_pass_length),
        region_area_m2=float(region.area),
        order_hint="index",   # lines alternate and boundary arcs join them: the method's own order
    )
    if gap is not None:
        metadata["predicted_gap_fraction"] = float(gap)
    log.info("equidistant_patch %s: along %s, spacing %.1f mm, %d lines, %d passes, %d links, %.2f s", patch.name,
             along, spacing * 1e3, n_lines, len(passes), n_links, time.perf_counter() - t_start)
    return ToolPath(surface, tuple(passes), "equidistant", metadata)


def _longer_direction(patch) -> str:
    """``"u"`` when the middle u iso-curve is at least as long as the middle v iso-curve."""
    (u0, u1), (v0, v1) = patch.domain
    t = np.linspace(0.0, 1.0, 201)
    pu = patch.evaluate(u0 + t * (u1 - u0), np.full(t.shape, 0.5 * (v0 + v1)))
    pv = patch.evaluate(np.full(t.shape, 0.5 * (u0 + u1)), v0 + t * (v1 - v0))
    lu = np.linalg.norm(np.diff(pu, axis=0), axis=1).sum()
    lv = np.linalg.norm(np.diff(pv, axis=0), axis=1).sum()
    return "u" if lu >= lv else "v"


def _boundary_polygon(amap: ArcLengthMap, boundary, step: float):
    """A user polygon (part frame) projected onto the patch and mapped to ``(σ, τ)``."""
    from shapely.geometry import Polygon

    P = np.asarray(boundary, float)
    if P.ndim != 2 or P.shape[1] != 3 or len(P) < 3 or not np.isfinite(P).all():
        raise InputError(f"boundary must be a finite (k >= 3, 3) polygon in metres, got shape {P.shape}")
    if np.linalg.norm(P[0] - P[-1]) > 0:
        P = np.vstack([P, P[:1]])
    seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
    n = np.maximum(np.ceil(seg / max(5 * step, 2e-3)).astype(int), 1)
    t = np.concatenate([np.arange(k) / k for k in n])
    i = np.repeat(np.arange(len(seg)), n)
    dense = P[i] + t[:, None] * (P[i + 1] - P[i])
    u, v, dist = amap.patch.project(dense)
    if dist.max() > BOUNDARY_TOLERANCE:
        j = int(np.argmax(dist))
        raise InputError(f"boundary point {dense[j].round(4).tolist()} is {dist[j] * 1e3:.1f} mm from the patch "
                         f"(limit {BOUNDARY_TOLERANCE * 1e3:.0f} mm); give the boundary on the part surface")
    s, tau = amap.from_parameters(u, v)
    poly = Polygon(np.stack([s, tau], 1))
    if not poly.is_valid:
        poly = poly.buffer(0)
    if poly.is_empty or poly.area <= 0:
        raise InputError("the boundary polygon encloses no area on the patch")
    return poly


def _map_polyline(amap: ArcLengthMap, st: np.ndarray, point_spacing: float):
    """Points ``(k, 3)`` and normals on the patch along a polyline ``(j, 2)`` in ``(σ, τ)``,
    uniform in 3D arc length with steps ``≤ point_spacing``, ends exact."""
    seg = np.linalg.norm(np.diff(st, axis=0), axis=1)
    lam = np.concatenate([[0.0], np.cumsum(seg)])
    if lam[-1] <= 0:
        u, v = amap.to_parameters(st[:1, 0], st[:1, 1])
        return amap.patch.evaluate(u, v), amap.patch.normals(u, v)

    def at(x):
        return np.interp(x, lam, st[:, 0]), np.interp(x, lam, st[:, 1])

    # Dense pass to measure the 3D length, then uniform 3D steps.
    n0 = max(int(math.ceil(lam[-1] / (0.25 * point_spacing))), 8) + 1
    x0 = np.linspace(0.0, lam[-1], n0)
    x0 = np.union1d(x0, lam)
    p0 = amap.patch.evaluate(*amap.to_parameters(*at(x0)))
    c0 = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p0, axis=0), axis=1))])
    n = max(int(math.ceil(c0[-1] * 1.002 / point_spacing)), 1) + 1
    x = np.interp(np.linspace(0.0, c0[-1], n), c0, x0)
    x[0], x[-1] = 0.0, lam[-1]
    u, v = amap.to_parameters(*at(x))
    return amap.patch.evaluate(u, v), amap.patch.normals(u, v)


def _boundary_arc(rings, start, end, max_length):
    """The shorter arc of the ring holding both ``start`` and ``end`` ``(2,)`` (in ``(σ, τ)``),
    as a polyline ``(j, 2)`` from ``start`` to ``end``; None when they are on no common ring or
    the arc is longer than ``max_length``."""
    best = None
    for ring in rings:
        seg = np.linalg.norm(np.diff(ring, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        total = cum[-1]
        pos, ok = [], True
        for q in (start, end):
            d, t = _project_on_ring(ring, q)
            if d > 1e-7 * max(total, 1.0):
                ok = False
                break
            pos.append(t)
        if not ok:
            continue
        fwd = (pos[1] - pos[0]) % total
        length = min(fwd, total - fwd)
        if length > max_length:
            continue
        if best is None or length < best[0]:
            best = (length, ring, cum, pos, fwd <= total - fwd)
    if best is None:
        return None
    _, ring, cum, (p0, p1), forward = best
    total = cum[-1]
    if forward:
        inner = (cum[:-1] - p0) % total
        mask = (inner > 0) & (inner < (p1 - p0) % total)
        idx = np.flatnonzero(mask)[np.argsort(inner[mask])]
    else:
        inner = (p0 - cum[:-1]) % total
        mask = (inner > 0) & (inner < (p0 - p1) % total)
        idx = np.flatnonzero(mask)[np.argsort(inner[mask])]
    return np.vstack([start, ring[idx], end])


def _project_on_ring(ring, q):
    """Distance from ``q`` to a closed polyline ``ring`` ``(j, 2)`` and the arc position of the foot."""
    a, b = ring[:-1], ring[1:]
    ab = b - a
    L2 = np.einsum("ij,ij->i", ab, ab)
    t = np.clip(np.divide(np.einsum("ij,ij->i", q - a, ab), L2, out=np.zeros(len(a)), where=L2 > 0), 0.0, 1.0)
    foot = a + t[:, None] * ab
    d = np.linalg.norm(foot - q, axis=1)
    i = int(np.argmin(d))
    cum = np.concatenate([[0.0], np.cumsum(np.sqrt(L2))])
    return float(d[i]), float(cum[i] + t[i] * np.sqrt(L2[i]))


def _patch_spacing(amap: ArcLengthMap, region, tool, *, n: int = 60):
    """Default spacing on a patch: contact chord across the line direction at grid samples inside
    the region, 0.2 % area-percentile.  Returns (spacing, predicted gap, rule)."""
    import shapely

    a = np.linspace(*amap.a_range, n)
    b = np.linspace(*amap.b_range, n)
    A, B = (g.ravel() for g in np.meshgrid(a, b, indexing="ij"))
    u, v = amap.uv(A, B)
    s, t = amap.from_parameters(u, v)
    inside = shapely.contains_xy(region, s, t) | shapely.intersects_xy(region.boundary, s, t)
    if inside.sum() < 4:
        inside[:] = True
    A, B, u, v = A[inside], B[inside], u[inside], v[inside]
    patch = amap.patch
    D = patch.derivatives(u, v, 2)
    Sa, Sb = (D[:, 1, 0], D[:, 0, 1]) if amap.along == "u" else (D[:, 0, 1], D[:, 1, 0])
    # Tangent of the line τ = const: S_a + S_b db/da with db/da = −τ_a / τ_b, τ_b = |S_b|.
    tau_a = amap.tau_derivative_a(u, v)
    tangent = Sa - (tau_a / np.linalg.norm(Sb, axis=1))[:, None] * Sb
    from ..surface.bspline import principal_from_derivatives

    curv = principal_from_derivatives(D)
    normals = np.cross(D[:, 1, 0], D[:, 0, 1])
    dA = np.linalg.norm(normals, axis=1)
    normals = normals / dA[:, None]
    # Sample areas: the parameter cell of each grid node (halved on the domain edges).
    wa = np.full(n, (a[-1] - a[0]) / (n - 1))
    wa[[0, -1]] *= 0.5
    wb = np.full(n, (b[-1] - b[0]) / (n - 1))
    wb[[0, -1]] *= 0.5
    areas = (np.outer(wa, wb).ravel()[inside]) * dA
    w = patch_widths(PrincipalCurvature(curv.k1, curv.k2, curv.d1, curv.d2), normals, tangent, tool)
    d = area_percentile(w, areas, SPACING_PERCENTILE)
    gap = float(np.sum(areas * np.clip(1.0 - w / d, 0.0, None)) / areas.sum())
    rule = (f"{SPACING_PERCENTILE:.1%} area-percentile of the contact chord across the line direction, local contact "
            f"model with the patch's exact curvature at {int(inside.sum())} grid samples (narrowest chord "
            f"{w.min() * 1e3:.1f} mm, predicted gap {gap:.2%})")
    return float(d), gap, rule
