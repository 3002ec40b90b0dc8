"""The :class:`ToolPath` record: ordered passes on a surface, the output of every planner."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError


@dataclass(frozen=True, eq=False)
class Pass:
    """One contact pass: points on the surface in processing order.

    Attributes
    ----------
    points : (k, 3) float
        TCP positions on the surface, m, part frame, k >= 2.
    normals : (k, 3) float
        Unit surface normals toward the tool at ``points`` (tool z is minus these).
    """

    points: np.ndarray
    normals: np.ndarray

    def __post_init__(self):
        p = np.asarray(self.points, float)
        n = np.asarray(self.normals, float)
        if p.ndim != 2 or p.shape[1] != 3 or len(p) < 2 or n.shape != p.shape:
            raise InputError(f"a pass needs points and normals of the same shape (k>=2, 3), got {p.shape} and {n.shape}")
        if not (np.isfinite(p).all() and np.isfinite(n).all()):
            raise InputError("a pass has NaN or infinite points or normals")
        p.setflags(write=False)
        n.setflags(write=False)
        object.__setattr__(self, "points", p)
        object.__setattr__(self, "normals", n)

    @property
    def length(self) -> float:
        """Polyline length, m."""
        return float(np.linalg.norm(np.diff(self.points, axis=0), axis=1).sum())

    def reversed(self) -> "Pass":
        """The same pass run the other way."""
        return Pass(self.points[::-1].copy(), self.normals[::-1].copy())


@dataclass(frozen=True, eq=False)
class ToolPath:
    """Ordered contact passes on one surface, as a planner returns them.

    The links between passes (retract, air move, approach) are added by the trajectory stage.

    Attributes
    ----------
    surface : Surface
        The surface the passes lie on.
    passes : tuple of Pass
        In processing order; each pass's direction is its feed direction.
    planner : str
        Name of the planner that made it (``"raster"``, ...).
    metadata : dict
        Planner settings and facts (spacing in m, direction, ...); JSON-serialisable values.
    """

    surface: object
    passes: tuple
    planner: str
    metadata: dict = field(default_factory=dict)

    def __post_init__(self):
        object.__setattr__(self, "passes", tuple(self.passes))

    @property
    def contact_length(self) -> float:
        """Total length of the passes, m."""
        return float(sum(p.length for p in self.passes))

    @property
    def n_points(self) -> int:
        return int(sum(len(p.points) for p in self.passes))
