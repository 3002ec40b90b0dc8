"""One trajectory from several run one after the other (the regions of a big part).

Each trajectory of :func:`swath.trajectory.time_path` starts and ends in the air, ``clearance`` above
its first and last pass.  :func:`join_trajectories` runs them in the order given, joined by a
straight air move at a constant speed from the end of one to the start of the next.  The joined
trajectory's passes are numbered on: pass ``j`` of the second trajectory becomes pass
``n_1 + j``, where ``n_1`` counts the passes of the first.

Where each part lands in the joined trajectory (its time shift and its first pass number) follows
from the ends of the parts before it alone (:class:`Ends`, :func:`join_offsets`), so the rows of
one part's stretch of ``trajectory.csv`` can be written (:func:`csv_rows`) as soon as the parts
before it are timed, without the others; the stretches, concatenated after
:func:`csv_header`, are the joined trajectory's file byte for byte.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .trajectory import CSV_COLUMNS, Trajectory


@dataclass(frozen=True)
class Ends:
    """What joining needs of one trajectory: its first and last times (s), its first and last
    positions (3,) (m), its pass count (``max(pass_index) + 1``, 0 without passes), its extra
    column names, its length and whether it starts or ends in contact."""

    t_first: float
    t_last: float
    start: tuple
    end: tuple
    n_passes: int
    extra: tuple
    n_samples: int
    contact_at_ends: bool

    @classmethod
    def of(cls, tr: Trajectory) -> Ends:
        n = len(tr)
        own = np.asarray(tr.pass_index)
        return cls(float(tr.t[0]) if n else 0.0, float(tr.t[-1]) if n else 0.0,
                   tuple(map(float, tr.position[0])) if n else (0.0,) * 3,
                   tuple(map(float, tr.position[-1])) if n else (0.0,) * 3,
                   int(own.max()) + 1 if (own >= 0).any() else 0, tuple(tr.extra), n,
                   bool(n and (tr.contact[0] or tr.contact[-1])))


def join_offsets(ends, *, link_speed: float) -> tuple[list[float], list[int], float]:
    """Time shifts (s) and first pass numbers of trajectories with ``ends`` (a sequence of
    :class:`Ends`) run in order, and the length of the air moves between them (m).

    Part ``i``'s samples are at ``t + shifts[i]`` in the joined trajectory and its pass ``j`` is
    pass ``first_pass[i] + j``; a later part only changes the figures of the parts after it.

    Raises
    ------
    InputError
        For no parts, a link speed that is not positive, an empty part, or one that starts or ends
        in contact.
    """
    ends = list(ends)
    if not ends:
        raise InputError("join_trajectories needs at least one trajectory")
    if not (np.isfinite(link_speed) and link_speed > 0):
        raise InputError(f"the link speed must be positive, in m/s; got {link_speed!r}")
    shifts: list[float] = []
    first_pass: list[int] = []
    shift, next_pass, link_length, last_time = 0.0, 0, 0.0, 0.0
    for i, e in enumerate(ends):
        if not e.n_samples:
            raise InputError(f"trajectory {i} to join is empty")
        if e.contact_at_ends:
            raise InputError(f"trajectory {i} to join starts or ends in contact; each must start and end in the air")
        if i:
            gap = float(np.linalg.norm(np.subtract(e.start, ends[i - 1].end)))
            link_length += gap
            # a strictly later first sample, even for a zero-length move
            shift = last_time + max(gap / link_speed, 1e-6) - e.t_first
        shifts.append(shift)
        first_pass.append(next_pass)
        last_time = float(np.float64(e.t_last) + np.float64(shift))
        next_pass += e.n_passes
    return shifts, first_pass, link_length


def _columns(tr: Trajectory, shift: float, first_pass: int, names) -> tuple[np.ndarray, np.ndarray, dict]:
    own = np.asarray(tr.pass_index)
    extra = {k: np.asarray(tr.extra[k]) if k in tr.extra else np.zeros(len(tr)) for k in names}
    return tr.t + shift, np.where(own >= 0, own + first_pass, -1), extra


def join_trajectories(trajectories, *, link_speed: float) -> Trajectory:
    """``trajectories`` (a sequence of Trajectory, not empty) run in order, as one Trajectory.

    Parameters
    ----------
    trajectories : sequence of Trajectory
        Each in the air at its start and end (as :func:`~swath.trajectory.time_path` makes them).
    link_speed : float
        Speed of the straight air moves between them, m/s.

    Returns
    -------
    Trajectory
        The samples of every trajectory, times shifted so each starts when the move to it ends;
        ``pass_index`` renumbered on; extra columns missing from a trajectory are 0 there; the first
        trajectory's metadata with ``joined_trajectories`` (count) and ``join_link_length_m``.
    """
    parts = list(trajectories)
    shifts, first_pass, link_length = join_offsets([Ends.of(tr) for tr in parts], link_speed=link_speed)
    names = list(dict.fromkeys(k for tr in parts for k in tr.extra))
    cols = [_columns(tr, s, f, names) for tr, s, f in zip(parts, shifts, first_pass)]
    extra = {k: np.concatenate([c[2][k] for c in cols]) for k in names}
    meta = dict(parts[0].metadata)
    meta.update(joined_trajectories=len(parts), join_link_length_m=link_length)
    return Trajectory(np.concatenate([c[0] for c in cols]), np.concatenate([tr.position for tr in parts]),
                      np.concatenate([tr.quaternion for tr in parts]), np.concatenate([tr.contact for tr in parts]),
                      np.concatenate([tr.feed for tr in parts]), np.concatenate([c[1] for c in cols]), extra=extra,
                      metadata=meta)


def csv_header(names) -> str:
    """The header line (with its newline) of the joined trajectory's ``trajectory.csv``, extra
    columns ``names`` (the union of the parts' extra columns, in order of first appearance)."""
    return ",".join(CSV_COLUMNS + ("feed", "pass") + tuple(names)) + "\n"


def csv_rows(tr: Trajectory, *, shift: float, first_pass: int, names) -> str:
    """The rows (no header) of ``tr``'s stretch of the joined trajectory's ``trajectory.csv``: its
    times shifted by ``shift`` (s), passes numbered from ``first_pass``, extra columns ``names``
    (0 where ``tr`` has none), as :func:`join_offsets` and :func:`csv_header` place it."""
    t, pass_index, extra = _columns(tr, shift, first_pass, names)
    one = Trajectory(t, tr.position, tr.quaternion, tr.contact, tr.feed, pass_index, extra=extra)
    text = one.to_csv_text()
    return text[text.index("\n") + 1:]
