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


#: FORMATS.md: in-contact samples at most this far apart in time, also after re-timing, s.
MAX_CONTACT_DT = 0.020


def _slerp(qa, qb, w) -> np.ndarray:
    """(m, 4) unit quaternions between ``qa`` and ``qb`` (m, 4) at fractions ``w`` (m,)."""
    dot = np.sum(qa * qb, axis=1)
    qb = np.where(dot[:, None] < 0, -qb, qb)
    dot = np.abs(dot)
    ang = np.arccos(np.clip(dot, -1.0, 1.0))
    s = np.sin(ang)
    small = s < 1e-9
    wa = np.where(small, 1 - w, np.sin((1 - w) * ang) / np.where(small, 1, s))
    wb = np.where(small, w, np.sin(w * ang) / np.where(small, 1, s))
    out = wa[:, None] * qa + wb[:, None] * qb
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def resample_contact(trajectory, solution, model, cell, *, max_dt: float = 0.8 * MAX_CONTACT_DT,
                     max_joint_step: float = 0.045):
    """Insert samples into contact steps longer than ``max_dt`` or turning a joint by more than ``max_joint_step``.

    After re-timing, a contact step can last longer than FORMATS.md's 20 ms (the robot slows down
    where a joint limit binds), and near a singularity one step can turn a joint far.  Such a step
    gets evenly spaced new samples: time, position and feed linear, orientation by slerp, and
    joint values from the model's inverse kinematics on the step's branch (the 2π-equivalent nearest
    the joint-space interpolation; that interpolation itself, with its forward-kinematics pose,
    where the inverse kinematics has no solution).

    Parameters
    ----------
    trajectory : Trajectory
        Re-timed.
    solution : JointSolution
        On ``trajectory``'s samples.
    model : RobotModel
    cell : Cell
    max_dt : float
        Longest contact step after resampling, s (default 16 ms, 20 % under the format's 20 ms so a
        later re-timing pass that stretches a step slightly stays within it).
    max_joint_step : float
        Largest joint change between contact samples, rad.

    Returns
    -------
    (Trajectory, JointSolution)
    """
    from .joint_moves import insert_samples
    from .pose import make_transform, matrix_to_quat, quat_to_matrix

    tr, sol = trajectory, solution
    n = len(tr)
    if n < 2:
        return tr, sol
    in_pass = (tr.contact[1:] & tr.contact[:-1] & (tr.pass_index[1:] == tr.pass_index[:-1]) & (tr.pass_index[1:] >= 0)
               & sol.reachable[1:] & sol.reachable[:-1])
    dt = np.diff(tr.t)
    dq = np.max(np.abs(np.diff(sol.q, axis=0)), axis=1)
    dq = np.where(np.isfinite(dq), dq, 0.0)
    k = np.maximum(np.ceil(dt / max_dt - 1e-9), np.ceil(dq / max_joint_step - 1e-9)).astype(int)
    k = np.where(in_pass, np.maximum(k, 1), 1)
    steps = np.flatnonzero(k > 1)
    if not len(steps):
        return tr, sol
    at = np.repeat(steps + 1, k[steps] - 1)
    w = np.concatenate([np.arange(1, kk) / kk for kk in k[steps]])
    i0 = at - 1
    t = tr.t[i0] * (1 - w) + tr.t[at] * w
    pos = tr.position[i0] * (1 - w)[:, None] + tr.position[at] * w[:, None]
    quat = _slerp(tr.quaternion[i0], tr.quaternion[at], w)
    q_lin = sol.q[i0] * (1 - w)[:, None] + sol.q[at] * w[:, None]
    branch = sol.branch[at]
    poses = make_transform(quat_to_matrix(quat), pos)
    flange = cell.flange2base(poses)
    q = q_lin.copy()
    if model.kind == "numeric":
        raw = np.concatenate([model.ik(f[None], seed=s)[:, 0] for f, s in zip(flange, q_lin)])
    else:
        raw = model.ik(flange)[np.arange(len(at)), np.clip(branch, 0, None)]
    two_pi = 2 * np.pi
    cand = raw + two_pi * np.round((q_lin - raw) / two_pi)
    good = np.all(np.isfinite(cand), axis=1) & (np.max(np.abs(cand - q_lin), axis=1) < 0.25)
    q[good] = cand[good]
    # where no solution: the joint interpolation, its pose by forward kinematics
    if (~good).any():
        back = cell.tcp2part(model.fk(q_lin[~good]))
        pos[~good] = back[:, :3, 3]
        quat[~good] = matrix_to_quat(back[:, :3, :3])
    m = len(at)
    return insert_samples(tr, sol, model, at, t=t, position=pos, quaternion=quat, contact=np.ones(m, bool),
                          pass_index=tr.pass_index[at], q=q, joint_move=np.zeros(m, bool), branch=branch, fraction=w)
