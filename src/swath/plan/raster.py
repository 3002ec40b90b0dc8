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
from dataclasses import dataclass

import numpy as np

from ..contact.widths import raster_spacing, surface_memo
from ..core import Pass, ToolPath
from ..errors import InfeasibleError, InputError
from ..surface.topology import mesh_edges
from .common import check_min_pass_length, feed_and_cross, plane_passes, positive, select_direction, split_direction
from .slicing import slice_mesh

log = logging.getLogger("swath.plan")

#: Refuse plans that would need more cutting planes than this (a spacing typo such as 1e-6).
MAX_PLANES = 20000


#: Feed angles (rad, from the first principal axis) tried when the direction is left to swath.
AUTO_ANGLES = (0.0, math.pi / 4, math.pi / 2, 3 * math.pi / 4)


def raster(surface, tool, *, spacing: float | None = None, direction=None, point_spacing: float = 1e-3,
           min_pass_length: float | None = None, cross_direction=None, fill_gaps: bool | None = None,
           edge_margin: float | None = None, spacing_on: str | None = None, progress=None) -> ToolPath:
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
    direction : None, float or (3,) float
        Feed direction.  None (default): chosen among :data:`AUTO_ANGLES` by :func:`choose_angle`
        — the direction whose planes cross the part's curvature, so the equal spacing wastes least
        (the shortest predicted path whose predicted gap stays within 0.1 %; near-ties go to the
        principal axis).  A number: the angle (rad) of the feed from the surface's first principal
        axis (largest spread) about its third axis (the normal of the best-fit plane).  A vector:
        the feed direction in the part frame (only its component in the best-fit plane matters).
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

    fill_gaps : bool, optional
        After the planes, check where the passes really leave the surface untouched (beside holes,
        at a piece's far side, where slivers were dropped, in the corners a diagonal direction
        leaves; :mod:`swath.plan.gaps`) and add a short fill pass across each such patch.
        ``predicted_gap_fraction`` is then measured from where the passes fall.  None (default):
        fill with the default spacing, not with a given ``spacing`` — the spacing the user asked for
        is kept (one plane per ``spacing`` across each piece, no extra passes) and the share of the
        surface it leaves untouched is measured the same way, in ``predicted_gap_fraction``, with a
        warning in ``metadata["warnings"]`` above :data:`GAP_WARN_SHARE`.
    edge_margin : float, optional
        Least distance (m, along the cross direction or on the surface, as ``spacing_on`` says)
        from each piece's extent to its outermost planes.  None (default): the planes keep ``spacing`` and the margin is what is left,
        anywhere in ``(0, spacing / 2]`` — on the flat plate with a rotary pad at its least-ripple
        spacing 6.5 mm, the pad more than half off the part.  Given: where the margin left would
        be smaller, the outermost planes move in to ``edge_margin`` (at most half the spacing of
        planes spread evenly over the extent, ``extent / (2 p)``) and the same number of planes
        spread evenly between them (spacing below ``spacing``: same contact length, the edge no
        farther from a pass than the middle between two passes); ``math.inf`` spreads the planes
        evenly over every piece.  See :func:`plane_offsets` for what it did to the removal.
    spacing_on : {"surface", "projection"}, optional
        Where ``spacing`` (and ``edge_margin``) is measured.  ``"surface"``: on the surface across
        the passes, the planes placed at equal steps of the mean surface distance between them
        (:func:`swath.plan.surface_planes.surface_plane_offsets`), so on a part sloping by θ across
        the passes they lie ``spacing`` apart there, not ``spacing / cos θ``.  ``"projection"``:
        along the cross direction, equally spaced planes.  None (default): ``"surface"`` for a
        given ``spacing``, ``"projection"`` for the default covering spacing (worked out in
        projection: the chord times the slope factor).  The same planes on a part flat across the
        passes.  ``"swath"``: on the surface, with the steps following the local swath width:
        neighbouring planes lie about ``spacing · w / w_ref`` apart there, ``w`` the contact
        model's width across the passes along their level (the median over the samples within
        half a spacing of it) and ``w_ref`` the median over the part, so ``spacing`` is the step
        where the swath has its median width and the ratio of step to width is the same
        everywhere (:func:`swath_widths_across`, ``relative_width`` of
        :func:`swath.plan.surface_planes.surface_plane_offsets`).  Without a ``spacing``,
        ``"swath"`` places the covering spacing as ``"projection"`` does (that rule already
        follows the narrowest chord).
    progress : callable, optional
        Unused (raster is fast); accepted so every planner has the same call shape.

    Returns
    -------
    ToolPath
        Passes piece by piece (``Pass.region``; every connected piece gets planes over its own
        extent), level by level (``Pass.level`` = plane index, increasing along the cross
        direction), each running along the feed, several fragments on a plane in order along it;
        fill passes (``kind="touch_up"``) on the level nearest to them.  The ``order`` stage's
        ``snake`` method turns every other plane round (boustrophedon).  Points lie exactly on
        the mesh, ``≤ point_spacing`` apart along the pass; normals are the smooth vertex normals
        interpolated barycentrically in the face holding each point.
        ``metadata``: spacing_m, angle_rad, feed_direction, cross_direction, n_planes, n_passes,
        dropped_fragments, dropped_length_m, point_spacing_m, min_pass_length_m, margin_m (the
        largest margin of any piece), spacing_rule, edge_rule (how ``edge_margin`` placed the
        outer planes), plane_spacing_m (per piece,
        the mean distance between its planes, below spacing_m where ``edge_margin`` moved them),
        plane_extent_m (per piece, its extent across the planes), spacing_on (margins, spacings and
        extents are measured there; with ``"swath"``, plane_extent_m is the extent in steps at the
        reference width times ``spacing``, and swath_reference_width_m is ``w_ref``), predicted_gap_fraction (not with a given spacing and ``fill_gaps=False``), and
        ``warnings`` when that share is above :data:`GAP_WARN_SHARE`.

    Raises
    ------
    InputError
        On a non-positive or non-finite ``spacing``, ``point_spacing`` or ``min_pass_length``, a
        non-finite ``angle``, a bad ``direction``, a negative ``edge_margin`` or a spacing needing more than
        :data:`MAX_PLANES` planes.
    InfeasibleError
        When no slice fragment is long enough to become a pass.
    """
    t_start = time.perf_counter()
    point_spacing = positive("point_spacing", point_spacing)
    if spacing is not None:
        spacing = positive("spacing", spacing)
    min_pass_length = check_min_pass_length(min_pass_length, tool.pad_radius)
    if edge_margin is not None and not edge_margin >= 0:                  # NaN fails too
        raise InputError(f"edge_margin must be a length >= 0 in m, math.inf or None, got {edge_margin!r}")
    if spacing_on is None:
        spacing_on = "projection" if spacing is None else "surface"
    if spacing_on not in SPACING_ON:
        raise InputError(f"spacing_on must be one of {', '.join(SPACING_ON)}, got {spacing_on!r}")
    if spacing_on == "swath" and spacing is None:
        spacing_on = "projection"             # the covering spacing follows the narrowest chord already
    angle, vector = split_direction(direction)
    if fill_gaps is None and spacing is None:
        fill_gaps = True                      # a spacing the user fixed is honoured (None: measured, not topped up)

    if angle is None and vector is None and cross_direction is None:
        return _auto_direction(surface, tool, spacing=spacing, point_spacing=point_spacing,
                               min_pass_length=min_pass_length, fill_gaps=fill_gaps, edge_margin=edge_margin,
                               spacing_on=spacing_on, t_start=t_start)
    feed, cross = feed_and_cross(surface, angle=angle or 0.0, direction=vector)
    direction_rule = "given direction" if vector is not None else "given angle"
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
    return _plan_along(surface, tool, feed, cross, angle=angle or 0.0, direction_rule=direction_rule, spacing=spacing,
                       point_spacing=point_spacing, min_pass_length=min_pass_length, fill_gaps=fill_gaps,
                       edge_margin=edge_margin, spacing_on=spacing_on, t_start=t_start)


#: Where a raster's spacing is measured (``raster(spacing_on=...)``).
SPACING_ON = ("surface", "projection", "swath")

#: Predicted untouched share of the surface above which a plan warns.
GAP_WARN_SHARE = 5e-3


#: Contact length (m) one more pass is worth when directions are compared: its approach, retract
#: and the move to the next pass take about as long as this much contact at a 50 mm/s feed.
PASS_ALLOWANCE = 0.1


def _auto_direction(surface, tool, *, spacing, point_spacing, min_pass_length, fill_gaps, edge_margin, t_start,
                    spacing_on="surface"):
    """Plan along each of :data:`AUTO_ANGLES` and keep the cheapest: contact length plus
    :data:`PASS_ALLOWANCE` per pass, fill passes included (near-ties within 2 % go to the earlier
    angle, the principal axis first)."""
    planned = []
    for a in AUTO_ANGLES:
        feed, cross = feed_and_cross(surface, angle=a)
        passes, finish = _plan_along(surface, tool, feed, cross, angle=a, direction_rule="candidate",
                                     spacing=spacing, point_spacing=point_spacing, min_pass_length=min_pass_length,
                                     fill_gaps=fill_gaps, edge_margin=edge_margin, spacing_on=spacing_on,
                                     t_start=t_start, defer_fill=True)
        planned.append((a, sum(p.length for p in passes) + PASS_ALLOWANCE * len(passes), finish))
    # Fill passes only add to a candidate's cost: the candidates are completed cheapest first, and
    # one that costs more than 1.02 times a completed one before its fill passes cannot be chosen,
    # nor be the cheapest, so its gap check is not made (it is listed with its cost before filling).
    rows: list = [None] * len(planned)
    unfilled = set()
    for i in sorted(range(len(planned)), key=lambda i: planned[i][1]):
        a, before, finish = planned[i]
        done = [r[1] for r in rows if r is not None and r[0] not in unfilled]
        if fill_gaps and done and before > 1.02 * min(done) * (1 + 1e-9):
            tp = finish(False)
            unfilled.add(a)
        else:
            tp = finish(fill_gaps)
        rows[i] = (a, tp.contact_length + PASS_ALLOWANCE * len(tp.passes), tp)
    cheapest = min(r[1] for r in rows)
    best = next(r for r in rows if r[1] <= 1.02 * cheapest)
    summary = ", ".join(f"{math.degrees(a):.0f} deg: {len(tp.passes)} passes, {tp.contact_length:.2f} m"
                        + (" before fill passes (cannot be chosen)" if a in unfilled else "")
                        for a, _, tp in rows)
    rule = (f"auto: least contact length + {PASS_ALLOWANCE:g} m per pass (fill passes included) among "
            f"({summary})")
    log.info("raster direction %s", rule)
    for msg in best[2].metadata.get("warnings", []):
        log.warning("%s", msg)
    meta = dict(best[2].metadata, direction_rule=rule,
                candidates=[dict(direction_deg=math.degrees(a), length_m=tp.contact_length, n_passes=len(tp.passes),
                                 predicted_gap_fraction=(None if a in unfilled else
                                                         tp.metadata.get("predicted_gap_fraction")),
                                 filled=bool(fill_gaps) and a not in unfilled)
                            for a, _, tp in rows])
    return best[2].replace(metadata=meta)


def _plan_along(surface, tool, feed, cross, *, angle, direction_rule, spacing, point_spacing, min_pass_length,
                fill_gaps, t_start, edge_margin=None, spacing_on="surface", defer_fill=False):
    """The raster plan with this feed and cutting-plane normal (see :func:`raster`); with
    ``defer_fill``, the planes' passes and ``finish(fill_gaps) -> ToolPath``, which completes it."""
    choice = None
    if spacing is None:
        if choice is None:
            choice = raster_spacing(surface, tool, cross)
        spacing, rule = choice.spacing, choice.rule
    else:
        rule = "given"
        choice = None

    # Planes for each connected piece over its own extent, so no piece is left between two planes.
    pieces = surface.face_pieces()
    passes, n_planes, margin, dropped, dropped_length, n_slices = [], 0, 0.0, 0, 0.0, 0
    plane_spacing, plane_extent = [], []
    heights = surface.vertices @ cross
    across = swath_widths_across(surface, tool, cross, pieces) if spacing_on == "swath" else None
    for k in range(len(pieces)):
        offsets, m, steps, extent = piece_offsets(surface, pieces, k, heights, cross, spacing,
                                                  edge_margin=edge_margin or 0.0, spacing_on=spacing_on,
                                                  widths=across)
        margin = max(margin, m)
        plane_extent.append(extent)
        plane_spacing.append(float(np.mean(steps)) if len(steps) else float(spacing))
        n_planes += len(offsets)
        piece_f, piece_n = piece_faces(surface, pieces, k)
        slices = slice_mesh(surface.vertices, piece_f, cross, offsets, values=surface.normals,
                            edges=piece_edges(surface, pieces, k))
        n_slices += len(slices)
        lengths = np.array([pl.length for pl in slices])
        short = lengths < min_pass_length
        dropped += int(short.sum())
        dropped_length += float(lengths[short].sum())
        kept = [pl for pl, sh in zip(slices, short) if not sh]
        passes += plane_passes(kept, feed, piece_n, point_spacing, region=k)
    if not passes:
        along = float(np.ptp(surface.vertices @ feed))
        raise InfeasibleError(
            f"raster found no pass: {n_slices} slice fragments on {n_planes} planes, all shorter than "
            f"min_pass_length={min_pass_length * 1e3:.1f} mm (the part spans {along * 1e3:.1f} mm along the feed); "
            "lower min_pass_length or choose a feed direction along the part")

    def finish(fill_gaps):
        """The plan, fill passes added when ``fill_gaps`` (as in :func:`raster`)."""
        passes, n_fill, gap = planned, 0, None
        if fill_gaps:
            passes, n_fill, gap = _fill_gaps(surface, tool, planned, pieces, feed, cross, spacing, point_spacing)
        elif fill_gaps is None:
            from .gaps import CoverageCheck

            gap = CoverageCheck(surface, tool, feed).gap_fraction(passes)
        metadata = dict(
            spacing_m=float(spacing), angle_rad=float(angle or 0.0), direction_rule=direction_rule,
            feed_direction=feed.tolist(),
            cross_direction=cross.tolist(), n_planes=int(n_planes), n_pieces=len(pieces), n_passes=len(passes),
            n_fill_passes=n_fill, dropped_fragments=dropped, dropped_length_m=dropped_length,
            point_spacing_m=float(point_spacing), min_pass_length_m=float(min_pass_length), margin_m=float(margin),
            spacing_rule=rule, edge_rule=("spacing kept, margin what is left" if edge_margin is None else
                                          "planes spread evenly" if math.isinf(edge_margin) else
                                          f"outer planes at least {1e3 * edge_margin:.4g} mm in"),
            plane_spacing_m=plane_spacing, plane_extent_m=plane_extent, spacing_on=spacing_on,
        )
        if across is not None:
            metadata["swath_reference_width_m"] = across.reference
        if gap is not None:
            metadata["predicted_gap_fraction"] = gap
            if gap > GAP_WARN_SHARE:
                name = surface.name or "the surface"
                if fill_gaps:
                    msg = (f"raster: {100 * gap:.1f} % of {name} is predicted to stay untouched even after the fill "
                           "passes; lower the spacing, choose another direction or segment the part")
                else:
                    msg = (f"raster: the given spacing {1e3 * spacing:.4g} mm leaves {100 * gap:.1f} % of {name} "
                           f"untouched ({_count(len(passes), 'pass', 'passes')} on {_count(n_planes, 'plane', 'planes')}; "
                           f"the pad's contact reaches about {1e3 * _median_chord(surface, tool, cross):.0f} mm across "
                           "a pass); lower the spacing, "
                           "leave it out for the full-coverage default, or add fill passes (fill_gaps = true under "
                           "[planner_options] in a job file, fill_gaps=True in Python)")
                if direction_rule != "candidate":
                    log.warning("%s", msg)
                metadata["warnings"] = [msg]
        elif choice is not None:
            metadata["predicted_gap_fraction"] = choice.gap_fraction
        log.info("raster %s: spacing %.1f mm, %d planes, %d passes (%d fill), %d fragments dropped, %d points, %.2f s",
                 surface.name, spacing * 1e3, n_planes, len(passes), n_fill, dropped, sum(len(p.points) for p in passes),
                 time.perf_counter() - t_start)
        return ToolPath(surface, passes, "raster", metadata)

    planned = passes
    return (planned, finish) if defer_fill else finish(fill_gaps)


def _count(n: int, one: str, many: str) -> str:
    return f"{n} {one if n == 1 else many}"


def _median_chord(surface, tool, cross) -> float:
    """The median contact chord (m) across passes cut by planes normal to ``cross``: the width one
    pass covers, for the gap warning."""
    from ..contact.widths import effective_widths, pad_scale_samples

    w_eff, _ = effective_widths(pad_scale_samples(surface, tool), tool, cross)
    return float(np.median(w_eff))


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
    from ..contact.widths import effective_widths, gap_fraction, pad_scale_samples

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


def piece_edges(surface, pieces, k: int):
    """``mesh_edges`` of piece ``k`` of ``surface.face_pieces()`` (``pieces``), computed once per surface
    and shared by the candidate directions and the fill passes."""
    return surface_memo(surface, ("piece_edges", len(pieces), k), lambda: mesh_edges(surface.faces[pieces[k]]))


def piece_vertices(surface, pieces, k: int) -> np.ndarray:
    """Sorted indices of the vertices of piece ``k`` of ``surface.face_pieces()`` (``pieces``),
    computed once per surface and shared by the candidate directions."""
    def make():
        # np.unique(surface.faces[pieces[k]]): the same sorted indices, from a mask of the vertices used
        used = np.zeros(len(surface.vertices), bool)
        used[piece_faces(surface, pieces, k)[0].ravel()] = True
        return np.flatnonzero(used)

    return surface_memo(surface, ("piece_vertices", len(pieces), k), make)


def piece_faces(surface, pieces, k: int) -> tuple[np.ndarray, np.ndarray]:
    """``surface.faces[pieces[k]]`` ``(f, 3)`` and ``surface.face_normals[pieces[k]]`` ``(f, 3)`` of
    piece ``k`` of ``surface.face_pieces()`` (``pieces``), taken once per surface (read-only) and
    shared by the candidate directions and the fill passes (one memo entry for every piece)."""
    store = surface_memo(surface, ("piece_faces", len(pieces)), dict)
    if k not in store:
        faces, normals = surface.faces[pieces[k]], surface.face_normals[pieces[k]]
        faces.setflags(write=False)
        normals.setflags(write=False)
        store[k] = (faces, normals)
    return store[k]


def piece_of_vertex(surface, pieces) -> np.ndarray:
    """``(n,)`` int: the piece of ``surface.face_pieces()`` (``pieces``) each vertex belongs to (-1:
    none), computed once per surface (read-only)."""
    def make():
        out = np.full(len(surface.vertices), -1)
        for k in range(len(pieces)):
            out[piece_faces(surface, pieces, k)[0].ravel()] = k
        out.setflags(write=False)
        return out

    return surface_memo(surface, ("piece_of_vertex", len(pieces)), make)


def piece_offsets(surface, pieces, k: int, heights: np.ndarray, cross: np.ndarray, spacing: float, *,
                  edge_margin: float = 0.0, spacing_on: str = "surface",
                  widths: SwathWidths | None = None) -> tuple[np.ndarray, float, np.ndarray, float]:
    """The cutting planes of piece ``k`` of ``surface.face_pieces()`` (``pieces``): their offsets
    ``(p,)`` along ``cross`` (m), the margin left at each end, the steps between neighbours
    ``(p - 1,)`` and the piece's extent across the planes (m), all three measured where
    ``spacing_on`` says (:func:`raster`); ``heights`` are ``surface.vertices @ cross`` (m).  Where
    every face of the piece is parallel to ``cross`` (within 1e-9), the surface's steps are the
    projected ones and :func:`plane_offsets` places them.  ``spacing_on = "swath"`` needs the
    part's ``widths`` across the passes (:func:`swath_widths_across`)."""
    from .surface_planes import level_widths, surface_plane_offsets

    ids = piece_vertices(surface, pieces, k)
    faces = pieces[k]
    if spacing_on == "swath" and widths is not None:
        piece_f, normals = piece_faces(surface, pieces, k)
        mine = widths.piece == k
        piece = heights[ids]
        grid = np.linspace(piece.min(), piece.max(), max(2, int(math.ceil(4 * np.ptp(piece) / spacing)) + 1))
        ratio = (level_widths(widths.heights[mine], widths.widths[mine], widths.areas[mine], grid, 0.5 * spacing)
                 / widths.reference) if mine.any() else np.ones_like(grid)
        return surface_plane_offsets(heights, piece_f, surface.face_areas[faces], normals, cross, spacing,
                                     edge_margin=edge_margin, vertex_ids=ids, relative_width=(grid, ratio))
    if spacing_on in ("surface", "swath"):
        piece_f, normals = piece_faces(surface, pieces, k)
        if np.abs(normals @ cross).max() > 1e-9:
            return surface_plane_offsets(heights, piece_f, surface.face_areas[faces], normals, cross, spacing,
                                         edge_margin=edge_margin, vertex_ids=ids)
    offsets, margin = plane_offsets(heights[ids], spacing, edge_margin=edge_margin)
    return offsets, margin, np.diff(offsets), float(np.ptp(heights[ids]))


@dataclass(frozen=True)
class SwathWidths:
    """The contact model's swath width across the passes of one raster direction, at the part's
    pad-scale samples (:func:`swath_widths_across`).

    Attributes
    ----------
    heights : (s,) float
        ``x · cross`` of the samples, m.
    widths : (s,) float
        The width of the contact patch across the feed ``n × cross`` at each sample, m.
    areas : (s,) float
        The area each sample stands for, m².
    piece : (s,) int
        The piece of ``surface.face_pieces()`` each sample lies on.
    reference : float
        ``w_ref``: the area-weighted median of ``widths``, m.
    """

    heights: np.ndarray
    widths: np.ndarray
    areas: np.ndarray
    piece: np.ndarray
    reference: float


#: Samples whose surface slopes more steeply than this across the passes (``|n × c|`` below it,
#: the sine of the angle between the normal and the cutting-plane normal) are left out of the swath
#: widths: the feed ``n × c`` is ill-defined on a wall facing the planes.
WIDTH_SLOPE_FLOOR = 0.3


def swath_widths_across(surface, tool, cross, pieces) -> SwathWidths:
    """The swath width across passes cut by planes normal to ``cross`` (unit, (3,)), from the
    local contact model with curvature fitted over the pad
    (:func:`swath.contact.widths.pad_scale_samples`, :func:`swath.contact.widths.effective_widths`),
    for ``raster(spacing_on="swath")``; ``pieces`` is ``surface.face_pieces()``.

    Raises
    ------
    InfeasibleError
        When the model finds contact at no sample (no width to follow).
    """
    from ..contact.widths import effective_widths, pad_scale_samples

    samples = pad_scale_samples(surface, tool)
    w_eff, slope = effective_widths(samples, tool, cross)
    chord = w_eff / np.maximum(slope, 1e-300)
    ok = (slope >= WIDTH_SLOPE_FLOOR) & np.isfinite(chord) & (chord > 0)
    if not ok.any():
        raise InfeasibleError("spacing_on='swath': the contact model finds no swath width on this part across "
                              "these passes; use spacing_on='surface'")

    piece = piece_of_vertex(surface, pieces)[surface.kdtree.query(samples.points[ok])[1]]
    w, a = chord[ok], samples.areas[ok]
    k = np.argsort(w)
    cdf = np.cumsum(a[k])
    reference = float(w[k][min(int(np.searchsorted(cdf, 0.5 * cdf[-1])), len(k) - 1)])
    return SwathWidths(samples.points[ok] @ np.asarray(cross, float), w, a, piece, reference)


def plane_offsets(heights: np.ndarray, spacing: float, *, edge_margin: float = 0.0) -> tuple[np.ndarray, float]:
    """Offsets ``(p,)`` of planes about ``spacing`` apart centred on the extent of ``heights`` (m).

    ``p = ceil(extent / spacing)`` (at least 1), so the margin left at each end, returned second,
    is the same at both ends and lies in ``(0, spacing / 2]``.  When that margin is below
    ``edge_margin`` (m), the outermost planes move in to ``min(edge_margin, extent / (2 p))`` and
    the ``p`` planes are spread evenly between them (closer than ``spacing``; at the cap the
    planes sit in the middles of ``p`` equal strips, as far from the ends as the middle between
    two planes is from either).

    Measured on the built-in parts (``benchmarks/bench_feed.py``'s setting: 50 mm/s, the feed
    optimised to the least depth, simulated removal CoV over the samples at least R from the open
    boundary; the same passes and contact length in every row, coverage 1.0 and predicted gap 0),
    ``edge_margin`` None -> ``math.inf`` (planes spread evenly):

    * orbital pad, default spacing: plate 0.293 -> 0.258 (2.00 -> 1.97 R), panel 0.268 -> 0.125
      (1.95 -> 1.75 R), blade 0.232 -> 0.200 (at a least depth of 19.1 against 10.6 um);
    * orbital pad at its least-ripple 1.68 R: plate 0.099 -> 0.122, panel 0.120 -> 0.129 (0.107 at
      R/2), blade 0.186 -> 0.240 (0.202 at R/2);
    * rotary pad at its least-ripple 1.88 R: plate 0.140 -> 0.285 (0.135 at R/4, 0.215 at R/2),
      panel 0.152 -> 0.242, blade 0.295 -> 0.384.

    Moving the rotary plate's outer planes from 6.5 mm to 30 mm in takes the band just inside R
    from 1.30 to 0.96 of the interior mean, but the closer planes raise the ripple from 0.075 to
    0.287: a spacing away from the least-ripple one costs more than the edge band gives back.
    What helps the default spacing is the closer planes themselves (ripple 0.28 -> 0.25 on the
    plate, 0.24 -> 0.10 on the panel).
    """
    lo, hi = float(np.min(heights)), float(np.max(heights))
    extent = hi - lo
    n = max(int(math.ceil(extent / spacing)), 1)
    if n > MAX_PLANES:
        raise InputError(f"spacing {spacing * 1e3:.4g} mm would need {n} cutting planes across "
                         f"{extent * 1e3:.1f} mm (limit {MAX_PLANES}); is the spacing in metres?")
    margin = 0.5 * (extent - (n - 1) * spacing)
    if n > 1 and margin < edge_margin:
        margin = min(float(edge_margin), extent / (2 * n))
        step = (extent - 2 * margin) / (n - 1)
        return lo + margin + np.arange(n) * step, margin
    offsets = 0.5 * (lo + hi) + (np.arange(n) - 0.5 * (n - 1)) * spacing
    return offsets, margin


def _fill_gaps(surface, tool, passes, pieces, feed, cross, spacing, point_spacing):
    """Add fill passes where the plan leaves the surface untouched; returns the passes (sorted by
    piece, level and position along the feed), how many were added and the predicted gap share."""
    from .gaps import CoverageCheck, fill_passes, fill_rounds
    from .slicing import PlaneSlicer

    check = CoverageCheck(surface, tool, feed)
    owner = piece_of_vertex(surface, pieces)
    slicers: dict = {}

    def slice_piece(k, offset):
        # slice_passes(surface, pieces[k], cross, offset, feed, point_spacing, edges=...), with the
        # piece's faces, face normals and heights taken once for all its fill passes
        if k not in slicers:
            piece_f, piece_n = piece_faces(surface, pieces, k)
            slicers[k] = (PlaneSlicer(surface.vertices, piece_f, cross, values=surface.normals,
                                      edges=piece_edges(surface, pieces, k)), piece_n)
        cut, face_normals = slicers[k]
        return [(p.points, p.normals) for p in plane_passes(cut(offset), feed, face_normals, point_spacing)]

    def fills_for(patches, passes):
        # each pass's mean position across the feed, and its piece: the fill takes the level of the
        # nearest pass of its own piece
        across = np.array([float(np.mean(p.points @ cross)) for p in passes])
        piece = np.array([p.region for p in passes])
        new = []
        for idx in patches:
            nearest = surface.kdtree.query(check.points[idx[len(idx) // 2]])[1]
            k = int(max(owner[nearest], 0))

            def slicer(offset, k=k):
                return slice_piece(k, offset)

            for pts, nrm, off in fill_passes(check, [idx], slicer, feed, cross, tool.pad_radius):
                level = int(np.argmin(np.where(piece == k, np.abs(off - across), np.inf)))
                new.append(Pass(pts, nrm, level=passes[level].level, region=k, kind="touch_up"))
        return new

    passes, added = fill_rounds(check, passes, fills_for)
    passes.sort(key=lambda p: (p.region, p.level, float(p.points[0] @ feed)))
    return passes, added, check.gap_fraction(passes)
