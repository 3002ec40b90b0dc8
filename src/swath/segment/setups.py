"""Closed parts all round: orientations of the part on the table (setups) that together expose
every face, with their count kept small.

In a setup the part rests on the table with a direction ``up`` (part frame) pointing away from it;
the tool comes from above.  A triangle is *exposed* in a setup when its outward normal is within
``max_angle`` of ``up``, it stands at least ``table_clearance`` above the table (the lowest
point of the part along ``up``), and the part itself does not hide it from above: the ray from it
along ``up`` leaves the part (:func:`swath.segment.sight.visible`), so the floor of a pocket or the
face under an overhang is not counted as reached from a direction the part blocks.  :func:`plan_setups` picks setups among the 26 directions of the
part's principal frame (cube faces, edges and corners) by greedy set cover of the area, assigns each
triangle to the chosen setup facing it best (the greedy count is then improved by an exhaustive
search over all combinations of up to four directions), and widens each setup's area by a band of exposed
triangles around it (``overlap``) so that the passes of neighbouring setups overlap at their seams.
"""

from __future__ import annotations

import itertools
import logging
from dataclasses import dataclass

import numpy as np

from ..errors import InfeasibleError, InputError
from ..io.part import Part
from .sight import visible

log = logging.getLogger(__name__)

#: Default largest angle between a triangle's normal and the setup's up direction, rad (75°).
DEFAULT_MAX_ANGLE = np.radians(75.0)


@dataclass(frozen=True, eq=False)
class Setup:
    """One orientation of a closed part on the table.

    Attributes
    ----------
    index : int
        1-based number of the setup, in the order they are run.
    up : (3,) float
        Unit direction in the part frame that points up, away from the table (the tool comes from it).
    assigned : (m,) bool
        Triangles this setup is responsible for.
    planned : (m,) bool
        Triangles planned on in this setup: ``assigned`` and an exposed band around it.
    faces : tuple of int
        Ids of the part faces with triangles assigned to this setup.
    area : float
        Area of the assigned triangles, m².
    hidden : float
        Area (m²) of the triangles to finish that face ``up`` within the angle but that the part
        hides from it (line of sight): what a judgement by the normal's angle alone would have
        counted as exposed.
    """

    index: int
    up: np.ndarray
    assigned: np.ndarray
    planned: np.ndarray
    faces: tuple
    area: float
    hidden: float = 0.0


def candidate_directions(part: Part) -> np.ndarray:
    """(26, 3) unit directions: the part's principal axes, their sums in pairs and in threes."""
    _, axes = part.surface.principal_axes
    dirs = []
    for c in itertools.product((-1, 0, 1), repeat=3):
        if any(c):
            d = np.asarray(c, float) @ axes
            dirs.append(d / np.linalg.norm(d))
    # cube faces first: the greedy cover prefers them on ties
    dirs.sort(key=lambda d: -np.abs(d @ axes.T).max())
    return np.array(dirs)


def exposure(part: Part, up: np.ndarray, *, max_angle: float = DEFAULT_MAX_ANGLE,
             table_clearance: float = 0.0, line_of_sight: bool = True) -> np.ndarray:
    """(m,) bool: triangles exposed to a tool coming from ``up`` (3,) with the part on the table:
    facing it within ``max_angle`` (rad), ``table_clearance`` (m) above the table and, with
    ``line_of_sight``, not hidden from ``up`` by the part itself."""
    s = part.surface
    up = np.asarray(up, float) / np.linalg.norm(up)
    facing = s.face_normals @ up >= np.cos(max_angle)
    if table_clearance > 0:
        height = s.vertices @ up
        low = height[s.faces].min(axis=1) - height.min()
        facing &= low >= table_clearance
    if line_of_sight and facing.any():
        facing &= visible(s, up, facing, closed=part.closed)
    return facing


#: Largest number of setups searched exhaustively (all combinations of the candidates) for a
#: smaller cover than the greedy one.
EXACT_SEARCH_UP_TO = 4


def _fewest(exposed: np.ndarray, normals: np.ndarray, area: np.ndarray, dirs: np.ndarray, below: int):
    """The smallest set of candidate directions (at most ``min(below, EXACT_SEARCH_UP_TO)``) that
    exposes every triangle, best aligned (area-weighted mean of each triangle's best cosine) among
    the smallest; None when no such set exists.

    ``exposed`` is ``(k, m)`` bool over the triangles to cover.  Triangles are grouped by exposure
    pattern (a group is covered when its pattern has a chosen direction), so the search runs over
    the distinct patterns, not the triangles.
    """
    patterns = np.unique(exposed.T, axis=0)      # (g, k): the distinct exposure patterns
    for size in range(1, min(below, EXACT_SEARCH_UP_TO) + 1):
        best, best_score = None, -np.inf
        combos = np.array(list(itertools.combinations(range(len(dirs)), size)), dtype=np.int64)
        for chunk in np.array_split(combos, max(1, len(combos) // 2048)):
            covers = patterns[:, chunk].any(axis=2).all(axis=0)                  # (c,)
            for combo in chunk[covers]:
                cosine = (normals @ dirs[combo].T).max(axis=1)
                score = float(cosine @ area)
                if score > best_score:
                    best, best_score = [int(i) for i in combo], score
        if best is not None:
            return best
    return None


def plan_setups(part: Part, *, max_angle: float = DEFAULT_MAX_ANGLE, table_clearance: float = 0.0,
                overlap: float = 0.0, max_setups: int = 8, directions=None,
                line_of_sight: bool = True) -> list[Setup]:
    """Setups that together expose the part's selected triangles, few of them.

    Parameters
    ----------
    part : Part
        A closed part, outward normals; its selected triangles are to be covered.
    max_angle : float
        Largest angle between a triangle's normal and the tool's direction, rad.
    table_clearance : float
        Triangles lower than this above the table (m) cannot be reached in a setup.
    overlap : float
        Width (m) of the band of exposed triangles added around each setup's own (e.g. a pad
        radius): neighbouring setups' passes then overlap at the seams.
    max_setups : int
        Refuse when more setups than this would be needed.
    directions : (k, 3) float, optional
        Candidate up directions (default :func:`candidate_directions`).
    line_of_sight : bool
        Count a triangle exposed only where the part does not hide it from the setup's up
        direction (:func:`exposure`); False judges by the normal's angle alone.

    Returns
    -------
    list of Setup
        Largest assigned area first.

    Raises
    ------
    InfeasibleError
        When some selected area is exposed in no candidate setup, or more than ``max_setups``
        setups are needed.
    """
    if not (0 < max_angle <= np.pi / 2):
        raise InputError(f"max_angle must lie in (0, 90°], got {np.degrees(max_angle):.3g}°")
    s = part.surface
    todo = part.work_triangles.copy()
    dirs = candidate_directions(part) if directions is None else np.asarray(directions, float)
    exposed = np.array([exposure(part, d, max_angle=max_angle, table_clearance=table_clearance,
                                 line_of_sight=line_of_sight) for d in dirs])
    area = s.face_areas
    reachable = exposed.any(axis=0)
    lost = todo & ~reachable
    if area[lost].sum() > 1e-6 * area[todo].sum():
        facing = np.array([exposure(part, d, max_angle=max_angle, table_clearance=table_clearance,
                                    line_of_sight=False) for d in dirs]).any(axis=0)
        hidden = float(area[lost & facing].sum())
        angle = float(area[lost & ~facing].sum())
        parts = []
        if angle > 0:
            parts.append(f"{angle * 1e4:.3g} cm² of the part faces no setup direction within {np.degrees(max_angle):.0f}° "
                         "(raise the angle)")
        if hidden > 0:
            parts.append(f"{hidden * 1e4:.3g} cm² is hidden by the part itself from every setup direction that "
                         "faces it (a pocket, bore or overhang)")
        raise InfeasibleError("; ".join(parts) + "; keep those areas out (--keep-out, e.g. a polygon or mask) or "
                              "finish them by hand")
    todo &= reachable
    chosen: list[int] = []
    left = todo.copy()
    while area[left].sum() > 1e-9 * max(area[todo].sum(), 1e-300):
        gain = (exposed & left) @ area
        best = int(np.argmax(gain))
        if gain[best] <= 0:
            break
        chosen.append(best)
        left &= ~exposed[best]
        if len(chosen) > max_setups:
            raise InfeasibleError(f"the part needs more than {max_setups} setups to expose every selected face")
    fewer = _fewest(exposed[:, todo], s.face_normals[todo], area[todo], dirs, len(chosen) - 1)
    if fewer is not None:
        chosen = fewer
    # each triangle to the chosen setup that faces it best
    score = np.where(exposed[chosen], (s.face_normals @ dirs[chosen].T).T, -np.inf)
    owner = np.argmax(score, axis=0)
    setups = []
    centroid = s.vertices[s.faces].mean(axis=1)
    from scipy.spatial import cKDTree

    for k, d in enumerate(chosen):
        assigned = todo & (owner == k)
        if not assigned.any():
            continue
        planned = assigned.copy()
        if overlap > 0:
            near, _ = cKDTree(centroid[assigned]).query(centroid, distance_upper_bound=overlap)
            planned |= np.isfinite(near) & exposed[d] & part.work_triangles
        faces = tuple(sorted({int(i) for i in part.face_ids[assigned]}))
        hidden = 0.0
        if line_of_sight:
            by_angle = exposure(part, dirs[d], max_angle=max_angle, table_clearance=table_clearance,
                                line_of_sight=False)
            hidden = float(area[todo & by_angle & ~exposed[d]].sum())
        setups.append(Setup(0, dirs[d], assigned, planned, faces, float(area[assigned].sum()), hidden))
    setups.sort(key=lambda st: -st.area)
    return [Setup(i + 1, st.up, st.assigned, st.planned, st.faces, st.area, st.hidden)
            for i, st in enumerate(setups)]
