"""The dwell linear programme of the feed optimisation: removal ``K t`` against a target, solved by HiGHS.

:func:`solve_dwell` is the programme :mod:`.optimise` describes (its docstring gives the constraints
and objectives); it adds the thinned-out sample rows that its solution over-removes and solves again.
:func:`thin_rows` chooses the sample rows a large part keeps (the worst per grid cell).
"""

from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp
from scipy.optimize import linprog

from ..errors import InfeasibleError, InputError
from .kernel import RemovalKernel

log = logging.getLogger("swath.feed.optimise")

#: Depth unit inside the solver, m (micrometres).
_DEPTH_UNIT = 1e-6

MODES = ("match", "max_removal")
OBJECTIVES = ("l1", "minimax")


def _accel_rows(nodes, a_t: float, p_ref):
    """Rows ``G t <= h`` of the linearised tangential-acceleration limit between neighbouring nodes,
    each linearised at its reference pace (:func:`swath.feed.caps.row_reference_pace` of ``p_ref``,
    s/m: one number or one per node)."""
    from .caps import row_reference_pace

    same = nodes.pass_index[1:] == nodes.pass_index[:-1]
    i = np.flatnonzero(same)
    if len(i) == 0:
        return sp.csr_matrix((0, len(nodes))), np.zeros(0)
    j = i + 1
    L = nodes.length
    dc = nodes.s_mid[j] - nodes.s_mid[i]
    p_ref = row_reference_pace(p_ref, len(nodes))[i]
    c = a_t * dc * p_ref**2                       # |p_j - p_i| <= c (3 p_k - 2 p_ref), k in {i, j}
    rows, cols, vals, rhs = [], [], [], []
    r = 0
    for sign in (1.0, -1.0):
        for k_is_i in (True, False):
            # sign (p_j - p_i) - 3 c p_k <= -2 c p_ref
            pi_coef = -sign / L[i]
            pj_coef = sign / L[j]
            if k_is_i:
                pi_coef = pi_coef - 3 * c / L[i]
            else:
                pj_coef = pj_coef - 3 * c / L[j]
            n = len(i)
            rows += [np.arange(r, r + n), np.arange(r, r + n)]
            cols += [i, j]
            vals += [pi_coef, pj_coef]
            rhs.append(-2 * c * p_ref)
            r += n
    G = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(r, len(nodes)))
    # scale each row to pace units of its reference pace
    scale = 1.0 / np.tile(p_ref, 4)
    return sp.diags(scale) @ G, np.concatenate(rhs) * scale


def solve_dwell(kernel: RemovalKernel, target: np.ndarray, *, tolerance, t_min: np.ndarray,
                t_max: np.ndarray, region: np.ndarray, mode: str = "match", objective: str = "l1",
                a_t: float | None = None, v_max: float | None = None, accel_ref=None, time_limit: float = 600.0,
                smoothing: float = 2e-2, method: str | None = None, max_rows: int = 5000, max_rounds: int = 6,
                time_weight: float = 1e-3, cap_rows: np.ndarray | None = None, found: dict | None = None,
                slack=0.0, on_solve=None, capped: np.ndarray | None = None):
    """Solve for the dwell ``(n,)`` (s); returns ``(dwell, status_text)``.

    ``time_weight``: a cost on every second of dwell, as a fraction of what a second of a typical
    node is worth to the objective, so that among dwells that match the target (nearly) equally
    well the shorter wins: nodes over no optimised sample run at the fastest feed instead of
    wherever the solver leaves them (on noether_raw_mesh a third of the nodes, at the slowest feed,
    tripled the cycle time).

    When the region has more than ``max_rows`` samples the programme sees a thinned set
    (:func:`thin_rows`); samples left out that the solution over-grinds are added as cap rows and the
    programme is solved again (at most ``max_rounds`` times), so the cap holds at every region sample.
    ``cap_rows`` (kernel sample indices) are held at the cap from the first solve on, and ``found``
    (a dict), if given, receives under ``"cap_rows"`` every sample held at the cap in the last
    solve: a later solve of the same kernel with other caps (the simulated rounds of
    :func:`~swath.feed.optimise.optimise_feed`) given them back skips the rounds that would find
    them again (crs_part_5: six solves of 5-8 s each per call).

    ``capped`` ((S,) bool, default ``region``): the samples held under ``target + tolerance``, the
    region's and others (the touched samples near the edges, whose removal the objective does not
    read: :func:`~swath.feed.optimise.optimise_feed` holds them under twice the region's cap, or
    under what the fastest feed removes there where that is more).

    ``accel_ref`` (s/m, one per node ``(n,)``): the paces the acceleration rows are linearised at
    (:func:`swath.feed.caps.row_reference_pace`; default ``1 / v_max`` for every row).

    ``slack`` (m, a scalar or one per kernel sample ``(S,)``): the rounds stop once no thinned-out
    sample is over its cap by more than this (never less than a thousandth of the largest
    tolerance); while one is, every sample over by more than that thousandth is a candidate cap
    row.  The last rounds chase ever smaller excesses: on crs_part_5 at a 12 µm target 0.36, 0.11
    and 0.011 µm, a solve of 7-9 s each.  :func:`~swath.feed.optimise.optimise_feed` gives a tenth
    of what it holds back under the stated tolerance, so the accepted excess stays inside it.

    Raises
    ------
    InfeasibleError
        When the fastest feed already removes more than ``target + tolerance`` somewhere in the
        region, or HiGHS reports the programme infeasible.
    """
    capped = region if capped is None else np.asarray(capped, bool) | region
    full = np.flatnonzero(capped)
    K_full = kernel.matrix[full].tocsr()
    tolerance = np.broadcast_to(np.asarray(tolerance, float), target.shape)
    tiny = 1e-3 * max(float(tolerance.max(initial=0.0)), 1e-9)
    cap = target[full] + tolerance[full]
    allowed = np.maximum(tiny, np.broadcast_to(np.asarray(slack, float), target.shape)[full])
    # cap rows from the start at each cell's peak of the fastest feed's removal: the ripple's peaks,
    # where the cap binds (the objective's thinned rows sit anywhere in their cells)
    extra = np.zeros(0, dtype=int)
    if len(full) > max_rows:
        peaks, _ = thin_rows(kernel.samples, region, max_rows, score=kernel.removal(t_min))
        extra = np.searchsorted(full, peaks)
        if cap_rows is not None and len(cap_rows):
            given = np.asarray(cap_rows, dtype=int)
            given = given[capped[given]]                       # (not capped: no cap)
            extra = np.union1d(extra, np.searchsorted(full, given))
    status = ""
    for _ in range(max(1, max_rounds)):
        if on_solve is not None:
            on_solve()
        dwell, status = _solve(kernel, target, tolerance=tolerance, t_min=t_min, t_max=t_max, region=region,
                               mode=mode, objective=objective, a_t=a_t, v_max=v_max, accel_ref=accel_ref,
                               time_limit=time_limit,
                               smoothing=smoothing, method=method, max_rows=max_rows, cap_rows=full[extra],
                               time_weight=time_weight)
        over = K_full @ dwell - cap
        if (over <= allowed).all():
            break
        bad = np.flatnonzero(over > tiny)
        worst = _worst_per_cell(kernel.samples.vertices[full[bad]], over[bad], kernel.samples.vertex_areas[full[bad]],
                                max(1, max_rows // 4))
        log.info("feed optimisation: %d thinned-out samples over the cap by up to %.3g um; adding the worst %d",
                 len(bad), over.max() / _DEPTH_UNIT, len(worst))
        extra = np.union1d(extra, bad[worst])
    else:
        over = K_full @ dwell - cap
        if (over > allowed).any():
            log.warning("feed optimisation: after %d rounds %d samples are still over the cap by up to %.3g um",
                        max_rounds, int(np.sum(over > allowed)), over.max() / _DEPTH_UNIT)
    if found is not None:
        found["cap_rows"] = full[extra]
    return dwell, status


def _solve(kernel: RemovalKernel, target: np.ndarray, *, tolerance: np.ndarray, t_min: np.ndarray,
           t_max: np.ndarray, region: np.ndarray, mode: str, objective: str, a_t, v_max, time_limit: float,
           accel_ref=None,
           smoothing: float, method, max_rows: int, cap_rows: np.ndarray, time_weight: float = 0.0):
    """One solve of the programme on the thinned region rows plus the extra ``cap_rows``: ``(dwell, status)``.

    Raises
    ------
    InfeasibleError
        When the fastest feed already removes more than ``target + tolerance`` somewhere in the
        region, or HiGHS reports the programme infeasible.
    """
    if mode not in MODES:
        raise InputError(f"mode must be one of {MODES}, got {mode!r}")
    if objective not in OBJECTIVES:
        raise InputError(f"objective must be one of {OBJECTIVES}, got {objective!r}")
    K = kernel.matrix
    rows, w = thin_rows(kernel.samples, region, max_rows)
    A = (K[rows] / _DEPTH_UNIT).tocsr()                    # µm per s
    d = target[rows] / _DEPTH_UNIT
    u = d + tolerance[rows] / _DEPTH_UNIT
    w = w / w.mean()
    if method is None:
        method = "highs-ipm" if (mode == "match" and objective == "l1") else "highs"

    n = K.shape[1]
    all_rows = np.flatnonzero(region)
    r0 = (K[all_rows] @ t_min) / _DEPTH_UNIT
    d_all = target[all_rows] / _DEPTH_UNIT
    tol_all = tolerance[all_rows] / _DEPTH_UNIT
    excess = r0 - (d_all + tol_all)
    if len(all_rows) and excess.max() > 1e-9:
        j = int(np.argmax(excess))
        where = kernel.samples.vertices[all_rows[j]]
        share = float(np.mean(excess > 1e-9))
        raise InfeasibleError(
            f"the fastest allowed feed already removes {r0[j]:.3g} um at ({where[0]:.4f}, {where[1]:.4f}, "
            f"{where[2]:.4f}) m, more than the target {d_all[j]:.3g} um plus the tolerance "
            f"{tol_all[j]:.3g} um ({100 * share:.1f} % of the optimised samples are over); raise the "
            f"target to at least {float(np.max(r0 - tol_all)):.3g} um or the tolerance, raise the "
            "feed limit, or plan the passes farther apart")
    G = sp.csr_matrix((0, n))
    h = np.zeros(0)
    if a_t is not None and v_max is not None:
        G, h = _accel_rows(kernel.nodes, a_t, 1.0 / v_max if accel_ref is None else accel_ref)
    if len(cap_rows):
        G = sp.vstack([G, K[cap_rows] / _DEPTH_UNIT]).tocsr()
        h = np.concatenate([h, (target[cap_rows] + tolerance[cap_rows]) / _DEPTH_UNIT])
    m = len(rows)
    # Smoothing: g_e >= |p_j - p_i| / p_ref between neighbouring nodes, at a small cost.  Dwell along
    # a pass is otherwise free to alternate (the pad spans many nodes, so only window sums matter).
    nodes = kernel.nodes
    p_ref = 1.0 / (v_max if v_max is not None else float(np.max(nodes.length / t_min)))
    e = np.flatnonzero(nodes.pass_index[1:] == nodes.pass_index[:-1])
    E = len(e)
    Dm = sp.csr_matrix((np.concatenate([-1.0 / nodes.length[e], 1.0 / nodes.length[e + 1]]) / p_ref,
                        (np.tile(np.arange(E), 2), np.concatenate([e, e + 1]))), shape=(E, n))
    col_weight = np.asarray(w @ A).ravel() * nodes.length          # objective change per unit pace
    lam = smoothing * float(np.mean(col_weight)) * p_ref if n else 0.0
    log.debug("smoothing weight %g (column weight %g, p_ref %g)", lam, float(np.mean(col_weight)), p_ref)
    # The cost of a second of dwell: time_weight times what a second of a typical node (one over
    # some optimised sample) is worth to the area-weighted removal (the same in every objective, so
    # it weighs against the smoothing cost alike).
    touching = col_weight > 0
    per_second = float(np.mean(col_weight[touching] / nodes.length[touching])) if touching.any() else 0.0
    eps = np.full(n, time_weight * per_second)
    IE = sp.identity(E, format="csr")
    S_rows = sp.vstack([sp.hstack([Dm, -IE]), sp.hstack([-Dm, -IE])])   # on [t, g]
    opts = {"time_limit": time_limit, "presolve": True}

    def pad(M, k):                                   # M on t -> on [t, g, k extra]
        return sp.hstack([M, sp.csr_matrix((M.shape[0], E + k))])

    t_bounds = np.stack([t_min, t_max], axis=1)
    g_bounds = np.tile([0.0, np.inf], (E, 1))
    if mode == "max_removal":
        c = np.concatenate([-(w @ A) + eps, np.full(E, lam)])
        A_ub = sp.vstack([pad(A, 0), pad(G, 0), S_rows]).tocsc()
        b_ub = np.concatenate([u, h, np.zeros(2 * E)])
        res = linprog(c, A_ub=A_ub, b_ub=b_ub, bounds=np.concatenate([t_bounds, g_bounds]), method=method,
                      options=opts)
    elif objective == "l1":
        # A t - e+ + e- = d, 0 <= e+ <= tol, e- >= 0; minimise w (e+ + e-)
        I = sp.identity(m, format="csr")
        A_eq = sp.hstack([A, sp.csr_matrix((m, E)), -I, I]).tocsc()
        c = np.concatenate([eps, np.full(E, lam), w, w])
        A_ub = sp.vstack([pad(G, 2 * m), sp.hstack([S_rows, sp.csr_matrix((2 * E, 2 * m))])]).tocsc()
        b_ub = np.concatenate([h, np.zeros(2 * E)])
        tol_um = tolerance[rows] / _DEPTH_UNIT
        bounds = np.concatenate([t_bounds, g_bounds, np.stack([np.zeros(m), tol_um], axis=1), np.tile([0.0, np.inf], (m, 1))])
        res = linprog(c, A_ub=A_ub, b_ub=b_ub, A_eq=A_eq, b_eq=d, bounds=bounds, method=method, options=opts)
    else:
        # minimise z: d - A t <= z, A t <= u
        col = sp.csr_matrix(np.ones((m, 1)))
        zero = sp.csr_matrix((m, E))
        A_ub = sp.vstack([sp.hstack([-A, zero, -col]), sp.hstack([A, zero, sp.csr_matrix((m, 1))]),
                          pad(G, 1), sp.hstack([S_rows, sp.csr_matrix((2 * E, 1))])]).tocsc()
        b_ub = np.concatenate([-d, u, h, np.zeros(2 * E)])
        zscale = float(np.mean(col_weight)) * p_ref if n else 1.0
        c = np.concatenate([eps, np.full(E, lam), [zscale]])
        bounds = np.concatenate([t_bounds, g_bounds, [[0.0, np.inf]]])
        res = linprog(c, A_ub=A_ub, b_ub=b_ub, bounds=bounds, method=method, options=opts)
    if res.x is None and res.status == 4 and method == "highs-ipm":
        # interior point in numerical trouble (seen on the panel with 5000 rows): the same programme by
        # the dual simplex, slower but robust
        log.info("feed optimisation: interior point reports %r; solving again with the dual simplex", res.message)
        if mode != "max_removal" and objective == "l1":
            res = linprog(c, A_ub=A_ub, b_ub=b_ub, A_eq=A_eq, b_eq=d, bounds=bounds, method="highs-ds", options=opts)
    x = None if res.x is None else res.x[:n]
    if res.status == 2:
        raise InfeasibleError(f"the feed optimisation is infeasible ({res.message}); the acceleration limit, the "
                              "speed caps and the over-removal tolerance cannot all hold: raise the tolerance or "
                              "the acceleration limit")
    if x is None:
        raise InfeasibleError(f"the feed optimisation stopped without a solution: {res.message}")
    return np.clip(x, t_min, t_max), f"{res.status}: {res.message}"


def _worst_per_cell(points: np.ndarray, over: np.ndarray, areas: np.ndarray, limit: int) -> np.ndarray:
    """Indices of at most about ``limit`` of ``points`` ``(k, 3)`` (m): the one with the largest
    ``over`` in each cell of a cubic grid sized so their area (``areas``, m²) gives about ``limit``
    cells (neighbouring samples share their dwell nodes, so capping the worst caps its neighbours)."""
    if len(points) <= limit:
        return np.arange(len(points))
    cell = float(np.sqrt(areas.sum() / limit))
    key = np.floor(points / cell).astype(np.int64)
    order = np.argsort(-over, kind="stable")
    _, first = np.unique(key[order], axis=0, return_index=True)
    return order[first]


def thin_rows(samples, region: np.ndarray, max_rows: int, score: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """At most about ``max_rows`` region samples for the programme: one per cell of a cubic grid
    sized so the region's area gives about ``max_rows`` cells (the one with the largest ``score``,
    ``(S,)``, when given: the removal at the fastest feed, so the cap rows sit on the ripple's
    peaks and few left-out samples end over the cap), weighted by the area of its cell's region
    samples.  Returns ``(rows (k,) int, weights (k,) float m²)``; all region samples when they
    are few enough."""
    rows = np.flatnonzero(region)
    areas = samples.vertex_areas
    if len(rows) <= max_rows:
        return rows, areas[rows]
    cell = float(np.sqrt(areas[rows].sum() / max_rows))
    key = np.floor(samples.vertices[rows] / cell).astype(np.int64)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    weight = np.bincount(inverse, weights=areas[rows])
    if score is not None:
        order = np.lexsort((-score[rows], inverse))            # by cell, the highest score first
        first = order[np.concatenate([[0], np.flatnonzero(np.diff(inverse[order])) + 1])]
    return rows[first], weight


# ----------------------------------------------------------------------------------------------
# From dwell to a feed profile
# ----------------------------------------------------------------------------------------------
