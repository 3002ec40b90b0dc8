"""Feed (dwell) optimisation to a target depth map, as a linear programme solved by HiGHS.

Variables are the dwell times ``t_i`` (s) of the dwell nodes (:mod:`.kernel`); removal is ``K t``.
With ``Δs_i`` the node length the feed through node ``i`` is ``v_i = Δs_i / t_i``.

Constraints (all linear in ``t``)
---------------------------------
* feed ``v_min <= v_i <= cap_i``: the bounds ``Δs_i / cap_i <= t_i <= Δs_i / v_min``, with ``cap_i``
  the smallest of the feed limit and the centripetal ``sqrt(a_c / κ)`` and angular ``ω_max / ρ``
  caps along the node, computed on the timing grid exactly as :func:`swath.trajectory.time_path`
  does (:func:`node_speed_caps`);
* never over-grind: ``(K t)_j <= target_j + tolerance`` at every sample of the optimised region
  (touched samples at least ``boundary_margin`` from the open boundary);
* tangential acceleration ``|dv/dt| <= a_t``: with the pace ``p = 1/v = t/Δs``, ``dv/dt = −p'/p³``, so
  ``|p_{i+1} − p_i| <= a_t Δc p³`` between neighbouring nodes ``Δc`` apart.  ``p³`` is replaced by its
  tangent at ``p_ref = 1 / v_max`` (below ``p³`` for every ``p >= p_ref``), written at both nodes:
  a conservative linearisation.

Objectives
----------
* ``mode="match"``, ``objective="l1"``: minimise the area-weighted ``Σ a_j |(K t)_j − target_j|``;
  ``objective="minimax"``: minimise the largest under-removal ``max_j (target_j − (K t)_j)``.
* ``mode="max_removal"`` (Wang, hub grinding §2): maximise the removed volume ``Σ a_j (K t)_j``
  subject to the constraints above.

Depths are scaled to micrometres inside the solver so that HiGHS's absolute tolerances (1e-7) are
far below anything that matters.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.optimize import linprog

from ..core import ToolPath
from ..errors import InfeasibleError, InputError
from ..trajectory.constraints import FeedLimit, FeedProfile, TangentialAccelLimit
from ..trajectory.geometry import arc_length
from .caps import accel_feasible_pace, node_speed_caps, split_constraints
from .kernel import RemovalKernel, build_kernel, interior_mask, trajectory_node_dwell

log = logging.getLogger(__name__)

#: Depth unit inside the solver, m (micrometres).
_DEPTH_UNIT = 1e-6

MODES = ("match", "max_removal")
OBJECTIVES = ("l1", "minimax")


@dataclass(frozen=True, eq=False)
class FeedResult:
    """An optimised feed and what it is predicted to do.

    Attributes
    ----------
    profile : FeedProfile
        One speed (m/s) per point of every pass; give it to :func:`swath.trajectory.time_path`.
    dwell : (n,) float
        Dwell per node, s.
    speed : (n,) float
        Feed through each node, m/s.
    kernel : RemovalKernel
    target : (S,) float
        Target depth on the kernel's samples, m.
    predicted : (S,) float
        Predicted removal ``K @ dwell``, m.
    region : (S,) bool
        Samples the optimisation was asked to match (touched, at least ``boundary_margin`` in).
    metrics : dict
        Figures with units in their keys: ``status``, ``solve_time_s``, ``kernel_time_s``,
        ``removal_cov``, ``removal_mean_m``, ``target_mean_m``, ``max_over_removal_m``,
        ``max_under_removal_m``, ``residual_rms_m``, ``contact_time_s``, ``fastest_contact_time_s``, and
        with ``simulate=``: ``simulated_rounds`` (per round ``max_over_target_m``, ``samples_over``,
        ``held_back_ratio``), ``simulated_max_over_target_m``, ``simulate_time_s`` (``solve_time_s``
        then includes the re-solves), ...
    """

    profile: FeedProfile
    dwell: np.ndarray
    speed: np.ndarray
    kernel: RemovalKernel
    target: np.ndarray
    predicted: np.ndarray
    region: np.ndarray
    metrics: dict = field(default_factory=dict)


# ----------------------------------------------------------------------------------------------
# The linear programme
# ----------------------------------------------------------------------------------------------
def _accel_rows(nodes, a_t: float, p_ref: float):
    """Rows ``G t <= h`` of the linearised tangential-acceleration limit between neighbouring nodes."""
    same = nodes.pass_index[1:] == nodes.pass_index[:-1]
    i = np.flatnonzero(same)
    if len(i) == 0:
        return sp.csr_matrix((0, len(nodes))), np.zeros(0)
    j = i + 1
    L = nodes.length
    dc = nodes.s_mid[j] - nodes.s_mid[i]
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
    # scale each row to pace units of the reference pace
    return G / p_ref, np.concatenate(rhs) / p_ref


def solve_dwell(kernel: RemovalKernel, target: np.ndarray, *, tolerance, t_min: np.ndarray,
                t_max: np.ndarray, region: np.ndarray, mode: str = "match", objective: str = "l1",
                a_t: float | None = None, v_max: float | None = None, time_limit: float = 600.0,
                smoothing: float = 2e-2, method: str | None = None, max_rows: int = 5000, max_rounds: int = 6):
    """Solve for the dwell ``(n,)`` (s); returns ``(dwell, status_text)``.

    When the region has more than ``max_rows`` samples the programme sees a thinned set
    (:func:`thin_rows`); samples left out that the solution over-grinds are added as cap rows and the
    programme is solved again (at most ``max_rounds`` times), so the cap holds at every region sample.

    Raises
    ------
    InfeasibleError
        When the fastest feed already removes more than ``target + tolerance`` somewhere in the
        region, or HiGHS reports the programme infeasible.
    """
    full = np.flatnonzero(region)
    K_full = kernel.matrix[full].tocsr()
    tolerance = np.broadcast_to(np.asarray(tolerance, float), target.shape)
    tiny = 1e-3 * max(float(tolerance.max(initial=0.0)), 1e-9)
    cap = target[full] + tolerance[full]
    # cap rows from the start at each cell's peak of the fastest feed's removal: the ripple's peaks,
    # where the cap binds (the objective's thinned rows sit anywhere in their cells)
    extra = np.zeros(0, dtype=int)
    if len(full) > max_rows:
        peaks, _ = thin_rows(kernel.samples, region, max_rows, score=kernel.removal(t_min))
        extra = np.searchsorted(full, peaks)
    status = ""
    for _ in range(max(1, max_rounds)):
        dwell, status = _solve(kernel, target, tolerance=tolerance, t_min=t_min, t_max=t_max, region=region,
                               mode=mode, objective=objective, a_t=a_t, v_max=v_max, time_limit=time_limit,
                               smoothing=smoothing, method=method, max_rows=max_rows, cap_rows=full[extra])
        over = K_full @ dwell - cap
        bad = np.flatnonzero(over > tiny)
        if len(bad) == 0:
            break
        worst = _worst_per_cell(kernel.samples.vertices[full[bad]], over[bad], kernel.samples.vertex_areas[full[bad]],
                                max(1, max_rows // 4))
        log.info("feed optimisation: %d thinned-out samples over the cap by up to %.3g um; adding the worst %d",
                 len(bad), over.max() / _DEPTH_UNIT, len(worst))
        extra = np.union1d(extra, bad[worst])
    else:
        over = K_full @ dwell - cap
        if over.max() > tiny:
            log.warning("feed optimisation: after %d rounds %d samples are still over the cap by up to %.3g um",
                        max_rounds, int(np.sum(over > tiny)), over.max() / _DEPTH_UNIT)
    return dwell, status


def _solve(kernel: RemovalKernel, target: np.ndarray, *, tolerance: np.ndarray, t_min: np.ndarray,
           t_max: np.ndarray, region: np.ndarray, mode: str, objective: str, a_t, v_max, time_limit: float,
           smoothing: float, method, max_rows: int, cap_rows: np.ndarray):
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
        G, h = _accel_rows(kernel.nodes, a_t, 1.0 / v_max)
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
    IE = sp.identity(E, format="csr")
    S_rows = sp.vstack([sp.hstack([Dm, -IE]), sp.hstack([-Dm, -IE])])   # on [t, g]
    opts = {"time_limit": time_limit, "presolve": True}

    def pad(M, k):                                   # M on t -> on [t, g, k extra]
        return sp.hstack([M, sp.csr_matrix((M.shape[0], E + k))])

    t_bounds = np.stack([t_min, t_max], axis=1)
    g_bounds = np.tile([0.0, np.inf], (E, 1))
    if mode == "max_removal":
        c = np.concatenate([-(w @ A), np.full(E, lam)])
        A_ub = sp.vstack([pad(A, 0), pad(G, 0), S_rows]).tocsc()
        b_ub = np.concatenate([u, h, np.zeros(2 * E)])
        res = linprog(c, A_ub=A_ub, b_ub=b_ub, bounds=np.concatenate([t_bounds, g_bounds]), method=method,
                      options=opts)
    elif objective == "l1":
        # A t - e+ + e- = d, 0 <= e+ <= tol, e- >= 0; minimise w (e+ + e-)
        I = sp.identity(m, format="csr")
        A_eq = sp.hstack([A, sp.csr_matrix((m, E)), -I, I]).tocsc()
        c = np.concatenate([np.zeros(n), np.full(E, lam), w, w])
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
        c = np.concatenate([np.zeros(n), np.full(E, lam), [zscale]])
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
def dwell_to_profile(toolpath: ToolPath, nodes, dwell: np.ndarray) -> FeedProfile:
    """A :class:`FeedProfile` (one speed per pass point, m/s): every point takes the feed of the
    node it lies in, so each node is crossed in its dwell (the speed changes within one point step,
    about 1 mm, at node boundaries; the timing's acceleration limit rounds those steps).  Linear
    interpolation of the pace between node middles instead moved up to 40 % of the tolerance of
    over-removal between nodes on the plate benchmark."""
    speed = nodes.length / dwell
    speeds = []
    for k, p in enumerate(toolpath.passes):
        a, b = nodes.pass_start[k], nodes.pass_start[k + 1]
        s = arc_length(p.points)
        j = np.clip(np.searchsorted(nodes.s_end[a:b], s, side="left"), 0, b - a - 1)
        speeds.append(speed[a:b][j])
    return FeedProfile(tuple(speeds))



def _time_dwell(toolpath, nodes, dwell: np.ndarray, *, cons: list, v_min: float, v_max: float, heading_scale: float,
                rounds: int, ratio_tolerance: float):
    """The feed profile that makes :func:`swath.trajectory.time_path` spend ``dwell`` (s) in each node:
    the node feeds, corrected by the timed-to-planned dwell ratio for at most ``rounds`` rounds.
    Returns ``(profile, timed_ratio or None, last timed trajectory or None)``."""
    command = nodes.length / dwell
    profile = dwell_to_profile(toolpath, nodes, dwell)
    timed_ratio, traj = None, None
    for _ in range(max(0, int(rounds))):
        from ..trajectory import time_path

        traj = time_path(toolpath, cons + [profile], heading_scale=heading_scale)
        timed = trajectory_node_dwell(traj, nodes, toolpath)
        timed_ratio = np.where(dwell > 0, timed / dwell, 1.0)
        if np.abs(timed_ratio - 1).max() <= ratio_tolerance:
            break
        command = np.clip(command * timed_ratio, v_min, v_max)      # time_path applies the real caps itself
        profile = dwell_to_profile(toolpath, nodes, nodes.length / command)
        traj = None
    return profile, timed_ratio, traj


def _simulated_on_kernel(removal, samples) -> np.ndarray:
    """The largest simulated depth (m) at the simulator's samples nearest to each kernel sample,
    ``(S,)``: the removal's own values when both sample the part alike (the usual case)."""
    sim_points = np.asarray(removal.surface.vertices, float)
    depth = np.asarray(removal.depth, float)
    if depth.shape != (len(sim_points),):
        raise InputError(f"simulate must return one depth per sample ({len(sim_points)}), got shape {depth.shape}")
    if sim_points.shape == samples.vertices.shape and np.allclose(sim_points, samples.vertices, atol=1e-9):
        return depth
    _, nearest = samples.kdtree.query(sim_points)
    out = np.zeros(len(samples.vertices))
    np.maximum.at(out, nearest, depth)
    return out

def resolve_target(target, samples) -> np.ndarray:
    """Target depth ``(S,)`` (m) on the kernel's samples from a number (uniform depth, m), an
    ``(S,)`` array, or an object with ``depth_on(surface)`` (:class:`swath.feed.targets.TargetMap`)."""
    S = len(samples.vertices)
    if hasattr(target, "depth_on"):
        out = np.asarray(target.depth_on(samples), float)
    elif np.ndim(target) == 0:
        out = np.full(S, float(target))
    else:
        out = np.asarray(target, float)
    if out.shape != (S,) or not np.isfinite(out).all() or (out < 0).any():
        raise InputError(f"the target depth must be one finite depth >= 0 m per sample ({S}), got shape "
                         f"{out.shape}; give a depth in m, a per-sample array or a TargetMap")
    return out


def removal_stats(depth: np.ndarray, target: np.ndarray, areas: np.ndarray, mask: np.ndarray) -> dict:
    """Removal figures over ``mask``: CoV, mean, residual and the worst over/under-removal (m)."""
    if not mask.any():
        nan = float("nan")
        return {"removal_cov": nan, "removal_mean_m": nan, "target_mean_m": nan, "max_over_removal_m": nan,
                "max_under_removal_m": nan, "residual_rms_m": nan, "region_area_m2": 0.0}
    a, d, t = areas[mask], depth[mask], target[mask]
    mean = float(np.average(d, weights=a))
    std = float(np.sqrt(np.average((d - mean) ** 2, weights=a)))
    r = d - t
    return {"removal_cov": std / mean if mean > 0 else float("nan"), "removal_mean_m": mean,
            "target_mean_m": float(np.average(t, weights=a)), "max_over_removal_m": float(r.max()),
            "max_under_removal_m": float(-r.min()), "residual_rms_m": float(np.sqrt(np.average(r**2, weights=a))),
            "region_area_m2": float(a.sum())}


def optimise_feed(toolpath: ToolPath, tool, constraints, *, target, tolerance: float, mode: str = "match",
                  objective: str = "l1", v_min: float | None = None, boundary_margin: float | None = None,
                  kernel: RemovalKernel | None = None, node_spacing: float | None = None,
                  sample_spacing: float | None = None, heading_scale: float = 5e-3, time_limit: float = 600.0,
                  region: np.ndarray | None = None, smoothing: float = 2e-2, cap_margin: float = 0.5,
                  model_error: float = 0.10,
                  max_rows: int = 5000, timing_rounds: int = 5, ratio_tolerance: float = 0.01, trajectory=None,
                  simulate=None, simulate_rounds: int = 3, simulate_margin: float = 0.02,
                  progress=None) -> FeedResult:
    """Optimise the feed along every pass of ``toolpath`` so its removal matches ``target``.

    Parameters
    ----------
    toolpath : ToolPath
        Passes from any planner.
    tool : Tool
    constraints : sequence
        The trajectory constraints: a :class:`FeedLimit` (the largest feed, m/s) and optionally
        :class:`CentripetalLimit`, :class:`AngularSpeedLimit`, :class:`TangentialAccelLimit`.
    target : float, (S,) float or TargetMap
        Target depth, m: a uniform depth, one per kernel sample, or a
        :class:`swath.feed.targets.TargetMap`.
    tolerance : float
        Largest allowed removal above the target, m (a hard constraint at every optimised sample).
    mode : {"match", "max_removal"}
        Match the target (``objective`` ``"l1"`` or ``"minimax"``) or Wang's maximal removal without
        over-grinding.
    v_min : float, optional
        Slowest feed, m/s (default a tenth of the feed limit).
    boundary_margin : float, optional
        Samples closer than this (m) to the open boundary are not optimised (default the pad radius;
        the pad hangs over the edge there).
    kernel : RemovalKernel, optional
        A kernel already built for ``toolpath`` (else built here with ``node_spacing`` and
        ``sample_spacing``, m).
    heading_scale : float
        As in :func:`swath.trajectory.time_path`, m (for the angular-speed caps).
    region : (S,) bool, optional
        Kernel samples to match (instead of every touched sample ``boundary_margin`` in).
    cap_margin : float
        Fraction of ``tolerance`` held back for the difference between the kernel and the timed
        trajectory (the simulator's pose discretisation moves single samples by a few %): the
        programme caps the kernel removal at ``target + tolerance − holdback`` with ``holdback`` the
        larger of ``cap_margin·tolerance`` and ``model_error`` times the region's mean target.
    model_error : float
        Fraction of the target depth by which an independent removal simulation of the timed
        trajectory may differ from the kernel on single samples (pose discretisation on both
        sides).  Measured on the plate at the default steps against a 0.25 mm-pose reference: the
        kernel −5..+3 %, :func:`swath.simulate.simulate_removal` (poses one sample spacing apart)
        ±5.5 %; the simulator above the kernel by up to 8.7 % of the target on the benchmark plate.  When it exceeds the tolerance, the programme's cap falls below
        the target (the target is lowered by the difference): never over-grinding as the simulator
        measures it then costs a little depth.  Measured by ``bench_feed.py`` on an optimised
        (varying) feed: the kernel is within 0.01-0.26 µm of the trajectory integrated at every
        sample.  :func:`swath.simulate.simulate_removal` used to lump 6-17 mm of a fast stretch
        (a fixed count of samples), then 0.6 s of a slow one (a fixed travel), into one pose, and
        moved single samples by up to +27 % of the target; it now bounds both.  ``simulate=``
        corrects for what remains.
    trajectory : Trajectory, optional
        ``toolpath`` timed at any feed: the kernel then uses its contact poses (see
        :func:`build_kernel`); recommended on scans.
    timing_rounds : int
        Rounds of timing correction (default 3): the profile is timed with
        :func:`swath.trajectory.time_path` under ``constraints``, each node's commanded feed is scaled
        by its timed-to-planned dwell ratio (within the feed range) and the profile rebuilt, until
        every ratio is within ``ratio_tolerance`` of 1.  The timing's acceleration sweep rounds the
        speed steps between nodes and otherwise adds up to 10 % of dwell where the feed changes
        (measured: 1, 2, 3 rounds leave at most 11 %, 7 %, 5.5 %).  0 skips it (no timing inside;
        then the passes' start and end at rest are not known to the programme either).
    max_rows : int
        Largest number of sample rows in the programme's objective (more region samples are thinned
        to one per grid cell, area-weighted; see :func:`thin_rows`), and as many cap rows at the
        cells' peaks.  The HiGHS interior-point time grows faster than linearly with it; measured on
        the panel (47k region samples, 651 nodes): 20000 rows 12.2 s CPU, 8000 6.9 s, 4000 3.6 s,
        with the same CoV (0.136) and over-removal.
    smoothing : float
        Weight of the cost on pace changes between neighbouring nodes, relative to the objective
        (ties between dwell distributions with the same removal go to the smoother one).
    time_limit : float
        HiGHS time limit, s.
    simulate : callable, optional
        ``simulate(trajectory)`` → an object with ``surface.vertices`` ``(S', 3)`` (m) and ``depth``
        ``(S',)`` (m), e.g. ``lambda traj: swath.simulate.simulate_removal(traj, surface, tool)``
        (the feed stage may not import the simulator).  When given, the timed trajectory is
        simulated and, while a region sample is simulated over ``target + tolerance``, the
        programme's cap at the kernel samples under it is tightened by the measured ratio
        (kernel / simulated removal there, less ``simulate_margin`` of the target) and the
        programme solved and timed again, at most ``simulate_rounds`` times (logged; figures in
        ``metrics["simulated_rounds"]``).  Caps are only ever tightened, never below what the
        fastest feed removes; when no cap changes the loop stops with a warning (the target is
        below what the fastest feed the limits allow removes there).
    simulate_rounds : int
        Most simulate / re-solve rounds (default 3).
    simulate_margin : float
        Extra fraction of the target taken off a tightened cap (the simulator's pose grouping moves
        with the feed, so the measured ratio shifts a little from round to round).
    progress : callable, optional
        ``progress(stage, done, total)`` with ``stage`` in ``"kernel"``, ``"solve"``, ``"simulate"``.

    Returns
    -------
    FeedResult

    Raises
    ------
    InfeasibleError
        When even the largest allowed feed removes more than ``target + tolerance`` somewhere (the
        message names the sample, both depths and the least feasible target).
    """
    cons = split_constraints(constraints)
    v_max = cons[FeedLimit].speed
    v_min = 0.1 * v_max if v_min is None else float(v_min)
    if not (np.isfinite(v_min) and 0 < v_min <= v_max):
        raise InputError(f"v_min must lie in (0, feed limit {v_max:g}] m/s, got {v_min!r}")
    if not (np.isfinite(tolerance) and tolerance >= 0):
        raise InputError(f"tolerance must be a depth >= 0 m, got {tolerance!r}")
    margin = tool.pad_radius if boundary_margin is None else float(boundary_margin)
    t0 = time.perf_counter()
    if kernel is None:
        cb = None if progress is None else (lambda done, total: progress("kernel", done, total))
        kernel = build_kernel(toolpath, tool, node_spacing=node_spacing, sample_spacing=sample_spacing,
                              trajectory=trajectory, progress=cb)
    t_kernel = time.perf_counter() - t0
    nodes = kernel.nodes
    target_s = resolve_target(target, kernel.samples)
    caps = np.clip(node_speed_caps(toolpath, nodes, list(cons.values()), heading_scale=heading_scale), v_min, v_max)
    if timing_rounds > 0:
        # the timing's own floor: a pass starts and ends at rest, so its first and last nodes take
        # longer than Δs / cap at any command; the programme must know (else those nodes over-grind)
        from ..trajectory import time_path

        fastest_traj = time_path(toolpath, list(cons.values()), heading_scale=heading_scale)
        floor = trajectory_node_dwell(fastest_traj, nodes, toolpath)
        caps = np.clip(np.minimum(caps, nodes.length / np.maximum(floor, 1e-12)), v_min, v_max)
    t_min, t_max = nodes.length / caps, nodes.length / v_min
    tl = cons.get(TangentialAccelLimit)
    if tl is not None:
        # the fastest profile that meets the linearised acceleration rows (else a sharp cap next to
        # a free node leaves the programme infeasible)
        pace = np.minimum(accel_feasible_pace(1.0 / caps, nodes, tl.a_t, 1.0 / v_max), 1.0 / v_min)
        t_min = nodes.length * pace
        caps = 1.0 / pace
    touched = np.diff(kernel.matrix.tocsr().indptr) > 0
    if region is None:
        region = touched & interior_mask(kernel.samples, margin)
    else:
        region = np.asarray(region, bool)
        if region.shape != touched.shape:
            raise InputError(f"region must be one bool per kernel sample ({len(touched)}), got shape {region.shape}")
        region = region & touched
    if progress is not None:
        progress("solve", 0, 1)
    t1 = time.perf_counter()
    if not (0 <= cap_margin < 1):
        raise InputError(f"cap_margin must lie in [0, 1), got {cap_margin!r}")
    if not (0 <= model_error < 1):
        raise InputError(f"model_error must be a fraction of the target depth in [0, 1), got {model_error!r}")
    mean_target = float(np.average(target_s[region], weights=kernel.samples.vertex_areas[region])) if region.any() else 0.0
    lp_tolerance = tolerance - max(cap_margin * tolerance, model_error * mean_target)
    # the programme's cap: the held-back one, but never below what the fastest feed removes (where
    # that lies between, those nodes simply run at the fastest feed); a target above the cap is lowered
    fastest = kernel.removal(t_min)
    cap = np.maximum(target_s + lp_tolerance, np.minimum(fastest, target_s + tolerance))
    lp_target = np.minimum(target_s, cap)
    solve_kw = dict(t_min=t_min, t_max=t_max, region=region, mode=mode, objective=objective,
                    a_t=None if tl is None else tl.a_t, v_max=v_max, time_limit=time_limit, smoothing=smoothing,
                    max_rows=max_rows)
    dwell, status = solve_dwell(kernel, lp_target, tolerance=cap - lp_target, **solve_kw)
    t_solve = time.perf_counter() - t1
    if progress is not None:
        progress("solve", 1, 1)
    timing = dict(cons=list(cons.values()), v_min=v_min, v_max=v_max, heading_scale=heading_scale,
                  rounds=timing_rounds, ratio_tolerance=ratio_tolerance)
    profile, timed_ratio, traj = _time_dwell(toolpath, nodes, dwell, **timing)
    sim_rounds = []
    t_simulate = 0.0
    if simulate is not None:
        limit = target_s + tolerance
        excess = 0.0
        for rnd in range(max(0, int(simulate_rounds)) + 1):
            if traj is None:
                from ..trajectory import time_path

                traj = time_path(toolpath, timing["cons"] + [profile], heading_scale=heading_scale)
            if progress is not None:
                progress("simulate", rnd, simulate_rounds + 1)
            t3 = time.perf_counter()
            worst = _simulated_on_kernel(simulate(traj), kernel.samples)
            t_simulate += time.perf_counter() - t3
            over = worst - limit
            timed_pred = kernel.removal(trajectory_node_dwell(traj, nodes, toolpath))
            bad = np.flatnonzero(region & (over > 0))
            sim_rounds.append({"max_over_target_m": float(np.max(worst[region] - target_s[region], initial=0.0)),
                               "samples_over": int(len(bad))})
            log.info("feed optimisation, simulated round %d: largest simulated removal over the target %.3g um "
                     "(tolerance %.3g um), %d samples over", rnd, sim_rounds[-1]["max_over_target_m"] / _DEPTH_UNIT,
                     tolerance / _DEPTH_UNIT, len(bad))
            if len(bad) == 0:
                break
            if rnd == simulate_rounds:
                log.warning("feed optimisation: after %d simulated rounds %d samples are still simulated over the "
                            "target + tolerance by up to %.3g um (%d of them at the fastest feed already); raise "
                            "simulate_rounds, the tolerance or the target", simulate_rounds, len(bad),
                            float(over[bad].max()) / _DEPTH_UNIT, int(np.sum(fastest[bad] >= cap[bad] * (1 - 1e-9))))
                break
            # The simulator removes worst / timed_pred of what the kernel predicts.  Where it measured
            # over the limit, cap the kernel at limit · (kernel / simulated) less a margin; everywhere,
            # hold back the largest excess ratio seen where the kernel removes at least half the
            # target (the simulator's pose grouping moves with the feed, so the excess moves too).
            # Never below the fastest feed's removal.
            ratio = worst / np.maximum(timed_pred, 1e-300)
            counted = region & (timed_pred >= 0.5 * target_s)
            excess = max(float(np.max(ratio[counted], initial=1.0)) - 1.0, excess)
            tightened = limit / (1.0 + excess) - simulate_margin * target_s
            tightened[bad] = np.minimum(tightened[bad], limit[bad] / ratio[bad] - simulate_margin * target_s[bad])
            new_cap = np.maximum(np.minimum(cap, tightened), np.minimum(fastest, cap))
            sim_rounds[-1]["held_back_ratio"] = excess
            if np.array_equal(new_cap, cap):
                # nothing left to tighten (the samples over are at the fastest feed already): another
                # round would solve, time and simulate the same programme again
                log.warning("feed optimisation: %d samples are simulated over the target + tolerance by up to "
                            "%.3g um and their caps cannot be tightened (the fastest feed the limits allow "
                            "removes that much); raise the target or the tolerance, or the feed limit", len(bad),
                            float(over[bad].max()) / _DEPTH_UNIT)
                break
            cap = new_cap
            lp_target = np.minimum(target_s, cap)
            t2 = time.perf_counter()
            dwell, status = solve_dwell(kernel, lp_target, tolerance=cap - lp_target, **solve_kw)
            t_solve += time.perf_counter() - t2
            profile, timed_ratio, traj = _time_dwell(toolpath, nodes, dwell, **timing)
    speed = nodes.length / dwell
    predicted = kernel.removal(dwell)
    metrics = {"status": status, "mode": mode, "objective": objective, "kernel_time_s": t_kernel,
               "solve_time_s": t_solve, "n_nodes": len(nodes), "n_region_samples": int(region.sum()),
               "kernel_nonzeros": int(kernel.matrix.nnz), "tolerance_m": float(tolerance),
               "programme_cap_over_target_m": float(lp_tolerance),
               "v_min_m_per_s": v_min, "v_max_m_per_s": v_max, "contact_time_s": float(dwell.sum()),
               "fastest_contact_time_s": float(t_min.sum()), "speed_mean_m_per_s": float(np.mean(speed)),
               "speed_min_m_per_s": float(speed.min()), "speed_max_m_per_s": float(speed.max())}
    metrics.update(removal_stats(predicted, target_s, kernel.samples.vertex_areas, region))
    log.info("feed optimisation (%s/%s): %d nodes, %d samples, CoV %.3f, solve %.1f s", mode, objective, len(nodes),
             region.sum(), metrics["removal_cov"], t_solve)
    if sim_rounds:
        metrics["simulated_rounds"] = sim_rounds
        metrics["simulated_max_over_target_m"] = sim_rounds[-1]["max_over_target_m"]
        metrics["simulate_time_s"] = t_simulate
    if timed_ratio is not None:
        metrics["timed_dwell_ratio_p5_p50_p95"] = [float(x) for x in np.percentile(timed_ratio, [5, 50, 95])]
    return FeedResult(profile, dwell, speed, kernel, target_s, predicted, region, metrics)
