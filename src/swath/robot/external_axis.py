"""The external axis (a rotary positioner) in the robot programs.

A trajectory run with a positioner carries the axis angle per sample in its extra column
:data:`AXIS_COLUMN` (rad).  The writers of :mod:`swath.robot.programs` put it in the programs:

* RAPID — the first external axis ``eax_a`` of every ``robtarget`` and ``jointtarget`` (deg);
* KRL — ``E1`` of every ``E6POS`` (deg);
* ``joints.csv`` — a ``positioner`` column (rad) after the robot's joints;
* URScript — refused: URScript has no standard external axis (:func:`check_axis_formats`).

With a positioner the Cartesian targets are in the robot base frame (the work object / ``$BASE`` is
the base itself): each target is where the TCP is when the axis stands at that target's angle, so the
controller moves the arm and the axis together, target by target.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError

#: The trajectory's extra column with the positioner's axis angle, rad.
AXIS_COLUMN = "positioner"


def axis_angles(trajectory) -> np.ndarray | None:
    """(n,) the positioner's axis angle per sample, rad, or None without a positioner."""
    extra = getattr(trajectory, "extra", {})
    return None if AXIS_COLUMN not in extra else np.asarray(extra[AXIS_COLUMN], dtype=float)


def eax_text(trajectory, i: int) -> str:
    """RAPID ``extjoint`` of sample ``i``: ``eax_a`` the axis angle (deg), the others unused (9E9)."""
    theta = axis_angles(trajectory)
    first = "9E9" if theta is None else f"{math.degrees(theta[i]):.6f}"
    return f"[{first},9E9,9E9,9E9,9E9,9E9]"


def e1_text(trajectory, i: int) -> str:
    """KRL ``E1`` of sample ``i`` (deg; 0.0 without a positioner)."""
    theta = axis_angles(trajectory)
    return "0.0" if theta is None else f"{math.degrees(theta[i]):.6f}"


def header_lines(trajectory, comment: str) -> list[str]:
    """The programs' statement about the external axis (empty without a positioner)."""
    if axis_angles(trajectory) is None:
        return []
    return [f"{comment} positioner: the part turns on a rotary positioner (external axis 1: RAPID eax_a, KRL E1, deg); "
            "the work object / $BASE is the robot base, so the targets are TCP poses in the robot base frame with the "
            "axis angle they belong to,",
            f"{comment} so the arm and the axis move together from target to target (every sample is a target: at most "
            "2 mm of TCP travel and 20 ms apart on the part)"]


def axis_samples(reachable, joint_move) -> np.ndarray:
    """(m,) indices of the samples a Cartesian program with a positioner writes: every reachable sample
    but the inner rows of a joint move (the controller interpolates those itself).  The targets are not
    thinned: the TCP may stand still in the base frame while the axis turns the part under it."""
    jm = np.asarray(joint_move, bool)
    inner = jm.copy()
    inner[:-1] &= jm[1:]
    inner[-1:] = False
    return np.flatnonzero(np.asarray(reachable, bool) & ~inner)


def check_axis_formats(formats) -> None:
    """Refuse program formats that cannot carry the positioner's axis (URScript)."""
    bad = [f for f in (str(x).strip().lower() for x in formats) if f == "urscript"]
    if bad:
        raise InputError("URScript has no standard external axis, so a job on a rotary positioner cannot be written "
                         "as URScript; write rapid, krl, ros or csv (joints.csv has the axis angle in its "
                         "`positioner` column) and drive the positioner from its own controller")
