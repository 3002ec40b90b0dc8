"""Helpers every planner shares: option checks, the feed/cross directions in the best-fit plane,
the automatic-direction rule, and turning slice fragments into tagged passes."""

from __future__ import annotations

import logging
import math

import numpy as np

from ..core import Pass
from ..errors import InputError
from ..surface.frames import feed_and_cross  # noqa: F401  (the planners' feed/cross rule)
from ..surface.geometry import normalize

log = logging.getLogger("swath.plan")

#: Default shortest pass, as a fraction of the pad radius.
MIN_PASS_FRACTION = 0.25


def is_number(x) -> bool:
    """A real number (not a bool)."""
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, bool)


def positive(name: str, value) -> float:
    """``value`` as a float if it is a positive finite length (m); else :class:`InputError` naming it."""
    if not (is_number(value) and math.isfinite(value) and value > 0):
        raise InputError(f"{name} must be a positive, finite length in metres, got {value!r}")
    return float(value)


def check_min_pass_length(min_pass_length, pad_radius: float) -> float:
    """The shortest pass kept, m: ``MIN_PASS_FRACTION · R`` when None, else a checked length >= 0."""
    if min_pass_length is None:
        return MIN_PASS_FRACTION * pad_radius
    if not (is_number(min_pass_length) and math.isfinite(min_pass_length) and min_pass_length >= 0):
        raise InputError(f"min_pass_length must be a finite length >= 0 m, got {min_pass_length!r}")
    return float(min_pass_length)


def split_direction(direction) -> tuple[float | None, np.ndarray | None]:
    """A planner's ``direction`` option as ``(angle, vector)``: None (choose automatically), an
    angle in rad from the part's first principal axis, or a (3,) vector in the part frame."""
    if direction is None or (isinstance(direction, str) and direction == "auto"):
        return None, None
    if is_number(direction):
        if not math.isfinite(direction):
            raise InputError(f"direction angle must be a finite number of radians, got {direction!r}")
        return float(direction), None
    return None, np.asarray(direction, float)


def select_direction(rows, max_gap: float, planner: str):
    """The direction rule shared by the planners that pick their own feed direction.

    ``rows`` are ``(angle_rad, predicted_gap_fraction, predicted_length_m, payload)``.  The shortest
    candidate whose gap is at most ``max_gap`` wins, near-ties (within 2 %) going to the earlier
    candidate (the principal axis first); if none qualifies, the one with the smallest gap.
    Returns the winning row and a one-line description for metadata.
    """
    ok = [r for r in rows if r[1] <= max_gap]
    if ok:
        shortest = min(r[2] for r in ok)
        best = next(r for r in ok if r[2] <= 1.02 * shortest)
    else:
        best = min(rows, key=lambda r: r[1])
    summary = ", ".join(f"{math.degrees(r[0]):.0f} deg: {r[2]:.2f} m, gap {100 * r[1]:.2f}%" for r in rows)
    rule = f"auto: shortest predicted path with gap <= {100 * max_gap:.1f}% among ({summary})"
    log.info("%s direction %s", planner, rule)
    return (float(best[0]),) + tuple(best[1:]), rule


def plane_passes(polylines, feed, face_normals, point_spacing, *, region: int = 0) -> list[Pass]:
    """Slice fragments as passes, level by level (the fragment's plane or level-set index), each
    running along ``feed`` and, on a level, in order along it; resampled at ``point_spacing`` (m).
    The ``order`` stage sequences them (snake order alternates every other level)."""
    from .resampling import resample_all

    by_plane: dict[int, list] = {}
    for pl in polylines:
        by_plane.setdefault(pl.plane, []).append(pl)
    ordered = []
    for plane in sorted(by_plane):
        oriented = [_orient(pl, feed) for pl in by_plane[plane]]
        oriented.sort(key=lambda pl: float(pl.points[0] @ feed))
        ordered += oriented
    passes = []
    for pl, sm in zip(ordered, resample_all(ordered, point_spacing)):    # resample(pl, point_spacing) each
        assert sm.values is not None          # slices carry the vertex normals as values
        normals = normalize(sm.values)
        bad = np.linalg.norm(normals, axis=1) < 0.5
        if bad.any():   # opposite vertex normals across a fold: fall back to the facet normal
            normals[bad] = face_normals[sm.faces[bad]]
        passes.append(Pass(sm.points, normals, level=int(pl.plane), region=region))
    return passes


def _orient(pl, travel):
    """Run an open fragment along ``travel``; start a closed loop at its rearmost point."""
    proj = pl.points @ travel
    if not pl.closed:
        return pl if proj[-1] >= proj[0] else pl.reversed()
    return pl.rolled(int(np.argmin(proj[:-1])))


def slice_passes(surface, faces, cross, offset: float, feed, point_spacing: float, *, edges=None) -> list:
    """The fragments of the plane ``x·cross = offset`` through ``surface``'s faces ``faces``, each
    running along ``feed``, resampled at ``point_spacing``: ``[(points (k, 3), normals (k, 3))]``.
    ``edges``: ``mesh_edges(surface.faces[faces])`` when the caller has it."""
    from .slicing import slice_mesh

    out = []
    for p in plane_passes(slice_mesh(surface.vertices, surface.faces[faces], cross, [offset], values=surface.normals,
                                     edges=edges),
                          feed, surface.face_normals[faces], point_spacing):
        out.append((p.points, p.normals))
    return out
