"""Step-overs in contact: join consecutive passes when the pad can slide from one to the next.

Wang's local paths (§4, Figure 4-2) are *continuous*: inside a region the pad steps over from one
sweep line to the next along the region's edge without lifting, and only the moves between regions
are air.  Here a move from a pass's end ``p`` to the next pass's start ``q`` is made in contact when

* ``|q - p| <= max_gap`` (a step-over, not a crossing), and
* the straight chord from ``p`` to ``q``, sampled every ``step``, lies within ``tolerance`` of the
  surface everywhere (it does not cross a gap between pieces or a hole wider than that), and
* the chord's samples moved to their closest points on the surface form an unbroken path: no two
  consecutive points more than ``3 * step`` apart (where the chord cuts the corner of a hole or of
  the outline, the path runs along its edge instead, as the pad centre does at the passes' ends),
  no longer than ``MAX_DETOUR`` times the chord (a ragged edge would make it zigzag), and
* the tool turns by at most ``MAX_TURN`` from the pass's end onto the chord and from the chord onto
  the next pass (a step-over turns by about 90 degrees; a move back along the pass is no step-over,
  and the trajectory stage would crawl through the reversal at the angular-speed limit).

The connector is that path, with the surface's smooth normals; :func:`join_passes` splices it between the two passes, so the
trajectory runs it as contact (it removes material along the edge like any contact move) and the
link, with its retract and approach, disappears.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..core import Pass, ToolPath
from ..errors import InputError

#: Consecutive points of a joined pass closer than this (m) are merged.
MIN_STEP = 1e-5
#: Longest contact step-over path as a multiple of its chord.
MAX_DETOUR = 1.2
#: Largest turn of the travel direction onto and off a contact step-over, rad (120 degrees).
MAX_TURN = 2 * np.pi / 3


class StepOverJoiner:
    """Decides which moves between passes the pad makes in contact, and how.

    Parameters
    ----------
    surface : Surface
        The part.
    max_gap : float
        Longest step-over made in contact, m (e.g. 1.5 x the pass spacing).
    tolerance : float, optional
        Largest distance of the chord from the surface, m (default ``0.25 * max_gap``).
    step : float, optional
        Sample spacing of the chord and of the connector, m (default ``max_gap / 20``, at most 2 mm).

    Raises
    ------
    InputError
        On a non-positive ``max_gap``, ``tolerance`` or ``step``.
    """

    def __init__(self, surface, *, max_gap: float, tolerance: float | None = None, step: float | None = None):
        for name, value in (("max_gap", max_gap), ("tolerance", tolerance), ("step", step)):
            if value is not None and not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
                raise InputError(f"join {name} must be a positive length in m, got {value!r}")
        self.surface = surface
        self.max_gap = float(max_gap)
        self.tolerance = 0.25 * self.max_gap if tolerance is None else float(tolerance)
        self.step = min(self.max_gap / 20.0, 2e-3) if step is None else float(step)

    def _samples(self, p: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, int]:
        """``((m, 3) points along the chords from p (k, 3) to q (k, 3), s)``: m = k * s, s points per chord."""
        s = max(int(np.ceil(self.max_gap / self.step)), 1) + 1
        w = np.linspace(0.0, 1.0, s)[None, :, None]
        return (p[:, None, :] * (1 - w) + q[:, None, :] * w).reshape(-1, 3), s

    def feasible(self, p, q, exit_tangent=None, entry_tangent=None) -> np.ndarray:
        """(k,) bool: whether each move ``p[i] -> q[i]`` ((k, 3) float, m) can be made in contact;
        with the travel directions at the end of the pass left (``exit_tangent``, (k, 3)) and at
        the start of the pass entered (``entry_tangent``), the turns onto and off the move count."""
        p = np.atleast_2d(np.asarray(p, float))
        q = np.atleast_2d(np.asarray(q, float))
        chord = q - p
        length = np.linalg.norm(chord, axis=1)
        ok = length <= self.max_gap
        u = chord / np.maximum(length, 1e-12)[:, None]
        for t in (exit_tangent, entry_tangent):
            if t is not None:
                t = np.atleast_2d(np.asarray(t, float))
                t = t / np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-12)
                ok &= (length < 1e-9) | ((t * u).sum(axis=1) >= np.cos(MAX_TURN) - 1e-12)
        if not ok.any():
            return ok
        pts, s = self._samples(p[ok], q[ok])
        closest, dist, _ = self.surface.closest_points(pts)
        closest = closest.reshape(-1, s, 3)
        jump = np.linalg.norm(np.diff(closest, axis=1), axis=2).max(axis=1)
        chord_step = np.linalg.norm(q[ok] - p[ok], axis=1) / (s - 1)
        path = np.linalg.norm(np.diff(closest, axis=1), axis=2).sum(axis=1)
        ok[np.flatnonzero(ok)] = (dist.reshape(-1, s).max(axis=1) <= self.tolerance) & \
            (jump <= 3 * np.maximum(chord_step, 1e-9) + 1e-9) & \
            (path <= MAX_DETOUR * (s - 1) * chord_step + 1e-9)
        return ok

    def connector(self, p, q, exit_tangent=None, entry_tangent=None):
        """The contact move from ``p`` to ``q`` ((3,) float, m): ``(points (m, 3), normals (m, 3))``
        on the surface, first and last the surface points nearest ``p`` and ``q``; None when the
        move cannot be made in contact (see :meth:`feasible`; tangents (3,) optional)."""
        p = np.asarray(p, float)
        q = np.asarray(q, float)
        tangents = [None if t is None else np.asarray(t, float)[None] for t in (exit_tangent, entry_tangent)]
        if not self.feasible(p[None], q[None], *tangents)[0]:
            return None
        n = max(int(np.ceil(np.linalg.norm(q - p) / self.step)), 1) + 1
        w = np.linspace(0.0, 1.0, n)[:, None]
        closest, _, face = self.surface.closest_points(p * (1 - w) + q * w)
        return closest, self.surface.interpolate_normals(closest, face)

    def pairs(self, exit_points: np.ndarray, entry_points: np.ndarray, exit_tangents=None,
              entry_tangents=None) -> tuple[np.ndarray, np.ndarray]:
        """Index pairs ``(i, j)`` (two (k,) int arrays) with ``exit_points[i] -> entry_points[j]``
        ((N, 3) and (M, 3) float, m; travel directions there (N, 3) and (M, 3), optional) feasible
        in contact."""
        tree = cKDTree(np.asarray(entry_points, float))
        near = tree.query_ball_point(np.asarray(exit_points, float), r=self.max_gap)
        i = np.array([a for a, js in enumerate(near) for _ in js], dtype=np.int64)
        j = np.array([b for js in near for b in js], dtype=np.int64)
        if len(i) == 0:
            return i, j
        ok = self.feasible(exit_points[i], entry_points[j],
                           None if exit_tangents is None else np.asarray(exit_tangents)[i],
                           None if entry_tangents is None else np.asarray(entry_tangents)[j])
        return i[ok], j[ok]


def join_passes(toolpath: ToolPath, joiner: StepOverJoiner) -> ToolPath:
    """``toolpath`` with every two consecutive passes that ``joiner`` can connect in contact made
    one pass: the first, the connector, the second (level, region and kind of the first; kind
    ``pass`` if either is a full pass).  Links are dropped (route them again).

    Returns
    -------
    ToolPath
        ``metadata`` gains ``joined_step_overs`` (how many moves became contact),
        ``joined_contact_m`` (the connectors' length, m) and ``join_max_gap_m``.
    """
    out: list[Pass] = []
    joined = 0
    extra = 0.0
    for p in toolpath.passes:
        if out:
            conn = joiner.connector(out[-1].points[-1], p.points[0], out[-1].points[-1] - out[-1].points[-2],
                                    p.points[1] - p.points[0])
            if conn is not None:
                prev = out[-1]
                pts, nrm = conn
                kind = "pass" if "pass" in (prev.kind, p.kind) else prev.kind
                # connector points the snapping to an edge made (nearly) coincide are dropped: the
                # trajectory stage cannot time a turn on a zero-length step
                mid_p, mid_n = _thin(np.vstack([prev.points[-1:], pts[1:-1], p.points[:1]]),
                                     np.vstack([prev.normals[-1:], nrm[1:-1], p.normals[:1]]), 0.25 * joiner.step)
                all_p = np.vstack([prev.points, mid_p[1:-1], p.points])
                all_n = np.vstack([prev.normals, mid_n[1:-1], p.normals])
                keep = np.r_[True, np.linalg.norm(np.diff(all_p, axis=0), axis=1) >= MIN_STEP]
                out[-1] = prev.replace(points=all_p[keep], normals=all_n[keep], kind=kind)
                joined += 1
                extra += float(np.linalg.norm(np.diff(mid_p, axis=0), axis=1).sum())
                continue
        out.append(p)
    meta = dict(toolpath.metadata, joined_step_overs=joined, joined_contact_m=extra, join_max_gap_m=joiner.max_gap)
    return toolpath.replace(passes=tuple(out), links=None, metadata=meta)


def _thin(points: np.ndarray, normals: np.ndarray, min_step: float):
    """Drop points closer than ``min_step`` (m) to the last kept one; the first and last stay (the
    last replaces a kept point too close to it)."""
    keep = [0]
    for i in range(1, len(points) - 1):
        if np.linalg.norm(points[i] - points[keep[-1]]) >= min_step:
            keep.append(i)
    if len(keep) > 1 and np.linalg.norm(points[-1] - points[keep[-1]]) < min_step:
        keep.pop()
    keep.append(len(points) - 1)
    return points[keep], normals[keep]
