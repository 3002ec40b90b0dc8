"""A cheap test of the robot's arm against the part, for choosing branches and placements.

The job's collision check (:mod:`swath.robot.collision`) runs coal on the written joint path; this
module answers the question earlier and in bulk, before a branch or a placement is chosen: does a
configuration put one of the link capsules (:func:`swath.robot.collision.link_bodies`, the same
bodies the collision check uses) into the part?

The part's surface is sampled (:func:`swath.cell.collide.surface_points`) into a k-d tree in the part
frame, once.  Each capsule's axis is sampled every ``radius / 2``; a capsule is taken to touch the
part when a sample lies within ``radius + step / 2 + bound + margin`` of a surface point (``bound``
the surface sampling's covering radius), so the test errs on the side of a hit by at most a few
millimetres.  A first query per capsule with its bounding sphere drops the capsules far from the part.
"""

from __future__ import annotations

import numpy as np

from ..cell import Capsule


class ArmPartCheck:
    """Whether configurations put the arm's link capsules into the part.

    Parameters
    ----------
    model : RobotModel
    vertices : (n, 3) float
        The part's mesh vertices, part frame, m.
    faces : (m, 3) int, optional
        Its triangles (without them the vertices alone are the surface).
    spacing : float
        Surface sampling, m (default 0.02).
    margin : float
        Extra distance a capsule must keep from the part, m (default 0).
    """

    def __init__(self, model, vertices, faces=None, *, spacing: float = 0.02, margin: float = 0.0):
        from scipy.spatial import cKDTree

        from ..cell.collide import surface_points
        from .collision import link_bodies

        v = np.asarray(vertices, dtype=float)
        if faces is not None and len(faces):
            pts, bound = surface_points(v, np.asarray(faces), spacing=spacing)
        else:
            pts, bound = v, 0.0
        self.model = model
        self.tree = cKDTree(pts)
        self.bound = float(bound)
        self.margin = float(margin)
        self.links = []
        for mb in link_bodies(model):
            shape = mb.body.shape
            if mb.link == 0 or not isinstance(shape, Capsule):     # the base column: the placement keeps out
                continue
            step = 0.5 * shape.radius
            k = max(2, int(np.ceil(shape.length / step)) + 1)
            z = np.linspace(-0.5 * shape.length, 0.5 * shape.length, k)
            axis_body = np.c_[np.zeros((k, 2)), z, np.ones(k)]         # (k, 4) homogeneous, body frame
            axis_link = axis_body @ mb.body.body2frame.T
            reach = shape.radius + 0.5 * (z[1] - z[0]) + self.bound + self.margin
            self.links.append((mb.link, mb.body.name, axis_link, reach, 0.5 * shape.length + reach))

    def hits(self, q, part2base, *, chunk: int = 20000) -> np.ndarray:
        """(n,) bool: configuration i puts a link capsule into the part.

        Parameters
        ----------
        q : (n, 6) float
            Joint values, rad.
        part2base : (4, 4) float
            The part's placement (``p_base = part2base @ p_part``), m.
        """
        q = np.asarray(q, dtype=float).reshape(-1, self.model.chain.n_joints)
        base2part = np.linalg.inv(np.asarray(part2base, dtype=float))
        out = np.zeros(len(q), bool)
        for s in range(0, len(q), chunk):
            link2part = base2part @ self.model.chain.frames(q[s:s + chunk])       # (m, L, 4, 4)
            for link, _, axis_link, reach, sphere in self.links:
                t = link2part[:, link]                                          # (m, 4, 4)
                centre = t[:, :3, 3] + np.einsum("mij,j->mi", t[:, :3, :3], axis_link[:, :3].mean(axis=0))
                near = np.flatnonzero(~out[s:s + chunk])
                if not len(near):
                    break
                d, _ = self.tree.query(centre[near], distance_upper_bound=sphere)
                near = near[np.isfinite(d)]
                if not len(near):
                    continue
                pts = np.einsum("mij,kj->mki", t[near, :3, :], axis_link)         # (m', k, 3)
                d, _ = self.tree.query(pts.reshape(-1, 3), distance_upper_bound=reach)
                hit = np.isfinite(d).reshape(len(near), -1).any(axis=1)
                out[s + near[hit]] = True
        return out
