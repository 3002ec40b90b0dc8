"""The :class:`ToolPath` record: passes on a surface, the neutral record every stage reads.

A planner returns a ToolPath whose passes carry where they came from (``level``, ``region``,
``kind``); the ``order`` stage sequences them and may add the air :class:`Link` between
consecutive passes; the ``trajectory`` stage times the result.  Records are immutable: stages
return new ones (:meth:`ToolPath.replace`).
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError

#: Kinds of pass: a regular coverage pass, or a short touch-up across a pocket the pad rode over.
PASS_KINDS = ("pass", "touch_up")


def _frozen_copy(a, shape_hint: str) -> np.ndarray:
    out = np.array(a, dtype=float, copy=True)
    out.setflags(write=False)
    return out


@dataclass(frozen=True, eq=False)
class Pass:
    """One contact pass: points on the surface in processing order.

    Attributes
    ----------
    points : (k, 3) float
        TCP positions on the surface, m, part frame, k >= 2 (copied; read-only).
    normals : (k, 3) float
        Unit surface normals toward the tool at ``points`` (tool z is minus these).
    level : int
        The planner's index of the slice, level set or generation the pass lies on (-1: none).
        Passes on one level are parallel neighbours of the passes on the next.
    region : int
        Index of the region (piece of the part, or segment) the pass covers (0 for one region).
    kind : str
        ``"pass"`` (regular coverage) or ``"touch_up"`` (a short pass across a pocket).
    """

    points: np.ndarray
    normals: np.ndarray
    level: int = -1
    region: int = 0
    kind: str = "pass"

    def __post_init__(self):
        p = _frozen_copy(self.points, "points")
        n = _frozen_copy(self.normals, "normals")
        if p.ndim != 2 or p.shape[1] != 3 or len(p) < 2 or n.shape != p.shape:
            raise InputError(f"a pass needs points and normals of the same shape (k>=2, 3), got {p.shape} and {n.shape}")
        if not (np.isfinite(p).all() and np.isfinite(n).all()):
            raise InputError("a pass has NaN or infinite points or normals")
        if self.kind not in PASS_KINDS:
            raise InputError(f"pass kind must be one of {PASS_KINDS}, got {self.kind!r}")
        object.__setattr__(self, "points", p)
        object.__setattr__(self, "normals", n)
        object.__setattr__(self, "level", int(self.level))
        object.__setattr__(self, "region", int(self.region))

    @functools.cached_property
    def length(self) -> float:
        """Polyline length, m (worked out once: the points are read-only)."""
        return float(np.linalg.norm(np.diff(self.points, axis=0), axis=1).sum())

    def reversed(self) -> Pass:
        """The same pass run the other way."""
        return dataclasses.replace(self, points=self.points[::-1], normals=self.normals[::-1])

    def replace(self, **changes) -> Pass:
        """A copy with some fields changed (``level``, ``region``, ``kind``, ...)."""
        return dataclasses.replace(self, **changes)


@dataclass(frozen=True, eq=False)
class Link:
    """An air move between two consecutive passes.

    Attributes
    ----------
    waypoints : (m, 3) float
        The route from the lift-off point of one pass to the touch-down point of the next, m,
        both ends included, clear of the part.
    """

    waypoints: np.ndarray

    def __post_init__(self):
        w = _frozen_copy(self.waypoints, "waypoints")
        if w.ndim != 2 or w.shape[1] != 3 or len(w) < 2 or not np.isfinite(w).all():
            raise InputError(f"a link needs finite waypoints of shape (m>=2, 3), got {w.shape}")
        object.__setattr__(self, "waypoints", w)

    @property
    def length(self) -> float:
        """Route length, m."""
        return float(np.linalg.norm(np.diff(self.waypoints, axis=0), axis=1).sum())


@dataclass(frozen=True, eq=False)
class ToolPath:
    """Contact passes on one surface, in processing order, and optionally the links between them.

    Attributes
    ----------
    surface : Surface
        The surface the passes lie on.
    passes : tuple of Pass
        In processing order; each pass's direction is its feed direction.
    planner : str
        Name of the planner that made it (``"raster"``, ...).
    metadata : dict
        Planner settings and facts (spacing in m, direction, ...); JSON-serialisable values, units
        in the key names.
    links : tuple of Link, optional
        ``len(passes) - 1`` air moves, link ``i`` from the end of pass ``i`` to the start of pass
        ``i + 1``; None until the ``order`` stage routes them (the trajectory stage then routes
        them itself).
    """

    surface: object
    passes: tuple
    planner: str
    metadata: dict = field(default_factory=dict)
    links: tuple | None = None

    def __post_init__(self):
        passes = tuple(self.passes)
        if not all(isinstance(p, Pass) for p in passes):
            raise InputError("ToolPath passes must be Pass records")
        object.__setattr__(self, "passes", passes)
        object.__setattr__(self, "metadata", dict(self.metadata))
        if self.links is not None:
            links = tuple(self.links)
            if len(links) != max(len(passes) - 1, 0):
                raise InputError(f"a tool path with {len(passes)} passes needs {max(len(passes) - 1, 0)} links, "
                                 f"got {len(links)}")
            object.__setattr__(self, "links", links)

    @property
    def contact_length(self) -> float:
        """Total length of the passes, m."""
        return float(sum(p.length for p in self.passes))

    @property
    def n_points(self) -> int:
        """Number of pass points."""
        return int(sum(len(p.points) for p in self.passes))

    @property
    def regions(self) -> np.ndarray:
        """(n_passes,) int region of each pass."""
        return np.array([p.region for p in self.passes], dtype=int)

    @property
    def levels(self) -> np.ndarray:
        """(n_passes,) int level of each pass."""
        return np.array([p.level for p in self.passes], dtype=int)

    def replace(self, **changes) -> ToolPath:
        """A copy with some fields changed; changing ``passes`` drops links unless new ones are given."""
        if "passes" in changes and "links" not in changes:
            changes["links"] = None
        return dataclasses.replace(self, **changes)
