"""Contact-aware uniform-coverage planner (Jaeger, ch. 4), on meshes.

Each pass is laid along the previous pass's ribbon boundary, so that neighbouring swaths meet
with a set overlap wherever the pad's real contact width changes with curvature:

1. A seed curve is chosen: part of the boundary on one side of the region (default), a slice
   through the middle, or a polyline the user gives.
2. From the latest passes a geodesic distance field ``d`` is computed over the surface (heat
   method, :mod:`potpourri3d`).  At every surface point the pad's swath width ``w_here`` across the
   would-be pass (whose feed runs along the level sets of ``d``) comes from the local contact model
   (principal curvatures and the solved sink at the set force), and ``w_prev`` is the width of the
   previous pass at its nearest point.
3. The next pass is the zero level set of
   ``g = d − (1 − overlap) · (w_prev + w_here) / 2``:
   its near ribbon edge meets the previous ribbon edge with ``overlap`` of the local width.  Jaeger
   finds this point by bisection along a cross curve from each base point of the previous pass;
   here the same condition is solved on every mesh edge (the zero crossing of ``g``), which gives
   the passes everywhere at once and breaks them cleanly at holes and ragged boundaries.
4. Passes are smoothed, projected back on the surface, cut where they turn too tightly for the
   tool to follow at speed (:data:`SHARP_TURN_SPEED_FRACTION`), and repeated until no uncovered
   area remains; the last pass is pulled in so its ribbon reaches the far boundary.  Pockets the
   pad rode over get short touch-up passes across them.  Passes are finally ordered zig-zag (each
   starts at the end nearest the previous one's end); the trajectory stage adds the short
   cross-over links.

The pass direction is free: :func:`uniform` tries several seed directions and keeps the one with
the shortest predicted cycle time (see ``direction``).
"""

from __future__ import annotations

import functools
import logging
import math
import multiprocessing
import pickle
import time
from concurrent.futures import ProcessPoolExecutor, as_completed

import numpy as np

from ..core import ToolPath
from ..core.cpus import usable_cpus
from ..errors import InfeasibleError, InputError
from ..surface.geometry import normalize
from .common import feed_and_cross
from .slicing import level_sets, resample, slice_mesh
from .uniform_model import _Context
from .uniform_passes import _area, _finished, _insert_near, _on_surface_pass, _touch_up, _touched_by

log = logging.getLogger("swath.plan")


#: A pass is cut where following it at the feed would turn the tool about its axis faster than
#: ``max_angular`` / this fraction, i.e. where the angular-speed limit would slow the pad below this
#: fraction of the feed.  A pad that slows in contact dwells, and a tight hook or a small loop of a
#: level set (a pass turning round at a part edge, circling a bump) grinds a ring into the part; the
#: pieces either side are kept and the tool turns in the air between them instead.
SHARP_TURN_SPEED_FRACTION = 0.5

#: Candidate seed directions (rad from the first principal axis) for ``direction="auto"``.
AUTO_DIRECTIONS = tuple(np.radians([0.0, 30.0, 60.0, 90.0, 120.0, 150.0]))


def uniform(surface, tool, *, overlap: float = 0.1, direction=None, seed="boundary",
            point_spacing: float = 1e-3, min_pass_length: float | None = None, max_passes: int = 400,
            feed: float = 0.05, max_angular: float = 1.0, cost=None,
            work_spacing: float | None = None, progress=None, workers: int | None = None) -> ToolPath:
    """Cover a surface with passes laid along each other's ribbon boundaries (uniform coverage).

    Parameters
    ----------
    surface : Surface
        The part surface (normals toward the tool).
    tool : Tool
        The pad; its contact model sets the swath widths.
    overlap : float
        Overlap of neighbouring swaths as a fraction of the local width (default 0.1 = 10 %).
    direction : None, float or (3,) array
        Seed direction: the passes run along the feed direction at this angle (rad) from the
        surface's first principal axis (or along this vector, projected into the best-fit plane).
        None (default): plans with each of :data:`AUTO_DIRECTIONS` and keeps the cheapest by
        ``cost``.  The candidates are recorded in the metadata.
    seed : "boundary", "middle" or (k, 3) array
        The seed curve: the boundary on the low side across the feed direction, a slice through the
        middle (passes grow to both sides), or a polyline on the surface (m).
    point_spacing : float
        Arc-length step between pass points, m (default 1 mm).
    min_pass_length : float, optional
        Pieces shorter than this are dropped, m (default R/4).
    max_passes : int
        Safety limit on the number of pass generations.
    feed, max_angular : float
        Feed (m/s) and angular-speed limit (rad/s): a pass is cut where, at this feed, the tool
        would turn about its axis faster than ``max_angular`` / :data:`SHARP_TURN_SPEED_FRACTION`
        (the tool would slow and dwell there).
    cost : callable, optional
        ``cost(toolpath) -> (value, description)`` ranking candidate directions (lower is better),
        e.g. the predicted cycle time under the very limits and links the job's trajectory will
        use (:func:`swath.cli.job.cycle_time_cost` builds one).  Default: contact length plus the
        straight-line air distance between consecutive passes in zig-zag order, m.
    work_spacing : float, optional
        Edge length (m) the surface is subdivided to for the distance fields (default from the part
        size, between R/12 and R/4, coarsened if the mesh would exceed about
        :data:`MAX_WORK_VERTICES` vertices).
    progress : callable, optional
        ``progress(stage: str, done: int, total: int)``, called as candidate directions finish.
    workers : int, optional
        Processes that plan the candidate directions of automatic direction at once (default
        ``min(candidates, CPU count)``; 1 = one after another in this process).  On Linux the
        workers are forked after the working mesh is built here and share it; elsewhere each
        spawned worker builds its own.  Each ranks its candidates with ``cost``, which must then pickle (a
        module-level function or a record with ``__call__``; otherwise the candidates are planned
        here, one after another).  The plan is the same whatever the number of workers.

    Returns
    -------
    ToolPath
        ``metadata``: overlap_fraction, direction_rad, direction_rule, seed, n_passes, work_spacing_m,
        n_touch_up_passes and touch_up_passes (their indices in ``passes``; the passes also carry
        ``kind="touch_up"``), candidates (per direction: length_m, cost) for automatic direction,
        order_hint ``"zigzag"``.  Each pass's ``level`` is its generation.
    """
    pieces = surface.face_pieces()
    if len(pieces) > 1:
        # Each piece is covered on its own: a distance field from one piece's seed never reaches another.
        options = dict(overlap=overlap, direction=direction, seed=seed, point_spacing=point_spacing,
                       min_pass_length=min_pass_length, max_passes=max_passes, feed=feed, max_angular=max_angular,
                       cost=cost, work_spacing=work_spacing, progress=progress, workers=workers)
        return _per_piece(surface, tool, pieces, options)
    if not (isinstance(overlap, (int, float)) and 0.0 <= overlap < 0.9):
        raise InputError(f"overlap must be a fraction in [0, 0.9), e.g. 0.1 for 10 %, got {overlap!r}")
    if not (np.isfinite(point_spacing) and point_spacing > 0):
        raise InputError(f"point_spacing must be a positive length in metres, got {point_spacing!r}")
    R = tool.pad_radius
    min_pass_length = 0.25 * R if min_pass_length is None else float(min_pass_length)
    if not (feed > 0 and max_angular > 0):
        raise InputError(f"feed and max_angular must be positive (m/s, rad/s), got {feed!r}, {max_angular!r}")
    if workers is not None and not (isinstance(workers, int) and workers >= 1):
        raise InputError(f"workers must be a whole number >= 1 (1 = no worker processes), got {workers!r}")
    context_args = (surface, tool, work_spacing, max_angular / (SHARP_TURN_SPEED_FRACTION * feed))

    if direction is None or (isinstance(direction, str) and direction == "auto"):
        # The working mesh is built here only when the candidates are planned here.
        return _auto(functools.cache(lambda: _Context(*context_args[:3], max_turn_curvature=context_args[3])),
                     overlap=overlap, seed=seed, point_spacing=point_spacing,
                     min_pass_length=min_pass_length, max_passes=max_passes,
                     cost=cost or length_cost, progress=progress, workers=workers, context_args=context_args)
    if isinstance(direction, str):
        raise InputError(f"direction must be None (auto), an angle in radians or a 3-vector, got {direction!r}")
    ctx = _Context(*context_args[:3], max_turn_curvature=context_args[3])
    if isinstance(direction, (int, float)) and math.isfinite(direction):
        return _plan(ctx, float(direction), overlap=overlap, seed=seed, point_spacing=point_spacing,
                     min_pass_length=min_pass_length, max_passes=max_passes, rule="given angle")
    vec = np.asarray(direction, float).reshape(-1) if not isinstance(direction, (int, float)) else None
    if vec is None or vec.shape != (3,) or not np.isfinite(vec).all():
        raise InputError(f"direction must be None (auto), a finite angle in radians or a 3-vector, got {direction!r}")
    return _plan(ctx, vec, overlap=overlap, seed=seed, point_spacing=point_spacing,
                 min_pass_length=min_pass_length, max_passes=max_passes, rule="given vector")


def _plan(ctx: _Context, angle, *, overlap, seed, point_spacing, min_pass_length, max_passes, rule,
          extra_meta=None) -> ToolPath:
    """One uniform plan with the feed at ``angle`` (rad from the first principal axis, or a 3-vector)."""
    layout = _layout(ctx, angle, overlap=overlap, seed=seed, min_pass_length=min_pass_length, max_passes=max_passes)
    return _toolpath(ctx.surface, layout, point_spacing=point_spacing, rule=rule, extra_meta=extra_meta)


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
    covered = np.zeros(len(W.vertices), bool)
    current = _seed_curves(ctx, seed, cross, step)
    reach = 0.5 - overlap     # pass centre this many local widths beyond the covered edge
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
        # Distance from what is covered so far (or from the seed before the first pass).
        src = ctx.nearest_vertices(sources) if sources is not None else ctx.frontier(covered)
        if len(src) == 0:
            break
        d = ctx.distance(src)
        if sources is None:
            d[covered] = 0.0
        left = (d > 0) & ~covered
        if _area(W, left) <= 1e-4 * W.area:
            break
        band = np.flatnonzero((d <= 2.5 * R) & left)
        w_here = _band_widths(ctx, d, band, reach)
        g = d - reach * w_here
        pieces = level_sets(W.vertices, W.faces, g, [0.0], edges=ctx.edges)
        if not pieces:
            # The far boundary is nearer than a full step: pull the last pass in so its ribbon
            # reaches the boundary.
            w_here = _band_widths(ctx, d, band, reach, everywhere=True)
            d_far = float(np.max(d[left]))
            w_left = float(np.median(w_here[left]))
            level = max(d_far - reach * w_left, 0.5 * d_far)
            pieces = level_sets(W.vertices, W.faces, d - level, [0.0], edges=ctx.edges)
        new = _finished(ctx, pieces, step, min_pass_length)
        gained = _touched_by(ctx, new)
        if not (gained & ~covered).any():
            # Cutting at sharp turns left nothing that reaches new area (a short seed stretch gives a
            # first level set curled round it; a pocket's level set is a small loop): a pass that
            # makes the tool slow down beats none.
            whole = _finished(ctx, pieces, step, min_pass_length, cut=False)
            gained_whole = _touched_by(ctx, whole)
            log.debug("uniform generation %d: cut pieces gain nothing; whole pieces gain %.4f m2",
                      len(generations), _area(W, gained_whole & ~covered))
            new, gained = whole, gained_whole
        log.debug("uniform generation %d: %d level-set pieces, %d kept, uncovered %.4f m2", len(generations),
                  len(pieces), len(new), _area(W, left))
        if not (gained & ~covered).any():
            notes.append("uniform: a pass generation covered nothing new, so the planner stopped there")
            log.info("%s", notes[-1])
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
        notes.append(f"uniform: {100 * (1 - covered_pred):.1f} % of {ctx.surface.name or 'the part'} is predicted to "
                     "stay untouched (regions no pass reaches); lower the overlap's step or segment the part")
    return dict(angle=float(angle), feed_dir=feed_dir, polylines=merged,
                levels=[generation_of.get(id(p), -1) for p in merged], touch_up_index=touch_up_index,
                covered_pred=covered_pred, notes=notes, n_generations=len(generations), n_touch_ups=len(touch_ups),
                overlap=float(overlap), seed=seed if isinstance(seed, str) else "polyline",
                min_pass_length=float(min_pass_length), work_spacing=ctx.work_spacing,
                seconds=time.perf_counter() - t0)


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
    return ToolPath(surface, passes, "uniform", meta)


def length_cost(toolpath) -> tuple[float, str]:
    """Contact length plus the straight air distance between passes run zig-zag (each from the end
    nearer the previous end), m: the default ranking of candidate directions."""
    total, end = toolpath.contact_length, None
    for p in toolpath.passes:
        first, last = p.points[0], p.points[-1]
        if end is not None:
            d_first, d_last = np.linalg.norm(first - end), np.linalg.norm(last - end)
            total += min(d_first, d_last)
            end = last if d_first <= d_last else first
        else:
            end = last
    return float(total), "contact + straight air length (m)"


def _auto(make_context, *, overlap, seed, point_spacing, min_pass_length, max_passes, cost, progress=None, workers=None,
          context_args=None):
    say = progress or (lambda stage, done, total: None)
    # Candidates are ranked at a 2 mm point spacing; the winner's passes (whose layout does not
    # depend on the point spacing) are then resampled at the one asked for.
    options = dict(overlap=overlap, seed=seed, point_spacing=max(point_spacing, 2e-3),
                   min_pass_length=min_pass_length, max_passes=max_passes)
    angles = [float(a) for a in AUTO_DIRECTIONS]
    n_workers = min(len(angles), usable_cpus()) if workers is None else min(int(workers), len(angles))
    if n_workers > 1 and context_args is not None and not _pickles(cost):
        log.info("uniform: the cost function does not pickle, so the candidate directions are planned here, one "
                 "after another (give a module-level function or a record with __call__)")
        n_workers = 1
    say("planning (uniform): trying pass directions", 0, len(angles) + 1)
    if n_workers > 1 and context_args is not None:
        rows = _candidates_in_workers(context_args, angles, options, cost, n_workers, say,
                                      make_context=make_context)
    else:
        from threadpoolctl import threadpool_limits

        rows = []
        # One BLAS thread, as in the worker processes: the planner's matrix products are thin
        # ((n, 3) @ (3,)), where a second BLAS thread only synchronises (a plane slice of a 170k-vertex
        # working mesh took 12 ms with two threads and 0.1 ms with one on a loaded machine).
        with threadpool_limits(limits=1, user_api="blas"):
            for k, a in enumerate(angles):
                rows.append(_candidate(make_context(), a, options, cost))
                say("planning (uniform): trying pass directions", k + 1, len(angles) + 1)
    results, layouts, what = [], {}, ""
    for a, row in zip(angles, rows):
        if isinstance(row, str):
            log.info("uniform: direction %.0f deg infeasible: %s", math.degrees(a), row)
            continue
        length, value, what, covered, layouts[a] = row
        results.append((a, length, value, covered))
        log.info("uniform candidate %.0f deg: %.2f m in contact, cost %.4g (%s)", math.degrees(a), length, value, what)
    if not results:
        raise InfeasibleError("uniform found no feasible direction; check min_pass_length and the part size")
    # A direction must cover (a pad riding on the crests of waves narrower than itself leaves the
    # troughs untouched, so passes along the waves can miss area); among those that cover, the
    # cheapest wins.
    top = max(r[3] for r in results)
    good = [r for r in results if r[3] >= min(0.995, top - 0.002)]
    best = min(good, key=lambda r: r[2])
    candidates = [dict(direction_deg=math.degrees(a), length_m=L, cost=c, predicted_coverage_fraction=cv)
                  for a, L, c, cv in results]
    rule = (f"auto: lowest {what} among the directions whose predicted coverage is at least "
            f"{100 * min(0.995, top - 0.002):.1f} %")
    return _toolpath(context_args[0], layouts[best[0]], point_spacing=point_spacing, rule=rule,
                     extra_meta={"candidates": candidates})


def _candidate(ctx, angle: float, options: dict, cost):
    """Plan one candidate direction and rank it: ``(contact length m, cost, cost description,
    predicted coverage fraction, layout)``, or the reason (str) when the direction is infeasible."""
    options = dict(options)
    point_spacing = options.pop("point_spacing")
    try:
        layout = _layout(ctx, angle, **options)
    except InfeasibleError as exc:
        return str(exc)
    tp = _toolpath(ctx.surface, layout, point_spacing=point_spacing, rule="candidate")
    value, what = cost(tp)
    return tp.contact_length, float(value), what, tp.metadata["predicted_coverage_fraction"], layout


def _pickles(obj) -> bool:
    try:
        pickle.dumps(obj)
    except Exception:       # noqa: BLE001 - any failure means "plan here"
        return False
    return True


def _candidates_in_workers(context_args, angles, options, cost, n_workers, say, *, make_context=None) -> list:
    """:func:`_candidate` of every angle in ``n_workers`` worker processes, in the order of ``angles``.

    Where the platform forks safely (Linux) and ``make_context`` is given, the working mesh is built
    once here and the workers are forked from this process: they inherit it and the imported
    modules, so neither the set-up nor the imports are repeated per worker.  Elsewhere the workers
    are spawned and each builds the working mesh once (the same deterministic set-up as here).
    Either way each worker runs with one BLAS / OpenMP / numba thread, so the workers do not
    oversubscribe the cores, and the plans are the same as planned here one after another.
    """
    global _WORKER_CONTEXT
    if make_context is not None and _can_fork():
        _WORKER_CONTEXT = make_context()
        _warm_before_fork(_WORKER_CONTEXT, cost)
        try:
            return _run_pool(multiprocessing.get_context("fork"), None, angles, options, cost, n_workers, say)
        finally:
            _WORKER_CONTEXT = None
    # The part's own derived arrays the working mesh reads (curvature, smooth normals, KD-tree) are
    # computed here, as in a serial run, and travel with the pickled surface.
    surface = context_args[0]
    _ = surface.curvature, surface.normals, surface.kdtree
    return _run_pool(multiprocessing.get_context("spawn"), context_args, angles, options, cost, n_workers, say)


def _warm_before_fork(ctx: _Context, cost) -> None:
    """Load here, once, what every forked worker would otherwise load on its first candidate: the
    compiled kernels of the working mesh (:meth:`_Context.warm`) and whatever the cost function
    imports (its ``prepare()``, if it has one: the job's cycle-time cost imports the trajectory
    stage and toppra, about 0.3 s of CPU per worker)."""
    ctx.warm()
    prepare = getattr(cost, "prepare", None)
    if callable(prepare):
        prepare()


def _can_fork() -> bool:
    """Whether worker processes may be forked: Linux (fork is unsafe on macOS and absent on Windows)."""
    import sys

    return sys.platform.startswith("linux") and "fork" in multiprocessing.get_all_start_methods()


def _run_pool(mp_context, context_args, angles, options, cost, n_workers, say) -> list:
    done = 0
    with ProcessPoolExecutor(max_workers=n_workers, mp_context=mp_context, initializer=_worker_init,
                             initargs=(context_args,)) as pool:
        futures = [pool.submit(_worker_candidate, a, options, cost) for a in angles]
        for _ in as_completed(futures):
            done += 1
            say("planning (uniform): trying pass directions", done, len(angles) + 1)
        return [f.result() for f in futures]


#: The working mesh of a worker process (built once by :func:`_worker_init`).
_WORKER_CONTEXT: _Context | None = None


def _worker_init(context_args) -> None:
    global _WORKER_CONTEXT
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=1)
    try:
        import numba

        numba.set_num_threads(1)
    except ImportError:     # pragma: no cover - numba is a dependency
        pass
    if context_args is None:        # forked: the working mesh came with the process
        return
    surface, tool, work_spacing, max_turn_curvature = context_args
    _WORKER_CONTEXT = _Context(surface, tool, work_spacing, max_turn_curvature=max_turn_curvature)


def _worker_candidate(angle: float, options: dict, cost):
    return _candidate(_WORKER_CONTEXT, angle, options, cost)


# ----------------------------------------------------------------------------------------------
# pieces
# ----------------------------------------------------------------------------------------------
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




def _per_piece(surface, tool, pieces, options) -> ToolPath:
    """Plan every connected piece with :func:`uniform` and join them (``Pass.region`` = piece)."""
    passes, metas, covered = [], [], 0.0
    for k, faces in enumerate(pieces):
        sub = surface.sub_surface(faces, name=f"{surface.name}[piece {k}]")
        tp = uniform(sub, tool, **options)
        passes += [p.replace(region=k) for p in tp.passes]
        metas.append(tp.metadata)
        covered += tp.metadata["predicted_coverage_fraction"] * sub.area
    meta = dict(metas[0])
    meta.update(n_pieces=len(pieces), n_passes=len(passes), pieces=metas,
                predicted_coverage_fraction=covered / surface.area, order_hint="zigzag",
                touch_up_passes=[i for i, p in enumerate(passes) if p.kind == "touch_up"],
                n_touch_up_passes=sum(p.kind == "touch_up" for p in passes))
    log.info("uniform %s: %d pieces planned one by one, %d passes", surface.name, len(pieces), len(passes))
    return ToolPath(surface, passes, "uniform", meta)
