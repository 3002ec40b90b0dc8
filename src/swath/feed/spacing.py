"""Pass spacing for even removal: raster passes at chosen offsets, chosen greedily or jointly with the feed.

* :func:`raster_at_offsets` — raster passes on cutting planes at given offsets along the cross
  direction (the raster planner's slicing and snake order, with free offsets).
* :func:`greedy_offsets` — Wang's greedy strategy: each next plane's step from the previous one is
  chosen by a coarse scan and then a pattern search from the best (his Algorithm 2: try ``x ± step``, keep improvements, shrink the step
  by ``alpha`` until it is below ``eps``) minimising the residual ``target − removal`` over the strip
  between the two planes.  The removal counts the passes placed so far, the candidate pass and a
  look-ahead copy one step further (the strip also gets removal from the next pass); each pass's
  dwell is scaled by the least-squares factor within the feed range.  A small cost per pass length
  (``length_weight``) keeps the search from crowding passes for a negligible gain.
* :func:`joint_spacing` — the joint optimisation of spacing and feeds: for every candidate equal
  spacing (a golden-section search over the spacing after a coarse scan) the feed is optimised by
  :func:`swath.feed.optimise_feed`, and the spacing whose optimised removal has the smallest
  area-weighted residual plus length cost wins.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..core import ToolPath
from ..errors import InfeasibleError, InputError
from ..order.sequence import snake
from ..plan.common import MIN_PASS_FRACTION, feed_and_cross, plane_passes
from ..plan.slicing import slice_mesh
from ..trajectory.constraints import FeedLimit
from .caps import split_constraints
from .kernel import build_kernel, interior_mask
from .optimise import optimise_feed, resolve_target

log = logging.getLogger(__name__)


def raster_at_offsets(surface, tool, offsets, *, angle: float = 0.0, direction=None, point_spacing: float = 1e-3,
                      min_pass_length: float | None = None, planner: str = "raster-offsets") -> ToolPath:
    """Raster passes on cutting planes at ``offsets`` (m) along the raster's cross direction.

    The cross direction is that of :func:`swath.plan.raster` with the same ``angle`` (rad) or
    ``direction``; offsets are heights ``x · cross`` of the cutting planes, in any order (sorted
    here).  Fragments shorter than ``min_pass_length`` (default ``R/4``) are dropped.

    Raises
    ------
    InfeasibleError
        When no plane yields a pass.
    """
    offsets = np.sort(np.asarray(offsets, float).reshape(-1))
    if len(offsets) == 0 or not np.isfinite(offsets).all():
        raise InputError(f"give at least one finite plane offset in m, got {offsets!r}")
    if min_pass_length is None:
        min_pass_length = MIN_PASS_FRACTION * tool.pad_radius
    feed, cross = feed_and_cross(surface, angle=angle, direction=direction)
    slices = slice_mesh(surface.vertices, surface.faces, cross, offsets, values=surface.normals)
    kept = [pl for pl in slices if pl.length >= min_pass_length]
    if not kept:
        raise InfeasibleError(f"no cutting plane among {len(offsets)} offsets "
                              f"({offsets.min() * 1e3:.1f}..{offsets.max() * 1e3:.1f} mm) yields a pass of at least "
                              f"{min_pass_length * 1e3:.1f} mm; give offsets within the part")
    passes = plane_passes(kept, feed, surface.face_normals, point_spacing)
    meta = {"offsets_m": offsets.tolist(), "cross_direction": cross.tolist(), "feed_direction": feed.tolist(),
            "angle_rad": float(angle), "n_passes": len(passes), "point_spacing_m": float(point_spacing)}
    return snake(ToolPath(surface, tuple(passes), planner, meta))


@dataclass(frozen=True, eq=False)
class SpacingResult:
    """Chosen plane offsets, the tool path on them and its optimised feed.

    Attributes
    ----------
    offsets : (p,) float
        Cutting-plane offsets along the cross direction, m.
    toolpath : ToolPath
    feed : FeedResult or None
        The optimised feed on ``toolpath`` (None if not computed).
    metrics : dict
        ``method``, ``solve_time_s``, ``evaluations``, ``spacing_mean_m`` ... (units in keys).
    trials : list of dict
        Every evaluated candidate (spacing or step, score).
    """

    offsets: np.ndarray
    toolpath: ToolPath
    feed: object
    metrics: dict = field(default_factory=dict)
    trials: list = field(default_factory=list)


def _pattern_search(f, x0: float, step: float, lo: float, hi: float, *, alpha: float = 0.5, eps: float = 1e-4,
                    max_evals: int = 40):
    """Wang's modified pattern search in one variable on ``[lo, hi]``: returns ``(x, f(x), evals)``."""
    x, fx = x0, f(x0)
    evals = 1
    while step >= eps and evals < max_evals:
        moved = False
        for cand in (x + step, x - step):
            if lo <= cand <= hi:
                fc = f(cand)
                evals += 1
                if fc < fx:
                    x, fx, moved = cand, fc, True
                    break
        if not moved:
            step *= alpha
    return x, fx, evals


def greedy_offsets(surface, tool, constraints, *, target, angle: float = 0.0, direction=None,
                   step_range: tuple[float, float] | None = None, length_weight: float = 0.01,
                   n_coarse: int = 0, boundary_margin: float | None = None, progress=None) -> SpacingResult:
    """Wang's greedy pass spacing: place planes one by one, each step chosen by pattern search.

    Parameters
    ----------
    surface : Surface
    tool : Tool
    constraints : sequence
        Trajectory constraints; the :class:`FeedLimit` gives the fastest feed, a tenth of it the slowest.
    target : float, (S,) float or TargetMap
        Target depth, m.
    angle, direction
        Raster direction (see :func:`raster_at_offsets`).
    step_range : (float, float), optional
        Smallest and largest step between planes, m (default ``(0.3 R, 2 R)``).
    length_weight : float
        Cost per unit of ``2R / step`` (relative path length) added to the relative residual.
    n_coarse : int
        Steps scanned evenly over ``step_range`` to start each pattern search from the best (0: start
        from the previous step, as Wang does; on the plate an 8-step scan found the same steps at 7x
        the cost).
    boundary_margin : float, optional
        Samples nearer the open boundary than this (m) are not scored (default the pad radius).
    progress : callable, optional
        ``progress(done_fraction_of_width, 1.0)`` after each plane.

    Returns
    -------
    SpacingResult
        With ``feed`` None: run :func:`swath.feed.optimise_feed` on ``toolpath`` for the final feed.
    """
    t_start = time.perf_counter()
    cons = split_constraints(constraints)
    v_max = cons[FeedLimit].speed
    R = tool.pad_radius
    lo_step, hi_step = (0.3 * R, 2.0 * R) if step_range is None else step_range
    if not (0 < lo_step < hi_step):
        raise InputError(f"step_range must be (smallest, largest) step in m with 0 < smallest < largest, got {step_range}")
    margin = R if boundary_margin is None else boundary_margin
    _, cross = feed_and_cross(surface, angle=angle, direction=direction)
    probe = build_kernel(raster_at_offsets(surface, tool, [float(np.median(surface.vertices @ cross))],
                                           angle=angle, direction=direction), tool)
    samples = probe.samples
    h = samples.vertices @ cross
    D = resolve_target(target, samples)
    w = samples.vertex_areas * interior_mask(samples, margin)
    p_lo, p_hi = 1.0 / v_max, 10.0 / v_max                     # pace range (s/m)
    cache: dict[float, tuple] = {}                          # offset -> (sample indices, removal) (sparse)

    def unit_removal(offset: float) -> np.ndarray:
        """Removal (m) of the passes on one plane crossed at 1 m/s (dwell = length)."""
        key = round(offset, 7)
        if key not in cache:
            try:
                tp = raster_at_offsets(surface, tool, [offset], angle=angle, direction=direction)
            except InfeasibleError:
                cache[key] = (np.zeros(0, dtype=int), np.zeros(0))
            else:
                k = build_kernel(tp, tool, samples=samples)
                r = k.removal(k.nodes.length)
                nz = np.flatnonzero(r)
                cache[key] = (nz, r[nz])
        out = np.zeros(len(h))
        idx, val = cache[key]
        out[idx] = val
        return out

    acc = np.zeros(len(h))
    hmin, hmax = float(h.min()), float(h.max())
    offsets = [hmin + 0.5 * R]
    first = unit_removal(offsets[0])
    trials = []
    step = 1.0 * R
    evals = 0
    while offsets[-1] + lo_step < hmax - 0.25 * R:
        prev = offsets[-1]

        def score(d, prev=prev):
            r_new = unit_removal(prev + d)
            r_look = unit_removal(prev + 2 * d) if prev + 2 * d < hmax else np.zeros(len(h))
            strip = (h >= prev) & (h <= prev + d) & (w > 0)
            if not strip.any():
                return 1e9
            resid0 = D[strip] - acc[strip] - p_prev * first[strip]
            basis = r_new[strip] + r_look[strip]
            ww = w[strip]
            denom = float(np.sum(ww * basis * basis))
            pace = float(np.clip(np.sum(ww * basis * resid0) / denom, p_lo, p_hi)) if denom > 0 else p_lo
            r = resid0 - pace * basis
            rel = math.sqrt(float(np.sum(ww * r * r)) / float(ww.sum())) / max(float(np.average(D[strip], weights=ww)), 1e-15)
            trials.append({"offset_m": prev + d, "step_m": d, "score": rel})
            return rel + length_weight * (2 * R / d)

        if len(offsets) == 1:
            p_prev = _best_pace(first, D, w, p_lo, p_hi)
        # coarse scan for the start (the residual has several local minima in the step: the ripple of
        # overlapping pad profiles), then Wang's pattern search from the best
        if n_coarse >= 2:
            coarse = np.linspace(lo_step, hi_step, n_coarse)
            start = float(coarse[int(np.argmin([score(c) for c in coarse]))])
            first_step = (hi_step - lo_step) / (2 * (n_coarse - 1))
        else:
            start, first_step = float(np.clip(step, lo_step, hi_step)), 0.25 * R
        d, _, n = _pattern_search(score, start, first_step, lo_step, hi_step, eps=0.02 * R)
        evals += n + max(n_coarse, 0)
        # fix the previous pass at its pace; the new one becomes "first" for the next step
        acc = acc + p_prev * first
        offsets.append(prev + d)
        first = unit_removal(prev + d)
        p_prev = _best_pace(first, np.maximum(D - acc, 0.0), w * ((h >= prev) & (h <= prev + d)), p_lo, p_hi)
        step = d
        if progress is not None:
            progress((prev + d - hmin) / max(hmax - hmin, 1e-12), 1.0)
    tp = raster_at_offsets(surface, tool, offsets, angle=angle, direction=direction, planner="greedy-spacing")
    steps = np.diff(offsets)
    metrics = {"method": "greedy pattern search", "solve_time_s": time.perf_counter() - t_start, "evaluations": evals,
               "n_planes": len(offsets), "spacing_mean_m": float(steps.mean()) if len(steps) else float("nan"),
               "spacing_min_m": float(steps.min()) if len(steps) else float("nan"),
               "spacing_max_m": float(steps.max()) if len(steps) else float("nan")}
    return SpacingResult(np.asarray(offsets), tp, None, metrics, trials)


def _best_pace(r: np.ndarray, D: np.ndarray, w: np.ndarray, p_lo: float, p_hi: float) -> float:
    denom = float(np.sum(w * r * r))
    return float(np.clip(np.sum(w * r * D) / denom, p_lo, p_hi)) if denom > 0 else p_lo


def joint_spacing(surface, tool, constraints, *, target, tolerance: float, angle: float = 0.0, direction=None,
                  spacing_range: tuple[float, float] | None = None, max_length_ratio: float = 1.5, n_coarse: int = 7,
                  n_refine: int = 5, length_weight: float = 0.01, objective: str = "minimax", progress=None,
                  **feed_options) -> SpacingResult:
    """Jointly choose an equal plane spacing and the feeds along the passes.

    Every evaluated spacing ``d`` plans :func:`raster_at_offsets` on planes ``d`` apart (centred on
    the part), optimises its feed (:func:`optimise_feed`, ``mode="match"``) and scores the relative
    area-weighted RMS residual plus ``length_weight · 2R/d``.  A coarse scan of ``n_coarse`` spacings
    over ``spacing_range`` (m; default ``(2R / max_length_ratio, 2R)``: contact length within
    ``max_length_ratio`` times the coverage lower bound on a plane) is refined by ``n_refine``
    golden-section steps around the best.  A spacing whose fastest feed already over-grinds
    (InfeasibleError) scores infinity.  ``feed_options`` go to :func:`optimise_feed` (e.g.
    ``sample_spacing``, ``node_spacing``).

    The feed changes removal only along the passes; across them the summed pad cross-profiles
    leave a ripple that depends on the spacing alone (:func:`swath.feed.ripple_cov`), so on a plane
    the winner is the analytic least-ripple spacing (:func:`swath.feed.ripple_spacing`).

    Returns
    -------
    SpacingResult
        With the best spacing's tool path and :class:`FeedResult`.
    """
    t_start = time.perf_counter()
    R = tool.pad_radius
    if not (np.isfinite(max_length_ratio) and max_length_ratio >= 1):
        raise InputError(f"max_length_ratio must be >= 1 (contact length over the coverage bound), got {max_length_ratio!r}")
    lo, hi = (2.0 * R / max_length_ratio, 2.0 * R) if spacing_range is None else spacing_range
    if not (0 < lo < hi):
        raise InputError(f"spacing_range must be (smallest, largest) in m with 0 < smallest < largest, got {spacing_range}")
    _, cross = feed_and_cross(surface, angle=angle, direction=direction)
    heights = surface.vertices @ cross
    results: dict[float, tuple] = {}
    trials = []

    def evaluate(d: float):
        key = round(d, 7)
        if key in results:
            return results[key][0]
        from ..plan.raster import plane_offsets

        offsets, _ = plane_offsets(heights, d)
        try:
            tp = raster_at_offsets(surface, tool, offsets, angle=angle, direction=direction, planner="joint-spacing")
            fr = optimise_feed(tp, tool, constraints, target=target, tolerance=tolerance, mode="match",
                               objective=objective, timing_rounds=0, **feed_options)
            score = fr.metrics["residual_rms_m"] / max(fr.metrics["target_mean_m"], 1e-15) + length_weight * 2 * R / d
        except InfeasibleError as exc:
            log.info("joint spacing: %.1f mm infeasible (%s)", d * 1e3, exc)
            tp, fr, score = None, None, math.inf
        results[key] = (score, offsets, tp, fr)
        trials.append({"spacing_m": d, "score": score,
                       "removal_cov": fr.metrics["removal_cov"] if fr else float("nan")})
        if progress is not None:
            progress(len(trials), n_coarse + n_refine)
        return score

    grid = np.linspace(lo, hi, n_coarse)
    scores = [evaluate(d) for d in grid]
    k = int(np.argmin(scores))
    a, b = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
    g = (math.sqrt(5) - 1) / 2
    for _ in range(n_refine):
        c1, c2 = b - g * (b - a), a + g * (b - a)
        if evaluate(c1) <= evaluate(c2):
            b = c2
        else:
            a = c1
    best = min(results.values(), key=lambda r: r[0])
    if not math.isfinite(best[0]):
        raise InfeasibleError(f"every spacing tried ({lo * 1e3:.1f}..{hi * 1e3:.1f} mm) over-grinds at the fastest "
                              "feed; raise the target or the tolerance, or the feed limit")
    score, offsets, tp, fr = best
    # the winner's feed again, with the timing correction (skipped while searching)
    fr = optimise_feed(tp, tool, constraints, target=target, tolerance=tolerance, mode="match", objective=objective,
                       kernel=fr.kernel, **feed_options)
    steps = np.diff(offsets)
    metrics = {"method": "joint equal spacing + feed", "solve_time_s": time.perf_counter() - t_start,
               "evaluations": len(trials), "n_planes": len(offsets),
               "spacing_mean_m": float(steps.mean()) if len(steps) else float("nan"), "score": score}
    return SpacingResult(np.asarray(offsets), tp, fr, metrics, trials)


__all__ = ["SpacingResult", "greedy_offsets", "joint_spacing", "raster_at_offsets"]
