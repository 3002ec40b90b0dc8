"""Simple pass orderings: the planner's levels in snake order, zig-zag, nearest end, as given.

Every method takes a :class:`~swath.core.ToolPath` whose passes carry ``level`` and ``region``
and returns a new one with the passes re-sequenced (and reversed where the method runs a pass the
other way); the links are left to be routed.

=========  ===========================================================================================
method     order
=========  ===========================================================================================
``snake``  region by region; levels in increasing order; inside a level the passes as the planner
           emitted them (along the feed); every other level (counted among the levels that have
           passes) runs backwards: its passes in reverse order, each reversed — boustrophedon
``zigzag`` the planner's order; each pass starts at the end nearer the previous pass's end
=========  ===========================================================================================
"""

from __future__ import annotations

import numpy as np

from ..core import ToolPath
from ..errors import InputError


def snake(toolpath: ToolPath) -> ToolPath:
    """Boustrophedon: levels in order per region, every other level run backwards."""
    passes = toolpath.passes
    out = []
    regions = sorted({p.region for p in passes})
    for region in regions:
        by_level: dict[int, list] = {}
        for p in passes:
            if p.region == region:
                by_level.setdefault(p.level, []).append(p)
        for k, level in enumerate(sorted(by_level)):
            group = by_level[level]
            out.extend(group if k % 2 == 0 else [p.reversed() for p in group[::-1]])
    return _with(toolpath, out, "snake")


def zigzag(toolpath: ToolPath) -> ToolPath:
    """The planner's order; each pass starts at the end nearer the previous pass's end."""
    passes = list(toolpath.passes)
    out = passes[:1]
    for p in passes[1:]:
        end = out[-1].points[-1]
        if np.linalg.norm(p.points[-1] - end) < np.linalg.norm(p.points[0] - end):
            p = p.reversed()
        out.append(p)
    return _with(toolpath, out, "zigzag")


def air_estimate(passes) -> float:
    """Straight-line distance from each pass's end to the next pass's start, summed, m (a lower
    bound of the air travel, used to compare orders)."""
    if len(passes) < 2:
        return 0.0
    ends = np.array([p.points[-1] for p in passes[:-1]])
    starts = np.array([p.points[0] for p in passes[1:]])
    return float(np.linalg.norm(starts - ends, axis=1).sum())


def _with(toolpath: ToolPath, passes: list, method: str) -> ToolPath:
    if len(passes) != len(toolpath.passes):
        raise InputError("ordering lost passes")            # a bug, not a user error
    meta = dict(toolpath.metadata)
    meta["order_method"] = method
    meta["order_air_estimate_m"] = air_estimate(passes)
    return toolpath.replace(passes=tuple(passes), metadata=meta)
