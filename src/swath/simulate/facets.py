"""How much of a removal's unevenness sits on the mesh's facet kinks.

On a coarse tessellation the pad's pressure collects on the kinks between flat facets
(:mod:`swath.contact.tessellation`).  :func:`ridge_profile` reads a simulated removal against the
distance of each interior sample to the nearest *marked* kink (an edge whose kink height is at
least ``min_ratio`` of the depression), convex and concave kinks apart: the mean depth in distance
bins over the interior mean, and the CoV of the samples near the kinks against those far from any.
Where the kinks drive the unevenness the depth peaks on the convex ones and the far samples are
clearly evener than the near ones.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..contact.tessellation import facet_kinks, shared_edges
from ..errors import InputError

#: Distance bins (m) of :func:`ridge_profile`.
RIDGE_BINS = (0.0, 5e-3, 10e-3, 20e-3, 40e-3, np.inf)


def kink_convexity(surface) -> np.ndarray:
    """(m,) +1 for a convex kink (the neighbour facet falls away from the tool side), −1 for a
    concave one, 0 for a flat edge; edges in the order of
    :func:`swath.contact.tessellation.shared_edges`."""
    edges, pair = shared_edges(surface.faces)
    F, V, fn = surface.faces, surface.vertices, surface.face_normals
    other = F[pair[:, 1]]
    far = np.where((other != edges[:, :1]) & (other != edges[:, 1:]), other, -1).max(axis=1)
    height = np.einsum("ij,ij->i", V[far] - V[edges[:, 0]], fn[pair[:, 0]])
    scale = np.linalg.norm(V[far] - V[edges[:, 0]], axis=1)
    return np.where(height < -1e-9 * scale, 1, np.where(height > 1e-9 * scale, -1, 0))


def _distance_to_edges(points: np.ndarray, a: np.ndarray, b: np.ndarray, step: float) -> np.ndarray:
    """(k,) distance (m) of ``points`` to the nearest of the segments ``a``–``b``, read from points
    along them at most ``step`` apart (exact to ``step / 2``); inf without segments."""
    if len(a) == 0:
        return np.full(len(points), np.inf)
    n = np.maximum(np.ceil(np.linalg.norm(b - a, axis=1) / step).astype(int), 1)
    t = np.concatenate([np.linspace(0.0, 1.0, k + 1) for k in n])
    seg = np.repeat(np.arange(len(a)), n + 1)
    along = a[seg] + t[:, None] * (b[seg] - a[seg])
    return cKDTree(along).query(points)[0]


def ridge_profile(removal, surface, tool, *, min_ratio: float = 0.2, bins=RIDGE_BINS, step: float = 1e-3) -> dict:
    """Removal against the distance to the nearest marked facet kink (module notes).

    Parameters
    ----------
    removal : RemovalMap
        The simulated removal on ``surface`` (its samples and depth).
    surface : Surface
        The part as meshed, whose facet kinks are read.
    tool : Tool
        The pad (its radius sets the interior; its depression the kink marking).
    min_ratio : float
        Kinks whose height is at least this fraction of the depression are marked.
    bins : sequence of float
        Distance bin edges, m, increasing from 0.
    step : float
        Spacing of the points read along the kinks, m.

    Returns
    -------
    dict
        ``marked_edges`` and ``marked_length_m`` (convex and concave), per bin
        ``convex_bins`` / ``concave_bins``: lists of ``(from_m, to_m, area_fraction,
        mean_over_interior_mean)``; ``near_cov`` and ``far_cov``: the CoV (each about its own mean)
        of the interior samples within ``bins[2]`` of a marked kink and of those farther than
        ``bins[-2]`` from every marked kink; ``interior_cov``.
    """
    if not (np.isfinite(min_ratio) and min_ratio >= 0):
        raise InputError(f"min_ratio must be >= 0, got {min_ratio!r}")
    edges_m = np.asarray(bins, float)
    if len(edges_m) < 3 or edges_m[0] != 0 or np.any(np.diff(edges_m) <= 0):
        raise InputError(f"bins must increase from 0 with at least three edges, got {bins!r}")
    kinks = facet_kinks(surface, tool)
    sign = kink_convexity(surface)
    marked = kinks.ratio >= min_ratio
    samples = removal.surface
    inner = samples.farther_from_boundary(tool.pad_radius)
    pts, z, a = samples.vertices[inner], np.asarray(removal.depth, float)[inner], samples.vertex_areas[inner]
    if len(z) == 0 or not a.sum() > 0:
        raise InputError("the removal has no interior samples (a pad radius in from the edges)")
    mu = float(np.average(z, weights=a))
    V = surface.vertices
    out: dict = {"interior_cov": float(np.sqrt(np.average((z - mu) ** 2, weights=a)) / mu)}
    dist = {}
    for name, s in (("convex", 1), ("concave", -1)):
        sel = marked & (sign == s)
        e = kinks.edges[sel]
        dist[name] = _distance_to_edges(pts, V[e[:, 0]], V[e[:, 1]], step)
        out[f"{name}_marked_edges"] = int(sel.sum())
        out[f"{name}_marked_length_m"] = float(kinks.length[sel].sum())
        rows = []
        for lo, hi in zip(edges_m[:-1], edges_m[1:], strict=True):
            inb = (dist[name] >= lo) & (dist[name] < hi)
            share = float(a[inb].sum() / a.sum())
            mean = float(np.average(z[inb], weights=a[inb]) / mu) if a[inb].sum() > 0 else float("nan")
            rows.append((float(lo), float(hi), share, mean))
        out[f"{name}_bins"] = rows
    nearest = np.minimum(dist["convex"], dist["concave"])

    def cov(m):
        if not a[m].sum() > 0:
            return float("nan")
        mm = np.average(z[m], weights=a[m])
        return float(np.sqrt(np.average((z[m] - mm) ** 2, weights=a[m])) / mm)

    near, far = nearest < edges_m[2], nearest >= edges_m[-2]
    out.update(near_cov=cov(near), far_cov=cov(far), near_area_fraction=float(a[near].sum() / a.sum()),
               far_area_fraction=float(a[far].sum() / a.sum()))
    return out
