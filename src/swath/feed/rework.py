"""Rework from a scan: the material a finishing run left, mapped onto the nominal part.

After a run the part is measured again.  Where the measured surface still stands proud of the
nominal (CAD) surface, material is left; :func:`excess_on_cad` maps that excess onto the CAD's
vertices (a :class:`~swath.feed.targets.TargetMap` the feed optimisation removes), and
:func:`rework_area` picks the faces a rework pass must cross to reach it.  :func:`residual_figures`
compares the excess with the removal a rework trajectory is predicted to make.

Scale of the problem: a sanding pass removes micrometres, so the scan must resolve micrometres
after averaging.  The excess at a CAD vertex is the mean signed height of the scan points within
``radius`` of it, so the noise of the map is about ``sigma / sqrt(points within radius)``: a
0.1 mm laser line with points 0.5 mm x 2 mm apart and a 5 mm radius gives about 13 µm, a 5 µm
white-light scanner under 1 µm.  :func:`excess_on_cad` reports that noise figure.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .targets import TargetMap


@dataclass(frozen=True, eq=False)
class ExcessMap:
    """Material left on the part, at the CAD's vertices (CAD frame).

    Attributes
    ----------
    target : TargetMap
        Depth to remove at each CAD vertex, m (0 where the scan is at or below the CAD surface,
        and where the scan did not measure).
    height : (n,) float
        Mean signed height of the scan above the CAD surface along its normal, m (NaN where no
        scan point lies within ``radius``).
    measured : (n,) bool
        CAD vertices with at least ``min_points`` scan points within ``radius``.
    noise : float
        Standard error of the mean height, m: the scan points' spread about the local mean over
        the square root of the median point count per vertex.
    radius : float
        Averaging radius, m.
    """

    target: TargetMap
    height: np.ndarray
    measured: np.ndarray
    noise: float
    radius: float


def excess_on_cad(cad, scan_points, *, scan2cad=None, radius: float = 5e-3, min_points: int = 3,
                  max_depth: float | None = None) -> ExcessMap:
    """Map a scan's excess over the nominal surface onto the CAD's vertices.

    Parameters
    ----------
    cad : Surface
        The nominal part, m, CAD frame, normals toward the tool.
    scan_points : (m, 3) float
        The measured surface after the run, m, scan frame.
    scan2cad : (4, 4) float, optional
        Rigid transform taking scan coordinates into the CAD frame (``p_cad = scan2cad @ p_scan``;
        the inverse of a registration's ``cad2scan``).  Default identity: the scan was taken in the
        CAD frame (a scanner calibrated in the cell, the part not moved).
    radius : float
        Averaging radius around each CAD vertex, m (default 5 mm).
    min_points : int
        Scan points a vertex needs within ``radius`` to count as measured.
    max_depth : float, optional
        Clip depths above this, m (spikes of the scan).

    Returns
    -------
    ExcessMap
    """
    from scipy.spatial import cKDTree

    pts = np.asarray(scan_points, float)
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < min_points or not np.isfinite(pts).all():
        raise InputError(f"the scan needs (m, 3) finite points, at least {min_points}; got shape {pts.shape}")
    if not (np.isfinite(radius) and radius > 0):
        raise InputError(f"the excess averaging radius must be > 0 m, got {radius!r}")
    if scan2cad is not None:
        m = np.asarray(scan2cad, float)
        if m.shape != (4, 4) or not np.allclose(m[:3, :3] @ m[:3, :3].T, np.eye(3), atol=1e-6) \
                or not np.allclose(m[3], [0, 0, 0, 1]):
            raise InputError(f"scan2cad: expected a (4, 4) rigid transform, got {np.array2string(m, precision=4)}")
        pts = pts @ m[:3, :3].T + m[:3, 3]
    closest, _, face = cad.closest_points(pts)
    normal = cad.interpolate_normals(closest, face)
    signed = np.einsum("ij,ij->i", pts - closest, normal)
    # Points beyond the CAD's edge project onto its boundary with a large sideways offset: their
    # height says nothing about the surface there.
    sideways = np.linalg.norm(pts - closest - signed[:, None] * normal, axis=1)
    keep = sideways < 0.25 * radius
    pts, signed = pts[keep], signed[keep]
    tree = cKDTree(pts)
    neighbours = tree.query_ball_point(cad.vertices, radius)
    counts = np.array([len(n) for n in neighbours])
    height = np.full(len(cad.vertices), np.nan)
    spread = []
    for i, idx in enumerate(neighbours):
        if len(idx) >= min_points:
            h = signed[idx]
            height[i] = h.mean()
            spread.append(h.std(ddof=1))
    measured = counts >= min_points
    if not measured.any():
        raise InputError(f"no CAD vertex has {min_points} scan points within {radius * 1e3:.3g} mm: the scan does not "
                         "lie on the part (register it first, or check --units / --scan-units)")
    noise = float(np.median(spread) / np.sqrt(np.median(counts[measured]))) if spread else float("nan")
    depth = np.where(measured, np.clip(np.nan_to_num(height), 0.0, None), 0.0)
    if max_depth is not None:
        depth = np.minimum(depth, float(max_depth))
    target = TargetMap(np.asarray(cad.vertices, float), depth, name=f"excess of the scan over {cad.name}")
    return ExcessMap(target, height, measured, noise, float(radius))


def rework_area(cad, depth, *, min_excess: float, grow: float) -> np.ndarray:
    """Faces of ``cad`` a rework plan covers: those within ``grow`` (m) of a vertex whose depth
    (``(n,)`` m) exceeds ``min_excess`` (m).  Returns ``(k,)`` int face indices (empty when no
    material is left)."""
    from scipy.spatial import cKDTree

    depth = np.asarray(depth, float)
    hot = depth > min_excess
    if not hot.any():
        return np.zeros(0, int)
    d, _ = cKDTree(cad.vertices[hot]).query(cad.vertices, distance_upper_bound=grow)
    near = np.isfinite(d)
    return np.flatnonzero(near[cad.faces].all(axis=1))


def residual_figures(excess, removal_points, removal_depth, *, min_excess: float) -> dict:
    """How much of the excess a predicted removal leaves, where the excess is above ``min_excess``.

    Parameters
    ----------
    excess : ExcessMap
    removal_points : (s, 3) float
        Removal samples, m, CAD frame.
    removal_depth : (s,) float
        Predicted removal at each sample, m.
    min_excess : float
        Samples whose excess is above this (m) are the rework area the figures describe.

    Returns
    -------
    dict
        ``excess_rms_m`` and ``excess_max_m`` (before), ``residual_rms_m`` (signed: left minus
        over-removed), ``residual_max_m`` (most left), ``over_removal_max_m`` (most removed below the
        nominal surface), ``residual_rms_fraction`` (residual RMS over excess RMS), ``rework_samples``.
    """
    target = excess.target.depth_on(_Points(removal_points))
    hot = target > min_excess
    if not hot.any():
        return {"rework_samples": 0}
    left = target[hot] - np.asarray(removal_depth, float)[hot]
    rms_before = float(np.sqrt(np.mean(target[hot] ** 2)))
    rms_after = float(np.sqrt(np.mean(left ** 2)))
    return {"excess_rms_m": rms_before, "excess_max_m": float(target[hot].max()),
            "residual_rms_m": rms_after, "residual_max_m": float(max(left.max(), 0.0)),
            "over_removal_max_m": float(max(-left.min(), 0.0)),
            "residual_rms_fraction": rms_after / rms_before if rms_before > 0 else float("nan"),
            "rework_samples": int(hot.sum())}


def register_excluding_excess(cad, scan_points, *, cad2scan=None, radius: float = 5e-3,
                              clean_below: float | None = None, rounds: int = 3, rng=0):
    """Place the CAD on a scan that still carries excess material, without the excess pulling it.

    A registration over the whole scan fits through the proud areas and tilts or lifts the CAD by
    a fraction of the excess (a 400 x 300 mm panel under a 10 µm dome of excess: the map 2.8 µm too
    shallow on average, 3.1 µm RMS off).  After a global registration
    (:func:`swath.scan.register_rigid`, unless ``cad2scan`` is given) each round maps the excess
    and registers again on the CAD vertices whose scan height is below ``clean_below`` (the part at
    its nominal surface, where the dome tapers out); on that panel three rounds bring the map within
    0.6 µm RMS of the truth and 0.1 µm on average.

    Parameters
    ----------
    cad : Surface
        Nominal part, m.
    scan_points : (m, 3) float
        The scan, m, in its own frame.
    cad2scan : (4, 4) float, optional
        A starting placement (e.g. from ``swath register``); default: a global search.
    radius : float
        Averaging radius of the excess map, m.
    clean_below : float, optional
        Height (m) under which a CAD vertex counts as nominal for the refinement (default twice the
        map's noise, at least 0.3 µm: a higher threshold lets the excess's foot lift the CAD).
    rounds : int
        Refinement rounds.
    rng : int or Generator
        Seed for the registration's subsampling.

    Returns
    -------
    (4, 4) float
        ``cad2scan``: CAD coordinates to scan coordinates.
    """
    from ..scan import register_rigid

    pts = np.asarray(scan_points, float)
    if cad2scan is None:
        cad2scan = register_rigid(cad, pts, rng=rng).matrix
    matrix = np.asarray(cad2scan, float)
    for _ in range(rounds):
        excess = excess_on_cad(cad, pts, scan2cad=np.linalg.inv(matrix), radius=radius)
        below = clean_below if clean_below is not None else max(2.0 * excess.noise, 3e-7)
        clean = excess.measured & (np.nan_to_num(excess.height, nan=np.inf) < below)
        if clean.sum() < 0.2 * len(clean):
            break                         # too little of the part at nominal to register on
        matrix = register_rigid(cad.vertices[clean], pts, source_normals=cad.normals[clean], coarse=False,
                                initial=matrix, trim=0.95, rng=rng).matrix
    return matrix


def removal_floor(tool, *, feed: float, spacing: float, lead_angle: float = 0.0) -> float:
    """The least depth (m) parallel passes ``spacing`` (m) apart remove on a plane at the fastest
    ``feed`` (m/s): the peak of their summed cross-profiles (:func:`swath.feed.ripple.cross_profile`).

    A rework plan cannot remove less than this wherever its passes run, so excess below it is
    either left or over-removed: the rework job's default threshold and tolerance start from it.
    """
    from .ripple import cross_profile

    if not (spacing > 0 and feed > 0):
        raise InputError(f"spacing and feed must be > 0, got {spacing!r} m and {feed!r} m/s")
    y = np.linspace(0.0, spacing, 64, endpoint=False)
    reach = int(np.ceil(2.0 * tool.pad_radius / spacing)) + 1
    total = sum(cross_profile(tool, y - k * spacing, speed=feed, lead_angle=lead_angle)
                for k in range(-reach, reach + 1))
    return float(np.max(total))


class _Points:
    """The ``vertices`` view :meth:`TargetMap.depth_on` reads."""

    def __init__(self, points):
        self.vertices = np.asarray(points, float)
