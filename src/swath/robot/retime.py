"""Re-time a trajectory so its joint motion keeps the robot's joint speed and acceleration limits.

Where a joint would move faster than its limit between two samples, the time step is stretched
(never shortened) to ``max_j |Δq_j| / (safety · v_max_j)``; then, where the finite-difference
acceleration exceeds its limit, both adjacent steps are stretched by ``sqrt(ratio)`` until none does
(or ``max_iterations`` is reached; the remaining ratio is reported).  Speeds only fall while
steps stretch, so the speed limits stay kept.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np


@dataclass(frozen=True, eq=False)
class Retiming:
    """Result of :func:`retime_joints`.

    Attributes
    ----------
    t : (n,) float
        New sample times, s.
    max_speed_ratio : float
        Largest ``|Δq/Δt| / v_max`` over all joints and steps after re-timing.
    max_accel_ratio : float
        Largest finite-difference ``|Δv/Δt| / a_max`` after re-timing.
    stretched_steps : int
        Steps made longer.
    added_time : float
        Duration added, s.
    """

    t: np.ndarray
    max_speed_ratio: float
    max_accel_ratio: float
    stretched_steps: int
    added_time: float


def joint_speed_ratio(t, q, max_speed) -> np.ndarray:
    """(n−1,) largest ``|Δq_j / Δt| / v_max_j`` per step (finite differences; 0 for a zero step)."""
    dt = np.diff(t)
    dq = np.abs(np.diff(q, axis=0))
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.max(dq / np.asarray(max_speed), axis=1) / dt
    return np.where(np.max(dq, axis=1) == 0, 0.0, np.where(dt > 0, ratio, np.inf))


def joint_accel_ratio(t, q, max_accel) -> np.ndarray:
    """(n−2,) largest finite-difference ``|Δv_j / Δt| / a_max_j`` at interior samples."""
    dt = np.diff(t)
    with np.errstate(divide="ignore", invalid="ignore"):
        v = np.where(dt[:, None] > 0, np.diff(q, axis=0) / dt[:, None], 0.0)
        a = np.diff(v, axis=0) / (0.5 * (dt[1:] + dt[:-1]))[:, None]
    a = np.where(np.isfinite(a), a, 0.0)
    return np.max(np.abs(a) / np.asarray(max_accel), axis=1)


def retime_joints(t, q, max_speed, max_accel, *, safety: float = 0.999, max_iterations: int = 200) -> Retiming:
    """Stretch time steps so the joint motion keeps speed and acceleration limits.

    Parameters
    ----------
    t : (n,) float
        Sample times, s.
    q : (n, 6) float
        Joint values, rad (finite).
    max_speed : (6,) float
        Joint speed limits, rad/s.
    max_accel : (6,) float
        Joint acceleration limits, rad/s².
    safety : float
        Fraction of each limit aimed at (default 0.999).
    max_iterations : int
        Passes of the acceleration loop.

    Returns
    -------
    Retiming
    """
    t = np.asarray(t, dtype=float)
    q = np.asarray(q, dtype=float)
    vmax = np.asarray(max_speed, dtype=float) * safety
    amax = np.asarray(max_accel, dtype=float) * safety
    dt_old = np.diff(t)
    dq = np.abs(np.diff(q, axis=0))
    dt = np.maximum(dt_old, np.max(dq / vmax, axis=1))
    for _ in range(max_iterations):
        tt = np.concatenate([[0.0], np.cumsum(dt)])
        ratio = joint_accel_ratio(tt, q, amax)
        over = ratio > 1.0
        if not over.any():
            break
        factor = np.ones(len(dt))
        f = np.sqrt(ratio[over]) * 1.0005
        idx = np.flatnonzero(over)
        np.maximum.at(factor, idx, f)
        np.maximum.at(factor, idx + 1, f)
        dt = dt * factor
    t_new = t[0] + np.concatenate([[0.0], np.cumsum(dt)])
    return Retiming(
        t=t_new,
        max_speed_ratio=float(np.max(joint_speed_ratio(t_new, q, max_speed), initial=0.0)),
        max_accel_ratio=float(np.max(joint_accel_ratio(t_new, q, max_accel), initial=0.0)),
        stretched_steps=int(np.sum(dt > dt_old * (1 + 1e-12))),
        added_time=float((t_new[-1] - t_new[0]) - (t[-1] - t[0])) if len(t) else 0.0,
    )


def retime_trajectory(trajectory, solution, model) -> tuple:
    """Re-time ``trajectory`` to the joint limits of ``model`` along ``solution``.

    Unreachable samples keep their place: the time between two reachable samples is spread over
    the unreachable ones between them in the original proportions.

    Returns
    -------
    (Trajectory, Retiming)
        The re-timed trajectory (``feed`` and ``wx, wy, wz`` scaled by the local slow-down; its
        metadata gains ``robot_retimed``) and the re-timing figures on the reachable samples.
    """
    idx = np.flatnonzero(solution.reachable)
    t_old = trajectory.t
    if len(idx) < 2:
        return trajectory, Retiming(t=t_old.copy(), max_speed_ratio=0.0, max_accel_ratio=0.0, stretched_steps=0,
                                    added_time=0.0)
    rt = retime_joints(t_old[idx], solution.q[idx], model.max_speed, model.max_accel)
    # piecewise-linear map from old to new time through the reachable samples; extrapolate at the ends
    t_new = np.interp(t_old, t_old[idx], rt.t)
    t_new[: idx[0]] = t_old[: idx[0]] - t_old[idx[0]] + rt.t[0]
    t_new[idx[-1] + 1:] = t_old[idx[-1] + 1:] - t_old[idx[-1]] + rt.t[-1]
    dt_old = np.diff(t_old)
    dt_new = np.diff(t_new)
    with np.errstate(divide="ignore", invalid="ignore"):
        step_scale = np.where(dt_new > 0, dt_old / dt_new, 1.0)
    scale = np.ones(len(t_old))
    if len(step_scale):
        scale[1:] = step_scale
        scale[:-1] = np.minimum(scale[:-1], step_scale)
    extra = {k: (v * scale if k in ("wx", "wy", "wz") else v) for k, v in trajectory.extra.items()}
    meta = dict(trajectory.metadata)
    meta["robot_retimed"] = {"stretched_steps": rt.stretched_steps, "added_time_s": rt.added_time}
    new = replace(trajectory, t=t_new, feed=trajectory.feed * scale, extra=extra, metadata=meta)
    return new, rt
