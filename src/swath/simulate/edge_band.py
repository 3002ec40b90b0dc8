"""What makes the edge band uneven: the band of :func:`swath.simulate.evenness.evenness_split` split by cause.

The band is the interior's samples within one pass spacing ``d`` of its edge: between ``R`` and
``R + d`` from the open boundary (``R`` the pad radius).  Its share of the interior variance
``V`` (``band_variance_fraction``) mixes two things: how much of the interior it is (on a part a
few pad widths across it is half of it) and how much more, or less, evenly it is removed than the
core.  :func:`band_causes` separates them and says where along the edge the difference is:

* **excess** — ``band_excess_variance_fraction``: the band's share of ``V`` less the share a band
  removed like the core would have (its area share times the core's mean square deviation about
  the interior mean, over ``V``).  Positive: the band is removed less evenly than the core, and that
  much of ``V`` is the edge's doing; negative: the band is evener than the core;
* **mean offset** — ``band_mean_offset_variance_fraction``: the part of the band's share that is
  its mean differing from the interior mean (the dose the edge passes give the band as a whole);
  the rest is the band's own spread;
* **by edge direction** — each band sample takes the direction of the boundary nearest to it
  (tangent of the open boundary, densified to 1 mm) and the travel direction of the nearest
  in-contact TCP sample: **side** where the boundary runs within 30° of the passes (the outermost
  pass runs beside it, the pad partly off the part), **pass ends** where it runs within 30° of
  across them (the passes start and end at it, the pad decelerating, turning and half off), and
  **oblique** in between (passes cut short by the boundary's shape).  Per group: its area share of
  the interior, its share of ``V``, its mean over the core's mean and its own CoV (about its own
  mean, over the core's mean);
* **profiles** — the mean depth over the core's mean in bins of ``d / 6`` of the distance from the
  boundary, from ``R`` to ``R + d`` (the band), for the side and the pass-end samples: the removal
  along a line perpendicular to the edge, averaged along it.

The groups' variance shares add up to the band's share exactly.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError
from .evenness import interior_and_core

#: Angle (rad) between the nearest boundary's tangent and the passes below which a band sample is
#: beside the outermost pass (``side``), and above ``π/2`` less which it is at the passes' ends.
SIDE_ANGLE = math.radians(30.0)

#: Bins across the band per spacing for the profiles perpendicular to the edge.
PROFILE_BINS = 6

#: The cause groups of the band, in the order the keys are written.
GROUPS = ("side", "ends", "oblique")


def _boundary_tangents(part, step: float = 1e-3):
    """Points ``(b, 3)`` along the open boundary of ``part`` (at most ``step`` m apart) and the unit
    tangent ``(b, 3)`` there; empty arrays on a closed surface."""
    from ..surface.polyline import densify

    points, tangents = [], []
    for loop in part.boundary_loops:
        p = densify(part.vertices[np.append(loop, loop[0])], step)[0]
        t = np.roll(p, -1, axis=0) - np.roll(p, 1, axis=0)
        t[0] = p[1] - p[-2]                       # the closing point repeats the first
        t[-1] = t[0]
        t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-300)
        points.append(p)
        tangents.append(t)
    if not points:
        return np.zeros((0, 3)), np.zeros((0, 3))
    return np.vstack(points), np.vstack(tangents)


def _travel_directions(trajectory) -> tuple[np.ndarray, np.ndarray]:
    """In-contact TCP positions ``(k, 3)`` of the passes and their unit travel directions ``(k, 3)``
    (central differences within each pass)."""
    live = np.flatnonzero(trajectory.contact & (trajectory.pass_index >= 0))
    if len(live) < 2:
        raise InputError("the trajectory has fewer than two in-contact samples; no band to split")
    pos = trajectory.position[live]
    label = trajectory.pass_index[live]
    before = np.concatenate([[False], label[1:] == label[:-1]])
    after = np.append(before[1:], False)
    ahead = np.where(after[:, None], np.roll(pos, -1, axis=0), pos)
    behind = np.where(before[:, None], np.roll(pos, 1, axis=0), pos)
    forward = ahead - behind
    forward /= np.maximum(np.linalg.norm(forward, axis=1, keepdims=True), 1e-300)
    return pos, forward


def band_causes(removal, trajectory, tool, *, spacing: float | None = None) -> dict:
    """Split the edge band's share of the interior removal variance by cause (module notes).

    Parameters
    ----------
    removal : RemovalMap
        The simulated removal (samples, depth).
    trajectory : Trajectory
        The trajectory that removed it (pass labels, in-contact positions).
    tool : Tool
        The pad (its radius sets the interior).
    spacing : float, optional
        The pass spacing ``d``, m: the band's width (default: measured,
        :func:`swath.simulate.ripple.pass_period`).

    Returns
    -------
    dict
        ``band_variance_fraction``, ``band_area_fraction``, ``band_excess_variance_fraction``,
        ``band_mean_offset_variance_fraction``, ``band_mean_over_core_mean_ratio``,
        ``band_own_cov`` and ``core_cov`` (CoVs about each one's own mean, over the core's mean);
        per group ``g`` of :data:`GROUPS`: ``band_<g>_area_fraction`` (of the interior),
        ``band_<g>_variance_fraction`` (of ``V``), ``band_<g>_mean_over_core_mean_ratio``,
        ``band_<g>_own_cov`` (an empty group: no area, no variance, NaN ratio and CoV);
        ``band_side_profile`` and ``band_ends_profile`` (lists of
        :data:`PROFILE_BINS` ratios, nearest the edge first; NaN for an empty bin); and
        ``band_spacing_m``.  NaN figures where the interior, the core or a group is empty.
    """
    from scipy.spatial import cKDTree

    from .ripple import pass_period

    d = pass_period(trajectory) if spacing is None else float(spacing)
    if not (np.isfinite(d) and d > 0):
        raise InputError(f"the pass spacing must be a positive length in m, got {d!r} (two passes or more needed)")
    nan = float("nan")
    out: dict = {"band_spacing_m": d}
    keys = ["band_variance_fraction", "band_area_fraction", "band_excess_variance_fraction",
            "band_mean_offset_variance_fraction", "band_mean_over_core_mean_ratio", "band_own_cov", "core_cov"]
    for g in GROUPS:
        keys += [f"band_{g}_area_fraction", f"band_{g}_variance_fraction", f"band_{g}_mean_over_core_mean_ratio",
                 f"band_{g}_own_cov"]
    out.update(dict.fromkeys(keys, nan))
    out["band_side_profile"] = [nan] * PROFILE_BINS
    out["band_ends_profile"] = [nan] * PROFILE_BINS
    samples = removal.surface
    part = getattr(samples, "part", samples)
    R = tool.pad_radius
    z = np.asarray(removal.depth, float)
    a = np.asarray(samples.vertex_areas, float)
    inner, core = interior_and_core(samples, R, R + d)
    band = inner & ~core
    total = float(a[inner].sum())
    if not total > 0 or not a[core].sum() > 0:
        return out
    mu = float(np.average(z[inner], weights=a[inner]))
    V = float(np.sum(a[inner] * (z[inner] - mu) ** 2) / total)
    mu_c = float(np.average(z[core], weights=a[core]))
    core_ms = float(np.average((z[core] - mu) ** 2, weights=a[core]))    # about the interior mean
    out["core_cov"] = float(np.sqrt(np.average((z[core] - mu_c) ** 2, weights=a[core])) / mu_c)

    def figures(mask, prefix):
        w = a[mask]
        if not w.sum() > 0:                     # an empty group: none of the area, none of the variance
            out[f"{prefix}_area_fraction"] = out[f"{prefix}_variance_fraction"] = 0.0
            return
        m = float(np.average(z[mask], weights=w))
        out[f"{prefix}_area_fraction"] = float(w.sum() / total)
        out[f"{prefix}_variance_fraction"] = float(np.sum(w * (z[mask] - mu) ** 2) / total / V) if V > 0 else nan
        out[f"{prefix}_mean_over_core_mean_ratio"] = m / mu_c
        out[f"{prefix}_own_cov"] = float(np.sqrt(np.average((z[mask] - m) ** 2, weights=w)) / mu_c)

    figures(band, "band")
    if not a[band].sum() > 0 or not V > 0:
        return out
    share = float(a[band].sum() / total)
    out["band_excess_variance_fraction"] = out["band_variance_fraction"] - share * core_ms / V
    mb = out["band_mean_over_core_mean_ratio"] * mu_c
    out["band_mean_offset_variance_fraction"] = share * (mb - mu) ** 2 / V

    boundary, tangent = _boundary_tangents(part)
    idx = np.flatnonzero(band)
    dist, nearest_edge = cKDTree(boundary).query(samples.vertices[idx])
    pos, forward = _travel_directions(trajectory)
    _, nearest_tcp = cKDTree(pos).query(samples.vertices[idx])
    along = np.abs(np.einsum("ij,ij->i", tangent[nearest_edge], forward[nearest_tcp]))
    group = {"side": along >= math.cos(SIDE_ANGLE), "ends": along <= math.sin(SIDE_ANGLE)}
    group["oblique"] = ~(group["side"] | group["ends"])
    for g in GROUPS:
        mask = np.zeros_like(band)
        mask[idx[group[g]]] = True
        figures(mask, f"band_{g}")
    edges = R + d * np.arange(PROFILE_BINS + 1) / PROFILE_BINS
    for g in ("side", "ends"):
        row = []
        for lo, hi in zip(edges[:-1], edges[1:]):
            k = group[g] & (dist >= lo) & (dist < hi)
            w = a[idx[k]]
            row.append(float(np.average(z[idx[k]], weights=w) / mu_c) if w.sum() > 0 else nan)
        out[f"band_{g}_profile"] = row
    return out


def band_line(m: dict) -> str:
    """The CLI's line on what makes the band uneven (``evenness_band_*`` metrics), or ``""``."""
    def value(key: str) -> float:               # None (NaN as metrics.json writes it) reads NaN
        x = m.get(key)
        return float("nan") if x is None else float(x)

    excess = value("evenness_band_excess_variance_fraction")
    if not np.isfinite(excess):
        return ""
    parts = []
    for g, name in (("side", "beside the outermost passes"), ("ends", "at the pass ends"), ("oblique", "oblique")):
        area = value(f"evenness_band_{g}_area_fraction")
        if np.isfinite(area) and area > 0:
            parts.append(f"{name} {100 * value(f'evenness_band_{g}_variance_fraction'):.0f} % of the variance on "
                         f"{100 * area:.0f} % of the interior (mean "
                         f"{value(f'evenness_band_{g}_mean_over_core_mean_ratio'):.3f} of the core's)")
    points = 100 * excess                       # of the interior's variance, over a band removed like the core
    if abs(points) < 0.5:
        verdict, held = "as evenly as", "it holds the share of the variance a band removed like the core would"
    else:
        verdict = "less evenly than" if points > 0 else "more evenly than"
        held = (f"it holds {abs(points):.0f} points {'more' if points > 0 else 'less'} of the interior's variance "
                "than a band removed like the core would")
    return f"  the band is removed {verdict} the core ({held}): " + "; ".join(parts)
