"""One direction of the uniform planner: the passes laid from a seed curve, generation after
generation, on the working mesh (:class:`swath.plan.uniform_model._Context`), and their resampling on
the part as a ToolPath.  :mod:`swath.plan.uniform` tries several directions and keeps the best."""

from __future__ import annotations

import logging
import math
import time

import numpy as np

from ..core import ToolPath
from ..errors import InfeasibleError, InputError
from ..surface.geometry import normalize
from .common import feed_and_cross
from .slicing import level_sets, resample, slice_mesh
from .uniform_model import _Context
from .uniform_passes import (
    _area,
    _chord_if_small_loop,
    _finished,
    _insert_near,
    _on_surface_pass,
    _touch_up,
    _touched_by,
)

log = logging.getLogger("swath.plan")


def _layout(ctx: _Context, angle, *, overlap, seed, min_pass_length, max_passes) -> dict:
    """The passes of :func:`_plan` as working-mesh polylines, before they are resampled on the
    surface (the point spacing plays no part in where they lie): a small picklable record."""
    t0 = time.perf_counter()
    W, tool = ctx.work, ctx.tool
    R = tool.pad_radius
    if isinstance(angle, np.ndarray):
        feed_dir, cross = feed_and_cross(ctx.surface, direction=angle)
        a0 = ctx.surface.principal_axes[1][0]
        angle = math.atan2(float(np.cross(a0, feed_dir) @ np.cross(feed_dir, cross)), float(a0 @ feed_dir))
    else:
        feed_dir, cross = feed_and_cross(ctx.surface, angle=angle)
    step = min(2e-3, 0.5 * ctx.work_spacing)

    generations = []          # each: list of pass points (k, 3)
    notes: list[str] = []     # what the kept plan must warn about
    stalled = False           # the generations stopped because one reached no new area
    covered = np.zeros(len(W.vertices), bool)
    current = _seed_curves(ctx, seed, cross, step)
    reach = 0.5 - overlap     # pass centre this many local widths beyond the covered edge
    stop = ctx.band_stop(reach)   # the distances a generation reads lie within this of its sources
    if isinstance(seed, str) and seed == "middle":
        first = (_finished(ctx, current, step, min_pass_length)
                 or _finished(ctx, current, step, min_pass_length, cut=False))
        if not first:
            raise InfeasibleError("the middle slice of the surface is shorter than min_pass_length")
        generations.append(first)
        for pts in first:
            covered |= ctx.touched(pts)
        sources = None
    else:
        sources = np.vstack(current)

    for _ in range(max_passes):
        # Distance from what is covered so far (or from the seed before the first pass), out to
        # the stop distance only (inf beyond it).
        src = ctx.nearest_vertices(sources) if sources is not None else ctx.frontier(covered)
        if len(src) == 0:
            break
        d = ctx.distance(src, stop)
        if sources is None:
            d[covered] = 0.0
        left = (d > 0) & ~covered
        if _area(W, left) <= 1e-4 * W.area:
            break
        band = np.flatnonzero((d <= 2.5 * R) & left)
        w_here = _band_widths(ctx, d, band, reach)
        # beyond the stop distance g > 0 (no face the level cuts has a corner there)
        g = np.where(np.isfinite(d), d - reach * w_here, stop)
        pieces = level_sets(W.vertices, W.faces, g, [0.0], edges=ctx.edges)
        new, gained = _kept_pieces(ctx, pieces, step, min_pass_length, covered, len(generations))
        if not pieces or (ctx.distance_method == "band" and not (gained & ~covered).any()):
            # The far boundary is nearer than a full step: pull the last pass in so its ribbon
            # reaches the boundary.  With the band distance this is done too where the level set
            # left only pieces too short to keep along that boundary (the square bowl's far edge:
            # 6 % of it left bare otherwise); the heat method's plans are kept as they were.  This
            # reads the largest distance left, so any vertex the band left without one gets it.
            if not np.isfinite(d[left]).all():
                d = ctx.distance(src)
                if sources is None:
                    d[covered] = 0.0
            w_here = _band_widths(ctx, d, band, reach, everywhere=True)
            reached = np.isfinite(d)
            if not (left & reached).any():                  # pragma: no cover - a connected mesh
                stalled = True
                break
            d_far = float(np.max(d[left & reached]))
            w_left = float(np.median(w_here[left]))
            level = max(d_far - reach * w_left, 0.5 * d_far)
            far = level_sets(W.vertices, W.faces, np.where(reached, d - level, d_far), [0.0], edges=ctx.edges)
            if far or not pieces:
                pieces = far
                new, gained = _kept_pieces(ctx, pieces, step, min_pass_length, covered, len(generations))
        log.debug("uniform generation %d: %d level-set pieces, %d kept, uncovered %.4f m2", len(generations),
                  len(pieces), len(new), _area(W, left))
        if not (gained & ~covered).any():
            # What is left is judged after the touch-ups (below): a warning only if area stays untouched.
            stalled = True
            log.info("uniform: a pass generation covered nothing new, so the planner stopped there")
            break
        generations.append(new)
        covered |= gained
        sources = None
    else:
        notes.append(f"uniform: stopped after max_passes={max_passes} generations")
        log.info("%s", notes[-1])

    passes_pts = [p for gen in generations for p in gen]
    generation_of = {id(p): g for g, gen in enumerate(generations) for p in gen}
    if not passes_pts:
        raise InfeasibleError("uniform found no pass: the surface is narrower than the shortest allowed pass "
                              f"({min_pass_length * 1e3:.1f} mm) in every direction tried")
    covered, touch_ups = _touch_up(ctx, passes_pts, covered, step, min_pass_length)
    merged = _insert_near(passes_pts, touch_ups)
    touch_up_index = [i for i, q in enumerate(merged) if any(q is t for t in touch_ups)]
    # Coverage the planner itself predicts (pad-touched area of the working mesh, with the sink
    # capped as in _Context.touched); the simulator's figure is the one to trust.
    covered_pred = float(W.vertex_areas[covered].sum() / W.area)
    if covered_pred < 0.995:
        why = "; the passes stopped where one more generation reached no new area" if stalled else ""
        notes.append(f"uniform: {100 * (1 - covered_pred):.1f} % of {ctx.surface.name or 'the part'} is predicted to "
                     f"stay untouched (regions no pass reaches{why}); lower the overlap's step or segment the part")
    return dict(angle=float(angle), feed_dir=feed_dir, polylines=merged,
                levels=[generation_of.get(id(p), -1) for p in merged], touch_up_index=touch_up_index,
                covered_pred=covered_pred, notes=notes, n_generations=len(generations), n_touch_ups=len(touch_ups),
                overlap=float(overlap), seed=seed if isinstance(seed, str) else "polyline",
                min_pass_length=float(min_pass_length), work_spacing=ctx.work_spacing,
                seconds=time.perf_counter() - t0)


def _kept_pieces(ctx: _Context, pieces, step, min_pass_length, covered, generation):
    """The passes ``[(k, 3), ...]`` a generation keeps of its level-set ``pieces`` and the working
    vertices ``(n,)`` bool they touch: the pieces cut at sharp turns, or, where that leaves nothing
    that reaches new area, the whole pieces."""
    new = _finished(ctx, pieces, step, min_pass_length)
    gained = _touched_by(ctx, new)
    if not (gained & ~covered).any():
        # Cutting at sharp turns left nothing that reaches new area (a short seed stretch gives a
        # first level set curled round it; a pocket's level set is a small loop): a pass that
        # makes the tool slow down beats none.  A small loop is crossed straight instead.
        whole = [_chord_if_small_loop(ctx, p, step, min_pass_length)
                 for p in _finished(ctx, pieces, step, min_pass_length, cut=False)]
        gained_whole = _touched_by(ctx, whole)
        log.debug("uniform generation %d: cut pieces gain nothing; whole pieces gain %.4f m2",
                  generation, _area(ctx.work, gained_whole & ~covered))
        new, gained = whole, gained_whole
    return new, gained


def _band_widths(ctx: _Context, d: np.ndarray, band: np.ndarray, reach: float, *,
                 everywhere: bool = False, directions=None) -> np.ndarray:
    """Swath widths ``w_here`` ``(n,)`` (m) across the passes that follow the level sets of the
    distance field ``d`` ``(n,)`` (m): ``2R`` off the ``band`` vertices, the local contact model's
    width on them.

    Only the zero level set of ``g = d - reach * w_here`` is extracted, and it reads ``g`` only on
    the faces it cuts (a face is cut where some corner has ``g < 0`` and some not).  Each band
    vertex's width lies between bounds over all directions (:attr:`WidthModel.min_width`,
    :attr:`WidthModel.max_width`), so where ``d`` is beyond ``reach`` times them the sign of ``g``
    is known without the width.  The widths are computed first where the sign is not known, then on
    every band vertex of a face the signs show is cut; the others get a bound of the right side
    (``g`` keeps its sign).  The level set is then the same, bit for bit, as with every width
    computed.  ``everywhere=True`` (or ``reach <= 0``) computes every band width.
    ``directions()``, if given, returns ``ctx.gradient_directions(d)`` ``(n, 3)``; otherwise the
    directions are computed at the vertices that need them only.
    """
    W = ctx.work
    w_here = np.full(len(W.vertices), 2 * ctx.tool.pad_radius)
    if len(band) == 0:
        return w_here

    def exact(idx):
        if len(idx):
            gdir = directions()[idx] if directions is not None else ctx.gradient_directions(d, idx)
            w_here[idx] = ctx.widths.across(idx, np.cross(W.normals[idx], gdir))

    if everywhere or not reach > 0:
        exact(band)
        return w_here
    high = ctx.widths.max_width[band]
    low = ctx.widths.min_width[band] * (1.0 - 1e-6)
    positive = d[band] - reach * (high * (1.0 + 1e-9)) > 0.0         # g > 0 whatever the width
    negative = d[band] - reach * low < 0.0                           # g < 0 whatever the width
    unknown = ~(positive | negative)                                 # (NaN bounds land here)
    w_here[band[positive]] = high[positive]
    w_here[band[negative]] = low[negative]
    exact(band[unknown])
    below = d - reach * w_here < 0.0                                 # now the sign of g everywhere
    F = W.faces
    b0, b1, b2 = below[F[:, 0]], below[F[:, 1]], below[F[:, 2]]
    cut = (b0 | b1 | b2) & ~(b0 & b1 & b2)
    on_cut_face = np.zeros(len(W.vertices), bool)
    on_cut_face[F[cut].ravel()] = True
    known = ~unknown
    exact(band[known & on_cut_face[band]])
    return w_here


def _toolpath(surface, layout: dict, *, point_spacing, rule, extra_meta=None) -> ToolPath:
    """The :func:`_layout` passes resampled ``point_spacing`` (m) apart on the surface, as a ToolPath."""
    t0 = time.perf_counter()
    touch_up_index = layout["touch_up_index"]
    passes = [_on_surface_pass(surface, p, point_spacing, level=level,
                               kind="touch_up" if i in touch_up_index else "pass")
              for i, (p, level) in enumerate(zip(layout["polylines"], layout["levels"]))]
    angle = layout["angle"]
    meta = dict(overlap_fraction=layout["overlap"], direction_rad=angle, direction_rule=rule,
                predicted_coverage_fraction=layout["covered_pred"],
                feed_direction=layout["feed_dir"].tolist(), seed=layout["seed"],
                n_passes=len(passes), n_generations=layout["n_generations"], n_touch_up_passes=layout["n_touch_ups"],
                touch_up_passes=list(touch_up_index), order_hint="zigzag", warnings=list(layout["notes"]),
                work_spacing_m=layout["work_spacing"],
                point_spacing_m=float(point_spacing), min_pass_length_m=layout["min_pass_length"],
                plan_time_s=layout["seconds"] + time.perf_counter() - t0)
    if extra_meta:
        meta.update(extra_meta)
    log.info("uniform %s: direction %.0f deg, %d passes in %d generations, %.2f m, %.1f s", surface.name,
             math.degrees(angle), len(passes), layout["n_generations"], sum(p.length for p in passes),
             meta["plan_time_s"])
    return ToolPath(surface, tuple(passes), "uniform", meta)


def _seed_curves(ctx, seed, cross, step) -> list[np.ndarray]:
    """Seed polylines (each (k, 3), on the working mesh)."""
    W = ctx.work
    if isinstance(seed, str):
        h = W.vertices @ cross
        if seed == "boundary":
            if not W.boundary_loops:
                raise InfeasibleError("the surface has no boundary to seed from; use seed='middle'")
            return [_boundary_seed(W, np.cross(cross, _mean_normal(W)), h, ctx.tool.pad_radius)]
        if seed == "middle":
            mid = 0.5 * (h.min() + h.max())
            lines = slice_mesh(W.vertices, W.faces, cross, [mid])
            return [resample(pl, step).points for pl in lines]
        raise InputError(f"seed must be 'boundary', 'middle' or a (k, 3) polyline, got {seed!r}")
    pts = np.asarray(seed, float)
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 2 or not np.isfinite(pts).all():
        raise InputError(f"a seed polyline must be a finite (k>=2, 3) array of points in metres, got {pts.shape}")
    closest, dist, _ = W.closest_points(pts)
    if dist.max() > ctx.tool.pad_radius:
        raise InputError(f"the seed polyline lies up to {dist.max() * 1e3:.1f} mm off the surface; "
                         "give points on the surface")
    return [closest]


def _mean_normal(W) -> np.ndarray:
    return normalize((W.face_normals * W.face_areas[:, None]).sum(axis=0)[None])[0]


def _boundary_seed(W, feed, h, R) -> np.ndarray:
    """The stretch of boundary on the low side across the feed that runs along the feed.

    Starting from the boundary vertex lowest in ``h`` (the coordinate across the feed), the loop is
    followed both ways while its tangent (smoothed over about R/2) stays within 50 degrees of the
    feed direction: the whole straight edge of a panel, the trailing edge of a blade, and only the
    near-parallel part of a ragged scan edge.
    """
    loops = W.boundary_loops
    k = int(np.argmin([h[l].min() for l in loops]))
    loop = loops[k]
    pts = W.vertices[loop]
    seg = np.linalg.norm(np.roll(pts, -1, axis=0) - pts, axis=1)
    span = max(3, int(np.ceil(0.5 * R / max(np.median(seg), 1e-9))))
    tangent = normalize(np.roll(pts, -span, axis=0) - np.roll(pts, span, axis=0))
    local = normalize(np.roll(pts, -1, axis=0) - np.roll(pts, 1, axis=0))
    # Both the smoothed and the local tangent must run along the feed: smoothing alone would
    # carry the run a little way round a corner.
    cos50 = np.cos(np.radians(50.0))
    along = (np.abs(tangent @ feed) >= cos50) & (np.abs(local @ feed) >= cos50)
    n = len(loop)
    start = int(np.argmin(h[loop]))
    lo = hi = start
    while along[(lo - 1) % n] and (hi - lo) < n - 1:
        lo -= 1
    while along[(hi + 1) % n] and (hi - lo) < n - 1:
        hi += 1
    run = [(i % n) for i in range(lo, hi + 1)]
    return pts[run] if len(run) >= 2 else pts[[start, (start + 1) % n]]
