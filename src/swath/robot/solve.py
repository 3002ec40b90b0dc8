"""Inverse kinematics along a whole trajectory on one continuous configuration branch.

Steps (:func:`solve_trajectory`):

1. every TCP pose goes to a flange pose in the base frame (:class:`Cell`), and the model returns
   every branch's joint values (:meth:`RobotModel.ik`);
2. per branch, joint values are unwrapped along time (the 2π-equivalent nearest the previous sample,
   inside the joint limits) and a sample is *feasible* where it exists, lies inside the joint
   limits, keeps the singularity margins and does not jump (> ``max_step``) from the previous one;
3. the branch is chosen at the start as the one feasible for the longest stretch; it is kept through
   every contact pass (no flips inside a pass); on an air link before a pass the current branch is
   kept when it covers that pass, otherwise the branch that reaches furthest from the pass's start
   is taken, switching on the link at the step farthest from the part (the middle of the air move
   at the clearance, never on the retract or the approach; reported in
   :attr:`JointSolution.switches`);
4. the chosen joint values are aligned turn by turn (:func:`align_turns`): each continuous run takes
   the 2π-equivalent per joint nearest the end of the run before it that keeps the whole run inside
   the joint limits, so a wrist never spins a whole turn on an air move unless its limits force it;
5. a step on an air link that changes branch or moves a joint by more than ``max_step`` is a
   *joint move* (:attr:`JointSolution.joint_move`): the programs write it as a joint move
   (``movej``, ``MoveAbsJ``, ``PTP``) and :func:`insert_joint_moves` interpolates it in joint space
   (≤ 2° per step) so the swept arm is on the trajectory;
6. samples no branch can serve are reported as :class:`UnreachableStretch` with their pass and
   position, and their joint rows are NaN.

The re-timing to joint speed and acceleration limits is in :mod:`swath.robot.retime`.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np

from ..cell import Cell
from ..errors import UnreachableError
from .models import RobotModel
from .pose import poses_from_trajectory

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Margins:
    """How far from singularities and limits a feasible configuration must stay.

    Attributes
    ----------
    wrist : float
        Minimum |sin θ5| (default sin 5°).
    elbow : float
        Minimum |sin| of the elbow stretch angle (default sin 5°).
    shoulder : float
        Minimum distance of the wrist centre from the axis-1 singular line, m (default 0.05).
    joint_limit : float
        Minimum distance from any joint position limit, rad (default 0).
    max_step : float
        Largest joint change between consecutive samples on one branch, rad (default 0.5);
        a larger change is a discontinuity, not a motion.
    floor_z : float or None
        Height of the table top in the base frame, m: a configuration whose link capsules (those
        of the collision check, :func:`swath.robot.collision.link_bodies`; the base column excepted)
        dip below it is not feasible, so the arm stays above the table (elbow up where the elbow
        would go down).  None (default): no floor.
    arm_part : ArmPartCheck or None
        The part for :class:`swath.robot.arm_part.ArmPartCheck`: a configuration that puts a link
        capsule into the part is not feasible, so the branch chosen (and the placement searched)
        keeps the arm out of it.  None (default): not checked.
    """

    wrist: float = math.sin(math.radians(5.0))
    elbow: float = math.sin(math.radians(5.0))
    shoulder: float = 0.05
    joint_limit: float = 0.0
    max_step: float = 0.5
    floor_z: float | None = None
    arm_part: object | None = field(default=None, compare=False, repr=False)


@dataclass(frozen=True)
class UnreachableStretch:
    """A run of consecutive samples no allowed branch reaches.

    Attributes
    ----------
    start, stop : int
        Sample indices ``[start, stop)``.
    pass_index : int
        Contact pass of the first sample (-1 on a link).
    position : (3,) float
        TCP position of the first sample in the part frame, m.
    reason : str
    """

    start: int
    stop: int
    pass_index: int
    position: tuple
    reason: str

    def describe(self) -> str:
        where = f"pass {self.pass_index}" if self.pass_index >= 0 else "an air link"
        x, y, z = (1e3 * v for v in self.position)
        return (f"samples {self.start}..{self.stop - 1} on {where}, starting at ({x:.1f}, {y:.1f}, {z:.1f}) mm "
                f"in the part frame: {self.reason}")


@dataclass(frozen=True, eq=False)
class JointSolution:
    """Joint values along a trajectory.

    Attributes
    ----------
    q : (n, 6) float
        Joint values, rad; NaN on unreachable samples.
    branch : (n,) int
        Branch slot of each sample (-1 unreachable).
    reachable : (n,) bool
    switches : list of dict
        Branch switches: ``sample``, ``from``, ``to`` (branch names), ``pass_after``.
    stretches : list of UnreachableStretch
    measures : dict of (n,) float
        ``wrist``, ``elbow``, ``shoulder_m``, ``manipulability``, ``joint_limit_margin_rad`` of the
        chosen configuration (NaN where unreachable).
    branch_names : tuple of str
    warning : str or None
        The unreachable poses in one sentence (how many, the first stretches, what to do); None
        when every pose is reached.
    joint_move : (n,) bool or None
        True at sample i where the step from sample i−1 to i is a joint move (interpolated in joint
        space, not along the Cartesian path): a branch change or a large joint turn on an air link.
        None: no joint moves.
    clearance : (n,) float or None
        Distance of each sample's TCP from the nearest in-contact sample, m (0 in contact); how far
        from the part a branch change happens.
    via : (n,) bool or None
        True at a joint move's target that the next joint move leaves from (a via-point of a lifted
        move, :mod:`swath.robot.sweep`): the programs write it as a joint-move target of its own.
        None: no via-points.
    """

    q: np.ndarray
    branch: np.ndarray
    reachable: np.ndarray
    switches: list = field(default_factory=list)
    stretches: list = field(default_factory=list)
    measures: dict = field(default_factory=dict)
    branch_names: tuple = ()
    warning: str | None = None
    joint_move: np.ndarray | None = None
    clearance: np.ndarray | None = None
    via: np.ndarray | None = None

    @property
    def reachable_fraction(self) -> float:
        return float(self.reachable.mean()) if len(self.reachable) else 1.0

    @property
    def joint_moves(self) -> np.ndarray:
        """(n,) bool :attr:`joint_move`, all False when None."""
        return np.zeros(len(self.q), bool) if self.joint_move is None else np.asarray(self.joint_move, bool)

    @property
    def vias(self) -> np.ndarray:
        """(n,) bool :attr:`via`, all False when None."""
        return np.zeros(len(self.q), bool) if self.via is None else np.asarray(self.via, bool)


def segments(trajectory) -> list[tuple[int, int, bool]]:
    """``(start, stop, is_pass)`` runs: contact passes (same pass index, in contact) and air links."""
    n = len(trajectory)
    key = np.where(trajectory.contact, trajectory.pass_index, -1)
    out = []
    start = 0
    for i in range(1, n + 1):
        if i == n or key[i] != key[start]:
            out.append((start, i, bool(key[start] >= 0)))
            start = i
    return out


def branch_table(flange2base, model: RobotModel, margins: Margins | None = None, *, seed=None, same_pass=None,
                 part2base=None, tool=None):
    """Every branch's unwrapped joint values and feasibility along a pose sequence.

    Parameters
    ----------
    flange2base : (n, 4, 4) float
        Flange poses in the base frame, m.
    model : RobotModel
    margins : Margins
    seed : (6,) float, optional
        Start of a numerical model's solver, rad.
    same_pass : (n,) bool, optional
        True where sample i and i−1 belong to one contact pass; only there does a step larger than
        ``margins.max_step`` count as a jump (on air links a large joint move is a real motion,
        e.g. the tool turning round between passes).  Default: everywhere.
    part2base : (4, 4) float, optional
        The part's placement, m, for ``margins.arm_part`` (default identity).
    tool : ToolBody, optional
        The tool's bodies on the flange: with ``margins.floor_z``, a pose that puts one of them below
        the table top is not feasible on any branch (the pose fixes the tool, whatever the arm does).

    Returns
    -------
    q : (n, B, 6) float
        Joint values per branch, rad (NaN where none).
    feasible : (n, B) bool
    reason : (n, B) int
        0 feasible, 1 no solution, 2 joint limit, 3 singularity, 4 jump, 5 the arm below
        ``margins.floor_z``, 6 the arm in the part (``margins.arm_part``), 7 the tool below
        ``margins.floor_z``.
    """
    margins = Margins() if margins is None else margins
    raw = model.ik(flange2base, seed=seed)
    n, nb, _ = raw.shape
    lo, hi = model.lower + margins.joint_limit, model.upper - margins.joint_limit
    q = np.full_like(raw, np.nan)
    reason = np.where(np.isfinite(raw[..., 0]), 0, 1)
    two_pi = 2 * math.pi
    mid = 0.5 * (lo + hi)
    prev = np.full((nb, 6), np.nan)
    jumps = np.zeros((n, nb), bool)
    for i in range(n):
        cur = raw[i]
        ok = np.isfinite(cur[:, 0])
        ref = np.where(np.isfinite(prev), prev, mid)
        if model.kind != "numeric":
            # the 2π-equivalent nearest the reference, then pulled inside the limits if a turn does it
            cand = cur + two_pi * np.round((ref - cur) / two_pi)
            # a half-turn (e.g. the tool turning round on a link) can go either way: take the way
            # toward the middle of the range, so repeated turns do not wind a joint onto its limit
            alt = cand - two_pi * np.sign(cand - mid)
            near_half = np.abs(alt - ref) < np.abs(cand - ref) + 0.6
            better = near_half & (np.abs(alt - mid) < np.abs(cand - mid)) & (alt >= lo) & (alt <= hi)
            cand = np.where(better, alt, cand)
            cand = np.where(cand > hi, cand - two_pi, cand)
            cand = np.where(cand < lo, cand + two_pi, cand)
        else:
            cand = cur
        inside = np.all((cand >= lo - 1e-12) & (cand <= hi + 1e-12), axis=1)
        has_prev = np.isfinite(prev[:, 0])
        step = np.max(np.abs(cand - np.where(has_prev[:, None], prev, cand)), axis=1)
        jump = ok & inside & has_prev & (step > margins.max_step) & (same_pass is None or same_pass[i])
        jumps[i] = jump
        reason[i] = np.where(ok & ~inside, 2, reason[i])
        q[i] = np.where(ok[:, None], cand, np.nan)
        good = ok & inside
        prev = np.where(good[:, None], cand, np.nan)
    flat = q.reshape(-1, 6)
    valid = np.isfinite(flat[:, 0])
    sing_ok: np.ndarray = np.zeros(len(flat), bool)
    if valid.any():
        m = model.singularity_measures(flat[valid])
        sing_ok[valid] = (m["wrist"] >= margins.wrist) & (m["elbow"] >= margins.elbow) & (m["shoulder_m"] >= margins.shoulder)
    sing_ok = sing_ok.reshape(n, nb)
    reason = np.where((reason == 0) & ~sing_ok, 3, reason)
    if margins.floor_z is not None:
        low = np.zeros(len(flat), bool)
        low[valid] = arm_below(model, flat[valid], margins.floor_z)
        reason = np.where((reason == 0) & low.reshape(n, nb), 5, reason)
        if tool is not None:
            from .tool_floor import tool_below

            reason = np.where((reason == 0) & tool_below(tool, flange2base, margins.floor_z)[:, None], 7, reason)
    if margins.arm_part is not None:
        todo = (reason == 0).reshape(-1)
        inside = np.zeros(len(flat), bool)
        if todo.any():
            at = np.eye(4) if part2base is None else part2base
            inside[todo] = margins.arm_part.hits(flat[todo], at)  # type: ignore[attr-defined]
        reason = np.where(inside.reshape(n, nb), 6, reason)
    reason = np.where((reason == 0) & jumps, 4, reason)
    return q, reason == 0, reason


def arm_below(model: RobotModel, q, floor_z: float, *, chunk: int = 20000) -> np.ndarray:
    """(n,) bool: the link capsules of the collision check (the base column excepted) dip below
    ``floor_z`` (m, base frame) at joint values ``q`` (n, 6) rad."""
    from ..cell import Capsule
    from .collision import link_bodies

    q = np.asarray(q, dtype=float)
    links = [(m.link, m.body.body2frame, m.body.shape) for m in link_bodies(model) if m.link > 0]
    out = np.zeros(len(q), bool)
    for s in range(0, len(q), chunk):
        frames = model.chain.frames(q[s:s + chunk])
        for link, body2frame, shape in links:
            if not isinstance(shape, Capsule):
                continue
            t = frames[:, link] @ body2frame
            half = 0.5 * shape.length * t[:, 2, 2]                  # z of the capsule axis' half length
            lowest = t[:, 2, 3] - np.abs(half) - shape.radius
            out[s:s + chunk] |= lowest < floor_z
    return out


_REASONS = {1: "no inverse-kinematics solution (out of reach)", 2: "outside the joint limits",
            3: "too close to a singularity", 4: "a joint would jump between samples",
            5: "the arm would dip into the table", 6: "the arm would hit the part",
            7: "the tool would dip into the table"}


def _run_lengths(feasible: np.ndarray) -> np.ndarray:
    """(n, B) number of consecutive feasible samples starting at each sample."""
    n = len(feasible)
    run = np.zeros((n + 1,) + feasible.shape[1:], int)
    for i in range(n - 1, -1, -1):
        run[i] = np.where(feasible[i], run[i + 1] + 1, 0)
    return run[:n]


def clearance_from_contact(trajectory) -> np.ndarray:
    """(n,) distance of each sample's TCP from the nearest in-contact sample's TCP, m.

    0 on contact samples; on air links it approximates the height above the part (the contact
    samples sample the processed surface every few millimetres along each pass).  All zeros when
    no sample is in contact.
    """
    pos = np.asarray(trajectory.position, dtype=float)
    on = np.asarray(trajectory.contact, bool) & (np.asarray(trajectory.pass_index) >= 0)
    if not on.any():
        return np.zeros(len(pos))
    from scipy.spatial import cKDTree

    dist, _ = cKDTree(pos[on]).query(pos)
    return np.where(on, 0.0, dist)


def choose_branches(feasible: np.ndarray, segs, clearance=None) -> np.ndarray:
    """(n,) branch per sample: constant inside passes, switched only on links (-1 never).

    Parameters
    ----------
    feasible : (n, B) bool
    segs : list of (start, stop, is_pass)
        :func:`segments`.
    clearance : (n,) float, optional
        Distance from the part, m (:func:`clearance_from_contact`).  A switch on a link is put on
        the step whose two samples are farthest from the part among the steps where the old branch
        serves up to it and the new one from it to the next pass; without it, at the latest such
        step.  Where that step is the link's first (the pad leaving the pass) and the new branch
        serves the pass before, the change moves to the link before that pass.
    """
    n, nb = feasible.shape
    run = _run_lengths(feasible)
    branch = np.zeros(n, int)
    current = int(np.argmax(run[0])) if n else 0
    for k, (s, e, is_pass) in enumerate(segs):
        if is_pass:
            branch[s:e] = current
            continue
        # A link: decide the branch for the next pass (or the rest when no pass follows).
        nxt = next(((s2, e2) for s2, e2, p2 in segs[k + 1:] if p2), None)
        target_start, target_len = (nxt[0], nxt[1] - nxt[0]) if nxt else (e, 0)
        if target_start >= n:
            branch[s:e] = current
            continue
        if run[target_start, current] >= target_len and np.all(feasible[s:target_start, current]):
            branch[s:e] = current
            continue
        cover = np.array([feasible[target_start:target_start + max(target_len, 1), b].sum() for b in range(nb)])
        score = cover * (n + 1) + run[target_start]
        new = int(np.argmax(score))
        if score[current] >= score[new]:
            new = current
        if new == current:
            branch[s:e] = current
            continue
        # candidate switch steps j-1 -> j with j in [s, e]: old branch on [s, j), new on [j, e)
        old_ok = np.concatenate([[True], np.cumprod(feasible[s:e, current]).astype(bool)])
        new_ok = np.concatenate([np.cumprod(feasible[s:e, new][::-1]).astype(bool)[::-1], [True]])
        cand = np.flatnonzero(old_ok & new_ok) + s
        if len(cand) and clearance is not None:
            lo_side = clearance[np.maximum(cand - 1, 0)]
            hi_side = clearance[np.minimum(cand, n - 1)]
            j = int(cand[np.argmax(np.minimum(lo_side, hi_side))])
        elif len(cand):
            j = int(cand[len(cand) // 2])
        else:
            # the old branch does not serve the link: switch where the new one starts to serve
            j = e
            while j > s and feasible[j - 1, new]:
                j -= 1
        if j == s and clearance is not None:
            # the change would be right where the pad leaves the part: where the new branch serves the pass
            # before and a link leads to it, change on that link instead, farthest from the part
            earlier = _earlier_switch(feasible, segs, k, current, new, clearance)
            if earlier is not None:
                branch[earlier:s] = new
        branch[s:j] = current
        branch[j:e] = new
        current = new
    return branch


def _earlier_switch(feasible, segs, k, old: int, new: int, clearance) -> int | None:
    """The sample on the link before the pass ``segs[k - 1]`` where the change from ``old`` to
    ``new`` is farthest from the part, when ``new`` serves that pass and the link from there on;
    None when there is no such link."""
    if k < 2 or not segs[k - 1][2] or segs[k - 2][2]:
        return None
    (ls, le, _), pe = segs[k - 2], segs[k - 1][1]
    if not feasible[le:pe, new].all():
        return None
    old_ok = np.concatenate([[True], np.cumprod(feasible[ls:le, old]).astype(bool)])
    new_ok = np.concatenate([np.cumprod(feasible[ls:le, new][::-1]).astype(bool)[::-1], [True]])
    cand = np.flatnonzero(old_ok & new_ok) + ls
    cand = cand[(cand > ls) & (cand < le)]          # inside the link, not where it meets a pass
    if not len(cand):
        return None
    n = len(clearance)
    side = np.minimum(clearance[np.maximum(cand - 1, 0)], clearance[np.minimum(cand, n - 1)])
    return int(cand[np.argmax(side)])


def align_turns(q, lower, upper, breaks) -> np.ndarray:
    """Joint values with each continuous run shifted by whole turns so the joints travel least between runs.

    Parameters
    ----------
    q : (n, 6) float
        Joint values, rad; NaN rows are gaps.
    lower, upper : (6,) float
        Joint limits, rad.
    breaks : (n,) bool
        True at sample i where a new run starts (a branch change); runs also start after a gap
        and where a joint turns by more than π in one step (a wrap taken by the unwrapping).

    Returns
    -------
    (n, 6) float
        Per run and joint, ``q + 2πk`` with integers ``k`` that keep each run inside the limits
        and, among those, minimise the summed joint change from the end of each run to the start
        of the next (dynamic programming over the runs, per joint; the first run nearest the middle
        of the range breaks ties), so a wrist never spins a whole turn between runs unless every
        choice that avoids it leaves a run outside the limits.  A run no ``k`` keeps inside is left
        as it is.
    """
    q = np.array(q, dtype=float)
    n = len(q)
    if not n:
        return q
    two_pi = 2 * math.pi
    lower = np.asarray(lower, dtype=float)
    upper = np.asarray(upper, dtype=float)
    finite = np.isfinite(q[:, 0])
    step = np.zeros(n)
    if n > 1:
        d = np.abs(np.diff(q, axis=0))
        step[1:] = np.where(np.isfinite(d), d, 0.0).max(axis=1)
    start = np.asarray(breaks, bool) | (step > math.pi)
    start[1:] |= finite[1:] & ~finite[:-1]
    start[0] = True
    runs: list[tuple[int, int]] = []
    for first_row in np.flatnonzero(start & finite):
        end = int(first_row) + 1
        while end < n and finite[end] and not start[end]:
            end += 1
        runs.append((int(first_row), end))
    if not runs:
        return q
    mid = 0.5 * (lower + upper)
    for j in range(q.shape[1]):
        options = []
        for a, b in runs:
            lo_k = int(np.ceil((lower[j] - q[a:b, j].min()) / two_pi - 1e-12))
            hi_k = int(np.floor((upper[j] - q[a:b, j].max()) / two_pi + 1e-12))
            options.append(np.arange(lo_k, hi_k + 1) if lo_k <= hi_k else np.array([0]))
        a0 = runs[0][0]
        cost = 1e-3 * np.abs(q[a0, j] + two_pi * options[0] - mid[j])
        back = []
        for r in range(1, len(runs)):
            last = q[runs[r - 1][1] - 1, j] + two_pi * options[r - 1]
            first = q[runs[r][0], j] + two_pi * options[r]
            total = cost[None, :] + np.abs(first[:, None] - last[None, :])
            back.append(np.argmin(total, axis=1))
            cost = total.min(axis=1)
        pick = int(np.argmin(cost))
        for r in range(len(runs) - 1, -1, -1):
            a, b = runs[r]
            q[a:b, j] += two_pi * options[r][pick]
            if r:
                pick = int(back[r - 1][pick])
    return q


def joint_move_steps(q, trajectory, branch, max_step: float) -> np.ndarray:
    """(n,) bool: the step into sample i is a joint move (air link; branch change or a joint turning
    more than ``max_step`` rad)."""
    n = len(q)
    out = np.zeros(n, bool)
    if n < 2:
        return out
    in_pass = (trajectory.pass_index[1:] == trajectory.pass_index[:-1]) & (trajectory.pass_index[1:] >= 0) \
        & trajectory.contact[1:] & trajectory.contact[:-1]
    both = np.isfinite(q[1:, 0]) & np.isfinite(q[:-1, 0])
    d = np.abs(np.diff(q, axis=0))
    big = np.where(np.isfinite(d), d, 0.0).max(axis=1) > max_step
    out[1:] = both & ~in_pass & ((branch[1:] != branch[:-1]) | big)
    return out


def solve_trajectory(trajectory, model: RobotModel, cell: Cell | None = None, *, margins: Margins | None = None,
                     strict: bool = False, seed=None, warn: bool = True) -> JointSolution:
    """Joint values along ``trajectory`` on one continuous configuration branch.

    Parameters
    ----------
    trajectory : Trajectory
        TCP poses in the part frame (m).
    model : RobotModel
    cell : Cell, optional
        Part placement and tool (default: part at the base origin, TCP on the flange).
    margins : Margins, optional
        Singularity and limit margins (default :class:`Margins`).
    strict : bool
        Raise :class:`UnreachableError` on any unreachable sample instead of reporting it.
    seed : (6,) float, optional
        Start configuration of a numerical model, rad.
    warn : bool
        Log the unreachable poses as a warning (default).  Either way the sentence is the
        solution's ``warning``; a caller that trials many cells (the placement search) or reports
        warnings itself (a job) passes False.

    Returns
    -------
    JointSolution

    Raises
    ------
    UnreachableError
        With ``strict`` and an unreachable stretch (the message names the first stretches).
    """
    cell = Cell() if cell is None else cell
    margins = Margins() if margins is None else margins
    segs = segments(trajectory)
    flange = cell.flange2base(poses_from_trajectory(trajectory))
    n = len(trajectory)
    same_pass = np.zeros(n, bool)
    same_pass[1:] = (trajectory.pass_index[1:] == trajectory.pass_index[:-1]) & (trajectory.pass_index[1:] >= 0)
    q_all, feasible, reason = branch_table(flange, model, margins, seed=seed, same_pass=same_pass,
                                          part2base=cell.part2base, tool=cell.tool)
    clearance = clearance_from_contact(trajectory)
    branch = choose_branches(feasible, segs, clearance)
    rows = np.arange(n)
    ok = feasible[rows, branch]
    q = np.where(ok[:, None], q_all[rows, branch], np.nan)
    change = np.zeros(n, bool)
    change[1:] = branch[1:] != branch[:-1]
    q = align_turns(q, model.lower + margins.joint_limit, model.upper - margins.joint_limit, change)
    names = model.branch_names
    switches = []
    for s in np.flatnonzero(np.diff(branch)) + 1:
        after = trajectory.pass_index[s:][trajectory.contact[s:]]
        switches.append({"sample": int(s), "from": names[branch[s - 1]], "to": names[branch[s]],
                         "pass_after": int(after[0]) if len(after) else -1,
                         "clearance_m": float(min(clearance[s - 1], clearance[s]))})
    stretches = []
    msg = None
    bad = ~ok
    i = 0
    while i < n:
        if not bad[i]:
            i += 1
            continue
        j = i
        while j < n and bad[j] and trajectory.pass_index[j] == trajectory.pass_index[i]:
            j += 1
        why = np.bincount(reason[i:j, branch[i]], minlength=6)[1:]
        stretches.append(UnreachableStretch(start=i, stop=j, pass_index=int(trajectory.pass_index[i]),
                                            position=tuple(float(v) for v in trajectory.position[i]),
                                            reason=_REASONS[int(np.argmax(why)) + 1] + f" on branch {names[branch[i]]}"))
        i = j
    if stretches:
        msg = (f"{int(bad.sum())} of {n} poses are unreachable for {model.name} in this cell; first: "
               + "; ".join(s.describe() for s in stretches[:3])
               + ". Move the part (--base, or --place) or choose a larger robot.")
        if not ok.any():
            # nothing to program: refused whether strict or not
            p_base = trajectory.position @ cell.part2base[:3, :3].T + cell.part2base[:3, 3]
            near = float(np.linalg.norm(p_base, axis=1).min())
            raise UnreachableError(f"none of the {n} poses is reachable for {model.name} in this cell (the nearest "
                                   f"lies {near:.2f} m from the robot base, its reach is about {model.reach:.2f} m); "
                                   "first: " + stretches[0].describe()
                                   + ". Move the part (--base, or --place) or choose a larger robot.")
        if strict:
            raise UnreachableError(msg)
        if warn:
            log.warning(msg)
    measures = {k: np.full(n, np.nan) for k in ("wrist", "elbow", "shoulder_m", "manipulability", "joint_limit_margin_rad")}
    if ok.any():
        m = model.singularity_measures(q[ok])
        for k, v in m.items():
            measures[k][ok] = v
        measures["joint_limit_margin_rad"][ok] = model.joint_limit_margin(q[ok])
    jm = joint_move_steps(q, trajectory, branch, margins.max_step)
    branch = np.where(ok, branch, -1)
    return JointSolution(q=q, branch=branch, reachable=ok, switches=switches, stretches=stretches,
                         measures=measures, branch_names=names, warning=msg, joint_move=jm, clearance=clearance)


def flips_inside_passes(solution: JointSolution, trajectory) -> int:
    """Number of branch changes between consecutive reachable samples of the same contact pass."""
    b = solution.branch
    same = (trajectory.pass_index[1:] == trajectory.pass_index[:-1]) & (trajectory.pass_index[1:] >= 0)
    both = (b[1:] >= 0) & (b[:-1] >= 0)
    return int(np.sum(same & both & (b[1:] != b[:-1])))
