"""Per-node speed caps for feed optimisation, computed as :func:`swath.trajectory.time_path` does.

The feed through a dwell node may not exceed the :class:`FeedLimit`, the centripetal cap
``sqrt(a_max / κ)`` or the angular cap ``ω_max / ρ`` anywhere along the node's stretch of pass.
"""

from __future__ import annotations

import numpy as np

from ..core import ToolPath
from ..errors import InputError
from ..trajectory.constraints import AngularSpeedLimit, CentripetalLimit, FeedLimit, FeedProfile, TangentialAccelLimit
from ..trajectory.geometry import path_curvature, resample_uniform, rotation_steps, smoothed_directions
from ..trajectory.orientation import tool_frames

#: Grid step (m) at which the speed caps are evaluated along the passes (the timing grid's).
_CAP_STEP = 1e-3


# ----------------------------------------------------------------------------------------------
def split_constraints(constraints) -> dict:
    """The trajectory constraint objects by type (one each at most; a :class:`FeedLimit` required)."""
    if isinstance(constraints, (FeedLimit, CentripetalLimit, AngularSpeedLimit, TangentialAccelLimit)):
        constraints = [constraints]
    out = {}
    for c in constraints:
        if isinstance(c, FeedProfile):
            continue                                   # an earlier plan's profile: replaced here
        if not isinstance(c, (FeedLimit, CentripetalLimit, AngularSpeedLimit, TangentialAccelLimit)):
            raise InputError(f"feed optimisation does not know the constraint {c!r}; give FeedLimit, "
                             "CentripetalLimit, AngularSpeedLimit and TangentialAccelLimit objects")
        if type(c) in out:
            raise InputError(f"two {type(c).__name__} constraints given; give each kind at most once")
        out[type(c)] = c
    if FeedLimit not in out:
        raise InputError("feed optimisation needs a FeedLimit: the largest feed (m/s) along the passes")
    return out


def node_speed_caps(toolpath: ToolPath, nodes, constraints, *, heading_scale: float = 5e-3) -> np.ndarray:
    """Largest feed (m/s) in every node ``(n,)``: the smallest cap on the node's stretch of pass.

    The caps are those of :func:`swath.trajectory.time_path`: the :class:`FeedLimit`, the
    centripetal ``sqrt(a_max / κ)`` with κ read at the limit's scale (:func:`path_curvature`), and
    the angular ``ω_max / ρ`` with ρ the tool frame's turn per metre (:func:`tool_frames` on the
    smoothed travel directions), on a 1 mm grid along each pass.
    """
    cons = split_constraints(constraints)
    caps = np.full(len(nodes), cons[FeedLimit].speed)
    cl, al = cons.get(CentripetalLimit), cons.get(AngularSpeedLimit)
    if cl is None and al is None:
        return caps
    for k, p in enumerate(toolpath.passes):
        s, pts, nrm = resample_uniform(p.points, _CAP_STEP, p.normals)
        if len(s) < 3:
            continue
        h = float(s[1] - s[0])
        grid_cap = np.full(len(s), np.inf)
        if cl is not None:
            kappa = path_curvature(pts, h, cl.scale)
            grid_cap = np.minimum(grid_cap, np.sqrt(cl.a_max / np.maximum(kappa, 1e-12)))
        if al is not None:
            nrm = nrm / np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-300)
            frames = tool_frames(nrm, smoothed_directions(pts, h, heading_scale))
            ds = np.maximum(np.linalg.norm(np.diff(pts, axis=0), axis=1), 1e-12)
            rho = np.linalg.norm(rotation_steps(frames), axis=1) / ds
            rho_node = np.maximum(np.concatenate([[0.0], rho]), np.concatenate([rho, [0.0]]))
            grid_cap = np.minimum(grid_cap, al.omega_max / np.maximum(rho_node, 1e-12))
        a, b = nodes.pass_start[k], nodes.pass_start[k + 1]
        # smallest grid cap within each node's interval (grid points inside or at its ends)
        lo = np.searchsorted(s, nodes.s_start[a:b], side="left")
        hi = np.searchsorted(s, nodes.s_end[a:b], side="right")
        hi = np.maximum(hi, lo + 1)
        cm = np.array([grid_cap[i:j].min() for i, j in zip(lo, np.minimum(hi, len(s)))])
        caps[a:b] = np.minimum(caps[a:b], cm)
    return caps


def accel_feasible_pace(p_min: np.ndarray, nodes, a_t: float, p_ref) -> np.ndarray:
    """The smallest pace ``(n,)`` (s/m) at or above ``p_min`` that meets the linearised acceleration
    rows of the feed programme between neighbouring nodes of a pass,
    ``|p_j − p_i| <= c (3 p_k − 2 p0)`` for ``k`` in ``{i, j}``, ``c = a_t Δc p0²``, ``p0`` the
    row's reference pace (:func:`row_reference_pace` of ``p_ref``: a scalar, or one per node).

    A forward and a backward sweep raise the pace ahead of (and behind) every node where a cap
    forces a slow-down, as :func:`swath.trajectory.timing.speed_profile` does for ``v²``; without it
    a sharp cap next to a free node makes the programme infeasible.
    """
    p = np.asarray(p_min, float).copy()
    same = nodes.pass_index[1:] == nodes.pass_index[:-1]
    p0 = row_reference_pace(p_ref, len(p))
    c = a_t * np.diff(nodes.s_mid) * p0**2

    def need(prev, ci, ri):
        # lower bound on the neighbour's pace from both forms of the row
        return max((prev + 2 * ci * ri) / (1 + 3 * ci), prev * (1 - 3 * ci) + 2 * ci * ri)

    for i in range(len(p) - 1):                       # forward: slow down after a slow node
        if same[i]:
            p[i + 1] = max(p[i + 1], need(p[i], c[i], p0[i]))
    for i in range(len(p) - 2, -1, -1):               # backward: slow down before a slow node
        if same[i]:
            p[i] = max(p[i], need(p[i + 1], c[i], p0[i]))
    return p


def row_reference_pace(p_ref, n: int) -> np.ndarray:
    """The pace ``(n - 1,)`` (s/m) each acceleration row between nodes ``i`` and ``i + 1`` is
    linearised at: ``p_ref`` where it is one number, else the smaller (faster) of the two nodes'
    ``p_ref[i]`` and ``p_ref[i + 1]`` (one per node, ``(n,)``).

    ``p³`` lies above every tangent of it, so a row never allows more than the limit, whatever its
    reference; it is exact at the reference and comes closer to the limit the nearer the reference
    lies to the paces the programme runs at.  The programme never runs a node faster than its
    fastest pace, so the fastest feasible profile is the best reference it can use: at ``1 / v_max`` for all rows, a slow acceleration limit under a
    high feed limit (``--feed 400mm/s --max-accel 0.05m/s2`` on the plate) held every node at 47 mm/s
    or less where the timing reaches 140 mm/s, and the programme then removed a third more than the
    target."""
    ref = np.asarray(p_ref, float)
    if ref.ndim == 0:
        return np.full(max(n - 1, 0), float(ref))
    if ref.shape != (n,):
        raise InputError(f"p_ref must be one pace or one per node ({n}), got shape {ref.shape}")
    return np.minimum(ref[:-1], ref[1:])
