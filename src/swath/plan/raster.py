"""The baseline planner: parallel plane slices in snake (boustrophedon) order.

The part is cut by equally spaced parallel planes; each plane's intersection with the surface,
split where it leaves the surface or crosses a hole, becomes one or more passes.  This is the
plane-slice raster of ros-industrial/noether, made unable to hang or fail on real meshes by the
topological slicer of :mod:`swath.plan.slicing`, with a default spacing read from the contact
model (:func:`swath.plan.widths.raster_spacing`).
"""

from __future__ import annotations

import logging
import math
import time

import numpy as np

from ..errors import InfeasibleError, InputError
from ..surface.geometry import normalize
from .slicing import resample, slice_mesh
from .toolpath import Pass, ToolPath
from .widths import raster_spacing

log = logging.getLogger("swath.plan")

#: Default shortest pass, as a fraction of the pad radius (see :func:`raster`).
MIN_PASS_FRACTION = 0.25
#: Refuse plans that would need more cutting planes than this (a spacing typo such as 1e-6).
MAX_PLANES = 20000


#: Feed angles (rad, from the first principal axis) tried when the direction is left to swath.
AUTO_ANGLES = (0.0, math.pi / 4, math.pi / 2, 3 * math.pi / 4)


def raster(surface, tool, *, spacing: float | None = None, angle: float | None = None, direction=None,
           point_spacing: float = 1e-3, min_pass_length: float | None = None, cross_direction=None) -> ToolPath:
    """Cover a surface with parallel plane slices, visited in snake order.

    Parameters
    ----------
    surface : Surface
        The part surface (normals toward the tool).
    tool : Tool
        The pad; sets the default spacing and the default ``min_pass_length``.
    spacing : float, optional
        Distance between cutting planes, m.  Default: the largest equal spacing that still covers
        the surface under the contact model (:func:`swath.plan.widths.raster_spacing`): the 0.2 %
        area-percentile of the contact chord across the slice, times the slope factor ``|n × c|``
        (clipped at 0.5), with curvature read at pad scale.
    angle : float, optional
        Rotation of the feed direction from the surface's first principal axis (largest spread)
        about its third axis (the normal of the best-fit plane), rad.  Default (None): chosen
        among :data:`AUTO_ANGLES` by :func:`choose_angle` — the direction whose planes cross the
        part's curvature, so the equal spacing wastes least (the shortest predicted path whose
        predicted gap stays within 0.1 %; near-ties go to the principal axis).
    direction : (3,) float, optional
        Feed direction in the part frame; overrides ``angle``.  Only its component in the
        best-fit plane matters.
    point_spacing : float
        Arc-length step between pass points, m (default 1 mm: ≤ 20 ms apart at 50 mm/s).
    cross_direction : (3,) float, optional
        Normal of the cutting planes, part frame, used as given (not re-derived from this surface's
        best-fit plane); the feed is ``direction`` (or the principal axis) made orthogonal to it.
        For regions of a segmented part (:func:`swath.segment.segment`), whose sweep lines are
        level sets along the parent's cross direction.
    min_pass_length : float, optional
        Slice fragments shorter than this (m) are dropped.  Default ``R/4`` (9.5 mm for a 3-inch
        pad): such slivers occur where a plane grazes a bump, a hole or the part's edge, and each
        would cost an approach and a retract.  The pad on the neighbouring passes reaches over
        most of them: on the shared meshes at spacings 10–100 mm (0–36 fragments dropped per
        plan) the area within 0.75 R of a dropped fragment and of no kept pass is at most 0.23 %
        (one fragment on bezier_complex_shape), typically below 0.05 %.

    Returns
    -------
    ToolPath
        Passes in snake order: planes by increasing offset along the cross direction, travel
        direction alternating from plane to plane (among planes that yield passes), several
        fragments on a plane visited in order along the travel direction.  Points lie exactly on
        the mesh, ``≤ point_spacing`` apart along the pass; normals are the smooth vertex normals
        interpolated barycentrically in the face holding each point.
        ``metadata``: spacing_m, angle_rad, feed_direction, cross_direction, n_planes, n_passes,
        dropped_fragments, dropped_length_m, point_spacing_m, min_pass_length_m, margin_m,
        spacing_rule, and for the default spacing predicted_gap_fraction.

    Raises
    ------
    InputError
        On a non-positive or non-finite ``spacing``, ``point_spacing`` or ``min_pass_length``, a
        non-finite ``angle``, a bad ``direction`` or a spacing needing more than
        :data:`MAX_PLANES` planes.
    InfeasibleError
        When no slice fragment is long enough to become a pass.
    """
    t_start = time.perf_counter()
    point_spacing = _positive("point_spacing", point_spacing)
    if spacing is not None:
        spacing = _positive("spacing", spacing)
    if min_pass_length is None:
        min_pass_length = MIN_PASS_FRACTION * tool.pad_radius
    elif not (_is_number(min_pass_length) and math.isfinite(min_pass_length) and min_pass_length >= 0):
        raise InputError(f"min_pass_length must be a finite length >= 0 m, got {min_pass_length!r}")
    if angle is not None and not (_is_number(angle) and math.isfinite(angle)):
        raise InputError(f"angle must be a finite number of radians, got {angle!r}")

    choice = None
    direction_rule = "given direction" if direction is not None else "given angle"
    if angle is None and direction is None:
        angle, choice, direction_rule = choose_angle(surface, tool, spacing=spacing)
    feed, cross = feed_and_cross(surface, angle=angle or 0.0, direction=direction)
    if cross_direction is not None:
        c = np.asarray(cross_direction, float).reshape(-1)
        if c.shape != (3,) or not np.isfinite(c).all() or np.linalg.norm(c) == 0:
            raise InputError(f"cross_direction must be a finite, non-zero 3-vector, got {cross_direction!r}")
        cross = c / np.linalg.norm(c)
        f = feed - (feed @ cross) * cross
        if np.linalg.norm(f) < 1e-6:
            raise InputError("cross_direction is along the feed direction; give a feed across the planes")
        feed = f / np.linalg.norm(f)
        direction_rule = "given cutting-plane normal"

    if spacing is None:
        if choice is None:
            choice = raster_spacing(surface, tool, cross)
        spacing, rule = choice.spacing, choice.rule
    else:
        rule = "given"
        choice = None

    offsets, margin = plane_offsets(surface.vertices @ cross, spacing)
    slices = slice_mesh(surface.vertices, surface.faces, cross, offsets, values=surface.normals)

    lengths = np.array([pl.length for pl in slices])
    short = lengths < min_pass_length
    dropped, dropped_length = int(short.sum()), float(lengths[short].sum())
    kept = [pl for pl, s in zip(slices, short) if not s]
    if not kept:
        along = float(np.ptp(surface.vertices @ feed))
        raise InfeasibleError(
            f"raster found no pass: {len(slices)} slice fragments on {len(offsets)} planes, all shorter than "
            f"min_pass_length={min_pass_length * 1e3:.1f} mm (the part spans {along * 1e3:.1f} mm along the feed); "
            "lower min_pass_length or choose a feed direction along the part")

    passes = snake_order(kept, feed, cross, surface, point_spacing)
    metadata = dict(
        spacing_m=float(spacing), angle_rad=float(angle or 0.0), direction_rule=direction_rule,
        feed_direction=feed.tolist(),
        cross_direction=cross.tolist(), n_planes=int(len(offsets)), n_passes=len(passes),
        dropped_fragments=dropped, dropped_length_m=dropped_length, point_spacing_m=float(point_spacing),
        min_pass_length_m=float(min_pass_length), margin_m=float(margin), spacing_rule=rule,
    )
    if choice is not None:
        metadata["predicted_gap_fraction"] = choice.gap_fraction
        if choice.gap_fraction > 5e-3:
            log.warning("raster: about %.1f%% of %s is predicted to fall between swaths at the default spacing "
                        "%.1f mm (%.1f%% of the area lies within 30 degrees of parallel to the cutting planes); "
                        "choose an angle/direction whose planes cut across the steep parts, or segment the part "
                        "first", 100 * choice.gap_fraction, surface.name or "the surface", spacing * 1e3,
                        100 * choice.steep_fraction)
    log.info("raster %s: spacing %.1f mm, %d planes, %d passes, %d fragments dropped, %d points, %.2f s",
             surface.name, spacing * 1e3, len(offsets), len(passes), dropped, sum(len(p.points) for p in passes),
             time.perf_counter() - t_start)
    return ToolPath(surface, passes, "raster", metadata)


def feed_and_cross(surface, *, angle: float = 0.0, direction=None) -> tuple[np.ndarray, np.ndarray]:
    """Unit feed direction in the best-fit plane ``(3,)`` and the cutting-plane normal ``(3,)``.

    The best-fit plane's normal (third principal axis) is oriented toward the tool (with the
    area-weighted mean facet normal); the feed is the first principal axis rotated by ``angle``
    about it, or ``direction`` projected into the plane; the cross direction is normal × feed.

    The axes are :attr:`Surface.principal_axes` (exact triangle moments).
    """
    axes = surface.principal_axes[1]
    a0, a2 = np.asarray(axes[0], float), np.asarray(axes[2], float)
    mean_normal = (surface.face_normals * surface.face_areas[:, None]).sum(axis=0)
    if a2 @ mean_normal < 0:
        a2 = -a2
    a1 = np.cross(a2, a0)
    if direction is None:
        feed = math.cos(angle) * a0 + math.sin(angle) * a1
    else:
        d = np.asarray(direction, float).reshape(-1)
        if d.shape != (3,) or not np.isfinite(d).all() or np.linalg.norm(d) == 0:
            raise InputError(f"direction must be a finite, non-zero 3-vector, got {direction!r}")
        d = d / np.linalg.norm(d)
        feed = d - (d @ a2) * a2
        if np.linalg.norm(feed) < 1e-6:
            raise InputError(f"direction {d.round(4).tolist()} is along the part's mean normal "
                             f"{a2.round(4).tolist()}; give a direction along the surface")
    cross = normalize(np.cross(a2, feed))
    feed = np.cross(cross, a2)
    return feed, cross


def choose_angle(surface, tool, *, spacing: float | None = None, angles=AUTO_ANGLES,
                 max_gap: float = 1e-3):
    """Pick the raster feed angle (rad from the first principal axis) for ``surface``.

    For each candidate angle the cutting planes' spacing is the default full-coverage spacing
    (:func:`raster_spacing`) or the given ``spacing``; the predicted contact length is
    ``Σ a |n × c| / d`` (slices ``d`` apart lie ``d / |n × c|`` apart on the surface) and the predicted
    gap the area share left between swaths.  The shortest candidate whose gap is at most
    ``max_gap`` wins; if none qualifies, the one with the smallest gap.

    Returns
    -------
    angle : float
        rad.
    choice : SpacingChoice or None
        The default-spacing computation for the winner (None when ``spacing`` was given).
    rule : str
        A one-line description of the decision, for metadata.
    """
    from .widths import effective_widths, gap_fraction, pad_scale_samples

    samples = pad_scale_samples(surface, tool)
    rows = []
    for a in angles:
        _, cross = feed_and_cross(surface, angle=a)
        if spacing is None:
            ch = raster_spacing(surface, tool, cross, samples=samples)
            d, gap = ch.spacing, ch.gap_fraction
        else:
            ch = None
            w_eff, _ = effective_widths(samples, tool, cross)
            d, gap = spacing, gap_fraction(w_eff, samples.areas, spacing)
        slope = np.linalg.norm(np.cross(samples.normals, cross), axis=1)
        length = float(np.sum(samples.areas * slope) / d)
        rows.append((a, gap, length, ch))
    best, rule = select_direction(rows, max_gap, "raster")
    return best[0], best[3], rule


def select_direction(rows, max_gap: float, planner: str):
    """The direction rule shared by the planners that pick their own feed direction.

    ``rows`` are ``(angle_rad, predicted_gap_fraction, predicted_length_m, payload)``.  The shortest
    candidate whose gap is at most ``max_gap`` wins, near-ties (within 2 %) going to the earlier
    candidate (the principal axis first); if none qualifies, the one with the smallest gap.
    Returns the winning row and a one-line description for metadata.
    """
    ok = [r for r in rows if r[1] <= max_gap]
    if ok:
        shortest = min(r[2] for r in ok)
        best = next(r for r in ok if r[2] <= 1.02 * shortest)
    else:
        best = min(rows, key=lambda r: r[1])
    summary = ", ".join(f"{math.degrees(r[0]):.0f} deg: {r[2]:.2f} m, gap {100 * r[1]:.2f}%" for r in rows)
    rule = f"auto: shortest predicted path with gap <= {100 * max_gap:.1f}% among ({summary})"
    log.info("%s direction %s", planner, rule)
    return (float(best[0]),) + tuple(best[1:]), rule


def plane_offsets(heights: np.ndarray, spacing: float) -> tuple[np.ndarray, float]:
    """Offsets ``(p,)`` of planes ``spacing`` apart centred on the extent of ``heights`` (m).

    ``p = ceil(extent / spacing)`` (at least 1), so the margin left at each end, returned second,
    is the same at both ends and lies in ``(0, spacing / 2]``.
    """
    lo, hi = float(np.min(heights)), float(np.max(heights))
    extent = hi - lo
    n = max(int(math.ceil(extent / spacing)), 1)
    if n > MAX_PLANES:
        raise InputError(f"spacing {spacing * 1e3:.4g} mm would need {n} cutting planes across "
                         f"{extent * 1e3:.1f} mm (limit {MAX_PLANES}); is the spacing in metres?")
    offsets = 0.5 * (lo + hi) + (np.arange(n) - 0.5 * (n - 1)) * spacing
    margin = 0.5 * (extent - (n - 1) * spacing)
    return offsets, margin


def snake_order(polylines, feed, cross, surface, point_spacing) -> list[Pass]:
    """Orient and order fragments plane by plane, alternating the travel direction; resample."""
    by_plane: dict[int, list] = {}
    for pl in polylines:
        by_plane.setdefault(pl.plane, []).append(pl)
    passes = []
    sign = 1.0
    for plane in sorted(by_plane):
        travel = sign * feed
        oriented = [_orient(pl, travel, cross) for pl in by_plane[plane]]
        oriented.sort(key=lambda pl: float(pl.points[0] @ travel))
        for pl in oriented:
            sm = resample(pl, point_spacing)
            normals = normalize(sm.values)
            bad = np.linalg.norm(normals, axis=1) < 0.5
            if bad.any():   # opposite vertex normals across a fold: fall back to the facet normal
                normals[bad] = surface.face_normals[sm.faces[bad]]
            passes.append(Pass(sm.points, normals))
        sign = -sign
    return passes


def _orient(pl, travel, cross):
    """Run an open fragment along ``travel``; start a closed loop at its rearmost point and run it
    counter-clockwise about ``cross`` (the plane normal), for a deterministic result."""
    proj = pl.points @ travel
    if not pl.closed:
        return pl if proj[-1] >= proj[0] else pl.reversed()
    pl = pl.rolled(int(np.argmin(proj[:-1])))
    rel = pl.points - pl.points[0]
    if np.cross(rel[:-1], rel[1:]).sum(axis=0) @ cross < 0:
        pl = pl.reversed()
    return pl


def _is_number(x) -> bool:
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, bool)


def _positive(name: str, value) -> float:
    if not (_is_number(value) and math.isfinite(value) and value > 0):
        raise InputError(f"{name} must be a positive, finite length in metres, got {value!r}")
    return float(value)
