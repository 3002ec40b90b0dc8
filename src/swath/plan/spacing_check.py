"""Measure how far apart a plan's passes really are along the surface: the geodesic distance from every pass point to the passes of the next level (any planner's output on a mesh)."""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..surface.geodesic import distance_field, locate_points, refine_mesh
from .seeds import polyline_band

log = logging.getLogger(__name__)


# ----------------------------------------------------------------------------------------------
# measuring the spacing of any tool path
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PassSpacing:
    """Geodesic distances between neighbouring passes of a tool path.

    Attributes
    ----------
    pairs : list of (int, int, (k,) float)
        ``(component, level, gaps)``: for every point of the passes at ``level``, its geodesic
        distance (m) to the passes at ``level + 1`` of the same piece.
    mean : float
        Mean of all gaps, m.
    spread : float
        ``(max − min) / mean`` over all gaps (0 = perfectly equidistant).
    pair_spread : (p,) float
        The same per neighbouring pair.
    percentiles : (3,) float
        5th, 50th and 95th percentile of all gaps, m.
    robust_spread : float
        ``(P95 − P5) / P50``: the spread without the few points (pass ends at ragged edges,
        next to dropped fragments or holes) whose neighbour level has no pass beside them.
    method : str
        Distance solver used.
    """

    pairs: list
    mean: float
    spread: float
    pair_spread: np.ndarray
    percentiles: np.ndarray
    robust_spread: float
    method: str


def pass_levels(toolpath) -> tuple[np.ndarray, np.ndarray]:
    """(component, level) of each pass: from the passes' own ``region`` and ``level``, from the plane
    offsets of a raster plan, otherwise the pass order (one level per pass)."""
    n = len(toolpath.passes)
    md = toolpath.metadata
    if n and all(p.level >= 0 for p in toolpath.passes):
        return toolpath.regions, toolpath.levels
    if toolpath.planner == "raster" and "cross_direction" in md and "spacing_m" in md:
        c = np.asarray(md["cross_direction"], float)
        off = np.array([float(np.mean(p.points @ c)) for p in toolpath.passes])
        return np.zeros(n, int), np.round((off - off.min()) / md["spacing_m"]).astype(int)
    return np.zeros(n, int), np.arange(n)


def pass_spacing(toolpath, *, max_edge: float = 3e-3, trim: float = 0.0, method: str = "fmm") -> PassSpacing:
    """Measure the geodesic distance from every pass point to the passes of the next level
    (a level pulled in to a far edge, ``metadata["pulled_in"]``, is not measured against).

    Parameters
    ----------
    toolpath : ToolPath
        Any plan on a mesh; levels come from :func:`pass_levels`.
    max_edge : float
        The surface is refined to this edge length (m) for the distance solves (fast-marching
        error is about a tenth of it on smooth parts).
    trim : float
        Points within this arc length (m) of either end of a pass are not measured.
    method : {"fmm", "heat"}

    Returns
    -------
    PassSpacing
    """
    surface = toolpath.surface
    V, F, _, _ = refine_mesh(surface.vertices, surface.faces, max_edge)
    from scipy.spatial import cKDTree

    tree = cKDTree(V[F].mean(axis=1))
    vtree = cKDTree(V)
    solver = None
    if method == "fmm":
        import potpourri3d as pp3d

        try:
            solver = pp3d.MeshFastMarchingDistanceSolver(V, F)
        except RuntimeError:
            solver = None
    comps, levels = pass_levels(toolpath)
    keys: dict[tuple[int, int], list[int]] = {}
    for i, (c, lv) in enumerate(zip(comps, levels)):
        keys.setdefault((int(c), int(lv)), []).append(i)
    pairs, used = [], set()
    pulled = {tuple(k) for k in toolpath.metadata.get("pulled_in", [])}
    for (c, lv), idx in sorted(keys.items()):
        nxt = keys.get((c, lv + 1))
        if not nxt or (c, lv + 1) in pulled:        # a pulled-in last level is closer on purpose
            continue
        band, band_d = polyline_band(V, [toolpath.passes[i].points for i in nxt], 1.5 * max_edge, tree=vtree)
        d, m = distance_field(V, F, source_vertices=band, source_distances=band_d, method=method, solver=solver)
        used.add(m)
        parts = []
        for i in idx:
            p = toolpath.passes[i].points
            if trim > 0:
                s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
                p = p[(s >= trim) & (s <= s[-1] - trim)]
            parts.append(p)
        pts = np.concatenate(parts)
        if len(pts) == 0:
            continue
        f, b, _ = locate_points(V, F, pts, tree=tree)
        pairs.append((c, lv, np.einsum("ij,ij->i", d[F[f]], b)))
    if not pairs:
        raise InputError("the tool path has no neighbouring passes to measure")
    allg = np.concatenate([g for _, _, g in pairs])
    mean = float(allg.mean())
    pair_spread = np.array([float(np.ptp(g) / g.mean()) for _, _, g in pairs])
    pct = np.percentile(allg, [5, 50, 95])
    return PassSpacing(pairs, mean, float(np.ptp(allg) / mean), pair_spread, pct, float((pct[2] - pct[0]) / pct[1]),
                       "+".join(sorted(used)))
