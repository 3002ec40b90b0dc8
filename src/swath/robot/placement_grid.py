"""The arm-in-part test of :class:`swath.robot.arm_part.ArmPartCheck`, answered from a distance grid.

The placement search asks the arm-in-part question for tens of thousands of configurations per
candidate placement, and each capsule axis sample is a k-d tree query there.  This module answers
the same question with the same answer, mostly by array look-ups:

* once per part, the distance from each node of a regular grid (``cell`` apart, over the part's
  surface samples padded by the largest capsule reach) to the nearest surface sample is taken from
  the check's k-d tree, up to the largest reach plus a cell diagonal (farther nodes are "far");
* a capsule axis sample ``p`` is looked up at its nearest node ``g``: by the triangle inequality
  the distance of ``p`` from the surface samples lies within ``D(g) ± |p − g|``, so the sample is
  surely clear when ``D(g) − |p − g|`` exceeds the capsule's reach, surely touching when
  ``D(g) + |p − g|`` is below it, and only in between (a thin shell about the reach) is the k-d tree
  asked, exactly as the check asks it.  Samples outside the grid are clear.

So :meth:`GridArmPartCheck.hits` returns what :meth:`ArmPartCheck.hits` returns, configuration
for configuration (a test compares them), in a fraction of the time.
"""

from __future__ import annotations

import numpy as np

#: Grid spacing, m.  Finer grids cost more to build (nodes ∝ 1/cell³) and leave fewer samples
#: between the bounds for the k-d tree.
DEFAULT_CELL = 0.04
#: At most this many grid nodes: a larger part gets a coarser grid (the answers stay the same).
MAX_NODES = 1_000_000
#: Samples closer than this to a bound (m) go to the k-d tree, so rounding never decides.
_EPS = 1e-9


class GridArmPartCheck:
    """:class:`swath.robot.arm_part.ArmPartCheck`'s answers from a distance grid (same results, faster).

    Parameters
    ----------
    check : ArmPartCheck
        The check whose k-d tree (``tree``, part frame, m), capsules (``links``) and model are used.
    cell : float
        Grid spacing, m (default :data:`DEFAULT_CELL`); widened so the grid has at most
        :data:`MAX_NODES` nodes.

    Attributes
    ----------
    distance : (nx, ny, nz) float
        Distance of each grid node from the nearest surface sample, m (``inf`` beyond the largest
        capsule reach plus a cell diagonal).
    origin : (3,) float
        Position of node (0, 0, 0), part frame, m.
    """

    def __init__(self, check, *, cell: float = DEFAULT_CELL):
        self.check = check
        self.model = check.model
        self.links = check.links
        self.tree = check.tree
        pts = np.asarray(self.tree.data, dtype=float)
        reach_max = max((r for *_, r, _ in self.links), default=0.0)
        self.cell = float(cell)
        while True:
            pad = reach_max + 2.0 * self.cell
            lo = pts.min(axis=0) - pad
            hi = pts.max(axis=0) + pad
            shape = np.maximum(np.ceil((hi - lo) / self.cell).astype(int) + 1, 1)
            if np.prod(shape) <= MAX_NODES:
                break
            self.cell *= max(1.05, float(np.prod(shape) / MAX_NODES) ** (1.0 / 3.0))
        axes = [lo[k] + self.cell * np.arange(shape[k]) for k in range(3)]
        nodes = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        bound = reach_max + np.sqrt(3.0) * self.cell
        d, _ = self.tree.query(nodes, distance_upper_bound=bound)
        self.distance = d.reshape(tuple(shape))
        self.origin = lo
        self.shape = shape
        self.bound = float(bound)
        self.box_lo, self.box_hi = pts.min(axis=0), pts.max(axis=0)

    def _bounds(self, p: np.ndarray):
        """Lower and upper bounds (m) on the distance of points ``p`` (k, 3) from the surface samples.

        Beyond the grid's reach (``inf`` nodes) and outside the grid, the lower bound is what is
        known there: the grid's distance bound less the offset from the node, or the distance
        from the box around the surface samples; the upper bound is ``inf``."""
        f = (p - self.origin) / self.cell
        i = np.rint(f).astype(np.int64)
        inside = np.all((i >= 0) & (i < self.shape), axis=1)
        lower = np.linalg.norm(np.maximum(np.maximum(self.box_lo - p, p - self.box_hi), 0.0), axis=1)
        upper = np.full(len(p), np.inf)
        j = i[inside]
        d = self.distance[j[:, 0], j[:, 1], j[:, 2]]
        e = self.cell * np.linalg.norm(f[inside] - j, axis=1)
        lower[inside] = np.maximum(lower[inside], np.minimum(d, self.bound) - e)
        upper[inside] = d + e
        return lower, upper

    def hits(self, q, part2base, *, chunk: int = 20000) -> np.ndarray:
        """(n,) bool: configuration i puts a link capsule into the part (as :meth:`ArmPartCheck.hits`).

        Parameters
        ----------
        q : (n, 6) float
            Joint values, rad.
        part2base : (4, 4) float
            The part's placement (``p_base = part2base @ p_part``), m.
        chunk : int
            Configurations per batch.
        """
        q = np.asarray(q, dtype=float).reshape(-1, self.model.chain.n_joints)
        base2part = np.linalg.inv(np.asarray(part2base, dtype=float))
        out = np.zeros(len(q), bool)
        for s in range(0, len(q), chunk):
            link2part = base2part @ self.model.chain.frames(q[s:s + chunk])       # (m, L, 4, 4)
            hit_c = out[s:s + chunk]
            for link, _, axis_link, reach, sphere in self.links:
                todo = np.flatnonzero(~hit_c)
                if not len(todo):
                    break
                t = link2part[todo, link]                                       # (m', 4, 4)
                # the capsule's bounding sphere first: capsules surely far from the part are dropped
                centre = t[:, :3, 3] + t[:, :3, :3] @ axis_link[:, :3].mean(axis=0)
                near = self._bounds(centre)[0] <= sphere + _EPS
                todo, t = todo[near], t[near]
                if not len(todo):
                    continue
                pts = np.einsum("mij,kj->mki", t[:, :3, :], axis_link).reshape(-1, 3)
                lower, upper = self._bounds(pts)
                k = len(axis_link)
                sure = (upper < reach - _EPS).reshape(len(todo), k).any(axis=1)
                unsure = ((lower <= reach + _EPS) & (upper >= reach - _EPS)).reshape(len(todo), k)
                ask = unsure & ~sure[:, None]
                if ask.any():
                    rows, cols = np.nonzero(ask)
                    d, _ = self.tree.query(pts.reshape(len(todo), k, 3)[rows, cols], distance_upper_bound=reach)
                    found = np.zeros(len(todo), bool)
                    found[rows[np.isfinite(d)]] = True
                    sure |= found
                hit_c[todo[sure]] = True
        return out
