"""A collision-free joint path for a joint move that no lift clears: via-points found in joint space.

:func:`swath.robot.sweep.clear_joint_moves` first tries the simple fixes (lift the move's ends, a
via-point raised above its middle, the arm raised).  Where none keeps the rules, :func:`route_joint_move`
looks for via-points between the two ends, each straight joint segment between them checked by the
job's :class:`~swath.robot.sweep.SweepCheck` at the same ≤ 2° steps as everything else:

1. **one joint group at a time**: the base (joint 1), the arm (joints 2 and 3) and the wrist (joints
   4–6) are moved to their end values in turn, in each of the six orders (a wrist-first or
   shoulder-first ordering, two via-points);
2. **a bidirectional random tree** (RRT-Connect) in joint space, inside the box the ends span
   widened by ``widen`` rad per joint (within the joint limits), grown from both ends with a seeded
   random generator, a fixed number of iterations and a fixed budget of checked segments, so the
   same job gives the same path on any machine and under any load; the path found is shortened by
   joining each node to the farthest later node it sees directly.

The via-points returned are the rows the programs write as joint-move targets.
"""

from __future__ import annotations

import itertools
import logging
import math

import numpy as np

log = logging.getLogger(__name__)

#: Joint groups moved one at a time: the base, the arm, the wrist.
GROUPS = ((0,), (1, 2), (3, 4, 5))


def route_joint_move(check, q0, q1, *, required: float, ignore=(), lower=None, upper=None, widen: float = math.pi / 2,
                     step: float = 0.35, iterations: int = 250, max_checks: int = 300, seed: int = 0):
    """Via-points of a joint path from ``q0`` to ``q1`` whose sweep keeps the rules, or None.

    Parameters
    ----------
    check : SweepCheck
        The job's scene (:class:`swath.robot.sweep.SweepCheck`).
    q0, q1 : (6,) float
        The move's ends, rad.
    required : float
        Distance from the part every swept body keeps, m (0: only no collision).
    ignore : iterable of (str, str)
        Body pairs not counted as hits (those touching at the ends on the job's path).
    lower, upper : (6,) float, optional
        Joint limits, rad (default the check's model's).
    widen : float
        The random tree samples the box the ends span widened by this much per joint, rad.
    step : float
        Largest joint change of one tree edge, rad.
    iterations : int
        Tree growth steps at most.
    max_checks : int
        Segments checked at most (each a sweep at ≤ 2° steps); the search gives up after them.
    seed : int
        Seed of the random generator.

    Returns
    -------
    (k, 6) float or None
        The via-points between the ends (k ≥ 0; 0 when the straight move already keeps the rules),
        rad; None when neither the group orderings nor the tree found a path.
    """
    q0, q1 = np.asarray(q0, dtype=float), np.asarray(q1, dtype=float)
    ignore = set(ignore)
    lower = check.model.lower if lower is None else np.asarray(lower, dtype=float)
    upper = check.model.upper if upper is None else np.asarray(upper, dtype=float)
    cache: dict = {}

    def clean(a, b) -> bool:
        key = (a.tobytes(), b.tobytes())
        if key not in cache:
            if len(cache) >= max_checks:
                raise _GiveUp
            # distances above the required one need not be exact
            cache[key] = check.sweep(np.array([a, b]), ignore=ignore, cap=required + 1e-3).ok(required)
        return cache[key]

    try:
        return _route(clean, q0, q1, lower, upper, widen, step, iterations, seed)
    except _GiveUp:
        log.debug("routing: gave up after %d checked segments", max_checks)
        return None


class _GiveUp(Exception):
    """The routing's budget of checked segments is spent."""


def _route(clean, q0, q1, lower, upper, widen: float, step: float, iterations: int, seed: int):
    """:func:`route_joint_move` on a ``clean(a, b)`` segment test."""
    if clean(q0, q1):
        return np.zeros((0, 6))
    for order in itertools.permutations(GROUPS):
        nodes = [q0]
        for g in order[:-1]:
            nxt = nodes[-1].copy()
            nxt[list(g)] = q1[list(g)]
            nodes.append(nxt)
        nodes.append(q1)
        if all(clean(a, b) for a, b in zip(nodes[:-1], nodes[1:])):
            return np.array(nodes[1:-1])
    path = _rrt_connect(clean, q0, q1, np.maximum(lower, np.minimum(q0, q1) - widen),
                        np.minimum(upper, np.maximum(q0, q1) + widen), np.random.default_rng(seed), step, iterations)
    if path is None:
        return None
    return np.array(_shortcut(clean, path)[1:-1]).reshape(-1, 6)


def _toward(a, b, step: float):
    """The point at most ``step`` (max-norm, rad) from ``a`` toward ``b``."""
    d = b - a
    size = float(np.max(np.abs(d)))
    return b.copy() if size <= step else a + d * (step / size)


def _rrt_connect(clean, q0, q1, lo, hi, rng, step: float, iterations: int):
    """A joint path (list of (6,) nodes from ``q0`` to ``q1``) whose every edge is ``clean``, or None."""
    trees = [[q0], [q1]]
    parents: list[list[int]] = [[-1], [-1]]

    def nearest(tree, x) -> int:
        return int(np.argmin(np.max(np.abs(np.array(tree) - x), axis=1)))

    def extend(t: int, x):
        """One step of tree ``t`` toward ``x``: the new node's index, or None where the step is not clean."""
        k = nearest(trees[t], x)
        new = _toward(trees[t][k], x, step)
        if not clean(trees[t][k], new):
            return None
        trees[t].append(new)
        parents[t].append(k)
        return len(trees[t]) - 1

    def branch(t: int, k: int) -> list:
        out = []
        while k >= 0:
            out.append(trees[t][k])
            k = parents[t][k]
        return out

    for it in range(iterations):
        a = it % 2
        b = 1 - a
        target = rng.uniform(lo, hi)
        k = extend(a, target)
        if k is None:
            continue
        goal = trees[a][k]
        # the other tree steps toward the new node until it reaches it or is blocked
        while True:
            j = extend(b, goal)
            if j is None:
                break
            if np.max(np.abs(trees[b][j] - goal)) < 1e-12:
                half_a, half_b = branch(a, k), branch(b, j)
                path = half_a[::-1] + half_b[1:] if a == 0 else half_b[::-1] + half_a[1:]
                return path
    return None


def _shortcut(clean, path: list) -> list:
    """The path with each node joined to the farthest later node it sees along a clean straight segment."""
    out = [path[0]]
    i = 0
    while i < len(path) - 1:
        j = len(path) - 1
        while j > i + 1 and not clean(path[i], path[j]):
            j -= 1
        out.append(path[j])
        i = j
    return out
