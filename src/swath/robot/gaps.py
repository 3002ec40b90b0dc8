"""Unreachable stretches become air: the pass is split there with a retract and an approach.

A pose no configuration reaches cannot be sanded; driving straight across it (what a program does
when it skips the sample) would press the pad along a line the plan never made, and counting it as
sanded overstates the coverage.  :func:`split_unreachable` rebuilds the trajectory the robot actually
runs: the unreachable samples are dropped, the pad lifts ``clearance`` along minus the tool z-axis at
the last reached sample (retract; level or straight up instead where that would take the arm or the
tool below the table top), the arm makes a joint move to above the next reached sample, and
lowers onto it (approach).  The joint move is one step flagged :attr:`JointSolution.joint_move`: the
programs write it as a joint move, :func:`swath.robot.joint_moves.insert_joint_moves` puts its swept
joints on the trajectory (at most 2° apart), and :func:`swath.robot.sweep.clear_joint_moves` checks
the sweep and lifts it higher, with via-points, where it would hit the part or the cell.  The
simulation and the metrics then run on this trajectory.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from .pose import matrix_to_quat, poses_from_trajectory


@dataclass(frozen=True, eq=False)
class Gap:
    """One stretch the robot skips in air.

    Attributes
    ----------
    pass_index : int
        Contact pass it interrupts (-1 on an air link).
    start, stop : int
        Dropped samples ``[start, stop)`` of the original trajectory.
    position : (3,) tuple of float
        First dropped TCP position, part frame, m.
    end_position : (3,) tuple of float
        Last dropped TCP position, part frame, m.
    contact_length : float
        Contact path length dropped, m.
    path : (k, 3) float
        The dropped TCP positions, part frame, m (for the report's 3D view).
    """

    pass_index: int
    start: int
    stop: int
    position: tuple
    end_position: tuple
    contact_length: float
    path: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def as_record(self) -> dict:
        return {"pass": self.pass_index, "start_sample": self.start, "stop_sample": self.stop,
                "start_m": list(self.position), "end_m": list(self.end_position),
                "contact_length_m": self.contact_length}


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``[start, stop)`` runs of True."""
    d = np.diff(np.r_[0, mask.astype(int), 0])
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def find_gaps(trajectory, reachable) -> list[Gap]:
    """The unreachable runs of ``trajectory`` (``reachable`` (n,) bool) as :class:`Gap` records."""
    out = []
    seg = np.linalg.norm(np.diff(trajectory.position, axis=0), axis=1)
    for s, e in _runs(~np.asarray(reachable, bool)):
        inside = np.flatnonzero(trajectory.contact[s:e])
        passes = trajectory.pass_index[s:e][trajectory.contact[s:e]]
        i = np.arange(max(s, 1), e)
        lengths = seg[i - 1][trajectory.contact[i] & trajectory.contact[i - 1]]
        out.append(Gap(pass_index=int(passes[0]) if len(inside) else -1, start=int(s), stop=int(e),
                       position=tuple(float(v) for v in trajectory.position[s]),
                       end_position=tuple(float(v) for v in trajectory.position[e - 1]),
                       contact_length=float(lengths.sum()), path=trajectory.position[s:e].copy()))
    return out


def _nearest_ik(model, cell, tcp2part, q_ref, *, max_change: float = 0.5) -> np.ndarray | None:
    """Joint values of one TCP pose nearest ``q_ref`` (any branch, 2π-equivalents, inside the limits,
    no joint more than ``max_change`` rad away), rad; None when there is none."""
    raw = model.ik(cell.flange2base(tcp2part[None]), seed=q_ref)[0]
    raw = raw[np.all(np.isfinite(raw), axis=1)]
    if not len(raw):
        return None
    cand = raw + 2 * math.pi * np.round((q_ref - raw) / (2 * math.pi))
    inside = np.all((cand >= model.lower) & (cand <= model.upper), axis=1)
    if not inside.any():
        return None
    cand = cand[inside]
    best = cand[int(np.argmin(np.max(np.abs(cand - q_ref), axis=1)))]
    return best if np.max(np.abs(best - q_ref)) <= max_change else None


def lift_directions(cell, pose) -> list:
    """Unit directions (part frame) a lift of ``pose`` may take, in order: back along the tool axis,
    and, where that goes down in the base frame, the same with its downward part removed (still away
    from the surface's tangent plane), then straight up.

    At a pass along the part's lower edge the surface normal can point below the horizon; a lift
    along the tool axis then lowers the tool and the wrist, which hang just above the table there."""
    up = cell.base2part[:3, :3] @ np.array([0.0, 0.0, 1.0])
    back = -np.asarray(pose[:3, 2], dtype=float)
    out = [back]
    down = float(back @ up)
    if down < 0.0:
        level = back - down * up
        size = float(np.linalg.norm(level))
        if size > 0.1:
            out.append(level / size)
        out.append(up)
    return out


def _clear_of_floor(model, cell, q, floor_z) -> bool:
    """Whether the arm's capsules and the tool's cylinders stay above ``floor_z`` (m, base frame) at ``q``."""
    if floor_z is None:
        return True
    from .solve import arm_below
    from .tool_floor import tool_below

    q = np.asarray(q, dtype=float)[None]
    if arm_below(model, q, floor_z)[0]:
        return False
    return not (cell.tool is not None and tool_below(cell.tool, model.fk(q), floor_z)[0])


def _lift(model, cell, pose, q_ref, clearance, floor_z=None):
    """Joint values of ``pose`` lifted by ``clearance`` (or a half, a quarter of it where the full lift
    is out of reach), rad; ``q_ref`` when no lift is reachable.

    The lift goes back along the tool axis; with a table top ``floor_z`` (m, base frame), a lift
    whose arm or tool would dip below it is replaced by one along the next of
    :func:`lift_directions` that stays above it."""
    first = None
    for d in lift_directions(cell, pose):
        for f in (1.0, 0.5, 0.25):
            p = pose.copy()
            p[:3, 3] += f * clearance * d
            q = _nearest_ik(model, cell, p, q_ref)
            if q is None:
                continue
            if _clear_of_floor(model, cell, q, floor_z):
                return q
            first = q if first is None else first
    return first if first is not None else np.asarray(q_ref, dtype=float)


def split_unreachable(trajectory, solution, model, cell, *, clearance: float = 0.02, air_speed: float = 0.1,
                      floor_z: float | None = None):
    """The trajectory the robot runs: unreachable samples replaced by retract, joint move, approach.

    Parameters
    ----------
    trajectory : Trajectory
        TCP poses in the part frame, m.
    solution : JointSolution
        Its joint values (``reachable`` marks what the robot reaches).
    model : RobotModel
    cell : Cell
    clearance : float
        Retract/approach height along minus the tool z-axis, m.
    air_speed : float
        Nominal TCP speed of the retract and approach, m/s (the robot stage re-times to the joint limits).
    floor_z : float, optional
        Table top in the base frame, m: the retract and the approach keep the arm and the tool above
        it (:func:`_lift`; default: no table).

    Returns
    -------
    trajectory : Trajectory
        With the unreachable samples dropped and the air samples inserted (``contact`` 0, ``pass`` -1).
    q : (m, 6) float
        Joint values of every sample of the new trajectory, rad: the solution's on kept samples, and on
        the inserted ones the lifted poses' joint values nearest the reached ones.
    gaps : list of Gap
    src : (m,) int
        Index of each sample in ``trajectory`` (-1 for an inserted air sample).  Each gap inserts the
        retract (a lifted pose of the last reached sample) and the joint move's target (a lifted pose
        of the next reached one); the job's end inserts the retract alone.
    """
    reach = np.asarray(solution.reachable, bool)
    gaps = find_gaps(trajectory, reach)
    if not gaps or not reach.any():
        return trajectory, solution.q.copy(), gaps, np.arange(len(trajectory))
    poses = poses_from_trajectory(trajectory)
    n = len(trajectory)
    pieces = []          # (poses (k,4,4), contact (k,), pass (k,), feed (k,), dt before each (k,), q (k,6), src (k,))

    def keep(lo, hi):
        idx = np.arange(lo, hi)
        dt = np.diff(trajectory.t[max(lo - 1, 0):hi])
        if lo == 0:
            dt = np.r_[0.0, dt]
        pieces.append((poses[idx], trajectory.contact[idx], trajectory.pass_index[idx], trajectory.feed[idx],
                       dt, solution.q[idx], idx))

    cursor = 0
    t_lift = clearance / air_speed
    for g in gaps:
        a, b = g.start - 1, g.stop            # last reached before, first reached after
        if a < 0:                              # the job starts unreachable: begin at the first reached sample
            cursor = b
            continue
        keep(cursor, a + 1)
        cursor = b
        qa = _lift(model, cell, poses[a], solution.q[a], clearance, floor_z)
        if b >= n:                             # the job ends unreachable: retract and stop
            pieces.append((cell.tcp2part(model.fk(qa[None])), np.zeros(1, bool), np.full(1, -1),
                           np.full(1, air_speed), np.full(1, t_lift), qa[None], np.full(1, -1)))
            break
        qb = _lift(model, cell, poses[b], solution.q[b], clearance, floor_z)
        q_air = np.array([qa, qb])
        air = cell.tcp2part(model.fk(q_air))
        # at least the time the slowest joint needs at half its speed limit (insert_joint_moves and the
        # re-timing refine it)
        t_joints = float(np.max(np.abs(qb - qa) / (0.5 * model.max_speed)))
        t_move = max(trajectory.t[b] - trajectory.t[a] - 2 * t_lift, t_joints, 1e-3)
        pieces.append((air, np.zeros(2, bool), np.full(2, -1), np.full(2, air_speed), np.r_[t_lift, t_move], q_air,
                       np.full(2, -1)))
    if cursor < n:
        keep(cursor, n)
    new_poses = np.concatenate([p[0] for p in pieces])
    contact = np.concatenate([p[1] for p in pieces]).astype(bool)
    pass_index = np.concatenate([p[2] for p in pieces]).astype(int)
    feed = np.concatenate([p[3] for p in pieces])
    dt = np.concatenate([p[4] for p in pieces])
    q = np.concatenate([p[5] for p in pieces])
    src = np.concatenate([p[6] for p in pieces])
    # the sample after each air block (the landing) takes t_lift from the last air sample
    landing = np.flatnonzero((src[1:] >= 0) & (src[:-1] < 0)) + 1
    dt[landing] = t_lift
    dt[0] = 0.0
    t = trajectory.t[src[0]] + np.cumsum(dt) if src[0] >= 0 else np.cumsum(dt)
    extra = {}
    for name, col in trajectory.extra.items():
        vals = np.zeros(len(src))
        vals[src >= 0] = col[src[src >= 0]]
        extra[name] = vals
    meta = dict(trajectory.metadata)
    meta["robot_gaps"] = [g.as_record() for g in gaps]
    new = replace(trajectory, t=t, position=new_poses[:, :3, 3].copy(), quaternion=matrix_to_quat(new_poses[:, :3, :3]),
                  contact=contact, feed=feed, pass_index=pass_index, extra=extra, metadata=meta)
    return new, q, gaps, src


def solution_after_split(solution, trajectory, q, src, model):
    """The :class:`JointSolution` of the split trajectory, without solving it again.

    Kept samples keep their joint values and branch; the retract and the joint move's target take
    :func:`split_unreachable`'s joint values (their poses are FK of them); the retract keeps the
    branch of the sample before it, the target takes the branch of the sample after it, and the
    step onto the target is a joint move.

    Parameters
    ----------
    solution : JointSolution
        Of the trajectory before the split.
    trajectory : Trajectory
        The split trajectory.
    q : (m, 6) float
        Its joint values, rad.
    src : (m,) int
        Index of each sample in the trajectory before the split (-1 for an inserted air sample).
    model : RobotModel

    Returns
    -------
    JointSolution
    """
    m = len(q)
    reach = np.all(np.isfinite(q), axis=1)
    branch = np.full(m, -1)
    kept = src >= 0
    branch[kept] = solution.branch[src[kept]]
    target = np.zeros(m, bool)                  # joint-move targets: an inserted sample after an inserted one
    target[1:] = (src[1:] < 0) & (src[:-1] < 0)
    for i in range(m - 2, -1, -1):              # a target: the branch it lands on
        if target[i] and reach[i] and branch[i + 1] >= 0:
            branch[i] = branch[i + 1]
    for i in range(1, m):                       # a retract: the branch it leaves from
        if branch[i] < 0 and reach[i]:
            branch[i] = branch[i - 1]
    for i in range(m - 2, -1, -1):              # the job's start: the branch it lands on
        if branch[i] < 0 and reach[i]:
            branch[i] = branch[i + 1]
    names = solution.branch_names
    switches = []
    for s in np.flatnonzero(np.diff(branch)) + 1:
        if branch[s] < 0 or branch[s - 1] < 0:
            continue
        after = trajectory.pass_index[s:][trajectory.contact[s:]]
        switches.append({"sample": int(s), "from": names[branch[s - 1]], "to": names[branch[s]],
                         "pass_after": int(after[0]) if len(after) else -1})
    measures = {k: np.full(m, np.nan) for k in solution.measures}
    if reach.any():
        for k, v in model.singularity_measures(q[reach]).items():
            if k in measures:
                measures[k][reach] = v
        measures["joint_limit_margin_rad"][reach] = model.joint_limit_margin(q[reach])
    # per-sample flags on the split samples: a kept sample keeps its joint-move flag, the step onto each
    # inserted target is a joint move; the distance from the part is measured again on the split trajectory
    from .solve import clearance_from_contact

    joint_move = np.zeros(m, bool)
    joint_move[kept] = solution.joint_moves[src[kept]]
    joint_move |= target & reach & np.r_[False, reach[:-1]]
    clearance = None if solution.clearance is None else clearance_from_contact(trajectory)
    return replace(solution, q=q, branch=np.where(reach, branch, -1), reachable=reach, switches=switches,
                   stretches=[], measures=measures, warning=None, joint_move=joint_move, clearance=clearance)


def _retracts(model, cell, pose, q, clearance: float) -> bool:
    """Whether the TCP can go straight back along its tool axis by 2.5 ``clearance`` (m) from ``pose``
    on the configuration ``q`` (no joint jumping): the gap's retract and room above it for the first
    lifts of :func:`swath.robot.sweep.clear_joint_moves`."""
    from .sweep import straight_line

    return straight_line(model, cell, pose, -2.5 * clearance * pose[:3, 2], q) is not None


def air_splits(trajectory, solution, model, cell, check, *, clearance: float, max_back: int = 400) -> tuple:
    """Samples to run as a gap (retract, joint move, approach) instead of as planned, and why.

    Two cases, both handed to :func:`split_unreachable` as if unreachable:

    * **a low configuration change**: a branch change whose step comes within ``clearance`` of the
      part where the old configuration cannot retract (it ends exactly where the pad leaves the pass)
      or the new one cannot rise.  The samples back to the last one the old configuration can retract
      from (at most ``max_back``, within its pass) and on to the first the new one can rise from are
      dropped, so the change happens in the gap's joint move, at the clearance and checked along its sweep;
    * **an air link that hits something** (the TCP under the table top beside the part, the arm
      against itself): its colliding samples, and one either side, are dropped; the gap's joint move
      goes over them at the clearance, lifted higher where its sweep still hits.

    Parameters
    ----------
    trajectory : Trajectory
    solution : JointSolution
    model : RobotModel
    cell : Cell
    check : SweepCheck
        The job's collision scene.
    clearance : float
        m.
    max_back : int
        Samples of a pass given up at most to retract before a change.

    Returns
    -------
    drop : (n,) bool
        Samples to drop (besides the unreachable ones).
    low_switches, air_hits : int
        How many changes and colliding air links were turned into gaps.
    """
    n = len(trajectory)
    drop = np.zeros(n, bool)
    reach = np.asarray(solution.reachable, bool)
    if n < 2 or not reach.any():
        return drop, 0, 0
    poses = poses_from_trajectory(trajectory)
    on = np.asarray(trajectory.contact, bool) & (np.asarray(trajectory.pass_index) >= 0)
    near = solution.clearance if solution.clearance is not None else np.zeros(n)
    b = solution.branch
    q = solution.q
    low = 0
    for j in (np.flatnonzero((b[1:] != b[:-1]) & (b[1:] >= 0) & (b[:-1] >= 0)) + 1).tolist():
        if min(float(near[j - 1]), float(near[j])) >= clearance:
            continue
        a = j - 1
        lo = max(0, j - 1 - max_back)
        while a >= lo and reach[a] and b[a] == b[j - 1] and not _retracts(model, cell, poses[a], q[a], clearance):
            a -= 1
        e = j
        hi = min(n, j + max_back)
        while e < hi and reach[e] and b[e] == b[j] and not _retracts(model, cell, poses[e], q[e], clearance):
            e += 1
        if a == j - 1 and e == j:
            continue                                  # both ends rise: the sweep's lift handles it
        if a < lo or e >= hi or not reach[max(a, 0)] or not reach[min(e, n - 1)]:
            continue                                  # no end to rise from: left to the sweep and its warning
        drop[a + 1:e] = True
        low += 1
    # air samples (not in contact, reached, not dropped) whose configuration hits something
    air = np.flatnonzero(~on & reach & ~drop)
    hits_air = 0
    if len(air):
        frames = model.chain.frames(q[air])
        hits = check.scene.check(frames)
        from .collision import tcp_grazes_table

        keep = tcp_grazes_table(hits.body_a, hits.body_b, hits.depth, invert=True)
        bad = np.zeros(n, bool)
        bad[air[np.unique(hits.pose[keep])]] = True
        for r0, r1 in _runs(bad):
            lo_, hi_ = max(int(r0) - 1, 0), min(int(r1) + 1, n)
            drop[lo_:hi_] |= ~on[lo_:hi_]              # never a contact sample: the gap's ends stay on the passes
            hits_air += 1
    return drop, low, hits_air
