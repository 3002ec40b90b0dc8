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
``greedy`` from the first pass, always the unvisited pass with an end nearest the current end
``index``  the planner's order and directions unchanged
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


def greedy(toolpath: ToolPath, *, start: np.ndarray | None = None) -> ToolPath:
    """Nearest end first: from ``start`` (m, default the first pass's start) always the unvisited
    pass with an end nearest the current position, run from that end."""
    passes = list(toolpath.passes)
    if not passes:
        return _with(toolpath, passes, "greedy")
    starts = np.array([p.points[0] for p in passes])
    ends = np.array([p.points[-1] for p in passes])
    left = np.ones(len(passes), bool)
    pos = starts[0] if start is None else np.asarray(start, float)
    out = []
    for _ in range(len(passes)):
        d0 = np.where(left, np.linalg.norm(starts - pos, axis=1), np.inf)
        d1 = np.where(left, np.linalg.norm(ends - pos, axis=1), np.inf)
        i0, i1 = int(np.argmin(d0)), int(np.argmin(d1))
        if d0[i0] <= d1[i1]:
            out.append(passes[i0])
            left[i0] = False
            pos = ends[i0]
        else:
            out.append(passes[i1].reversed())
            left[i1] = False
            pos = starts[i1]
    return _with(toolpath, out, "greedy")


def index(toolpath: ToolPath) -> ToolPath:
    """The passes as given."""
    return _with(toolpath, list(toolpath.passes), "index")


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
