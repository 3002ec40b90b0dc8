"""Joint moves put on the trajectory: samples inserted with their joints, and a branch change or a
large air turn swept in joint space at steps the collision check can follow.

:func:`insert_samples` adds samples to a trajectory and its :class:`~swath.robot.solve.JointSolution`
together; :func:`insert_joint_moves` interpolates every joint move of a solution on the trajectory,
timed rest to rest (:func:`_trapezoid_fraction`), the poses being forward kinematics of the joints.
"""

from __future__ import annotations

import math

import numpy as np

from ..cell import Cell
from .models import RobotModel
from .solve import JointSolution


def insert_samples(trajectory, solution: JointSolution, model: RobotModel, at, *, t, position, quaternion, contact,
                   pass_index, q, joint_move, branch, fraction, via=None):
    """Trajectory and joint solution with new samples inserted.

    Parameters
    ----------
    trajectory : Trajectory
    solution : JointSolution
        On ``trajectory``'s samples.
    model : RobotModel
        For the measures of the new rows.
    at : (m,) int
        Each new sample goes before original sample ``at[k]`` (sorted, ties keep their order).
    t, position, quaternion, contact, pass_index, q, joint_move, branch : arrays of m rows
        The new samples' fields (s, m, unit quaternion, bool, int, rad, bool, int).
    fraction : (m,) float
        Where between samples ``at − 1`` and ``at`` each new sample lies (0..1); feed and the extra
        columns are interpolated linearly with it.
    via : (m,) bool, optional
        The new samples that are via-points (:attr:`JointSolution.via`; default none).

    Returns
    -------
    (Trajectory, JointSolution)
        Switch samples and unreachable stretches renumbered; measures computed for the new rows.
    """
    from dataclasses import replace

    at = np.asarray(at, dtype=int)
    if not len(at):
        return trajectory, solution
    w = np.asarray(fraction, dtype=float)

    def lerp(col):
        col = np.asarray(col, dtype=float)
        return col[at - 1] * (1 - w) + col[at] * w

    feed = lerp(trajectory.feed)
    extra = {k: np.insert(np.asarray(v, dtype=float), at, lerp(v)) for k, v in trajectory.extra.items()}
    new_tr = replace(trajectory, t=np.insert(trajectory.t, at, t), position=np.insert(trajectory.position, at, position, axis=0),
                     quaternion=np.insert(trajectory.quaternion, at, quaternion, axis=0),
                     contact=np.insert(trajectory.contact, at, contact), feed=np.insert(trajectory.feed, at, feed),
                     pass_index=np.insert(trajectory.pass_index, at, pass_index), extra=extra)
    # old index i moves to i + (number of insertions before or at it)
    shift = np.searchsorted(np.sort(at), np.arange(len(trajectory) + 1), side="right")
    new_index = np.arange(len(trajectory) + 1) + shift
    qn = np.asarray(q, dtype=float)
    measures = {}
    ok_new = np.isfinite(qn[:, 0])
    m_new = {k: np.full(len(at), np.nan) for k in solution.measures}
    if ok_new.any() and solution.measures:
        sm = model.singularity_measures(qn[ok_new])
        for k, v in sm.items():
            if k in m_new:
                m_new[k][ok_new] = v
        if "joint_limit_margin_rad" in m_new:
            m_new["joint_limit_margin_rad"][ok_new] = model.joint_limit_margin(qn[ok_new])
    for k, v in solution.measures.items():
        measures[k] = np.insert(v, at, m_new[k])
    # a switch's sample stays the original target sample (rows inserted before it carry its branch)
    switches = [dict(sw, sample=int(new_index[sw["sample"]])) for sw in solution.switches]
    stretches = [replace(st, start=int(new_index[st.start]), stop=int(new_index[st.stop - 1]) + 1)
                 for st in solution.stretches]
    clearance = None
    if solution.clearance is not None:
        clearance = np.insert(solution.clearance, at, lerp(solution.clearance))
    new_sol = replace(solution, q=np.insert(solution.q, at, qn, axis=0),
                      branch=np.insert(solution.branch, at, branch),
                      reachable=np.insert(solution.reachable, at, ok_new),
                      joint_move=np.insert(solution.joint_moves, at, joint_move), switches=switches,
                      via=(None if via is None and solution.via is None else
                           np.insert(solution.vias, at, np.zeros(len(at), bool) if via is None else via)),
                      stretches=stretches, measures=measures, clearance=clearance)
    return new_tr, new_sol


def _trapezoid_fraction(duration: float, tau) -> np.ndarray:
    """Path fraction s(τ) in [0, 1] of a symmetric trapezoidal profile (ramps a quarter of the time each)."""
    tau = np.asarray(tau, dtype=float) / duration
    r = 0.25
    peak = 1.0 / (1.0 - r)                    # speed (per unit time) at cruise
    up = 0.5 * peak / r * tau ** 2
    mid = 0.5 * peak * r + peak * (tau - r)
    down = 1.0 - 0.5 * peak / r * (1.0 - tau) ** 2
    return np.where(tau < r, up, np.where(tau <= 1 - r, mid, down))


def insert_joint_moves(trajectory, solution: JointSolution, model: RobotModel, cell: Cell, *,
                       max_joint_step: float = math.radians(2.0), limit_fraction: float = 0.9):
    """Interpolate every joint move in joint space so no joint turns more than ``max_joint_step``
    between samples, timed as a rest-to-rest move.

    The new samples lie on the straight line in joint space between the move's two ends (what a
    controller's joint move does); their TCP poses are the forward kinematics of those joint values,
    out of contact, on no pass, flagged as joint moves.  The move lasts the trapezoidal profile's
    duration at ``limit_fraction`` of the joint speed and acceleration limits (ramps of a quarter of
    the time, so the ramps need 4/3 of the cruise speed over a quarter: the duration is stretched
    until both fit); later samples move later by the time added.

    Returns
    -------
    (Trajectory, JointSolution)
    """
    from dataclasses import replace

    from .pose import matrix_to_quat

    jm = solution.joint_moves
    idx = np.flatnonzero(jm)
    if not len(idx):
        return trajectory, solution
    q = solution.q
    vmax = model.max_speed * limit_fraction
    amax = model.max_accel * limit_fraction
    at: list[int] = []
    w: list[float] = []
    br: list[int] = []
    tau: list[float] = []
    added = np.zeros(len(trajectory))
    for i in idx:
        dq = q[i] - q[i - 1]
        k = max(int(math.ceil(float(np.max(np.abs(dq))) / max_joint_step)), 1)
        # profile with ramps of T/4 at peak speed 4/3·d/T: T = max over joints of the larger of
        # 4/3·d/v and sqrt(16/3·d/a) (ramp acceleration 16/3·d/T²)
        d = np.abs(dq)
        dur = float(max(np.max(4.0 / 3.0 * d / vmax), np.max(np.sqrt(16.0 / 3.0 * d / amax)),
                        trajectory.t[i] - trajectory.t[i - 1]))
        added[i] = dur - (trajectory.t[i] - trajectory.t[i - 1])
        for j in range(1, k):
            at.append(int(i))
            w.append(j / k)
            br.append(int(solution.branch[i]))
            tau.append(dur)
    t_shift = trajectory.t + np.cumsum(added)
    shifted = replace(trajectory, t=t_shift)
    if not at:
        return shifted, solution
    at_arr = np.array(at)
    w_arr = np.array(w)
    dur_arr = np.array(tau)
    # time of each new row: the profile's time at which the joint fraction w is reached
    grid = np.linspace(0.0, 1.0, 2001)
    t_new = np.empty(len(at_arr))
    for m, (i, wj, dur) in enumerate(zip(at_arr, w_arr, dur_arr)):
        t_new[m] = t_shift[i - 1] + np.interp(wj, _trapezoid_fraction(1.0, grid), grid) * dur
    qs_arr = q[at_arr - 1] + (q[at_arr] - q[at_arr - 1]) * w_arr[:, None]
    tcp2part = cell.tcp2part(model.fk(qs_arr))
    n_new = len(at_arr)
    return insert_samples(shifted, solution, model, at_arr, t=t_new, position=tcp2part[:, :3, 3],
                          quaternion=matrix_to_quat(tcp2part[:, :3, :3]), contact=np.zeros(n_new, bool),
                          pass_index=np.full(n_new, -1), q=qs_arr, joint_move=np.ones(n_new, bool),
                          branch=np.array(br), fraction=w_arr)
