"""Pad wear along a job: the media's age, media changes, and the feed that compensates the wear.

Abrasive cuts less as it wears.  swath models the Preston coefficient falling with the media's
time in contact ``a`` (s), ``k_p(a) = k_p0 · exp(−λ a)`` (:attr:`swath.contact.Tool.wear_rate` is
``λ``, calibrated from trials that record ``pad_age_s``, see :mod:`swath.simulate.calibrate`).

Media changes
-------------
A cell changes the abrasive on a schedule (every 300 s of sanding, say) or when it has lost a
share of its cut.  :func:`media_schedule` walks the trajectory's contact passes in time order and
changes the media *between* passes, retracted: before a pass that would take the media's age past
the limit (``every``, or ``−ln(1 − loss) / λ`` for a removal-rate ``loss``), unless the media is
still fresh (a single pass longer than the limit runs on one media).

On ``trajectory.csv`` the changes are two extra columns (:func:`trajectory_with_media`):

=============  ===================================================================================
column         meaning
=============  ===================================================================================
``media``      number of media changes made before the sample (0 on the first media); it steps up
               by one at the middle sample of the air move between the last pass on the old media
               and the first on the new, which is where the robot waits for the operator
``media_age``  the media's time in contact at the sample, s (0 just after a change)
=============  ===================================================================================

The robot programs write a comment and a stop for the operator at each step
(:func:`program_lines`).  The pause itself is not in the trajectory's time.

Feed compensation
-----------------
With ``λ > 0`` the removal rate at a sample is ``exp(−λ a)`` times the fresh media's.
:func:`compensate_wear` slows every contact step by that factor (feed ``v · exp(−λ a)``, dwell
``/ exp(−λ a)``), so that each point gets the removal the plan was made for.  Slowing lengthens
the time in contact, which ages the media faster: the ages, the changes and the feed are iterated
to a fixed point (a few rounds; the factor changes by ``λ·Δa`` per round).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, replace

import numpy as np

from ..errors import InputError

log = logging.getLogger(__name__)

#: What the programs tell the operator at a media change.
OPERATOR_MESSAGE = "swath: change the abrasive (media change {n}), then continue"


@dataclass(frozen=True)
class MediaSchedule:
    """The media along a trajectory.

    Attributes
    ----------
    media : (n,) int
        Media changes made before each sample (0 on the first media).
    age : (n,) float
        The media's time in contact at each sample, s.
    factor : (n,) float
        Removal rate over the fresh media's, ``exp(−λ · age)``.
    change_index : (m,) int
        Sample index of each change (the first sample on the new media: the middle of the air move).
    change_time : (m,) float
        Trajectory time of each change, s.
    limit : float
        Age at which the media is changed, s (inf: never).
    """

    media: np.ndarray
    age: np.ndarray
    factor: np.ndarray
    change_index: np.ndarray
    change_time: np.ndarray
    limit: float

    @property
    def changes(self) -> int:
        """Number of media changes."""
        return len(self.change_index)


def change_limit(wear_rate: float, *, every: float | None = None, loss: float | None = None) -> float:
    """Age (s of contact) at which media is changed: ``every``, or the age at which the removal rate
    has fallen by ``loss`` (a fraction, needs ``wear_rate`` > 0, 1/s), whichever comes first; inf
    when neither is given."""
    limit = math.inf
    if every is not None:
        if not (math.isfinite(every) and every > 0):
            raise InputError(f"media change interval must be a positive time, got {every!r} s")
        limit = float(every)
    if loss is not None:
        if not 0 < loss < 1:
            raise InputError(f"media change loss must lie between 0 and 100 %, got {loss!r}")
        if not wear_rate > 0:
            raise InputError("a media change at a loss of removal rate needs a pad that wears (a wear rate > 0)")
        limit = min(limit, -math.log1p(-loss) / wear_rate)
    return limit


def _contact_steps(trajectory) -> np.ndarray:
    """(n−1,) bool: steps whose two ends are in contact on the same pass."""
    c = np.asarray(trajectory.contact, bool)
    p = np.asarray(trajectory.pass_index)
    return c[1:] & c[:-1] & (p[1:] == p[:-1])


def media_schedule(trajectory, wear_rate: float = 0.0, *, every: float | None = None,
                   loss: float | None = None, changes=None) -> MediaSchedule:
    """The media's age and changes along ``trajectory`` (module docstring).

    Parameters
    ----------
    trajectory : Trajectory
        Timed samples with ``contact`` and ``pass_index``.
    wear_rate : float
        ``λ``, 1/s.
    every : float, optional
        Change the media at this age, s of contact.
    loss : float, optional
        Change the media when its removal rate has fallen by this fraction.
    changes : sequence of int, optional
        Change the media at these sample indices instead (off contact, between passes): the
        ages along a schedule already decided.

    Returns
    -------
    MediaSchedule
    """
    limit = change_limit(wear_rate, every=every, loss=loss)
    t = np.asarray(trajectory.t, float)
    n = len(t)
    steps = _contact_steps(trajectory)
    dt = np.where(steps, np.diff(t), 0.0)
    # contact runs: maximal stretches of contact steps
    starts = np.flatnonzero(steps & ~np.concatenate([[False], steps[:-1]]))
    ends = np.flatnonzero(steps & ~np.concatenate([steps[1:], [False]])) + 1        # last sample of each run
    media = np.zeros(n, int)
    age = np.zeros(n)
    fixed = None if changes is None else sorted(int(c) for c in changes)
    changes = []
    current, prev_end = 0.0, None
    cum = np.concatenate([[0.0], np.cumsum(dt)])
    for s, e in zip(starts, ends):
        length = cum[e] - cum[s]
        if fixed is not None:
            lo = -1 if prev_end is None else prev_end
            due = [c for c in fixed if lo < c <= s]
            if due:
                changes.append(due[-1])
                current = 0.0
        elif current > 0 and current + length > limit * (1 + 1e-12):
            # in the middle of the air move between the two passes (retracted, clear of the part)
            at = (prev_end + 1 + s) // 2 if prev_end is not None else s
            changes.append(int(at))
            current = 0.0
        age[s:e + 1] = current + (cum[s:e + 1] - cum[s])
        current += length
        if e + 1 < n:
            nxt = starts[starts > e]
            stop = nxt[0] if len(nxt) else n
            age[e + 1:stop] = current
        prev_end = e
    for c in changes:
        media[c:] += 1
    # off-contact samples after a change and before the next pass: fresh media
    for k, c in enumerate(changes):
        nxt = starts[starts >= c]
        age[c:(nxt[0] if len(nxt) else n)] = 0.0
    factor = np.exp(-wear_rate * age)
    idx = np.array(changes, int)
    return MediaSchedule(media, age, factor, idx, t[idx] if len(idx) else np.zeros(0), limit)


def trajectory_with_media(trajectory, schedule: MediaSchedule):
    """``trajectory`` with the ``media`` and ``media_age`` columns of ``schedule`` (module docstring)."""
    extra = dict(trajectory.extra)
    extra["media"] = schedule.media.astype(float)
    extra["media_age"] = schedule.age
    meta = dict(trajectory.metadata)
    meta["media_changes"] = int(schedule.changes)
    return replace(trajectory, extra=extra, metadata=meta)


def compensate_wear(trajectory, wear_rate: float, *, every: float | None = None, loss: float | None = None,
                    rounds: int = 20):
    """Slow the feed as the media wears so that the removal stays as planned (module docstring).

    Parameters
    ----------
    trajectory : Trajectory
        Timed for fresh media.
    wear_rate : float
        ``λ``, 1/s (0 returns the trajectory unchanged).
    every, loss : optional
        The media change rule of :func:`media_schedule`.
    rounds : int
        Fixed-point rounds of the ages and the feed (after three that place the changes).

    Returns
    -------
    (Trajectory, MediaSchedule)
        The re-timed trajectory (``t``, ``feed``, and the angular velocity columns ``wx, wy, wz``
        scaled on contact) and its media schedule.
    """
    sched = media_schedule(trajectory, wear_rate, every=every, loss=loss)
    if not wear_rate > 0:
        return trajectory, sched
    t0 = np.asarray(trajectory.t, float)
    dt0 = np.diff(t0)
    steps = _contact_steps(trajectory)
    contact = np.asarray(trajectory.contact, bool)

    def retimed(factor):
        mid = 0.5 * (factor[1:] + factor[:-1])
        t = np.concatenate([[t0[0]], t0[0] + np.cumsum(np.where(steps, dt0 / mid, dt0))])
        scale = np.where(contact, factor, 1.0)
        extra = {k: (np.asarray(v, float) * scale if k in ("wx", "wy", "wz") else v)
                 for k, v in trajectory.extra.items()}
        meta = dict(trajectory.metadata)
        meta["wear_compensation"] = True
        return replace(trajectory, t=t, feed=np.asarray(trajectory.feed, float) * scale, extra=extra, metadata=meta)

    # The changes follow the ages, which follow the feed.  With the changes kept, the ages and the
    # feed iterate to their fixed point; then the changes are placed again on the slower trajectory,
    # until they stay where they are.
    out = trajectory
    for _ in range(6):
        keep = sched.change_index
        for _ in range(max(1, rounds)):
            out = retimed(sched.factor)
            new = media_schedule(out, wear_rate, every=every, loss=loss, changes=keep)
            converged = np.max(np.abs(new.factor - sched.factor)) < 1e-10 if len(sched.factor) else True
            sched = new
            if converged:
                break
        out = retimed(sched.factor)
        again = media_schedule(out, wear_rate, every=every, loss=loss)
        if np.array_equal(again.change_index, sched.change_index):
            return out, sched
        settled, sched = sched, again
    # The changes alternate between two placements: keep the last one the feed was fitted to.
    log.info("the media changes alternate with the compensated feed; a media runs up to %.1f s of contact against the "
             "%.1f s limit", float(settled.age.max()), settled.limit)
    return retimed(settled.factor), settled


def program_lines(fmt: str, n: int, indent: str = "  ") -> list[str]:
    """The statements that stop the robot for media change ``n`` (1-based) in program format ``fmt``
    (``urscript``, ``rapid``, ``krl``): a comment and a wait for the operator."""
    msg = OPERATOR_MESSAGE.format(n=n)
    if fmt == "urscript":
        return [f"{indent}# media change {n}: the robot waits, retracted, while the operator changes the abrasive",
                f'{indent}popup("{msg}", "swath: media change", False, False, blocking=True)']
    if fmt == "rapid":
        return [f"{indent}! media change {n}: the robot waits, retracted, while the operator changes the abrasive",
                f'{indent}TPWrite "{msg}";', f"{indent}Stop;"]
    if fmt == "krl":
        return [f"{indent}; media change {n}: the robot waits, retracted, while the operator changes the abrasive",
                f"{indent}HALT"]
    raise InputError(f"no media change statements for program format {fmt!r}")


def changes_before(trajectory, idx) -> np.ndarray:
    """(len(idx),) int: media changes between kept sample ``idx[k−1]`` and ``idx[k]`` (the count
    the program must stop for before moving to ``idx[k]``); zeros when the trajectory has no
    ``media`` column."""
    media = trajectory.extra.get("media") if hasattr(trajectory, "extra") else None
    idx = np.asarray(idx, int)
    if media is None or len(idx) == 0:
        return np.zeros(len(idx), int)
    m = np.asarray(media, float)[idx].round().astype(int)
    return np.concatenate([[m[0]], np.diff(m)])


def media_stops(fmt: str, trajectory, idx, indent: str = "  ") -> dict:
    """Kept-sample position ``k`` -> the statements a program in ``fmt`` runs before moving to
    ``idx[k]`` (a media change happened in between); empty without a ``media`` column."""
    counts = changes_before(trajectory, idx)
    media = np.cumsum(counts)
    out: dict = {}
    for k in np.flatnonzero(counts > 0):
        lines: list[str] = []
        for n in range(int(media[k] - counts[k]) + 1, int(media[k]) + 1):
            lines += program_lines(fmt, n, indent)
        out[int(k)] = lines
    return out


def media_header(trajectory, comment: str = "#") -> str:
    """Comment lines naming the media changes (time and count) for a file that cannot hold
    statements (the ROS 2 JointTrajectory YAML); empty without changes."""
    media = trajectory.extra.get("media") if hasattr(trajectory, "extra") else None
    if media is None:
        return ""
    m = np.asarray(media, float).round().astype(int)
    steps = np.flatnonzero(np.diff(m) > 0) + 1
    return "".join(f"{comment} media change {int(m[i])} at t = {float(trajectory.t[i]):.3f} s: stop, retracted, and "
                   f"let the operator change the abrasive\n" for i in steps)
