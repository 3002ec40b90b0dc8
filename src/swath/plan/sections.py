"""Passes on given cutting planes: the raster slices of a region of a bigger part.

The raster planner lays its planes over the surface it is given.  A region of a big part
(:mod:`swath.segment.tiles`) must instead cut on the planes laid over the *whole* part, so that
the passes of neighbouring regions sit one spacing apart across the seam as they do inside a
region.  :func:`section_passes` slices on exactly the planes it is given and runs the passes of
even plane indices along ``feed`` and of odd ones against it: in plane order they make one snake
over the whole part, whichever region each plane belongs to.
"""

from __future__ import annotations

import numpy as np

from ..core.toolpath import ToolPath
from ..errors import InfeasibleError, InputError
from .common import plane_passes
from .slicing import slice_mesh


def section_passes(surface, *, axis, offsets, levels, feed, point_spacing: float = 1e-3,
                   min_pass_length: float = 0.0) -> ToolPath:
    """Slice ``surface`` on the planes ``p · axis = offsets[i]`` and order the passes plane by plane.

    Parameters
    ----------
    surface : Surface
        The region's surface (normals toward the tool).
    axis : (3,) float
        Plane normal (any length, not zero).
    offsets : (p,) float
        Plane heights along the unit axis, m, ascending.
    levels : (p,) int
        The planes' indices among all the part's planes: each pass gets its plane's ``level``; even
        levels run along ``feed``, odd ones against it.
    feed : (3,) float
        Feed direction of the even levels (any length; its part along ``axis`` is ignored).
    point_spacing : float
        Arc-length step between pass points, m.
    min_pass_length : float
        Slice fragments shorter than this (m) are left out.

    Returns
    -------
    ToolPath
        ``planner="sections"``, passes in level order (within a level, along the feed); metadata
        ``n_planes``, ``n_passes``, ``first_level``, ``point_spacing_m``, ``order_hint="snake"``.
    """
    axis = np.asarray(axis, float)
    norm = float(np.linalg.norm(axis))
    offsets, levels = np.asarray(offsets, float), np.asarray(levels, int)
    if not (norm > 0 and offsets.ndim == 1 and offsets.shape == levels.shape and len(offsets)):
        raise InputError(f"section_passes needs a non-zero axis and as many levels as offsets (at least one); got "
                         f"axis {axis.tolist()}, {offsets.shape} offsets and {levels.shape} levels")
    axis = axis / norm
    feed = np.asarray(feed, float)
    feed = feed - (feed @ axis) * axis
    if not np.linalg.norm(feed) > 1e-9:
        raise InputError("section_passes: the feed direction must not be parallel to the plane normal")
    feed /= np.linalg.norm(feed)
    slices = slice_mesh(surface.vertices, surface.faces, axis, offsets, values=surface.normals)
    kept = [pl for pl in slices if pl.length >= min_pass_length]
    passes = plane_passes(kept, feed, surface.face_normals, point_spacing)
    ordered = []
    for p in passes:                     # plane_passes: level = index into offsets, in level order
        level = int(levels[p.level])
        ordered.append(p.replace(level=level) if level % 2 == 0 else p.replace(level=level).reversed())
    # a level's fragments run the other way on odd levels: keep the snake by visiting them backwards
    out: list = []
    for level in sorted({p.level for p in ordered}):
        group = [p for p in ordered if p.level == level]
        out.extend(group if level % 2 == 0 else group[::-1])
    if not out:
        raise InfeasibleError(f"no pass on {len(offsets)} planes of {surface.name or 'the region'}: every slice is "
                              f"shorter than {min_pass_length * 1e3:.3g} mm")
    meta = {"n_planes": len(offsets), "n_passes": len(out), "first_level": int(levels[0]),
            "point_spacing_m": float(point_spacing), "feed_direction": feed.tolist(),
            "cross_direction": axis.tolist(), "order_hint": "snake"}
    return ToolPath(surface, tuple(out), "sections", metadata=meta)
