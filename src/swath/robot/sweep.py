"""Joint moves kept clear of the part: the swept tool and arm measured along the move, lifted when too low.

A joint move (a configuration change on an air link, the crossing of an unreachable gap, a large turn
in the air) is driven by the controller as a straight line in joint space; between its two ends the
tool and the arm sweep wherever that line takes them.  :class:`SweepCheck` follows the line at joint
steps of at most 2° and measures there the smallest distance of the swept bodies (the arm's link
capsules, the tool's bodies, the TCP and the pad, a disc of the pad's radius at the TCP normal to the
tool axis) to the part, and whether any body hits the table, a fixture
or the robot itself.

:func:`clear_joint_moves` holds every joint move of a solved job to two rules:

* a move that changes the configuration keeps at least the job's clearance from the part over its
  whole sweep;
* no move hits anything (the part, the table, a fixture, the robot).

A move that breaks a rule is lifted: a straight retract away from the part (along the tool axis, or
straight up in the base frame) to a few heights in turn, the joint move there, and a straight
approach back down to where it landed; where the straight joint line between the lifted ends still
dips too low, a via-point raised above the middle of the move is tried.  Where none of these keeps the
rules (a wall or a post across the move, the arm's own links in the way), via-points are searched in
joint space between the move's ends or the lowest clean lifted ends (:mod:`swath.robot.routing`: one
joint group at a time, then a seeded random tree).  The first candidate that
keeps both rules is taken (the lowest lift); the rows it adds are the rows the programs write (each
via-point a joint-move target of its own), so what was checked is what the robot is told to do.
When no candidate keeps the rules the move is left as planned (or replaced by the candidate that
comes closest) and :attr:`MoveSweep.ok` is False: the job's collision check then refuses a move that
collides, and the robot stage warns of one that stays too low.
"""

from __future__ import annotations

import itertools
import logging
import math
from dataclasses import dataclass, field

import numpy as np

from ..cell import SANDER_3IN
from .collision import MAX_JOINT_STEP, TCP_RADIUS, interpolate_joints, job_scene, tcp_grazes_table
from .joint_moves import insert_samples
from .pose import matrix_to_quat, poses_from_trajectory

log = logging.getLogger(__name__)

#: Lifts tried, as multiples of the clearance (the heights added to the joint move's ends), in order.
LIFTS = (1.25, 2.5, 5.0, 10.0)


@dataclass(frozen=True)
class Sweep:
    """What a swept joint path came to.

    Attributes
    ----------
    min_distance : float
        Smallest distance of the swept bodies (links, tool bodies, TCP, pad) to the part, m (exact below
        :attr:`SweepCheck.cap`, a lower bound above it).
    nearest : str
        The body that came nearest.
    hits : tuple of (str, str)
        Pairs of bodies that touch somewhere along the path (those that already touch at the move's
        ends on the job's path left out: the job's collision check reports them).
    """

    min_distance: float
    nearest: str
    hits: tuple = ()

    def ok(self, required: float) -> bool:
        """No collision, and at least ``required`` (m) from the part."""
        return not self.hits and self.min_distance >= required

    def key(self) -> tuple:
        """Sort key: collision-free first, then farther from the part."""
        return (not self.hits, self.min_distance)


class SweepCheck:
    """Distance and collision queries of joint paths in a job's cell.

    Parameters
    ----------
    model : RobotModel
    cell : Cell
        The job's cell (the default table is put in when the cell assumes one).
    part_vertices : (n, 3) float
        The part in the part frame, m.
    part_faces : (m, 3) int
    max_step : float
        Largest joint step between checked poses, rad (default 2°).
    cap : float
        Distances above this need not be exact, m.
    pad_radius : float or None
        Radius of the pad, m (default the 3-inch sander's, 38.1 mm): a disc at the TCP normal to the
        tool axis whose distance to the part counts with the other bodies' (its rim comes nearer a
        tilted surface than the TCP does); None: the TCP point alone.
    """

    def __init__(self, model, cell, part_vertices, part_faces, *, max_step: float = MAX_JOINT_STEP, cap: float = 0.3,
                 pad_radius: float | None = SANDER_3IN["pad_radius"]):
        self.model = model
        self.scene, self.cell = job_scene(model, cell, part_vertices, part_faces, tcp_radius=TCP_RADIUS,
                                          pad_radius=pad_radius)
        self.max_step = max_step
        self.cap = cap

    def sweep(self, q_nodes, *, ignore=(), cap: float | None = None) -> Sweep:
        """The joint path through ``q_nodes`` (k, 6) rad, straight in joint space between nodes;
        pairs of body names in ``ignore`` are not counted as hits (bodies that already touch where
        the path starts or ends on the job's own path: a lift cannot part them).  ``cap`` (m,
        default :attr:`cap`): distances above it need not be exact (a smaller one is quicker, and
        enough to tell whether a required distance is kept)."""
        q_fine, _ = interpolate_joints(np.asarray(q_nodes, dtype=float), max_step=self.max_step)
        frames = self.model.chain.frames(q_fine)
        d, who, _ = self.scene.min_distance(frames, "the part", cap=self.cap if cap is None else cap)
        pairs = tuple(sorted(self._pairs(frames) - set(ignore)))
        return Sweep(min_distance=d, nearest=who, hits=pairs)

    def touching(self, q) -> set:
        """Pairs of body names that touch at the joint values ``q`` (k, 6) rad."""
        return self._pairs(self.model.chain.frames(np.asarray(q, dtype=float)))

    def _pairs(self, frames) -> set:
        hits = self.scene.check(frames)
        keep = tcp_grazes_table(hits.body_a, hits.body_b, hits.depth, invert=True)
        return {(a, b) for a, b, k in zip(hits.body_a, hits.body_b, keep) if k}


@dataclass(frozen=True)
class MoveSweep:
    """One joint move's check and what was done to it.

    Attributes
    ----------
    pass_after : int
        The contact pass the move leads to (-1 after the last).
    after_pass : int
        The last contact pass before it (-1 before the first).
    branch_change : bool
    required_m : float
        Distance from the part the move must keep, m (the clearance for a configuration change, 0 else).
    planned : Sweep
        The move as planned.
    final : Sweep
        The move as written (the same when not lifted).
    lift_m : float
        Height of the retract and approach added, m (0: none).
    direction : str
        ``""`` (as planned), ``"tool axis"`` or ``"up"`` (the retract's direction), or ``"via only"``
        (the ends kept, a raised via-point between them).
    vias : int
        Via-points added between the lifted ends.
    """

    pass_after: int
    after_pass: int
    branch_change: bool
    required_m: float
    planned: Sweep
    final: Sweep
    lift_m: float = 0.0
    direction: str = ""
    vias: int = 0

    @property
    def ok(self) -> bool:
        return self.final.ok(self.required_m)

    def where(self) -> str:
        return "the air move before the first pass" if self.after_pass < 0 else f"the air move after pass {self.after_pass}"

    def as_record(self) -> dict:
        return {"after_pass": self.after_pass, "pass_after": self.pass_after, "branch_change": self.branch_change,
                "required_m": self.required_m, "planned_min_distance_m": self.planned.min_distance,
                "planned_collisions": [list(p) for p in self.planned.hits],
                "min_distance_m": self.final.min_distance, "nearest_body": self.final.nearest,
                "collisions": [list(p) for p in self.final.hits], "lift_m": self.lift_m,
                "lift_direction": self.direction, "vias": self.vias, "ok": self.ok}


def ik_near(model, cell, tcp2part, q_ref, *, max_change: float) -> tuple[np.ndarray, int] | None:
    """Joint values of one TCP pose (4, 4) nearest ``q_ref`` (any branch, 2π-equivalents inside the
    limits, no joint more than ``max_change`` rad away) and their branch slot; None when there is none."""
    raw = model.ik(cell.flange2base(np.asarray(tcp2part)[None]), seed=q_ref)[0]
    slots = np.flatnonzero(np.all(np.isfinite(raw), axis=1))
    if not len(slots):
        return None
    cand = raw[slots] + 2 * math.pi * np.round((q_ref - raw[slots]) / (2 * math.pi))
    inside = np.all((cand >= model.lower) & (cand <= model.upper), axis=1)
    if not inside.any():
        return None
    cand, slots = cand[inside], slots[inside]
    dist = np.max(np.abs(cand - q_ref), axis=1)
    k = int(np.argmin(dist))
    return (cand[k], int(slots[k])) if dist[k] <= max_change else None


def straight_line(model, cell, tcp2part, offset, q_start, *, step: float = 0.005, max_change: float = 0.25):
    """A straight TCP move by ``offset`` (3,) m in the part frame, orientation held, from ``tcp2part``
    at joint values ``q_start``: every ``step`` m the joint values nearest the last.

    Returns
    -------
    (k + 1, 4, 4) poses and (k + 1, 6) joint values (the first row the start), or None where the
    line leaves the reach or a joint would jump more than ``max_change`` rad in one step.
    """
    length = float(np.linalg.norm(offset))
    k = max(1, math.ceil(length / step))
    poses = np.repeat(np.asarray(tcp2part, dtype=float)[None], k + 1, axis=0)
    poses[:, :3, 3] += np.linspace(0.0, 1.0, k + 1)[:, None] * np.asarray(offset, dtype=float)
    q = [np.asarray(q_start, dtype=float)]
    for p in poses[1:]:
        got = ik_near(model, cell, p, q[-1], max_change=max_change)
        if got is None:
            return None
        q.append(got[0])
    return poses, np.array(q)


@dataclass
class _Plan:
    """The rows a lift adds before the move's landing sample."""

    poses: np.ndarray                 # (m, 4, 4) tcp2part
    q: np.ndarray                     # (m, 6)
    joint_move: np.ndarray            # (m,) bool
    via: np.ndarray                   # (m,) bool
    branch: np.ndarray                # (m,) int
    after: np.ndarray                 # (m,) bool: on the landing side (approach)
    sweep: Sweep
    lift: float
    direction: str
    vias: int = 0
    times: list = field(default_factory=list)


def _candidates(model, cell, check: SweepCheck, p0, p1, q0, q1, b0, b1, clearance: float, up_part, ignore):
    """Lifted versions of the joint move ``q0 → q1`` (TCP poses ``p0``, ``p1``), lowest first: per
    height, the ends retracted along the tool axis, then straight up, each without and with a raised
    via-point; where neither retract is reachable (the ends at the edge of the reach), the ends as
    they are with the via-point alone."""
    for factor in LIFTS:
        h = factor * clearance
        lifted = False
        for direction, d0, d1 in (("tool axis", -p0[:3, 2], -p1[:3, 2]), ("up", up_part, up_part)):
            ret = straight_line(model, cell, p0, h * d0, q0)
            app = straight_line(model, cell, p1, h * d1, q1)
            if ret is None or app is None:
                continue
            lifted = True
            if check.sweep(ret[1], ignore=ignore).hits or check.sweep(app[1], ignore=ignore).hits:
                continue
            yield from _chains(model, cell, check, ret, app, b0, b1, h, direction, up_part, ignore)
        if not lifted:
            ret = (p0[None], np.asarray(q0, dtype=float)[None])
            app = (p1[None], np.asarray(q1, dtype=float)[None])
            yield from _chains(model, cell, check, ret, app, b0, b1, h, "via only", up_part, ignore, direct=False)


def _chains(model, cell, check, ret, app, b0, b1, h, direction, up_part, ignore, *, direct=True):
    """The joint moves between the top of a retract ``ret`` and of an approach ``app`` ((poses, q),
    each from the job's path upward): straight (``direct``), then through a via-point ``h`` above the
    middle, then one ``h`` above it and ``h`` nearer the robot's axis."""
    top0, top1 = ret[1][-1], app[1][-1]
    chains: list[tuple] = [((), ret[0][-1])] if direct else []
    centre = 0.5 * (ret[0][-1][:3, 3] + app[0][-1][:3, 3])
    # toward the robot's axis, level: a via-point at the edge of the reach is found nearer the robot
    inward = cell.base2part[:3, 3] - centre
    inward -= (inward @ up_part) * up_part
    inward /= max(float(np.linalg.norm(inward)), 1e-12)
    for offset in (h * up_part, h * (up_part + inward)):
        mid = ret[0][-1].copy()
        mid[:3, 3] = centre + offset
        via = ik_near(model, cell, mid, 0.5 * (top0 + top1), max_change=math.pi)
        if via is not None:
            chains.append(((via,), mid))
    # a change of shoulder or elbow swings the wrist past the shoulder and the tool down beside the part:
    # through the arm raised (joints 2 and 3 where the wrist centre is highest), the others half-way
    # (and, that failing, raised with the start's wrist, then the wrist turned to the end's up there)
    if _arm_changes(model, b0, b1):
        chains += _raised_chains(model, cell, top0, top1)
    for vias, mid in chains:
        sw = check.sweep(np.array([top0] + [v[0] for v in vias] + [top1]), ignore=ignore)
        yield _plan(ret, app, vias, mid, sw, b0, b1, h if direct else 0.0, direction)


def _plan(ret, app, vias, mid, sw: Sweep, b0: int, b1: int, lift: float, direction: str) -> _Plan:
    """The rows of a retract ``ret`` and an approach ``app`` ((poses, q), each from the job's path
    upward) joined through ``vias`` ((q, branch slot) each) whose TCP poses are ``mid`` ((k, 4, 4),
    or one (4, 4) for all)."""
    a_poses, a_q = app[0][::-1], app[1][::-1]
    mids = np.reshape(mid, (-1, 4, 4))
    poses = np.concatenate([ret[0][1:]] + [mids[min(k, len(mids) - 1)][None] for k in range(len(vias))]
                           + [a_poses[:-1]])
    q = np.concatenate([ret[1][1:]] + [v[0][None] for v in vias] + [a_q[:-1]])
    nr, nv, na = len(ret[0]) - 1, len(vias), len(a_q) - 1
    # rows: the retract's (linear), the via-points and the approach's top (joint-move targets), the
    # approach's others (linear); a via-only chain has no approach rows: its last target is the landing
    jm = np.r_[np.zeros(nr, bool), np.ones(nv, bool), np.ones(min(na, 1), bool), np.zeros(max(na - 1, 0), bool)]
    via_flag = np.r_[np.zeros(nr, bool), np.ones(nv, bool), np.zeros(na, bool)]
    branch = np.r_[np.full(nr, b0), [v[1] for v in vias], np.full(na, b1)].astype(int)
    after = np.r_[np.zeros(nr + nv, bool), np.ones(na, bool)]
    return _Plan(poses, q, jm, via_flag, branch, after, sw, lift, direction, nv)


def _routed(model, cell, check: SweepCheck, p0, p1, q0, q1, b0, b1, clearance: float, up_part, ignore, need: float,
            *, attempts: int = 2):
    """Joint moves routed through via-points found in joint space (:func:`swath.robot.routing.route_joint_move`)
    between the move's own ends when they keep ``need`` (m) from the part, then between the lowest
    clean lifted ends; at most ``attempts`` routings."""
    from .routing import route_joint_move

    ends = []
    q0, q1 = np.asarray(q0, dtype=float), np.asarray(q1, dtype=float)
    if check.sweep(np.array([q0, q0]), ignore=ignore).ok(need) and check.sweep(np.array([q1, q1]), ignore=ignore).ok(need):
        ends.append(((p0[None], q0[None]), (p1[None], q1[None]), 0.0, "routed"))
    for factor in LIFTS:
        h = factor * clearance
        for direction, d0, d1 in (("tool axis", -p0[:3, 2], -p1[:3, 2]), ("up", up_part, up_part)):
            ret = straight_line(model, cell, p0, h * d0, q0)
            app = straight_line(model, cell, p1, h * d1, q1)
            if ret is None or app is None or check.sweep(ret[1], ignore=ignore).hits \
                    or check.sweep(app[1], ignore=ignore).hits:
                continue
            ends.append((ret, app, h, f"{direction}, routed"))
            break
    for ret, app, lift, direction in ends[:attempts]:
        found = route_joint_move(check, ret[1][-1], app[1][-1], required=need, ignore=ignore)
        if found is None:
            continue
        slots = [_slot(model, cell, v) for v in found]
        if any(sl is None for sl in slots):
            continue                                      # a via-point the controller could not be given
        vias = [sl[0] for sl in slots]
        mids = np.array([sl[1] for sl in slots]) if slots else ret[0][-1]
        sw = check.sweep(np.array([ret[1][-1]] + [v[0] for v in vias] + [app[1][-1]]), ignore=ignore)
        yield _plan(ret, app, vias, mids, sw, b0, b1, lift, direction)


def _raised_joints(model, ref) -> np.ndarray:
    """(2,) joints 2 and 3, rad, inside the limits, that put the wrist centre (the chain frame of joint 5)
    within 50 mm of its highest above the base with joints 1 and 4–6 at ``ref``'s, clear of the elbow
    and shoulder singularities (|sin| of the elbow ≥ 0.3, the wrist centre ≥ 0.1 m off axis 1; a grid
    of about 5° steps), the nearest to ``ref`` among them; ``ref[1:3]`` when none is."""
    ref = np.asarray(ref, dtype=float)
    lo, hi = model.lower[1:3], model.upper[1:3]
    n = np.maximum(2, np.ceil((hi - lo) / math.radians(5.0)).astype(int) + 1)
    a, b = np.meshgrid(np.linspace(lo[0], hi[0], n[0]), np.linspace(lo[1], hi[1], n[1]), indexing="ij")
    q = np.tile(ref, (a.size, 1))
    q[:, 1], q[:, 2] = a.ravel(), b.ravel()
    m = model.singularity_measures(q)
    ok = (m["elbow"] >= 0.3) & (m["shoulder_m"] >= 0.1)
    if not ok.any():
        return ref[1:3].copy()
    z = np.where(ok, model.chain.frames(q)[:, 4, 2, 3], -np.inf)
    top = np.flatnonzero(z >= z.max() - 0.05)
    k = top[int(np.argmin(np.abs(q[top, 1:3] - ref[1:3]).max(axis=1)))]
    return q[k, 1:3]


def _arm_changes(model, b0: int, b1: int) -> bool:
    """Whether branch ``b1`` differs from ``b0`` in more than the wrist (its name up to ``-wrist``)."""
    names = model.branch_names
    if not (0 <= b0 < len(names) and 0 <= b1 < len(names)):
        return b0 != b1
    return names[b0].split("-wrist")[0] != names[b1].split("-wrist")[0]


def _slot(model, cell, q):
    """``((q, branch slot), tcp2part)`` of joint values ``q`` (6,) rad, or None where the inverse
    kinematics does not give them back (a singular configuration)."""
    tcp2part = cell.tcp2part(model.fk(q[None]))[0]
    got = ik_near(model, cell, tcp2part, q, max_change=1e-6)
    return None if got is None else ((got[0], got[1]), tcp2part)


def _raised_via(model, cell, q0, q1):
    """A joint-move via-point with the arm raised between ``q0`` and ``q1`` (6,) rad: joints 1, 4 and 6
    half-way, joint 5 half-way unless that is near the wrist singularity (then ``q0``'s), joints 2 and 3
    at :func:`_raised_joints`; ``((q, branch slot),), tcp2part`` or None."""
    if model.chain.n_joints != 6:
        return None
    q0, q1 = np.asarray(q0, dtype=float), np.asarray(q1, dtype=float)
    q = 0.5 * (q0 + q1)
    if abs(math.sin(q[4])) < 0.3:
        q[4] = q0[4]
    q[1:3] = _raised_joints(model, q)
    got = _slot(model, cell, q)
    return None if got is None else ((got[0],), got[1])


def _raised_chains(model, cell, q0, q1) -> list:
    """Via-point chains through the raised arm (:func:`_raised_via`): the one via-point, then two: the
    arm raised with ``q0``'s joints 1 and 4–6, and turned to ``q1``'s up there (raise, turn, lower)."""
    out = []
    one = _raised_via(model, cell, q0, q1)
    if one is not None:
        out.append(one)
        q_top = one[0][0][0]
        first, second = q_top.copy(), q_top.copy()
        keep = [0, 3, 4, 5]
        first[keep], second[keep] = np.asarray(q0, dtype=float)[keep], np.asarray(q1, dtype=float)[keep]
        a, b = _slot(model, cell, first), _slot(model, cell, second)
        if a is not None and b is not None:
            out.append(((a[0], b[0]), np.stack([a[1], b[1]])))
    return out


def clear_joint_moves(trajectory, solution, model, cell, check: SweepCheck, *, clearance: float,
                      air_speed: float = 0.1):
    """Every joint move of ``solution`` checked along its sweep, and lifted where it breaks a rule.

    Parameters
    ----------
    trajectory : Trajectory
        TCP poses in the part frame (m), the samples of ``solution``.
    solution : JointSolution
        Its joint values; :attr:`JointSolution.joint_move` marks the moves.
    model : RobotModel
    cell : Cell
    check : SweepCheck
    clearance : float
        Distance from the part a configuration change keeps, m.
    air_speed : float
        TCP speed of the added retracts and approaches, m/s (the re-timing refines it).

    Returns
    -------
    trajectory, solution
        With the lifts' rows inserted (retract and approach rows, via-points as joint-move targets).
    sweeps : list of MoveSweep
        One per joint move, in time order.
    """
    from dataclasses import replace

    jm = solution.joint_moves
    moves = [int(i) for i in np.flatnonzero(jm) if i > 0 and solution.reachable[i] and solution.reachable[i - 1]]
    if not moves:
        return trajectory, solution, []
    poses = poses_from_trajectory(trajectory)
    up_part = cell.base2part[:3, :3] @ np.array([0.0, 0.0, 1.0])
    on = np.asarray(trajectory.contact, bool) & (np.asarray(trajectory.pass_index) >= 0)
    last_pass = np.maximum.accumulate(np.where(on, trajectory.pass_index, -1))
    sweeps, plans = [], []
    for i in moves:
        b0, b1 = int(solution.branch[i - 1]), int(solution.branch[i])
        need = clearance if b0 != b1 else 0.0
        after = trajectory.pass_index[i:][on[i:]]
        ignore = check.touching(solution.q[[i - 1, i]])
        planned = check.sweep(solution.q[[i - 1, i]], ignore=ignore)
        chosen = None
        if not planned.ok(need):
            best = None
            args = (model, cell, check, poses[i - 1], poses[i], solution.q[i - 1], solution.q[i], b0, b1, clearance,
                    up_part, ignore)
            # the simple fixes first (lifts, a raised via-point), then via-points found in joint space
            for cand in itertools.chain(_candidates(*args), _routed(*args, need)):
                if cand.sweep.ok(need):
                    chosen = cand
                    break
                if best is None or cand.sweep.key() > best.sweep.key():
                    best = cand
            if chosen is None and best is not None and best.sweep.key() > planned.key():
                chosen = best
        rec = MoveSweep(pass_after=int(after[0]) if len(after) else -1, after_pass=int(last_pass[i - 1]),
                        branch_change=b0 != b1, required_m=need, planned=planned,
                        final=planned if chosen is None else chosen.sweep,
                        lift_m=0.0 if chosen is None else chosen.lift,
                        direction="" if chosen is None else chosen.direction,
                        vias=0 if chosen is None else chosen.vias)
        sweeps.append(rec)
        if chosen is not None:
            plans.append((i, chosen))
            log.info("robot: %s lifted %.0f mm (%s, %d via-point(s)): %.1f mm from the part, was %.1f mm",
                     rec.where(), 1e3 * rec.lift_m, rec.direction, rec.vias, 1e3 * rec.final.min_distance,
                     1e3 * planned.min_distance)
    if not plans:
        return trajectory, solution, sweeps
    # times: the added rows at air speed (joint-move targets 1 ms apart: insert_joint_moves times them)
    t = np.asarray(trajectory.t, dtype=float)
    added = np.zeros(len(t))
    at, t_new, rows = [], [], []
    for i, plan in plans:
        seg = np.linalg.norm(np.diff(np.concatenate([poses[i - 1][None], plan.poses, poses[i][None]])[:, :3, 3],
                                     axis=0), axis=1)
        dt = np.where(np.r_[plan.joint_move, False], 1e-3, np.maximum(seg / air_speed, 1e-3))
        added[i] = float(dt.sum())
        rows.append((i, plan, np.cumsum(dt)[:-1]))
    shift = np.cumsum(added)
    t_shift = t + shift
    joint_move = jm.copy()
    for i, plan, offsets in rows:
        at += [i] * len(plan.q)
        t_new.append(t_shift[i - 1] + offsets)
        # the landing: the approach's last step, or (no approach) the last joint move's target
        joint_move[i] = not plan.after.any()
    tr = replace(trajectory, t=t_shift)
    sol = replace(solution, joint_move=joint_move)
    cat = np.concatenate
    n_new = len(at)
    new_poses = cat([p.poses for _, p in plans])
    return (*insert_samples(tr, sol, model, np.array(at), t=cat(t_new), position=new_poses[:, :3, 3],
                            quaternion=matrix_to_quat(new_poses[:, :3, :3]), contact=np.zeros(n_new, bool),
                            pass_index=np.full(n_new, -1), q=cat([p.q for _, p in plans]),
                            joint_move=cat([p.joint_move for _, p in plans]), branch=cat([p.branch for _, p in plans]),
                            fraction=cat([p.after.astype(float) for _, p in plans]),
                            via=cat([p.via for _, p in plans])), sweeps)


def sweep_metrics(sweeps: list[MoveSweep]) -> dict:
    """Keys: ``n_swept_joint_moves``, ``n_lifted_joint_moves`` (lifted or given a via-point), ``n_joint_moves_not_clear`` (moves that
    still break a rule), ``min_switch_clearance_m`` (smallest swept distance to the part of a move
    that changes the configuration; NaN without one), ``joint_move_sweeps`` (records, at most 50)."""
    changes = [s.final.min_distance for s in sweeps if s.branch_change]
    return {"n_swept_joint_moves": len(sweeps), "n_lifted_joint_moves": sum(s.direction != "" for s in sweeps),
            "n_joint_moves_not_clear": sum(not s.ok for s in sweeps),
            "min_switch_clearance_m": float(min(changes)) if changes else float("nan"),
            "joint_move_sweeps": [s.as_record() for s in sweeps[:50]]}


def sweep_warnings(sweeps: list[MoveSweep], clearance: float) -> list[str]:
    """One sentence per joint move that still breaks a rule after the lifts were tried."""
    out = []
    for s in sweeps:
        if s.ok or s.final.hits:          # a collision is the collision check's to refuse
            continue
        out.append(f"robot: the configuration change on {s.where()} sweeps the {s.final.nearest} within "
                   f"{1e3 * s.final.min_distance:.1f} mm of the part (the clearance is {1e3 * clearance:.0f} mm) and "
                   "no lift of up to "
                   f"{1e3 * LIFTS[-1] * clearance:.0f} mm clears it; move the part (--base, --place) [W-ROBOT-LOW-SWITCH]")
    return out
