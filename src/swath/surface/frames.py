"""The feed and cross directions of a surface: a direction in its best-fit plane and the normal
of the planes that cut across it (raster slices, sweep lines)."""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError
from .geometry import normalize


def feed_and_cross(surface, *, angle: float = 0.0, direction=None) -> tuple[np.ndarray, np.ndarray]:
    """Unit feed direction in the best-fit plane ``(3,)`` and the cutting-plane normal ``(3,)``.

    The best-fit plane's normal (third principal axis) is oriented toward the tool (with the
    area-weighted mean facet normal); the feed is the first principal axis rotated by ``angle``
    about it, or ``direction`` projected into the plane; the cross direction is normal × feed.

    The axes are :attr:`Surface.principal_axes` (exact triangle moments).
    """
    axes = surface.principal_axes[1]
    a0, a2 = np.asarray(axes[0], float), np.asarray(axes[2], float)
    mean_normal = (surface.face_normals * surface.face_areas[:, None]).sum(axis=0)
    if a2 @ mean_normal < 0:
        a2 = -a2
    a1 = np.cross(a2, a0)
    if direction is None:
        feed = math.cos(angle) * a0 + math.sin(angle) * a1
    else:
        d = np.asarray(direction, float).reshape(-1)
        if d.shape != (3,) or not np.isfinite(d).all() or np.linalg.norm(d) == 0:
            raise InputError(f"direction must be a finite, non-zero 3-vector, got {direction!r}")
        d = d / np.linalg.norm(d)
        feed = d - (d @ a2) * a2
        if np.linalg.norm(feed) < 1e-6:
            raise InputError(f"direction {d.round(4).tolist()} is along the part's mean normal "
                             f"{a2.round(4).tolist()}; give a direction along the surface")
    cross = normalize(np.cross(a2, feed))
    feed = np.cross(cross, a2)
    return feed, cross
