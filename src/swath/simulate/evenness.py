"""Where the interior removal CoV comes from: across the passes, along them, between them, the edge band.

The interior CoV (:func:`swath.simulate.removal.plan_metrics`, samples more than a pad radius from
the open boundary) mixes several causes that call for different fixes.  :func:`evenness_split`
splits its variance ``V = Σ a (z − μ)² / Σ a`` (``z`` the depth, ``a`` the sample areas, ``μ``
their mean) exactly into parts that add up:

* **band** — the samples of the interior within ``band_width`` (default one pass spacing) of its
  edge, i.e. between ``R`` and ``R + band_width`` from the open boundary: what the edge passes and
  the feed near the edges leave.  The rest is the **core**;
* over the core, each sample belongs to the pass whose in-contact TCP positions are nearest, and to
  a stretch of that pass one spacing long (a *cell*, one ripple period across and one spacing
  along).  By the law of total variance the core's share is
  ``between passes + along passes + within cells``:

  - **between passes**: the variance of the pass means (a pass removing more or less than its
    neighbours: spacing that does not follow the local width, a feed level that differs);
  - **along passes**: the variance of the cell means about their pass's mean (the depth averaged
    over one spacing changes along the pass: the contact width changes with the curvature, or the
    feed does);
  - **within cells**: what is left inside one period across the passes: the ripple.

Each part is stated as its share of ``V`` and as a CoV ``sqrt(part) / μ``; ``core_cov``
is the CoV of the core alone (its own mean).  Also stated: ``across_profile_cov``, the ripple of
the removal profile across the passes averaged along them (per pass, the depth in bins of the
lateral offset, each bin's mean about the pass's mean, area-weighted over the core).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError


def _label_samples(points: np.ndarray, normals: np.ndarray, trajectory):
    """For each sample ``(k, 3)``: the nearest in-contact TCP sample's pass, its travelled distance
    along that pass (m) and the sample's signed offset across the travel direction (m)."""
    from scipy.spatial import cKDTree

    live = np.flatnonzero(trajectory.contact & (trajectory.pass_index >= 0))
    if len(live) < 2:
        raise InputError("the trajectory has fewer than two in-contact samples; nothing to split")
    pos = trajectory.position[live]
    labels = trajectory.pass_index[live]
    same = np.concatenate([[False], labels[1:] == labels[:-1]])        # the sample before is of the same pass
    step = np.where(same, np.linalg.norm(np.diff(pos, axis=0, prepend=pos[:1]), axis=1), 0.0)
    travel = np.cumsum(step)
    starts = np.flatnonzero(~same)
    travel = travel - np.repeat(travel[starts], np.diff(np.append(starts, len(travel))))
    # travel directions by central differences within each pass
    after = np.append(same[1:], False)
    forward = np.where(after[:, None], np.roll(pos, -1, axis=0), pos) - np.where(same[:, None], np.roll(pos, 1, axis=0), pos)
    _, nearest = cKDTree(pos).query(points)
    across = np.cross(normals, forward[nearest])
    across /= np.maximum(np.linalg.norm(across, axis=1, keepdims=True), 1e-300)
    offset = np.einsum("ij,ij->i", points - pos[nearest], across)
    return labels[nearest], travel[nearest], offset


def interior_and_core(samples, inner: float, outer: float) -> tuple[np.ndarray, np.ndarray]:
    """``(samples.farther_from_boundary(inner), samples.farther_from_boundary(outer))`` (bool
    ``(n,)`` each, ``inner <= outer`` in m) from one nearest-neighbour query: the same boundary
    points (a :class:`~swath.simulate.samples.RemovalSamples`' part's edges sampled at half its
    spacing, else the surface's boundary vertices)."""
    from scipy.spatial import cKDTree

    from ..surface.polyline import densify

    part = getattr(samples, "part", None)
    surface = samples if part is None else part
    loops = surface.boundary_loops
    n = len(samples.vertices)
    if not loops:
        return np.ones(n, bool), np.ones(n, bool)
    if part is None:
        boundary = surface.vertices[np.unique(np.concatenate(loops))]
    else:
        step = 0.5 * samples.spacing
        boundary = np.vstack([densify(surface.vertices[np.append(lp, lp[0])], step)[0] for lp in loops])
    dist, _ = cKDTree(boundary).query(samples.vertices, distance_upper_bound=outer)
    return ~(dist < inner) if inner > 0 else np.ones(n, bool), ~np.isfinite(dist) if outer > 0 else np.ones(n, bool)


def _weighted_var(values: np.ndarray, weights: np.ndarray, mean: float) -> float:
    return float(np.sum(weights * (values - mean) ** 2) / weights.sum())


def evenness_split(removal, trajectory, tool, *, spacing: float | None = None,
                   band_width: float | None = None, bins: int = 16) -> dict:
    """Split the interior removal variance into the band, between, along and within passes (module notes).

    Parameters
    ----------
    removal : RemovalMap
        The simulated removal (samples, depth).
    trajectory : Trajectory
        The trajectory that removed it (pass labels, in-contact positions).
    tool : Tool
        The pad (its radius sets the interior).
    spacing : float, optional
        The pass spacing, m (default: measured, :func:`swath.simulate.ripple.pass_period`).
    band_width : float, optional
        Width of the band inside the interior's edge, m (default ``spacing``).
    bins : int
        Lateral offset bins per spacing for ``across_profile_cov``.

    Returns
    -------
    dict
        ``interior_cov``, ``band_area_fraction``, ``band_variance_fraction``, ``core_cov``,
        ``between_passes_variance_fraction``, ``along_passes_variance_fraction``,
        ``within_cells_variance_fraction`` (the four fractions add to 1), the same as CoVs
        (``band_cov``, ``between_passes_cov``, ``along_passes_cov``, ``within_cells_cov``:
        ``sqrt(part of V) / μ``), ``across_profile_cov``, ``band_mean_over_core_mean_ratio`` and
        ``split_spacing_m``.  NaN figures when the interior is empty.  When no interior sample
        lies beyond the band (``band_area_fraction`` 1), the passes split the whole interior: the
        three pass figures add to 1, and ``band_variance_fraction``, ``band_cov``, ``core_cov``
        and ``band_mean_over_core_mean_ratio`` are NaN.
    """
    from .ripple import pass_period

    d = pass_period(trajectory) if spacing is None else float(spacing)
    if not (np.isfinite(d) and d > 0):
        raise InputError(f"the pass spacing must be a positive length in m, got {d!r} (two passes or more needed)")
    band = d if band_width is None else float(band_width)
    if not (np.isfinite(band) and band >= 0):
        raise InputError(f"band_width must be a length >= 0 m, got {band_width!r}")
    samples = removal.surface
    depth = np.asarray(removal.depth, float)
    inner, core = interior_and_core(samples, tool.pad_radius, tool.pad_radius + band)
    core &= inner
    idx = np.flatnonzero(inner)
    nan = float("nan")
    keys = ("interior_cov", "band_area_fraction", "band_variance_fraction", "core_cov",
            "between_passes_variance_fraction", "along_passes_variance_fraction", "within_cells_variance_fraction",
            "band_cov", "between_passes_cov", "along_passes_cov", "within_cells_cov", "across_profile_cov",
            "band_mean_over_core_mean_ratio")
    out = dict.fromkeys(keys, nan)
    out["split_spacing_m"] = d
    a_all = samples.vertex_areas
    if len(idx) == 0 or not a_all[idx].sum() > 0:
        return out
    a, z = a_all[idx], depth[idx]
    mu = float(np.average(z, weights=a))
    total_w = a.sum()
    V = _weighted_var(z, a, mu)
    out["interior_cov"] = float(np.sqrt(V) / mu)
    in_core = core[idx]
    ab, zb = a[~in_core], z[~in_core]
    out["band_area_fraction"] = float(ab.sum() / total_w)
    vb = float(np.sum(ab * (zb - mu) ** 2) / total_w)
    # no core (every interior sample within the band: a part of holes and narrow strips, the hub,
    # noether_raw_mesh): the passes split the whole interior, and the band's figures stay NaN
    no_core = not a[in_core].sum() > 0
    split = np.ones(len(idx), bool) if no_core else in_core
    ac, zc = a[split], z[split]
    cidx = idx[split]
    kpass, travel, offset = _label_samples(samples.vertices[cidx], samples.normals[cidx], trajectory)
    mu_c = float(np.average(zc, weights=ac))
    if not no_core:
        out["core_cov"] = float(np.sqrt(_weighted_var(zc, ac, mu_c)) / mu_c)
        out["band_mean_over_core_mean_ratio"] = float(np.average(zb, weights=ab) / mu_c) if ab.sum() > 0 else nan
    # the core's share of V (about the interior mean), split by the law of total variance

    def group_means(key):
        _, inv = np.unique(key, return_inverse=True)
        inv = inv.ravel()
        wsum = np.bincount(inv, weights=ac)
        return (np.bincount(inv, weights=ac * zc) / wsum)[inv]

    def joint(second):                       # one integer key per (pass, second) pair
        second = second - second.min()
        return kpass.astype(np.int64) * (int(second.max()) + 1) + second

    pass_mean = group_means(kpass)
    cell_mean = group_means(joint(np.floor(travel / d).astype(np.int64)))
    between = float(np.sum(ac * (pass_mean - mu) ** 2) / total_w)
    along = float(np.sum(ac * (cell_mean - pass_mean) ** 2) / total_w)
    within = float(np.sum(ac * (zc - cell_mean) ** 2) / total_w)
    # between + along + within = core_share exactly (nested groups); the band's share is vb
    parts = (("between_passes", between), ("along_passes", along), ("within_cells", within))
    for name, part in parts if no_core else (("band", vb),) + parts:
        out[f"{name}_variance_fraction"] = part / V if V > 0 else nan
        out[f"{name}_cov"] = float(np.sqrt(max(part, 0.0)) / mu)
    lateral = np.clip(np.floor((offset / d + 0.5) * bins), 0, bins - 1).astype(np.int64)
    profile = group_means(joint(lateral))
    out["across_profile_cov"] = float(np.sqrt(np.sum(ac * (profile - pass_mean) ** 2) / ac.sum()) / mu_c)
    return out


def evenness_metrics(removal, trajectory, tool) -> dict:
    """:func:`evenness_split`'s figures for ``metrics.json``, with the band's causes of
    :func:`swath.simulate.edge_band.band_causes` (its scalars), each key prefixed ``evenness_``; an
    empty dict when the trajectory has fewer than two passes (no spacing to split by)."""
    from .ripple import pass_period

    d = pass_period(trajectory)
    if not (np.isfinite(d) and d > 0):
        return {}
    from .edge_band import band_causes

    out = {f"evenness_{k}": v for k, v in evenness_split(removal, trajectory, tool, spacing=d).items()}
    causes = band_causes(removal, trajectory, tool, spacing=d)       # the band by cause (scalars only)
    out.update({f"evenness_{k}": v for k, v in causes.items() if isinstance(v, float) and f"evenness_{k}" not in out
                and k != "band_spacing_m"})
    return out


def variance_shares(m: dict) -> dict[str, float]:
    """The shares (per cent) of the interior variance in ``m``'s ``evenness_*_variance_fraction``
    metrics, keyed ``within_cells``, ``along_passes``, ``between_passes`` and ``band``: NaN where a
    figure is missing or null (``band`` on a part with no core)."""
    def share(key: str) -> float:
        value = m.get(f"evenness_{key}_variance_fraction")
        return float("nan") if value is None else 100.0 * float(value)

    return {key: share(key) for key in ("within_cells", "along_passes", "between_passes", "band")}


def split_line(m: dict) -> str:
    """The CLI's line on where the interior CoV comes from (``evenness_*`` metrics), or ``""``."""
    share = variance_shares(m)
    cov = m.get("evenness_interior_cov")
    if cov is None or not np.isfinite(cov) or not np.isfinite(share["within_cells"]):
        return ""
    passes = (f"{share['within_cells']:.0f} % is the ripple across the passes, {share['along_passes']:.0f} % along "
              f"them, {share['between_passes']:.0f} % between passes")
    core = m.get("evenness_core_cov")
    if core is None or not np.isfinite(core):
        # no core: every interior sample lies in the band (the hub's holes, noether_raw_mesh's ragged scan)
        return (f"  interior CoV {cov:.3f}: every interior sample lies within one spacing "
                f"({1e3 * m['evenness_split_spacing_m']:.0f} mm) of the interior's edge (holes or a ragged "
                f"boundary); of its variance {passes}")
    return (f"  interior CoV {cov:.3f}: of its variance {passes}, {share['band']:.0f} % the band one spacing inside "
            f"the edge (CoV without it {core:.3f})")
