"""Order pass groups and choose their path types to waste least air (Wang §4).

A *group* is a run of passes processed together — the passes of one region, or a single pass.
Each group offers *variants* (path types), each with an entry point (where the pad touches down)
and an exit point (where it lifts off):

* a group of several passes has Wang's four types, start corner x sweep direction: the passes in
  the given order or in reverse order, each pass as given or every pass flipped.  For a
  boustrophedon (snake) group all four keep the snake, so the links inside the group keep their
  lengths and only the group's entry and exit change;
* a single pass has two: as given or flipped.

Choosing one variant per group and the visiting order so that the air travel from each group's
exit to the next group's entry (plus, optionally, from a start point to the first entry) is least
is a generalised travelling-salesman problem (GTSP): one city per group must be visited, chosen
among its variants.  It is solved here by the Noon–Bean transform (the GTSP becomes an asymmetric
TSP whose optimal tours visit every cluster's nodes consecutively) and the Lin–Kernighan–Helsgaun
heuristic (LKH, through the ``elkai`` package); when every group is a single pass, as a symmetric
TSP on the passes' ends with the pass edges fixed.  :func:`solve_portfolio` (the ``gtsp`` method)
takes the exact optimum of :func:`held_karp` (dynamic programming over subsets of groups x end
variants) up to :data:`EXACT_UP_TO` groups, else the better of two LKH calls polished by
:func:`improve_tour` (2-opt and Or-opt on the group order, path types re-chosen by DP for each
order).  Baselines: ``index`` (as given) and ``greedy`` (from the current exit, the nearest entry
among the groups left).

The air distance between a lift-off point ``p`` (normal ``n``) and a touch-down point ``q`` (normal
``m``) is first taken as ``c + |(p + c n) - (q + c m)| + c`` with the clearance ``c``: retract, a
straight move at the clearance, approach — what :class:`~swath.order.routing.AirGuard` flies when
that move clears the part.  Where it does not, the route climbs over the part; :func:`~swath.order.stage.route_tour`
routes every link a tour uses, raises its cost to the route's and solves again, so the tour's
costs are those of the links the trajectory flies.  By time, a link costs
:func:`~swath.order.variants.link_time_estimate` (the trajectory stage's rounded, toppra-timed
link in closed form, within 0.05 s per link on the hub) and a contact step-over the contact time
it adds (:func:`~swath.order.variants.contact_cost`).  ``benchmarks/bench_order.py`` table 4
checks both link by link against the timed trajectory.
"""

from __future__ import annotations

import logging
from itertools import pairwise

import numpy as np

from ..errors import InputError
from .variants import (  # noqa: F401  (re-exported)
    CONTACT_WEIGHT,
    LinkModel,
    Variants,
    contact_cost,
    group_variants,
    link_matrix,
    link_time_estimate,
    pass_ends,
    tour_length,
)

log = logging.getLogger("swath.order")

#: Largest number of groups :func:`held_karp` accepts (2^n x (4n) states).
MAX_EXACT_GROUPS = 14
#: Air distances are scaled to integers for LKH with this many units per metre (0.01 mm).
_INT_SCALE = 1e5
METHODS = ("gtsp", "greedy", "index", "exact")


def solve_index(variants: Variants) -> list[int]:
    """Groups as given, each in its first path type (as planned)."""
    first = np.unique(variants.group, return_index=True)[1]
    return [int(i) for i in first]


def solve_greedy(variants: Variants, D: np.ndarray, start_cost: np.ndarray | None) -> list[int]:
    """Nearest entry first: from the start point (or the first group as planned) always go to the
    closest entry among the groups not yet visited."""
    n_groups = variants.n_groups
    done = np.zeros(n_groups, bool)
    if start_cost is None:
        node = solve_index(variants)[0]
    else:
        node = int(np.argmin(start_cost))
    tour = [node]
    done[variants.group[node]] = True
    while not done.all():
        cost = np.where(done[variants.group], np.inf, D[node])
        node = int(np.argmin(cost))
        tour.append(node)
        done[variants.group[node]] = True
    return tour


def held_karp(variants: Variants, D: np.ndarray, start_cost: np.ndarray | None) -> list[int]:
    """The exact optimum by dynamic programming over (set of visited groups, last node).

    Cost ``O(2^g N^2)`` for ``g`` groups and ``N`` nodes; refused beyond :data:`MAX_EXACT_GROUPS` groups.
    """
    g_of = variants.group
    n_groups = variants.n_groups
    if n_groups > MAX_EXACT_GROUPS:
        raise InputError(f"the exact order solver takes at most {MAX_EXACT_GROUPS} groups, got {n_groups}; "
                         "use method='gtsp'")
    N = len(g_of)
    C = D + variants.inner[None, :]                    # arriving at a node pays its inner links
    init = variants.inner + (0.0 if start_cost is None else start_cost)
    full = (1 << n_groups) - 1
    dp = np.full((1 << n_groups, N), np.inf)
    parent = np.full((1 << n_groups, N), -1, dtype=np.int64)
    bit = 1 << g_of
    dp[bit, np.arange(N)] = init
    for mask in range(1, full + 1):
        row = dp[mask]
        live = np.isfinite(row)
        if not live.any():
            continue
        outside = (bit & mask) == 0
        if not outside.any():
            continue
        src = np.flatnonzero(live)
        cand = row[src][:, None] + C[np.ix_(src, np.flatnonzero(outside))]
        best = cand.argmin(axis=0)
        val = cand[best, np.arange(cand.shape[1])]
        tgt = np.flatnonzero(outside)
        new_mask = mask | bit[tgt]
        better = val < dp[new_mask, tgt]
        dp[new_mask[better], tgt[better]] = val[better]
        parent[new_mask[better], tgt[better]] = src[best[better]]
    node = int(np.argmin(dp[full]))
    tour, mask = [], full
    while node >= 0:
        tour.append(node)
        prev = int(parent[mask, node])
        mask ^= 1 << int(g_of[node])
        node = prev
    return tour[::-1]


def solve_gtsp(variants: Variants, D: np.ndarray, start_cost: np.ndarray | None, *, seed: int = 0,
               runs: int = 1, max_trials: int | None = None, subgradient: bool | None = None) -> list[int]:
    """Noon–Bean transform + LKH (``elkai``).

    The nodes of each group are joined in a zero-cost cycle; an arc from node ``u`` to a node ``w``
    of another group costs ``D[succ(u), w] + inner[w] + M`` where ``succ(u)`` is the next node on
    ``u``'s cycle (the tour enters a group at ``succ(u)``, runs round its cycle to ``u`` and leaves;
    the node it entered by is the chosen path type).  ``M`` (more than any tour's link cost) makes
    every optimal tour visit each group exactly once, in one block.  A depot node carries the start
    point (or costs nothing).  Distances are scaled to integers (0.01 mm).

    When every group is a single pass, the instance is solved as a symmetric TSP with the pass
    edges fixed instead (:func:`_solve_single_passes`).  ``subgradient``: whether LKH runs its
    subgradient ascent (default: on for the Noon–Bean instance, off for the fixed-edge one).
    """
    g_of = variants.group
    N = len(g_of)
    n_groups = variants.n_groups
    if n_groups == 1:
        return [int(np.argmin(variants.inner + (0 if start_cost is None else start_cost)))]
    if n_groups >= 2 and len(g_of) == 2 * n_groups:
        return _solve_single_passes(variants, D, start_cost, seed=seed, runs=runs, max_trials=max_trials,
                                    subgradient=bool(subgradient))
    succ = np.arange(N) + 1
    starts = np.unique(g_of, return_index=True)[1]
    ends = np.r_[starts[1:], N] - 1
    succ[ends] = starts                                # close each group's cycle
    entry_cost = D + variants.inner[None, :]
    scale = _INT_SCALE
    base = np.rint(entry_cost[succ] * scale).astype(np.int64)       # leaving from u means exiting succ(u)
    depot_out = np.rint((variants.inner + (0.0 if start_cost is None else start_cost)) * scale).astype(np.int64)
    big_m = int(base.max() + depot_out.max() + 1)
    if (n_groups + 2) * 2 * big_m > 2**31 - 1:
        scale = scale * (2**31 - 1) / ((n_groups + 2) * 2 * big_m)
        base = np.rint(entry_cost[succ] * scale).astype(np.int64)
        depot_out = np.rint((variants.inner + (0.0 if start_cost is None else start_cost)) * scale).astype(np.int64)
        big_m = int(base.max() + depot_out.max() + 1)
    forbid = 2 * big_m
    size = N + 1                                       # node N is the depot
    W = np.full((size, size), forbid, dtype=np.int64)
    W[:N, :N] = base + big_m
    same = g_of[:, None] == g_of[None, :]
    W[:N, :N][same] = forbid
    W[np.arange(N), succ] = np.where(succ != np.arange(N), 0, forbid)   # the zero-cost cycle
    W[N, :N] = depot_out + big_m                       # depot -> entry of the first group
    # back to the depot from u: the group was entered at succ(u), nothing more to pay
    W[:N, N] = big_m
    np.fill_diagonal(W, 0)
    if size < 3:
        return solve_index(variants)
    order = _lkh_atsp(W, seed=seed, runs=runs, max_trials=max_trials,
                      subgradient=True if subgradient is None else subgradient)
    k = order.index(N)
    order = order[k + 1:] + order[:k]
    tour, seen = [], set()
    for pos, node in enumerate(order):
        g = int(g_of[node])
        if g in seen:
            continue
        seen.add(g)
        tour.append(int(node))
    # The first node met in each block is the entry node (the block runs along the cycle); should
    # the tour split a block, the best path types for the order found repair it.
    return best_variants(variants, D, start_cost, [int(g_of[v]) for v in tour])


def _solve_single_passes(variants: Variants, D: np.ndarray, start_cost, *, seed: int, runs: int,
                         max_trials: int | None, subgradient: bool = False) -> list[int]:
    """All groups single passes: a symmetric TSP on the passes' 2n ends plus two depots.

    The move from a lift-off end to a touch-down end does not depend on which is which, so every
    pass becomes an edge between its two ends that the tour must use (cost 0; every other edge
    costs ``M`` more), and a start depot S and an end depot E joined the same way carry the start
    point (S to an end: the move from the start point; E to an end: 0).  Symmetric instances are
    about twice as small for LKH as the Noon–Bean transform and solve to better tours.
    """
    n = variants.n_groups
    # Ends: 2g = start of pass g (entry of node 2g, exit of node 2g + 1), 2g + 1 = its end.  Leaving
    # by end p means exiting node p ^ 1; arriving at end q means entering node q.
    dist = D[np.arange(2 * n) ^ 1][:, np.arange(2 * n)]
    dist = 0.5 * (dist + dist.T)                     # symmetric up to round-off (see the notes)
    size = 2 * n + 2
    S, E = 2 * n, 2 * n + 1
    cost = np.zeros((size, size))
    cost[:2 * n, :2 * n] = dist
    if start_cost is not None:
        # variant 0 of pass g enters at its start (node 2g), variant 1 at its end (node 2g + 1)
        cost[S, :2 * n] = cost[:2 * n, S] = start_cost
    scale = _INT_SCALE
    big_m = int(np.rint(cost.max() * scale)) + 1
    while (n + 2) * 2 * big_m > 2**31 - 1:
        scale /= 2
        big_m = int(np.rint(cost.max() * scale)) + 1
    W = np.rint(cost * scale).astype(np.int64) + big_m
    pair = np.arange(0, 2 * n + 2, 2)
    W[pair, pair + 1] = W[pair + 1, pair] = 0
    np.fill_diagonal(W, 0)
    tour = _lkh_atsp(W, seed=seed, runs=runs, max_trials=max_trials, symmetric=True, subgradient=subgradient)
    k = tour.index(S)
    tour = tour[k:] + tour[:k]
    if tour[1] == E:
        tour = [S] + tour[1:][::-1]
    out = []
    for a, b in zip(tour[1:-1:2], tour[2:-1:2]):
        if a // 2 != b // 2:                           # the tour left a pass edge out: not expected
            raise RuntimeError("LKH tour does not follow the pass edges")
        out.append(2 * (a // 2) + (a % 2))             # node index = 2 g + flipped
    return out


def best_variants(variants: Variants, D: np.ndarray, start_cost, groups_in_order) -> list[int]:
    """For a fixed order of groups, the best path type of each (shortest path over the layers of
    variants, ``O(g k²)``)."""
    g_of = variants.group
    layers = [np.flatnonzero(g_of == g) for g in groups_in_order]
    cost = variants.inner[layers[0]] + (0.0 if start_cost is None else start_cost[layers[0]])
    back = []
    for prev, cur in pairwise(layers):
        tot = cost[:, None] + D[np.ix_(prev, cur)] + variants.inner[cur][None, :]
        back.append(tot.argmin(axis=0))
        cost = tot.min(axis=0)
    j = int(cost.argmin())
    pick = [j]
    for b in back[::-1]:
        j = int(b[j])
        pick.append(j)
    pick = pick[::-1]
    return [int(layer[i]) for layer, i in zip(layers, pick)]


def reverse_nodes(variants: Variants) -> np.ndarray:
    """(N,) int: for each node, the node of the same group that runs it backwards (passes in the
    other order, each flipped: its entry is this node's exit and vice versa), or -1 if none."""
    key = {(int(g), bool(r), bool(f)): i for i, (g, r, f) in
           enumerate(zip(variants.group, variants.reverse_order, variants.flip))}
    out = np.full(len(variants.group), -1, dtype=np.int64)
    for i, (g, r, f) in enumerate(zip(variants.group, variants.reverse_order, variants.flip)):
        g, r, f = int(g), bool(r), bool(f)
        single = (g, True, False) not in key
        out[i] = key.get((g, r, not f) if single else (g, not r, not f), -1)
    return out


def improve_tour(variants: Variants, D: np.ndarray, start_cost: np.ndarray | None, tour, *,
                 max_rounds: int = 200, max_segment: int = 3) -> list[int]:
    """Local search on a GTSP tour: best path types for the group order (:func:`best_variants`),
    then 2-opt (a stretch of groups visited backwards, each group run backwards) and Or-opt (a run of
    up to ``max_segment`` groups moved elsewhere, as it is or backwards), best move first, until no
    move shortens the tour or ``max_rounds`` moves were made.  Never returns a longer tour.

    The moves assume that a group run backwards costs inside what it costs forwards (true of the
    air lengths and of the link times of :class:`LinkModel`); every accepted move is checked on
    the true cost.
    """
    rev = reverse_nodes(variants)
    tour = [int(v) for v in tour]
    if len(tour) < 3 or (rev < 0).any():
        return tour
    g_of = variants.group

    def total(t):
        return tour_length(variants, D, t, start_cost)

    best = best_variants(variants, D, start_cost, [int(g_of[v]) for v in tour])
    if total(best) <= total(tour):
        tour = best
    cur = total(tour)
    N = len(g_of)
    # a depot (index N): from it the start cost (or nothing), back to it nothing
    Dx = np.zeros((N + 1, N + 1))
    Dx[:N, :N] = D
    if start_cost is not None:
        Dx[N, :N] = start_cost
    revx = np.r_[rev, N]
    for _ in range(max_rounds):
        t = np.array([N] + tour)                       # cyclic: ... last -> depot -> first ...
        n = len(t)
        nxt = np.roll(t, -1)
        edge = Dx[t, nxt]                              # edge[i]: t[i] -> t[i+1]
        moves = []
        # 2-opt: positions i..j (1 <= i < j <= n-1) run backwards
        i = np.arange(1, n)[:, None]
        j = np.arange(1, n)[None, :]
        ok = j > i
        delta = (Dx[t[i - 1], revx[t[j]]] + Dx[revx[t[i]], nxt[j]] - edge[i - 1] - edge[j])
        delta = np.where(ok, delta, np.inf)
        k = np.unravel_index(np.argmin(delta), delta.shape)
        moves.append((float(delta[k]), "2opt", int(k[0]) + 1, int(k[1]) + 1, False, 0))
        # Or-opt: positions i..i+L-1 moved between t[p] and t[p+1], as they are or backwards
        for L in range(1, min(max_segment, n - 2) + 1):
            i = np.arange(1, n - L + 1)[:, None]
            e = i + L - 1
            gain = edge[i - 1] + edge[e] - Dx[t[i - 1], nxt[e]]
            p = np.arange(n)[None, :]
            inside = (p >= i - 1) & (p <= e)
            for backwards in (False, True):
                s_node, e_node = (revx[t[e]], revx[t[i]]) if backwards else (t[i], t[e])
                add = Dx[t[p], s_node] + Dx[e_node, nxt[p]] - edge[p]
                d = np.where(inside, np.inf, add - gain)
                k = np.unravel_index(np.argmin(d), d.shape)
                moves.append((float(d[k]), "or", int(k[0]) + 1, int(k[1]), backwards, L))
        move = min(moves, key=lambda m: m[0])
        if not move[0] < -1e-12:
            break
        tl = list(t)
        if move[1] == "2opt":
            _, _, a, b, _, _ = move
            tl[a:b + 1] = [int(revx[v]) for v in tl[a:b + 1][::-1]]
        else:
            _, _, a, after, backwards, L = move
            seg = tl[a:a + L]
            if backwards:
                seg = [int(revx[v]) for v in seg[::-1]]
            anchor_node = tl[after]
            rest = tl[:a] + tl[a + L:]
            q = rest.index(anchor_node)
            tl = rest[:q + 1] + seg + rest[q + 1:]
        k0 = tl.index(N)
        cand = [int(v) for v in tl[k0 + 1:] + tl[:k0]]
        cand = best_variants(variants, D, start_cost, [int(g_of[v]) for v in cand])
        new = total(cand)
        if not new < cur - 1e-12:
            break
        tour, cur = cand, new
    return tour


def _lkh_atsp(W: np.ndarray, *, seed: int, runs: int, max_trials: int | None, symmetric: bool = False,
              subgradient: bool = True) -> list[int]:
    """Solve the (asymmetric, or with ``symmetric`` the symmetric) TSP with integer weights ``W``
    (s, s) by LKH; a tour as node indices.  ``subgradient=False`` skips LKH's subgradient ascent
    and takes the candidate edges by plain cost: on the fixed-edge instances of
    :func:`_solve_single_passes` (every edge but the pass edges costs ``M`` more) the ascent misleads
    the candidate sets: at 199 passes of the hub, single runs were 1.3-3.8 % above the best of 100
    runs with it and 0-1.5 % without it (``benchmarks/bench_order.py``)."""
    try:
        import elkai
    except ImportError as exc:                         # pragma: no cover - elkai is a dependency
        raise InputError("order method 'gtsp' needs the elkai package (pip install elkai); "
                         "or choose method='greedy'") from exc
    n = len(W)
    trials = max_trials if max_trials is not None else min(n, 100)
    # With the ascent, a short initial subgradient period: 3-5x faster candidate sets on these
    # geometric instances.
    ascent = "INITIAL_PERIOD = 100\n" if subgradient else "SUBGRADIENT = NO\n"
    params = f"RUNS = {runs}\nMAX_TRIALS = {trials}\nSEED = {int(seed) + 1}\n{ascent}PROBLEM_FILE = :stdin:\n"
    kind = "TSP" if symmetric else "ATSP"
    problem = (f"TYPE : {kind}\nDIMENSION : {n}\nEDGE_WEIGHT_TYPE : EXPLICIT\nEDGE_WEIGHT_FORMAT : FULL_MATRIX\n"
               "EDGE_WEIGHT_SECTION\n" + "\n".join(" ".join(map(str, row)) for row in W.tolist()) + "\n")
    solve_problem = getattr(getattr(elkai, "_elkai", None), "solve_problem", None)
    if solve_problem is not None:
        tour = [int(i) - 1 for i in solve_problem(params, problem)]
    else:                                              # pragma: no cover - older/newer elkai layouts
        tour = [int(i) for i in elkai.DistanceMatrix(W.tolist()).solve_tsp(runs=max(runs, 1))][:-1]
    if sorted(tour) != list(range(n)):
        raise RuntimeError(f"LKH returned an invalid tour of {len(tour)} nodes for {n}")
    return tour


#: :func:`solve_portfolio` solves instances of at most this many groups exactly (Held–Karp).
EXACT_UP_TO = 10


def solve_portfolio(variants: Variants, D: np.ndarray, start_cost, *, seed: int = 0, runs: int = 1,
                    max_trials: int | None = None) -> list[int]:
    """The ``gtsp`` method: the exact optimum up to :data:`EXACT_UP_TO` groups; beyond, LKH twice,
    with and without its subgradient ascent (each is stuck in different local optima on these
    instances), the better tour polished by :func:`improve_tour`.  ``runs`` LKH runs each (at least
    ``ceil(200 / groups)``, at most 5: small instances get more runs for the same time).

    Measured on the hub (``benchmarks/bench_order.py``): within 1 % of the best of 100 LKH runs up
    to 200 passes, in well under a second.
    """
    n_groups = variants.n_groups
    if n_groups <= EXACT_UP_TO:
        return held_karp(variants, D, start_cost)
    runs = max(int(runs), min(5, -(-200 // n_groups)))
    tours = [solve_gtsp(variants, D, start_cost, seed=seed, runs=runs, max_trials=max_trials, subgradient=sub)
             for sub in (False, True)]
    best = min(tours, key=lambda t: tour_length(variants, D, t, start_cost))
    return improve_tour(variants, D, start_cost, best)


def solve(variants: Variants, D: np.ndarray, start_cost, method: str, *, seed: int = 0, runs: int = 1,
          max_trials: int | None = None) -> list[int]:
    """Dispatch to the solver ``method`` (one of :data:`METHODS`)."""
    if method == "index":
        return solve_index(variants)
    if method == "greedy":
        return solve_greedy(variants, D, start_cost)
    if method == "exact":
        return held_karp(variants, D, start_cost)
    if method == "gtsp":
        tour = solve_portfolio(variants, D, start_cost, seed=seed, runs=runs, max_trials=max_trials)
        # LKH is a heuristic: never return worse than the greedy baseline.
        greedy = solve_greedy(variants, D, start_cost)
        if tour_length(variants, D, greedy, start_cost) < tour_length(variants, D, tour, start_cost) - 1e-12:
            return greedy
        return tour
    raise InputError(f"unknown order method {method!r}; choose one of {', '.join(METHODS)}")
