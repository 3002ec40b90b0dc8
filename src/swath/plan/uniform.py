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

import dataclasses
import functools
import logging
import math
import multiprocessing
import pickle
import time
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait

import numpy as np

from ..core import ToolPath
from ..core.beside import can_fork
from ..core.cpus import usable_cpus
from ..errors import InfeasibleError, InputError
from .common import feed_and_cross
from .uniform_layout import _layout, _seed_curves, _toolpath
from .uniform_model import DEFAULT_DISTANCE_METHOD, DISTANCE_METHODS, _Context, load_touch_kernel, shared_context
from .uniform_progress import LAYOUT_STEPS, _PoolProgress, _progress_steps

log = logging.getLogger("swath.plan")


#: A pass is cut where following it at the feed would turn the tool about its axis faster than
#: ``max_angular`` / this fraction, i.e. where the angular-speed limit would slow the pad below this
#: fraction of the feed.  A pad that slows in contact dwells, and a tight hook or a small loop of a
#: level set (a pass turning round at a part edge, circling a bump) grinds a ring into the part; the
#: pieces either side are kept and the tool turns in the air between them instead.
SHARP_TURN_SPEED_FRACTION = 0.5

#: Candidate seed directions (rad from the first principal axis) for ``direction="auto"``.
AUTO_DIRECTIONS = tuple(np.radians([0.0, 30.0, 60.0, 90.0, 120.0, 150.0]))

#: The progress stage of ``direction="auto"``'s candidate directions laid and ranked (after the
#: working mesh's set-up, :data:`swath.plan.uniform_model.SETUP_STAGE`, where it is built here).
TRYING_STAGE = "planning (uniform): trying pass directions"

#: The progress stage of one given direction's passes laid (``done`` 0 before, 1 after).
LAYING_STAGE = "planning (uniform): laying the passes"


def uniform(surface, tool, *, overlap: float = 0.1, direction=None, seed="boundary",
            point_spacing: float = 1e-3, min_pass_length: float | None = None, max_passes: int = 400,
            feed: float = 0.05, max_angular: float = 1.0, cost=None,
            work_spacing: float | None = None, progress=None, workers: int | None = None,
            distance_method: str | None = None, candidate_paths: dict | None = None) -> ToolPath:
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
        straight-line air distance between consecutive passes in zig-zag order, m.  A cost whose
        ``passes_only`` attribute is true reads only the passes and the order hint, not the rest of
        the metadata, so directions that lay the same passes are ranked once.  A cost with a
        ``bounded(toolpath, bar)`` method (returning ``(None, why)`` once a lower bound of the cost
        exceeds ``bar``) lets a direction that cannot beat one already ranked stop early.
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
    distance_method : {"band", "heat"}, optional
        The distance solver of each generation (:data:`swath.plan.uniform_model.DISTANCE_METHODS`):
        the narrow-band fast marching, or potpourri3d's heat method on the whole working mesh
        (default :data:`swath.plan.uniform_model.DEFAULT_DISTANCE_METHOD`).
    candidate_paths : dict, optional
        With automatic direction on a part of one piece: filled with ``{direction rad: ToolPath}``
        of every ranked candidate, resampled at ``point_spacing`` (the passes ``uniform`` lays with
        that ``direction`` given), so a caller comparing the candidates need not plan them again.
        Every candidate that covers enough is then ranked in full (:class:`FullCost`), so which
        are ranked does not depend on the order the workers finish in.

    Returns
    -------
    ToolPath
        ``metadata``: overlap_fraction, direction_rad, direction_rule, seed, n_passes, work_spacing_m,
        n_touch_up_passes and touch_up_passes (their indices in ``passes``; the passes also carry
        ``kind="touch_up"``), candidates (per direction: direction_deg, length_m,
        predicted_coverage_fraction and cost, None for a direction that covers less than
        :func:`coverage_floor` asks, or whose passes alone take longer than a direction ranked
        before it that covers as much, and so cannot be chosen) for automatic direction, order_hint
        ``"zigzag"``.  Each pass's ``level`` is its generation.
    """
    pieces = surface.face_pieces()
    if len(pieces) > 1:
        # Each piece is covered on its own: a distance field from one piece's seed never reaches another.
        options = dict(overlap=overlap, direction=direction, seed=seed, point_spacing=point_spacing,
                       min_pass_length=min_pass_length, max_passes=max_passes, feed=feed, max_angular=max_angular,
                       cost=cost, work_spacing=work_spacing, progress=progress, workers=workers,
                       distance_method=distance_method)
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
    distance_method = DEFAULT_DISTANCE_METHOD if distance_method is None else distance_method
    if distance_method not in DISTANCE_METHODS:
        raise InputError(f"distance_method must be one of {', '.join(DISTANCE_METHODS)}, got {distance_method!r}")
    context_args = (surface, tool, work_spacing, max_angular / (SHARP_TURN_SPEED_FRACTION * feed), distance_method)

    if direction is None or (isinstance(direction, str) and direction == "auto"):
        # The working mesh is built here only when the candidates are planned here.  While its
        # child process finishes, this one loads what every candidate needs (the pad-touch kernel,
        # the cost's imports), which forked workers then inherit.
        cost = cost or length_cost
        if candidate_paths is not None:
            cost = FullCost(cost)
        return _auto(functools.cache(lambda: shared_context(*context_args[:3], max_turn_curvature=context_args[3],
                                                            beside=workers != 1, distance_method=distance_method,
                                                            while_building=functools.partial(_prepare_candidates,
                                                                                             tool, cost),
                                                            progress=progress)),
                     overlap=overlap, seed=seed, point_spacing=point_spacing,
                     min_pass_length=min_pass_length, max_passes=max_passes,
                     cost=cost, progress=progress, workers=workers, context_args=context_args,
                     candidate_paths=candidate_paths)
    if isinstance(direction, str):
        raise InputError(f"direction must be None (auto), an angle in radians or a 3-vector, got {direction!r}")
    given = float(direction) if isinstance(direction, (int, float)) and math.isfinite(direction) else None
    vec = np.asarray(direction, float).reshape(-1) if not isinstance(direction, (int, float)) else None
    if given is None and (vec is None or vec.shape != (3,) or not np.isfinite(vec).all()):
        raise InputError(f"direction must be None (auto), a finite angle in radians or a 3-vector, got {direction!r}")
    ctx = shared_context(*context_args[:3], max_turn_curvature=context_args[3], beside=workers != 1,
                         distance_method=distance_method, progress=progress)
    say = progress or (lambda stage, done, total: None)
    say(LAYING_STAGE, 0, 1)
    toolpath = _plan(ctx, vec if given is None else given, overlap=overlap, seed=seed, point_spacing=point_spacing,
                     min_pass_length=min_pass_length, max_passes=max_passes,
                     rule="given vector" if given is None else "given angle")
    say(LAYING_STAGE, 1, 1)
    return toolpath


def _plan(ctx: _Context, angle, *, overlap, seed, point_spacing, min_pass_length, max_passes, rule,
          extra_meta=None) -> ToolPath:
    """One uniform plan with the feed at ``angle`` (rad from the first principal axis, or a 3-vector)."""
    layout = _layout(ctx, angle, overlap=overlap, seed=seed, min_pass_length=min_pass_length, max_passes=max_passes)
    return _toolpath(ctx.surface, layout, point_spacing=point_spacing, rule=rule, extra_meta=extra_meta)


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


@dataclasses.dataclass(frozen=True)
class FullCost:
    """``cost`` without its early stop (``bounded``): every candidate is ranked in full.  Its
    ``passes_only`` and ``prepare`` are those of ``cost``."""

    cost: object

    def __call__(self, toolpath):
        return self.cost(toolpath)

    @property
    def passes_only(self) -> bool:
        return bool(getattr(self.cost, "passes_only", False))

    def prepare(self) -> None:
        prepare = getattr(self.cost, "prepare", None)
        if callable(prepare):
            prepare()


#: :func:`length_cost` reads the passes only (not the tool path's metadata): candidates with the
#: same passes have the same cost (see :func:`_candidate_group`).
length_cost.passes_only = True  # type: ignore[attr-defined]


def _auto(make_context, *, overlap, seed, point_spacing, min_pass_length, max_passes, cost, progress=None, workers=None,
          context_args=None, candidate_paths=None):
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
    in_workers = n_workers > 1 and context_args is not None
    if in_workers and not can_fork():
        groups = [[a] for a in angles]      # the working mesh is built in each spawned worker, not here
    else:
        groups = _same_seed_groups(make_context(), angles, seed)
    steps = _progress_steps(groups)
    say(TRYING_STAGE, 0, steps)
    if in_workers:
        rows_of = _candidates_in_workers(context_args, groups, options, cost, min(n_workers, len(groups)), say,
                                         make_context=make_context)
    else:
        from threadpoolctl import threadpool_limits

        rows_of, done, top = [], 0, -math.inf
        # One BLAS thread, as in the worker processes: the planner's matrix products are thin
        # ((n, 3) @ (3,)), where a second BLAS thread only synchronises (a plane slice of a 170k-vertex
        # working mesh took 12 ms with two threads and 0.1 ms with one on a loaded machine).
        with threadpool_limits(limits=1, user_api="blas"):
            for group in groups:
                rows = _candidate_group(make_context(), group, options, cost, top, _ranked_so_far(rows_of))
                rows_of.append(rows)
                top = max([top] + [r[3] for r in rows if not isinstance(r, str)])
                done += LAYOUT_STEPS + len(group)
                say(TRYING_STAGE, done, steps)
    row_at = {a: row for group, rows in zip(groups, rows_of) for a, row in zip(group, rows)}
    rows = [row_at[a] for a in angles]
    results, layouts, what = [], {}, ""
    for a, row in zip(angles, rows):
        if isinstance(row, str):
            log.info("uniform: direction %.0f deg infeasible: %s", math.degrees(a), row)
            continue
        length, value, described, covered, layouts[a] = row
        what = described or what
        results.append((a, length, value, covered))
    if not results:
        raise InfeasibleError("uniform found no feasible direction; check min_pass_length and the part size")
    # A direction must cover (a pad riding on the crests of waves narrower than itself leaves the
    # troughs untouched, so passes along the waves can miss area); among those that cover, the
    # cheapest wins.  Those that do not cover are not ranked (or their rank is not reported: which
    # of them were ranked depends on the order the workers finished in), nor are those whose passes
    # alone take longer than the cycle of a candidate ranked before that covers as much (_bar).
    floor = coverage_floor(max(r[3] for r in results))
    results = [(a, L, c if cv >= floor else None, cv) for a, L, c, cv in results]
    for a, L, c, cv in results:
        log.info("uniform candidate %.0f deg: %.2f m in contact, predicted coverage %.2f %%, %s", math.degrees(a), L,
                 100 * cv, f"cost {c:.4g} ({what})" if c is not None else "not ranked (covers too little, or its passes alone take "
                 "longer than a candidate covering as much)")
    best = min((r for r in results if r[2] is not None), key=lambda r: r[2])
    candidates = [dict(direction_deg=math.degrees(a), length_m=L, cost=c, predicted_coverage_fraction=cv)
                  for a, L, c, cv in results]
    rule = (f"auto: lowest {what} among the directions whose predicted coverage is at least "
            f"{100 * floor:.1f} %")
    if candidate_paths is not None:
        candidate_paths.update({a: _toolpath(context_args[0], layouts[a], point_spacing=point_spacing, rule="given angle")
                                for a, _, c, _ in results if c is not None})
    chosen = _toolpath(context_args[0], layouts[best[0]], point_spacing=point_spacing, rule=rule,
                       extra_meta={"candidates": candidates})
    say(TRYING_STAGE, steps, steps)                 # the winner's passes resampled: the last step
    return chosen


def coverage_floor(top: float) -> float:
    """The least predicted coverage fraction a candidate direction needs to be chosen, when the
    best candidate's is ``top``: within 0.2 % of it, and never more than 99.5 % asked."""
    return min(0.995, top - 0.002)


def _same_seed_groups(ctx, angles: list[float], seed) -> list[list[float]]:
    """``angles`` grouped by their seed curves: angles whose seeds are equal bit for bit.

    A direction enters :func:`_layout` only through its seed curve (which stretch of the boundary,
    or which middle slice; a given polyline is the same for every direction); after that every
    pass follows the distance field from the passes before.  Angles with the same seed therefore
    lay the same passes, and their layout is computed once (on crs_part_5, 60 and 90 degrees pick
    the same boundary stretch, as do 120 and 150).  An angle whose seed cannot be made is a group
    of its own (its layout reports why).
    """
    step = min(2e-3, 0.5 * ctx.work_spacing)
    groups: dict = {}
    for a in angles:
        _, cross = feed_and_cross(ctx.surface, angle=a)
        try:
            curves = _seed_curves(ctx, seed, cross, step)
        except InfeasibleError:
            groups[("no seed", a)] = [a]
            continue
        key = tuple((c.shape, np.ascontiguousarray(c, float).tobytes()) for c in curves)
        groups.setdefault(key, []).append(a)
    return list(groups.values())


def _candidate_group(ctx, group: list[float], options: dict, cost, top: float = -math.inf,
                     ranked: tuple = ()) -> list:
    """:func:`_candidate` of every angle in ``group`` (angles with the same seed curves): the layout
    is made once, then resampled and ranked with each angle's own direction recorded, unless its
    coverage is below the floor of the best coverage ``top`` seen before (:func:`_worth_ranking`).
    ``ranked``: ``(coverage, cost)`` of the candidates ranked before (:func:`_bar`)."""
    layout = _first_layout(ctx, group[0], options)
    return _group_rows(ctx, group, layout, options, cost, rank=_worth_ranking(layout, max(top, _coverage_of(layout))),
                       bar=_bar(ranked, layout))


def _ranked_so_far(rows_of) -> tuple:
    """``(predicted coverage, cost)`` of every candidate ranked in the row lists ``rows_of``."""
    return tuple((r[3], r[1]) for rows in rows_of if rows for r in rows
                 if not isinstance(r, str) and r[1] is not None)


def _bar(ranked, layout: dict | str) -> float:
    """The cost ``layout`` must stay under to be chosen: the least cost among the candidates ranked
    so far (``ranked``: ``(coverage, cost)`` pairs) that are eligible whenever it is: those that
    cover at least as much, and those that cover at least the most :func:`coverage_floor` ever
    asks (99.5 %).  A layout costing more than one of them can never win, and its ranking can
    stop early (:func:`_ranked`).  Infinity when there is none."""
    cover = _coverage_of(layout)
    always = coverage_floor(1.0)
    return min((c for cv, c in ranked if cv >= cover or cv >= always), default=math.inf)


def _candidate(ctx, angle: float, options: dict, cost):
    """Plan one candidate direction and rank it: ``(contact length m, cost, cost description,
    predicted coverage fraction, layout)``, or the reason (str) when the direction is infeasible."""
    return _candidate_group(ctx, [angle], options, cost)[0]


def _first_layout(ctx, angle: float, options: dict) -> dict | str:
    """The layout of direction ``angle`` (rad), or the reason (str) it is infeasible."""
    try:
        return _layout(ctx, angle, **{k: v for k, v in options.items() if k != "point_spacing"})
    except InfeasibleError as exc:
        return str(exc)


def _coverage_of(layout: dict | str) -> float:
    """A layout's predicted coverage fraction (-inf for an infeasible direction)."""
    return -math.inf if isinstance(layout, str) else float(layout["covered_pred"])


def _worth_ranking(layout: dict | str, top: float) -> bool:
    """Whether ``layout`` can still be chosen when the best coverage seen so far is ``top``: the
    floor (:func:`coverage_floor`) only rises as more candidates come in, so a layout below it
    now is below it at the end, and its cost (the slow part of a candidate after its layout) is
    never needed."""
    return isinstance(layout, str) or _coverage_of(layout) >= coverage_floor(top)


def _group_rows(ctx, group: list[float], layout: dict | str, options: dict, cost, rank: bool = True,
                bar: float = math.inf) -> list:
    """The rows of :func:`_candidate_group` from the group's layout (that of ``group[0]``); with
    ``rank=False`` the cost and its description are None (the passes are still resampled, for
    the contact length the candidates report), and so they are when the cost certainly exceeds
    ``bar`` (:func:`_ranked`)."""
    if isinstance(layout, str):
        return [layout] * len(group)
    def as_angle(a):          # the group's layout recorded with angle ``a``'s own direction
        return dict(layout, angle=float(a), feed_dir=feed_and_cross(ctx.surface, angle=a)[0])

    if not rank:
        tp = _toolpath(ctx.surface, layout, point_spacing=options["point_spacing"], rule="candidate")
        return [(tp.contact_length, None, None, layout["covered_pred"], as_angle(a) if i else layout)
                for i, a in enumerate(group)]
    rows = [_ranked(ctx.surface, layout, options["point_spacing"], cost, bar)]
    for a in group[1:]:
        other = as_angle(a)
        if getattr(cost, "passes_only", False):
            # the same passes in the same order: a cost that reads nothing else ranks them the same
            rows.append((*rows[0][:4], other))
        else:
            rows.append(_ranked(ctx.surface, other, options["point_spacing"], cost, bar))
    return rows


def _ranked(surface, layout: dict, point_spacing: float, cost, bar: float = math.inf):
    """``layout`` resampled at ``point_spacing`` (m) and ranked: the row of :func:`_candidate`.

    With a finite ``bar`` and a cost that has ``bounded(toolpath, bar)`` (returning the cost, or
    None once a lower bound of it exceeds ``bar``), a candidate that cannot beat ``bar`` is left
    unranked (cost None) after the cheap part of its ranking: the chosen plan is the same."""
    tp = _toolpath(surface, layout, point_spacing=point_spacing, rule="candidate")
    bounded = getattr(cost, "bounded", None)
    if math.isfinite(bar) and callable(bounded):
        value, what = bounded(tp, bar)
        if value is None:
            log.info("uniform: direction %.0f deg not ranked further: %s", math.degrees(layout["angle"]), what)
            return tp.contact_length, None, None, tp.metadata["predicted_coverage_fraction"], layout
    else:
        value, what = cost(tp)
    return tp.contact_length, float(value), what, tp.metadata["predicted_coverage_fraction"], layout


def _pickles(obj) -> bool:
    try:
        pickle.dumps(obj)
    except Exception:       # noqa: BLE001 - any failure means "plan here"
        return False
    return True


def _candidates_in_workers(context_args, groups, options, cost, n_workers, say, *, make_context=None) -> list:
    """:func:`_candidate_group` of every group of angles in ``n_workers`` worker processes, in the
    order of ``groups`` (each group's layout and its ranking are separate tasks: :func:`_run_pool`).

    Where the platform forks safely (Linux) and ``make_context`` is given, the working mesh is built
    once here and the workers are forked from this process: they inherit it and the imported
    modules, so neither the set-up nor the imports are repeated per worker.  Elsewhere the workers
    are spawned and each builds the working mesh once (the same deterministic set-up as here).
    Either way each worker runs with one BLAS / OpenMP / numba thread, so the workers do not
    oversubscribe the cores, and the plans are the same as planned here one after another.
    """
    global _WORKER_CONTEXT
    if make_context is not None and can_fork():
        _WORKER_CONTEXT = make_context()
        _warm_before_fork(_WORKER_CONTEXT, cost)
        try:
            return _run_pool(multiprocessing.get_context("fork"), None, groups, options, cost, n_workers, say)
        finally:
            _WORKER_CONTEXT = None
    # The part's own derived arrays the working mesh reads (curvature, smooth normals, KD-tree) are
    # computed here, as in a serial run, and travel with the pickled surface.
    surface = context_args[0]
    _ = surface.curvature, surface.normals, surface.kdtree
    return _run_pool(multiprocessing.get_context("spawn"), context_args, groups, options, cost, n_workers, say)


def _prepare_candidates(tool, cost) -> None:
    """What every candidate needs and the working mesh does not: the compiled pad-touch test
    (:func:`load_touch_kernel`) and the cost's imports (its ``prepare()``, if it has one)."""
    load_touch_kernel(tool)
    prepare = getattr(cost, "prepare", None)
    if callable(prepare):
        prepare()


def _warm_before_fork(ctx: _Context, cost) -> None:
    """Load here, once, what every forked worker would otherwise load on its first candidate: the
    compiled kernels of the working mesh (:meth:`_Context.warm`) and :func:`_prepare_candidates`
    (the job's cycle-time cost imports the trajectory stage and toppra, about 0.3 s of CPU per
    worker).  A context built by :func:`uniform` has done the latter while it was built; again
    it costs nothing."""
    ctx.warm()
    _prepare_candidates(ctx.tool, cost)


def _run_pool(mp_context, context_args, groups, options, cost, n_workers, say, clock=time.perf_counter) -> list:
    """The rows of every group, planned in ``n_workers`` processes as two kinds of task: each
    group's layout (the heat-method generations, most of the work), then its ranking (resampling
    and the cost: ordering and timing the passes).  Every layout is queued first; a ranking is
    handed out only when a worker is free and no layout waits, so the short ranking tasks fill
    the workers' last gaps instead of one worker sitting idle while the other finishes the
    longest layout (candidates' times are not known in advance).  By then most layouts are
    back, and one that covers less than they allow (:func:`_worth_ranking`) is only resampled,
    not ranked.  The same functions as :func:`_candidate_group`, so the same plan.  Progress
    counts :data:`LAYOUT_STEPS` steps as a layout comes back and one per direction as a ranking
    does (``LAYOUT_STEPS * groups + directions + 1`` in all, the last for the winner), the layouts
    still running by their time so far (:class:`_PoolProgress`; ``clock()``: seconds)."""
    top = -math.inf
    rows_of: list = [None] * len(groups)
    with ProcessPoolExecutor(max_workers=n_workers, mp_context=mp_context, initializer=_worker_init,
                             initargs=(context_args,)) as pool:
        layout_of = {pool.submit(_worker_layout, g[0], options): i for i, g in enumerate(groups)}
        steps = _PoolProgress(len(groups), n_workers, clock)
        rows_task: dict = {}
        pending: set[Future] = set(layout_of)
        held: list = []                           # (group index, layout) waiting for a free worker
        while pending or held:
            while held and len(pending) < n_workers:
                i, layout = held.pop(0)
                task = pool.submit(_worker_group_rows, groups[i], layout, options, cost, _worth_ranking(layout, top),
                                   _bar(_ranked_so_far(rows_of), layout))
                rows_task[task] = i
                pending.add(task)
            finished, pending = wait(pending, return_when=FIRST_COMPLETED)
            # several back at once: layouts first, each kind in the order submitted
            for f in sorted(finished, key=lambda f: (0, layout_of[f]) if f in layout_of else (1, rows_task[f])):
                if f in layout_of:
                    i, layout = layout_of[f], f.result()
                    top = max(top, _coverage_of(layout))
                    held.append((i, layout))
                    done = steps.back(layout=i)
                else:
                    rows_of[rows_task[f]] = f.result()
                    done = steps.back(ranked=len(groups[rows_task[f]]))
                say(TRYING_STAGE, done, _progress_steps(groups))
    return rows_of


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
    surface, tool, work_spacing, max_turn_curvature, distance_method = context_args
    _WORKER_CONTEXT = _Context(surface, tool, work_spacing, max_turn_curvature=max_turn_curvature, beside=False,
                               distance_method=distance_method)


def _worker_layout(angle: float, options: dict) -> dict | str:
    return _first_layout(_WORKER_CONTEXT, angle, options)


def _worker_group_rows(group: list[float], layout: dict | str, options: dict, cost, rank: bool = True,
                       bar: float = math.inf) -> list:
    return _group_rows(_WORKER_CONTEXT, group, layout, options, cost, rank, bar)


# ----------------------------------------------------------------------------------------------
# pieces
# ----------------------------------------------------------------------------------------------
def _per_piece(surface, tool, pieces, options) -> ToolPath:
    """Plan every connected piece with :func:`uniform` and join them (``Pass.region`` = piece)."""
    passes, metas, covered = [], [], 0.0
    for k, faces in enumerate(pieces):
        # the same piece surface on every call, so its working mesh is shared (shared_context)
        sub = surface.memo(("uniform piece", k), functools.partial(surface.sub_surface, faces,
                                                                   name=f"{surface.name}[piece {k}]"))
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
    return ToolPath(surface, tuple(passes), "uniform", meta)
