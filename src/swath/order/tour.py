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
heuristic (LKH, through the ``elkai`` package).  Baselines: ``index`` (as given) and ``greedy``
(from the current exit, the nearest entry among the groups left).  :func:`held_karp` solves small
instances exactly (dynamic programming over subsets of groups x end variants) to check the heuristic.

The air distance between a lift-off point ``p`` (normal ``n``) and a touch-down point ``q`` (normal
``m``) is estimated as ``c + |(p + c n) - (q + c m)| + c`` with the clearance ``c``: retract, a
straight move at the clearance, approach.  The trajectory stage routes the real links.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np

from ..errors import InputError

log = logging.getLogger("swath.order")

#: Largest number of groups :func:`held_karp` accepts (2^n x (4n) states).
MAX_EXACT_GROUPS = 14
#: Air distances are scaled to integers for LKH with this many units per metre (0.01 mm).
_INT_SCALE = 1e5
METHODS = ("gtsp", "greedy", "index", "exact")


@dataclass(frozen=True, eq=False)
class Variants:
    """The path types of every group, flattened into one list of nodes.

    Attributes
    ----------
    group : (N,) int
        Group of each node.
    reverse_order, flip : (N,) bool
        Whether the node runs the group's passes in reverse order, and flips every pass.
    entry, exit : (N, 3) float
        Touch-down and lift-off points raised by the clearance along the normals, m.
    inner : (N,) float
        Air length of the links inside the group for this variant, m.
    """

    group: np.ndarray
    reverse_order: np.ndarray
    flip: np.ndarray
    entry: np.ndarray
    exit: np.ndarray
    inner: np.ndarray

    @property
    def n_groups(self) -> int:
        return int(self.group.max()) + 1 if len(self.group) else 0


def group_variants(passes, groups, *, clearance: float) -> Variants:
    """Enumerate the path types of each group (see the module notes).

    Parameters
    ----------
    passes : sequence of Pass
    groups : list of list of int
        Pass indices of each group, in the group's own processing order.
    clearance : float
        Lift along the normal before an air move, m.
    """
    rows = []
    for g, idx in enumerate(groups):
        types = [(False, False), (False, True)] if len(idx) == 1 else \
            [(False, False), (False, True), (True, False), (True, True)]
        for rev, flip in types:
            seq = _sequence(passes, idx, rev, flip)
            inner = sum(_air(a, b, clearance) for a, b in zip(seq[:-1], seq[1:]))
            first, last = seq[0], seq[-1]
            rows.append((g, rev, flip, first[0] + clearance * first[1], last[2] + clearance * last[3], inner))
    g, rev, flip, entry, exit_, inner = zip(*rows)
    return Variants(np.array(g), np.array(rev), np.array(flip), np.array(entry), np.array(exit_), np.array(inner))


def _sequence(passes, idx, rev, flip):
    """(start point, start normal, end point, end normal) of each pass of a group variant."""
    order = list(idx)[::-1] if rev else list(idx)
    out = []
    for i in order:
        p = passes[i]
        a, b = (-1, 0) if flip else (0, -1)
        out.append((p.points[a], p.normals[a], p.points[b], p.normals[b]))
    return out


def _air(a, b, clearance: float) -> float:
    """Air length from the end of pass ``a`` to the start of pass ``b`` (tuples of :func:`_sequence`)."""
    return 2 * clearance + float(np.linalg.norm((a[2] + clearance * a[3]) - (b[0] + clearance * b[1])))


def link_matrix(variants: Variants, clearance: float) -> np.ndarray:
    """(N, N) air length from each node's exit to each node's entry, m (retract and approach included)."""
    d = np.linalg.norm(variants.exit[:, None, :] - variants.entry[None, :, :], axis=2)
    return d + 2 * clearance


def tour_length(variants: Variants, D: np.ndarray, nodes, start_cost: np.ndarray | None) -> float:
    """Air length (m) of visiting ``nodes`` in order: links between groups, links inside groups and the
    move from the start point (``start_cost[node]``) when one is given."""
    nodes = list(nodes)
    total = float(sum(D[a, b] for a, b in zip(nodes[:-1], nodes[1:])) + variants.inner[nodes].sum())
    if start_cost is not None and nodes:
        total += float(start_cost[nodes[0]])
    return total


# --- solvers: each returns a list of nodes, one per group, in visiting order -------------------------

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
               runs: int = 1, max_trials: int | None = None) -> list[int]:
    """Noon–Bean transform + LKH (``elkai``).

    The nodes of each group are joined in a zero-cost cycle; an arc from node ``u`` to a node ``w``
    of another group costs ``D[succ(u), w] + inner[w] + M`` where ``succ(u)`` is the next node on
    ``u``'s cycle (the tour enters a group at ``succ(u)``, runs round its cycle to ``u`` and leaves;
    the node it entered by is the chosen path type).  ``M`` (more than any tour's link cost) makes
    every optimal tour visit each group exactly once, in one block.  A depot node carries the start
    point (or costs nothing).  Distances are scaled to integers (0.01 mm).
    """
    g_of = variants.group
    N = len(g_of)
    n_groups = variants.n_groups
    if n_groups == 1:
        return [int(np.argmin(variants.inner + (0 if start_cost is None else start_cost)))]
    if n_groups >= 2 and len(g_of) == 2 * n_groups:
        return _solve_single_passes(variants, D, start_cost, seed=seed, runs=runs, max_trials=max_trials)
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
    order = _lkh_atsp(W, seed=seed, runs=runs, max_trials=max_trials)
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
                         max_trials: int | None) -> list[int]:
    """All groups single passes: a symmetric TSP on the passes' 2n ends plus two depots.

    The move from a lift-off end to a touch-down end does not depend on which is which, so every
    pass becomes an edge between its two ends that the tour must use (cost 0; every other edge
    costs ``M`` more), and a start depot S and an end depot E joined the same way carry the start
    point (S to an end: the move from the start point; E to an end: 0).  Symmetric instances are
    about twice as small for LKH as the Noon–Bean transform and solve to better tours.
    """
    n = variants.n_groups
    ends = np.empty((2 * n, 3))
    ends[0::2] = variants.entry[0::2]                # start of pass g, raised
    ends[1::2] = variants.exit[0::2]                 # end of pass g, raised
    inner_link = float(D[0, 0] - np.linalg.norm(variants.exit[0] - variants.entry[0]))   # 2 x clearance
    dist = np.linalg.norm(ends[:, None] - ends[None], axis=2) + inner_link
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
    tour = _lkh_atsp(W, seed=seed, runs=runs, max_trials=max_trials, symmetric=True)
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
    for prev, cur in zip(layers[:-1], layers[1:]):
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


def _lkh_atsp(W: np.ndarray, *, seed: int, runs: int, max_trials: int | None, symmetric: bool = False) -> list[int]:
    """Solve the (asymmetric, or with ``symmetric`` the symmetric) TSP with integer weights ``W``
    (s, s) by LKH; a tour as node indices."""
    try:
        import elkai
    except ImportError as exc:                         # pragma: no cover - elkai is a dependency
        raise InputError("order method 'gtsp' needs the elkai package (pip install elkai); "
                         "or choose method='greedy'") from exc
    n = len(W)
    trials = max_trials if max_trials is not None else min(n, 100)
    # A short initial subgradient period: 3-5x faster candidate sets on these geometric instances.
    params = (f"RUNS = {runs}\nMAX_TRIALS = {trials}\nSEED = {int(seed) + 1}\nINITIAL_PERIOD = 100\n"
              "PROBLEM_FILE = :stdin:\n")
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
        tour = solve_gtsp(variants, D, start_cost, seed=seed, runs=runs, max_trials=max_trials)
        # LKH is a heuristic: never return worse than the greedy baseline.
        greedy = solve_greedy(variants, D, start_cost)
        if tour_length(variants, D, greedy, start_cost) < tour_length(variants, D, tour, start_cost) - 1e-12:
            return greedy
        return tour
    raise InputError(f"unknown order method {method!r}; choose one of {', '.join(METHODS)}")


# --- the public entry point ----------------------------------------------------------------------

def default_groups(toolpath) -> list[list[int]]:
    """Groups of a tool path: its regions' passes (``metadata["pass_region"]``, in order of
    appearance) when known, otherwise one group per pass."""
    n = len(toolpath.passes)
    labels = toolpath.metadata.get("pass_region")
    if labels is None or len(labels) != n:
        return [[i] for i in range(n)]
    groups: dict = {}
    for i, r in enumerate(labels):
        groups.setdefault(r, []).append(i)
    return list(groups.values())


def order_toolpath(toolpath, *, groups=None, method: str = "gtsp", start=None, seed: int = 0,
                   clearance: float = 0.02, runs: int = 1, max_trials: int | None = None):
    """Reorder a tool path's pass groups and choose their path types to minimise air travel.

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
    runs, max_trials : int
        LKH runs and trials per run (default ``min(nodes, 100)``).

    Returns
    -------
    ToolPath
        The same passes, reordered and flipped (:meth:`Pass.reversed`); ``metadata`` gains
        ``order_method``, ``air_before_m`` (as given), ``air_after_m``, ``order_seconds``,
        ``order_groups`` (the group order as indices into ``groups``) and, when the input had it,
        ``pass_region`` reordered.

    Raises
    ------
    InputError
        On groups that do not partition the passes, an unknown method, a bad start point or clearance.
    """
    from ..plan.toolpath import ToolPath

    n = len(toolpath.passes)
    if n == 0:
        raise InputError("the tool path has no passes to order")
    if not (np.isfinite(clearance) and clearance >= 0):
        raise InputError(f"clearance must be a length >= 0 m, got {clearance!r}")
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
    variants = group_variants(toolpath.passes, groups, clearance=clearance)
    D = link_matrix(variants, clearance)
    start_cost = None if start_pt is None else np.linalg.norm(variants.entry - start_pt, axis=1) + clearance
    before = tour_length(variants, D, solve_index(variants), start_cost)
    tour = solve(variants, D, start_cost, method, seed=seed, runs=runs, max_trials=max_trials)
    after = tour_length(variants, D, tour, start_cost)
    seconds = time.perf_counter() - t0

    passes, regions = [], []
    labels = toolpath.metadata.get("pass_region")
    for node in tour:
        g = int(variants.group[node])
        idx = groups[g][::-1] if variants.reverse_order[node] else groups[g]
        for i in idx:
            p = toolpath.passes[i]
            passes.append(p.reversed() if variants.flip[node] else p)
            if labels is not None and len(labels) == n:
                regions.append(labels[i])
    meta = dict(toolpath.metadata)
    meta.update(order_method=method, air_before_m=before, air_after_m=after, order_seconds=seconds,
                order_groups=[int(variants.group[v]) for v in tour], order_clearance_m=float(clearance))
    if regions:
        meta["pass_region"] = regions
    log.info("order %s: %d passes in %d groups, air %.3f m -> %.3f m (%.2f s)", method, n, len(groups),
             before, after, seconds)
    return ToolPath(toolpath.surface, passes, toolpath.planner, meta)
