"""Whether the tool's bodies dip below the table top at a pose.

The tool is rigid on the flange, so its height over the table follows from the flange pose alone,
whatever branch the arm takes: a pose that puts the holder or the spindle into the table (a pass
running along the part's lowest edge with the tool near horizontal) cannot be run by any arm and
becomes a gap, like a pose out of reach.
"""

from __future__ import annotations

import numpy as np


def tool_below(tool, flange2base, floor_z: float) -> np.ndarray:
    """(n,) bool: a cylinder of ``tool.bodies`` reaches below ``floor_z`` (m, base frame).

    Parameters
    ----------
    tool : ToolBody
        Bodies posed in the flange frame; cylinders (the default sander's holder and spindle) are
        measured exactly, other shapes are left to the collision check.
    flange2base : (n, 4, 4) float
        Flange poses, m.
    floor_z : float
        The table top's height in the base frame, m.

    The lowest point of a cylinder of radius r and length l whose axis has the unit direction a
    and centre c is ``c_z - |a_z| l / 2 - r sqrt(1 - a_z²)``.
    """
    from ..cell.bodies import Cylinder

    flange2base = np.asarray(flange2base, dtype=float).reshape(-1, 4, 4)
    out = np.zeros(len(flange2base), bool)
    for body in tool.bodies:
        shape = body.shape
        if not isinstance(shape, Cylinder):
            continue
        body2base = flange2base @ np.asarray(body.body2frame, dtype=float)
        az = np.clip(np.abs(body2base[:, 2, 2]), 0.0, 1.0)
        lowest = body2base[:, 2, 3] - 0.5 * shape.length * az - shape.radius * np.sqrt(1.0 - az ** 2)
        out |= lowest < floor_z
    return out
