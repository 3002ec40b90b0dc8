"""Folds at a part's rim: pass stretches where the surface turns so sharply that the tool would crawl.

A pass that runs over a fold turns the tool frame with the surface normal: at a rate ``ρ`` (rad
per metre of travel) the angular speed limit ``ω_max`` holds the feed to ``ω_max / ρ``.  A scan's
rim often curls over (bezier_dac_scan: the surface turns by 85 degrees within 2 mm of its edge), and
a raster laid across it crawls there at 3 mm/s against the 50 mm/s feed: the pad dwells on the fold
and grinds it 20 times as deep as the part's inside (`W-HOT-SPOT`, docs/guide/hot-spots.md).

:func:`cut_rim_folds` cuts such stretches out of the passes, as the uniform planner cuts its own
passes at sharp turns: the pad lifts before the fold and lands after it.  A stretch is cut where all
of these hold:

* the limit holds the feed below :data:`HOLD_FRACTION` of it (``ω_max / ρ < HOLD_FRACTION · v``);
* over the run of such segments the normal turns by :data:`RIDGE_NET_TURN` or more from its start
  to its end (a scan's noise holds the feed in short runs that turn back and forth: those stay);
* the run comes within a pad radius of the part's open edge (a fold at the rim; a ridge inside the
  part, the blade's nose, is the planners' matter: :mod:`swath.cli.ridge_turn`).
"""

from __future__ import annotations

import logging

import numpy as np

log = logging.getLogger(__name__)

#: The feed counts as held where the angular speed limit allows less than this fraction of it.
HOLD_FRACTION = 0.5

#: A held stretch counts as a ridge only where the normal turns at least this much from its start to
#: its end, rad: a pass crossing the blade's nose turns by about 3 rad there, while on a scan
#: (bezier_dac_scan) the normals' noise holds the feed over 4.8 % of the raster's length in stretches
#: that turn back and forth, which no other planner's passes avoid.
RIDGE_NET_TURN = 1.0

#: Pieces of a cut pass shorter than this fraction of the pad radius are dropped (as the uniform
#: planner drops its pieces under R/4): a stub left on a rim's flange beyond the fold is not a pass.
MIN_PIECE_FRACTION = 0.25


def rotation_per_metre(points: np.ndarray, normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rate at which the surface normal turns along a pass, rad/m, per segment, and the
    segments' lengths, m.

    Parameters
    ----------
    points : (k, 3) float
        The pass's points, m.
    normals : (k, 3) float
        Unit surface normals there.

    Returns
    -------
    rate : (k - 1,) float
        The angle between neighbouring normals over the segment's length, rad/m (0 on a segment of
        no length).
    length : (k - 1,) float
        m.
    """
    p = np.asarray(points, float)
    n = np.asarray(normals, float)
    length = np.linalg.norm(np.diff(p, axis=0), axis=1)
    cos = np.clip(np.einsum("ij,ij->i", n[1:], n[:-1]), -1.0, 1.0)
    angle = np.arccos(cos)
    rate = np.divide(angle, length, out=np.zeros_like(angle), where=length > 1e-12)
    return rate, length


def ridge_runs(normals: np.ndarray, held: np.ndarray) -> np.ndarray:
    """``held`` (a pass's (k - 1,) segments where the limit holds the feed) kept only on the runs of
    held segments over which the unit ``normals`` ((k, 3)) turn by :data:`RIDGE_NET_TURN` or more
    from the run's first point to its last."""
    out = np.asarray(held, bool).copy()
    if not out.any():
        return out
    n = np.asarray(normals, float)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], out.astype(np.int8), [0]])))
    for a, b in zip(edges[::2], edges[1::2]):      # segments a..b-1: points a..b
        if np.arccos(np.clip(float(n[a] @ n[b]), -1.0, 1.0)) < RIDGE_NET_TURN:
            out[a:b] = False
    return out


def cut_rim_folds(toolpath, surface, *, feed: float, omega_max: float | None, pad_radius: float):
    """``toolpath`` with the stretches of its passes that crawl over a fold at the rim cut out
    (module notes).

    Parameters
    ----------
    toolpath : ToolPath
        The planner's passes (before ordering).
    surface : Surface
        The part (its open boundary).
    feed : float
        The job's feed, m/s.
    omega_max : float or None
        The angular speed limit, rad/s (None: no limit, nothing is cut).
    pad_radius : float
        m: a run within it of the open edge is a fold at the rim.

    Returns
    -------
    ToolPath
        The same object where nothing is cut; else the cut passes (pieces shorter than
        :data:`MIN_PIECE_FRACTION` of the pad radius dropped), ``metadata`` gaining ``rim_fold_cuts`` (stretches
        cut) and ``rim_fold_length_m`` (their contact length).
    """
    if omega_max is None or not omega_max > 0 or not toolpath.passes:
        return toolpath
    from ..core import Pass
    from ..surface.surface import farther_from_boundary

    passes, cuts, cut_length = [], 0, 0.0
    for p in toolpath.passes:
        rate, length = rotation_per_metre(p.points, p.normals)
        runs = ridge_runs(p.normals, omega_max / np.maximum(rate, 1e-12) < HOLD_FRACTION * feed)
        if not runs.any():
            passes.append(p)
            continue
        at_rim = ~farther_from_boundary(p.points, surface, pad_radius)
        keep = np.ones(len(p.points), bool)
        edges = np.flatnonzero(np.diff(np.concatenate([[0], runs.astype(np.int8), [0]])))
        for a, b in zip(edges[::2], edges[1::2]):          # segments a..b-1: points a..b
            if at_rim[a:b + 1].any():
                keep[a:b + 1] = False
                cuts += 1
                cut_length += float(length[a:b].sum())
        if keep.all():
            passes.append(p)
            continue
        idx = np.flatnonzero(keep)
        for piece in np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1):
            if len(piece) > 1 and length[piece[0]:piece[-1]].sum() >= MIN_PIECE_FRACTION * pad_radius:
                passes.append(Pass(p.points[piece], p.normals[piece], level=p.level, region=p.region, kind=p.kind))
    if not cuts or not passes:
        return toolpath
    log.info("%d stretches (%.0f mm in contact) cut out of the passes where they crawl over a fold at the rim",
             cuts, 1e3 * cut_length)
    return toolpath.replace(passes=tuple(passes), metadata=dict(toolpath.metadata, rim_fold_cuts=cuts,
                                                                rim_fold_length_m=cut_length))
