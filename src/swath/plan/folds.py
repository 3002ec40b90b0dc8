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
* the run lies at the rim (:func:`at_rim`): the part's open edge nearest to it is within a pad
  radius ahead of it or behind it along the pass (the pass crosses the fold toward the edge), or
  within a quarter of a pad radius in any direction (the fold hugs the edge).  A ridge inside the
  part is the planners' matter (:mod:`swath.cli.ridge_turn`), also where a pass crosses it near the
  part's end: the raster across the blade's nose, 33 mm from its tip, has the tip beside it, not
  ahead.
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

#: The open edge nearest a held run counts as ahead of it (or behind) within this angle of the
#: pass's travel, as the cosine: 60 degrees.
AHEAD_COS = 0.5

#: A held run this close to the open edge (as a fraction of the pad radius), in any direction, is at
#: the rim.
HUGGING_FRACTION = 0.25

#: The open edge is sampled this fraction of the pad radius apart for :func:`at_rim`.
EDGE_STEP_FRACTION = 0.05

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
        m: it sets how near the open edge a fold is at the rim (:func:`at_rim`) and the shortest
        piece kept.

    Returns
    -------
    ToolPath
        The same object where nothing is cut; else the cut passes (pieces shorter than
        :data:`MIN_PIECE_FRACTION` of the pad radius dropped), ``metadata`` gaining
        ``rim_fold_cuts`` (stretches cut) and ``rim_fold_length_m`` (their contact length).
    """
    if omega_max is None or not omega_max > 0 or not toolpath.passes:
        return toolpath
    from scipy.spatial import cKDTree

    from ..core import Pass
    from ..surface.polyline import densify

    passes, cuts, cut_length, edge = [], 0, 0.0, None
    for p in toolpath.passes:
        rate, length = rotation_per_metre(p.points, p.normals)
        runs = ridge_runs(p.normals, omega_max / np.maximum(rate, 1e-12) < HOLD_FRACTION * feed)
        if not runs.any():
            passes.append(p)
            continue
        if edge is None:
            loops = surface.boundary_loops
            if not loops:                                   # a closed part has no rim
                return toolpath
            # the edge sampled densely enough that its nearest point lies square to it, not at a
            # vertex of a long boundary edge off to one side
            step = EDGE_STEP_FRACTION * pad_radius
            edge = cKDTree(np.vstack([densify(surface.vertices[np.append(loop, loop[0])], step)[0] for loop in loops]))
        keep = np.ones(len(p.points), bool)
        edges = np.flatnonzero(np.diff(np.concatenate([[0], runs.astype(np.int8), [0]])))
        for a, b in zip(edges[::2], edges[1::2]):          # segments a..b-1: points a..b
            if at_rim(p.points[a:b + 1], edge, pad_radius):
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


def at_rim(run: np.ndarray, edge, pad_radius: float) -> bool:
    """Whether the held run ``run`` ((k, 3) points, m, in travel order) lies at the part's rim: the
    nearest of the open edge's points (``edge``, a :class:`scipy.spatial.cKDTree` of them) to the
    run's middle is within ``pad_radius`` (m) and within the angle :data:`AHEAD_COS` of the run's
    travel, either way, or within :data:`HUGGING_FRACTION` of ``pad_radius`` whatever its direction."""
    middle = run[len(run) // 2]
    distance, k = edge.query(middle)
    if distance <= HUGGING_FRACTION * pad_radius:
        return True
    if distance > pad_radius:
        return False
    travel = run[-1] - run[0]
    norm = float(np.linalg.norm(travel))
    if norm <= 0:
        return False
    return abs(float(travel @ (edge.data[k] - middle))) >= AHEAD_COS * norm * distance
