"""One trajectory from several run one after the other (the regions of a big part).

Each trajectory of :func:`swath.trajectory.time_path` starts and ends in the air, ``clearance`` above
its first and last pass.  :func:`join_trajectories` runs them in the order given, joined by a
straight air move at a constant speed from the end of one to the start of the next.  The joined
trajectory's passes are numbered on: pass ``j`` of the second trajectory becomes pass
``n_1 + j``, where ``n_1`` counts the passes of the first.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .trajectory import Trajectory


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
    if not parts:
        raise InputError("join_trajectories needs at least one trajectory")
    if not (np.isfinite(link_speed) and link_speed > 0):
        raise InputError(f"the link speed must be positive, in m/s; got {link_speed!r}")
    for i, tr in enumerate(parts):
        if not len(tr):
            raise InputError(f"trajectory {i} to join is empty")
        if tr.contact[0] or tr.contact[-1]:
            raise InputError(f"trajectory {i} to join starts or ends in contact; each must start and end in the air")
    names = list(dict.fromkeys(k for tr in parts for k in tr.extra))
    t: list[np.ndarray] = []
    pass_index: list[np.ndarray] = []
    shift, first_pass, link_length = 0.0, 0, 0.0
    for i, tr in enumerate(parts):
        if i:
            gap = float(np.linalg.norm(tr.position[0] - parts[i - 1].position[-1]))
            link_length += gap
            # a strictly later first sample, even for a zero-length move
            shift = t[-1][-1] + max(gap / link_speed, 1e-6) - tr.t[0]
        t.append(tr.t + shift)
        own = np.asarray(tr.pass_index)
        pass_index.append(np.where(own >= 0, own + first_pass, -1))
        first_pass += int(own.max()) + 1 if (own >= 0).any() else 0
    extra = {k: np.concatenate([tr.extra.get(k, np.zeros(len(tr))) for tr in parts]) for k in names}
    meta = dict(parts[0].metadata)
    meta.update(joined_trajectories=len(parts), join_link_length_m=link_length)
    return Trajectory(np.concatenate(t), np.concatenate([tr.position for tr in parts]),
                      np.concatenate([tr.quaternion for tr in parts]), np.concatenate([tr.contact for tr in parts]),
                      np.concatenate([tr.feed for tr in parts]), np.concatenate(pass_index), extra=extra,
                      metadata=meta)
