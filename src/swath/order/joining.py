"""Step-overs in contact: join consecutive passes when the pad can slide from one to the next.

Wang's local paths (§4, Figure 4-2) are *continuous*: inside a region the pad steps over from one
sweep line to the next along the region's edge without lifting, and only the moves between regions
are air.  Here a move from a pass's end ``p`` to the next pass's start ``q`` is made in contact when

* ``|q - p| <= max_gap`` (a step-over, not a crossing), and
* the straight chord from ``p`` to ``q``, sampled every ``step``, lies within ``tolerance`` of the
  surface everywhere (it does not cross a gap between pieces or a hole wider than that), and
* the chord's samples moved to their closest points on the surface form an unbroken path: no two
  consecutive points more than ``3 * step`` apart (where the chord cuts the corner of a hole or of
  the outline, the path runs along its edge instead, as the pad centre does at the passes' ends).

The connector is that path, with the surface's smooth normals; :func:`join_passes` splices it between the two passes, so the
trajectory runs it as contact (it removes material along the edge like any contact move) and the
link, with its retract and approach, disappears.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..core import Pass, ToolPath
from ..errors import InputError


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

    def _samples(self, p: np.ndarray, q: np.ndarray) -> np.ndarray:
        """(m, 3) points along the chords from ``p`` (k, 3) to ``q`` (k, 3), m = k * s, s per chord."""
        s = max(int(np.ceil(self.max_gap / self.step)), 1) + 1
        w = np.linspace(0.0, 1.0, s)[None, :, None]
        return (p[:, None, :] * (1 - w) + q[:, None, :] * w).reshape(-1, 3), s

    def feasible(self, p, q) -> np.ndarray:
        """(k,) bool: whether each move ``p[i] -> q[i]`` ((k, 3) float, m) can be made in contact."""
        p = np.atleast_2d(np.asarray(p, float))
        q = np.atleast_2d(np.asarray(q, float))
        ok = np.linalg.norm(q - p, axis=1) <= self.max_gap
        if not ok.any():
            return ok
        pts, s = self._samples(p[ok], q[ok])
        closest, dist, _ = self.surface.closest_points(pts)
        closest = closest.reshape(-1, s, 3)
        jump = np.linalg.norm(np.diff(closest, axis=1), axis=2).max(axis=1)
        chord_step = np.linalg.norm(q[ok] - p[ok], axis=1) / (s - 1)
        ok[np.flatnonzero(ok)] = (dist.reshape(-1, s).max(axis=1) <= self.tolerance) & \
            (jump <= 3 * np.maximum(chord_step, 1e-9) + 1e-9)
        return ok

    def connector(self, p, q):
        """The contact move from ``p`` to ``q`` ((3,) float, m): ``(points (m, 3), normals (m, 3))``
        on the surface, first and last the surface points nearest ``p`` and ``q``; None when the
        move cannot be made in contact."""
        p = np.asarray(p, float)
        q = np.asarray(q, float)
        if not self.feasible(p[None], q[None])[0]:
            return None
        n = max(int(np.ceil(np.linalg.norm(q - p) / self.step)), 1) + 1
        w = np.linspace(0.0, 1.0, n)[:, None]
        closest, _, face = self.surface.closest_points(p * (1 - w) + q * w)
        return closest, self.surface.interpolate_normals(closest, face)

    def pairs(self, exit_points: np.ndarray, entry_points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Index pairs ``(i, j)`` (two (k,) int arrays) with ``exit_points[i] -> entry_points[j]``
        ((N, 3) and (M, 3) float, m) feasible in contact."""
        tree = cKDTree(np.asarray(entry_points, float))
        near = tree.query_ball_point(np.asarray(exit_points, float), r=self.max_gap)
        i = np.array([a for a, js in enumerate(near) for _ in js], dtype=np.int64)
        j = np.array([b for js in near for b in js], dtype=np.int64)
        if len(i) == 0:
            return i, j
        ok = self.feasible(exit_points[i], entry_points[j])
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
            conn = joiner.connector(out[-1].points[-1], p.points[0])
            if conn is not None:
                prev = out[-1]
                pts, nrm = conn
                kind = "pass" if "pass" in (prev.kind, p.kind) else prev.kind
                out[-1] = prev.replace(points=np.vstack([prev.points, pts[1:-1], p.points]),
                                       normals=np.vstack([prev.normals, nrm[1:-1], p.normals]), kind=kind)
                joined += 1
                extra += float(np.linalg.norm(np.diff(np.vstack([prev.points[-1:], pts[1:-1], p.points[:1]]),
                                                      axis=0), axis=1).sum())
                continue
        out.append(p)
    meta = dict(toolpath.metadata, joined_step_overs=joined, joined_contact_m=extra, join_max_gap_m=joiner.max_gap)
    return toolpath.replace(passes=tuple(out), links=None, metadata=meta)
