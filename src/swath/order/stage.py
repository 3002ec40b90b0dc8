"""The order stage: a tour of a tool path's pass groups, its links routed round the part.

:func:`order_toolpath` builds each group's path types (:mod:`swath.order.variants`), costs the links
between them as the trajectory flies them, solves the tour (:mod:`swath.order.tour`) and, with
:func:`route_tour`, re-solves while a link it uses has to climb over the part.
"""

from __future__ import annotations

import logging
import time
from itertools import pairwise

import numpy as np

from ..errors import InputError
from .tour import reverse_nodes, solve, solve_index
from .variants import LinkModel, Variants, contact_cost, group_variants, link_matrix, tour_length

log = logging.getLogger("swath.order")


#: :func:`route_tour` solves again at most this many times.  On bezier_dac_scan (raster, 53 passes,
#: gtsp by length) the routed air of the best tour is 5.39 m after 0 or 8 rounds and 5.13 m after
#: 30 (10 s): the routes that climb are found a few per round.  The tour solved on straight moves
#: alone flies 5.84 m.
MAX_ROUTE_ROUNDS = 8


def route_tour(variants: Variants, tour, guard, model: LinkModel, D_len: np.ndarray, D: np.ndarray,
               checked: np.ndarray, *, solver=None, cost=None):
    """Make the links of a tour cost what their air routes do.

    Every air link of ``tour`` (a list of nodes; None: ``solver()``'s) not yet ``checked`` is routed
    by ``guard`` (:class:`~swath.order.routing.AirGuard`); where the route is longer than the
    straight move at the clearance that ``D_len`` (m) holds, ``D_len`` and ``D`` (the objective:
    ``model.cost`` of the route's length) are raised in place, for the link and for the same move
    run backwards.  Contact step-overs (``D_len == 0``) are not routed.

    With a ``solver`` (no arguments, returns a tour on the current ``D``) and ``cost`` (a tour's
    objective on the current ``D``) the tour is solved again while the last one had links that
    cost more than the solver assumed, at most :data:`MAX_ROUTE_ROUNDS` times, and the best tour
    at its routed cost is returned.  The straight move is the shortest route, so costs only rise,
    and a checked tour's cost is final: a tour none of whose links rose is as good for the routed
    costs as the solver can tell.

    Returns
    -------
    tour : list of int
    rounds : int
        How many times the tour was solved again.
    """
    rev = reverse_nodes(variants)
    rounds = 0
    if tour is None:
        tour = solver()
    best, best_cost = None, np.inf
    while True:
        raised = False
        for u, w in pairwise(tour):
            if checked[u, w] or D_len[u, w] <= 0.0:
                continue
            n_exit, n_entry = variants.exit_normal[u], variants.entry_normal[w]
            route = guard.route(variants.exit_point[u], n_exit / np.linalg.norm(n_exit), variants.entry_point[w],
                                n_entry / np.linalg.norm(n_entry))
            length = float(np.linalg.norm(np.diff(route, axis=0), axis=1).sum())
            pairs = [(u, w)] + ([(int(rev[w]), int(rev[u]))] if rev[u] >= 0 and rev[w] >= 0 else [])
            for a, b in pairs:
                checked[a, b] = True
                if length > D_len[a, b] + 1e-9:
                    D_len[a, b] = length
                    D[a, b] = model.cost(length, variants.exit_frame[a], variants.entry_frame[b])
                    raised = True
        if solver is None:
            return tour, rounds
        value = cost(tour)
        if value < best_cost - 1e-12:
            best, best_cost = tour, value
        if not raised or rounds >= MAX_ROUTE_ROUNDS:
            return best, rounds
        tour = solver()
        rounds += 1


# --- the public entry point ----------------------------------------------------------------------

def default_groups(toolpath) -> list[list[int]]:
    """Groups of a tool path: its regions' passes (``Pass.region``, in order of appearance) when it
    has several regions, otherwise one group per pass."""
    n = len(toolpath.passes)
    labels = [p.region for p in toolpath.passes]
    if len(set(labels)) <= 1:
        return [[i] for i in range(n)]
    groups: dict = {}
    for i, r in enumerate(labels):
        groups.setdefault(r, []).append(i)
    return list(groups.values())


def order_toolpath(toolpath, *, groups=None, method: str = "gtsp", start=None, seed: int = 0,
                   clearance: float = 0.02, link_speed: float | None = None, link_acceleration: float = 1.0,
                   omega_max: float | None = None, feed: float | None = None, runs: int = 1,
                   max_trials: int | None = None,
                   join_gap: float | None = None, join_tolerance: float | None = None,
                   keep_direction: bool = False, routed: bool = True, pad_radius: float | None = None):
    """Reorder a tool path's pass groups and choose their path types to minimise air travel
    (or, given ``link_speed``, link time).

    Parameters
    ----------
    toolpath : ToolPath
        The passes to order.
    groups : list of list of int, optional
        Pass indices of each group in the group's processing order; every pass in exactly one group.
        Default :func:`default_groups` (the regions of :func:`swath.plan.regions.plan_regions`, or
        single passes).
    method : {"gtsp", "greedy", "index", "exact"}
        ``gtsp``: Noon–Bean + LKH; ``greedy``: nearest entry; ``index``: as given (only the
        estimate is added); ``exact``: Held–Karp (at most :data:`MAX_EXACT_GROUPS` groups).
    start : (3,) float, optional
        Where the tool starts (e.g. home), part frame, m; its move to the first entry is counted.
    seed : int
        Seed of LKH's random choices.
    clearance : float
        Lift along the normal used in the air-length estimate, m.
    link_speed : float, optional
        Link speed, m/s.  When given, links are costed by time (a rest-to-rest trapezoid with
        ``link_acceleration``, m/s², and at least the tool's turn over ``omega_max``, rad/s) instead
        of length: with the trajectory stage's heading following the travel direction, a snake's
        180-degree turn at 1 rad/s costs 3.1 s, more than most short moves.
    link_acceleration : float
        m/s² (with ``link_speed``).
    omega_max : float, optional
        Angular speed limit, rad/s (with ``link_speed``).
    feed : float, optional
        Contact feed, m/s (with ``link_speed`` and ``join_gap``): a step-over made in contact
        costs the contact time it adds (:func:`~swath.order.variants.contact_cost`); default: a
        move at the link speed.
    runs, max_trials : int
        LKH runs and trials per run (default ``min(nodes, 100)``).
    join_gap : float, optional
        Make step-overs up to this long (m; e.g. 1.5 x the pass spacing) in contact where the pad
        can slide along the surface (:class:`~swath.order.joining.StepOverJoiner`): such moves cost
        no air in the order and the passes they join become one pass (Wang's continuous local
        paths).  Default None: every move between passes is an air move.
    join_tolerance : float, optional
        Largest distance of a contact step-over's chord from the surface, m (default
        ``0.25 * join_gap``).
    keep_direction : bool
        Keep every group's path type as given (its passes' order and directions); only the order of
        the groups is chosen.
    routed : bool
        Cost the links the tour uses by their air routes (:class:`~swath.order.routing.AirGuard`,
        as :func:`~swath.order.routing.route_links` and the trajectory stage fly them) instead of
        the straight move at the clearance: where a route must climb over the part, the link costs
        what the route does and the tour is solved again (:func:`route_tour`); links inside a
        group cost their routes too.  Default True (ignored for a tool path without a surface or
        with ``clearance == 0``).
    pad_radius : float, optional
        Pad radius, m, for the routes' reach box (default
        :data:`~swath.order.routing.DEFAULT_PAD_RADIUS`).

    Returns
    -------
    ToolPath
        The same passes, reordered and flipped (:meth:`Pass.reversed`); ``metadata`` gains
        ``order_method``, ``air_before_m`` (as given), ``air_after_m``, with ``link_speed`` also
        ``link_time_before_s`` and ``link_time_after_s`` (estimates), ``order_time_s``,
        ``order_groups`` (the group order as indices into ``groups``) and, when the input had it,
        ``pass_region`` reordered; with ``join_gap`` also ``joined_step_overs``,
        ``joined_contact_m`` and ``join_max_gap_m`` (:func:`~swath.order.joining.join_passes`):
        the tool path then has fewer, longer passes.

    Raises
    ------
    InputError
        On groups that do not partition the passes, an unknown method, a bad start point or clearance.
    """
    n = len(toolpath.passes)
    if n == 0:
        raise InputError("the tool path has no passes to order")
    model = LinkModel(clearance=clearance, speed=link_speed, acceleration=link_acceleration, omega_max=omega_max,
                      feed=feed)
    groups = default_groups(toolpath) if groups is None else [list(map(int, g)) for g in groups]
    flat = sorted(i for g in groups for i in g)
    if flat != list(range(n)) or any(len(g) == 0 for g in groups):
        raise InputError(f"groups must split the {n} passes into non-empty groups, each pass exactly once; "
                         f"got {len(flat)} indices in {len(groups)} groups")
    start_pt = None
    if start is not None:
        start_pt = np.asarray(start, float).reshape(-1)
        if start_pt.shape != (3,) or not np.isfinite(start_pt).all():
            raise InputError(f"start must be a finite point (3,) in m, got {start!r}")
    t0 = time.perf_counter()
    joiner = None
    if join_gap is not None:
        from .joining import StepOverJoiner

        joiner = StepOverJoiner(toolpath.surface, max_gap=join_gap, tolerance=join_tolerance)
    guard = None
    if routed and toolpath.surface is not None and clearance > 0:     # no surface: nothing to route round
        from .routing import DEFAULT_PAD_RADIUS, AirGuard

        guard = AirGuard(toolpath.surface, clearance, pad_radius=DEFAULT_PAD_RADIUS if pad_radius is None else pad_radius)
    variants = group_variants(toolpath.passes, groups, model=model, joiner=joiner, keep_direction=keep_direction,
                              guard=guard)
    D_len = link_matrix(variants, model=model)
    D = link_matrix(variants, model=model, cost=True)
    if joiner is not None:
        a, b = joiner.pairs(variants.exit_point, variants.entry_point, variants.exit_frame[:, :, 0],
                            variants.entry_frame[:, :, 0])
        D_len[a, b] = 0.0
        D[a, b] = contact_cost(model, variants.entry_point[b] - variants.exit_point[a], variants.exit_frame[a],
                               variants.entry_frame[b])
    start_len = start_cost = None
    if start_pt is not None:
        start_len = np.linalg.norm(variants.entry_point + clearance * variants.entry_normal - start_pt, axis=1) + clearance
        eye = np.broadcast_to(np.eye(3), (len(start_len), 3, 3))
        start_cost = model.cost(start_len, eye, eye)
    index = solve_index(variants)
    rounds = 0
    if guard is not None:
        checked = np.zeros(D.shape, bool)
        route_tour(variants, index, guard, model, D_len, D, checked)
        tour, rounds = route_tour(variants, None, guard, model, D_len, D, checked,
                                  solver=lambda: solve(variants, D, start_cost, method, seed=seed, runs=runs,
                                                       max_trials=max_trials),
                                  cost=lambda t: tour_length(variants, D, t, start_cost))
    else:
        tour = solve(variants, D, start_cost, method, seed=seed, runs=runs, max_trials=max_trials)
    before = tour_length(variants, D_len, index, start_len, inner=variants.inner_length)
    after = tour_length(variants, D_len, tour, start_len, inner=variants.inner_length)
    seconds = time.perf_counter() - t0

    passes = []
    for node in tour:
        g = int(variants.group[node])
        idx = groups[g][::-1] if variants.reverse_order[node] else groups[g]
        for i in idx:
            p = toolpath.passes[i]
            passes.append(p.reversed() if variants.flip[node] else p)
    meta = dict(toolpath.metadata)
    meta.update(order_method=method, air_before_m=before, air_after_m=after, order_time_s=seconds,
                order_groups=[int(variants.group[v]) for v in tour], order_clearance_m=float(clearance),
                order_route_rounds=rounds, order_objective="time" if model.timed else "length")
    if model.timed:
        meta.update(link_time_before_s=tour_length(variants, D, index, start_cost),
                    link_time_after_s=tour_length(variants, D, tour, start_cost))
    out = toolpath.replace(passes=tuple(passes), metadata=meta)
    if joiner is not None:
        from .joining import join_passes

        out = join_passes(out, joiner)
    log.info("order %s: %d passes in %d groups, air %.3f m -> %.3f m (%.2f s)", method, n, len(groups),
             before, after, seconds)
    return out
