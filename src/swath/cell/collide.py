"""Collision queries in the cell through coal (the successor of hpp-fcl).

A :class:`CollisionScene` holds the static bodies (the part as a triangle-mesh BVH, the table,
the fixtures; all in the robot base frame) and the moving bodies (robot links, tool bodies), each
attached to one frame of a kinematic chain.  :meth:`CollisionScene.check` takes those frames for
many poses at once and returns every pose where two bodies that may not touch do touch.

Speed: every body is covered by a few spheres; a pair is handed to coal only where a covering
sphere reaches the other body's bounding box (boxes, cylinders) or comes within a sphere radius
plus the longest mesh edge of a mesh vertex (meshes, through a k-d tree), so coal sees the few
poses that are close.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from .bodies import Body, Box, Mesh

log = logging.getLogger(__name__)


def _coal():
    try:
        import coal
    except ImportError:        # pragma: no cover - coal is a runtime dependency
        raise InputError("collision checking needs the coal package: pip install coal (a swath dependency)") from None
    return coal


@dataclass(frozen=True, eq=False)
class MovingBody:
    """A body attached to one frame of a moving chain.

    Attributes
    ----------
    body : Body
        Its shape, name and ``body2frame`` = body2link (m).
    link : int
        Index of the frame it rides on in the ``link2base`` array given to :meth:`CollisionScene.check`.
    """

    body: Body
    link: int


@dataclass(frozen=True, eq=False)
class CollisionHits:
    """Poses where two bodies touch.

    Attributes
    ----------
    pose : (h,) int
        Index of the pose (first axis of ``link2base``).
    body_a, body_b : list of str
        Names of the moving body and of the other body (static or moving).
    point_base : (h, 3) float
        A point of the contact in the base frame, m.
    depth : (h,) float
        Penetration depth reported by coal, m (0 when coal reports none).
    n_queries : int
        How many narrow-phase (coal) queries were made.
    """

    pose: np.ndarray
    body_a: list
    body_b: list
    point_base: np.ndarray
    depth: np.ndarray
    n_queries: int = 0
    stats: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.pose)


class CollisionScene:
    """Static and moving bodies, and which pairs are checked.

    Parameters
    ----------
    static : sequence of Body
        Bodies fixed in the base frame (``body2frame`` = body2base), including the part.
    moving : sequence of MovingBody
        Bodies riding on the chain's frames.
    skip : iterable of (str, str)
        Pairs (moving name, static or moving name) never checked: bodies in contact by design
        (the robot's first link on its table, the tool on the last wrist link).
    self_pairs : iterable of (int, int)
        Pairs of indices into ``moving`` checked against each other.
    cull_spacing : float
        Spacing of the points sampled on mesh bodies for culling, m (smaller culls more, costs
        memory: about area / spacing² points).
    """

    def __init__(self, static, moving, *, skip=(), self_pairs=(), cull_spacing: float = 0.008):
        coal = _coal()
        self.static = list(static)
        self.moving = list(moving)
        self.skip = {tuple(p) for p in skip}
        self.self_pairs = [tuple(p) for p in self_pairs]
        self._static_geom = []
        self._static_cull = []
        for b in self.static:
            geom = b.shape.coal()
            self._static_geom.append((geom, coal.Transform3s(b.body2frame[:3, :3].copy(), b.body2frame[:3, 3].copy())))
            if isinstance(b.shape, Mesh):
                from scipy.spatial import cKDTree

                pts, cover = surface_points(b.shape.vertices, b.shape.faces, spacing=cull_spacing)
                pts = pts @ b.body2frame[:3, :3].T + b.body2frame[:3, 3]
                # an unbalanced tree with big leaves answers these bounded queries ~5x faster here
                tree = cKDTree(pts, leafsize=64, balanced_tree=False, compact_nodes=False)
                self._static_cull.append(("mesh", tree, cover, *b.aabb()))
            elif isinstance(b.shape, Box):
                self._static_cull.append(("box", np.linalg.inv(b.body2frame), np.asarray(b.shape.size) / 2,
                                          *b.aabb()))
            else:
                self._static_cull.append(("aabb", None, 0.0, *b.aabb()))
        self._moving_geom = [m.body.shape.coal() for m in self.moving]
        self._cover = [m.body.shape.cover() for m in self.moving]
        # one sphere around each moving body's covering spheres: the first, cheapest cull
        self._bound = []
        for c, r in self._cover:
            mid = (c.min(axis=0) + c.max(axis=0)) / 2
            self._bound.append((mid, float(np.max(np.linalg.norm(c - mid, axis=1) + r))))

    def check(self, link2base) -> CollisionHits:
        """Every pose where a checked pair touches.

        Parameters
        ----------
        link2base : (n, n_frames, 4, 4) float
            The chain's frames in the base frame for ``n`` poses, m.

        Returns
        -------
        CollisionHits
        """
        coal = _coal()
        link2base = np.asarray(link2base, dtype=float)
        n = len(link2base)
        req = coal.CollisionRequest()
        req.enable_contact = True
        res = coal.CollisionResult()
        out_pose, out_a, out_b, out_p, out_d = [], [], [], [], []
        n_queries = 0
        n_candidates = 0
        body_pose = [link2base[:, m.link] @ m.body.body2frame for m in self.moving]
        bound_c = [t[:, :3, :3] @ mid + t[:, :3, 3] for t, (mid, _) in zip(body_pose, self._bound)]

        def query(i, geom_b, tf_b, poses, name_b):
            nonlocal n_queries
            geom_a = self._moving_geom[i]
            t = body_pose[i]
            for k in poses:
                res.clear()
                tf_a = coal.Transform3s(t[k, :3, :3].copy(), t[k, :3, 3].copy())
                tf = tf_b(k) if callable(tf_b) else tf_b
                n_queries += 1
                if coal.collide(geom_a, tf_a, geom_b, tf, req, res):
                    c = res.getContact(0)
                    out_pose.append(k)
                    out_a.append(self.moving[i].body.name)
                    out_b.append(name_b)
                    out_p.append(np.asarray(c.pos, dtype=float))
                    out_d.append(abs(float(c.penetration_depth)))

        for i, m in enumerate(self.moving):
            rb = self._bound[i][1]
            cov_c, cov_r = self._cover[i]
            for s, b in enumerate(self.static):
                if (m.body.name, b.name) in self.skip:
                    continue
                kind, cull, extra, lo, hi = self._static_cull[s]
                cand = np.flatnonzero(np.all((bound_c[i] + rb > lo) & (bound_c[i] - rb < hi), axis=1))
                if len(cand) and kind in ("mesh", "box"):
                    t = body_pose[i][cand]
                    c = np.swapaxes(t[:, :3, :3] @ cov_c.T, 1, 2) + t[:, None, :3, 3]     # (m, k, 3)
                    pn, pk = np.nonzero(np.ones(c.shape[:2], bool))
                    if kind == "mesh":
                        # every point of the mesh is within `extra` of a sampled point
                        d, _ = cull.query(c[pn, pk], distance_upper_bound=float(cov_r.max() + extra) + 1e-9)
                        close = d < cov_r[pk] + extra
                    else:
                        # exact sphere-box test in the box's frame
                        local = c[pn, pk] @ cull[:3, :3].T + cull[:3, 3]
                        close = np.linalg.norm(np.maximum(np.abs(local) - extra, 0.0), axis=1) < cov_r[pk]
                    cand = cand[np.unique(pn[close])]
                n_candidates += len(cand)
                query(i, *self._static_geom[s], cand, b.name)
        for i, j in self.self_pairs:
            if (self.moving[i].body.name, self.moving[j].body.name) in self.skip:
                continue
            gap = np.linalg.norm(bound_c[i] - bound_c[j], axis=1) - self._bound[i][1] - self._bound[j][1]
            cand = np.flatnonzero(gap < 0)
            if len(cand):
                ti, tj = body_pose[i][cand], body_pose[j][cand]
                (ci, ri), (cj, rj) = self._cover[i], self._cover[j]
                wi = np.swapaxes(ti[:, :3, :3] @ ci.T, 1, 2) + ti[:, None, :3, 3]
                wj = np.swapaxes(tj[:, :3, :3] @ cj.T, 1, 2) + tj[:, None, :3, 3]
                dist = np.linalg.norm(wi[:, :, None] - wj[:, None], axis=3)
                cand = cand[np.any(dist < ri[:, None] + rj[None], axis=(1, 2))]
            n_candidates += len(cand)
            tj_all = body_pose[j]

            def tf_j(k, tj=tj_all):
                return coal.Transform3s(tj[k, :3, :3].copy(), tj[k, :3, 3].copy())

            query(i, self._moving_geom[j], tf_j, cand, self.moving[j].body.name)
        order = np.argsort(np.asarray(out_pose, dtype=int), kind="stable")
        return CollisionHits(pose=np.asarray(out_pose, dtype=int)[order],
                             body_a=[out_a[k] for k in order], body_b=[out_b[k] for k in order],
                             point_base=np.asarray(out_p, dtype=float).reshape(-1, 3)[order],
                             depth=np.asarray(out_d, dtype=float)[order], n_queries=n_queries,
                             stats={"poses": n, "candidates": n_candidates})


    def distances(self, link2base, static: str, *, cap: float = 0.1):
        """Smallest distance of the moving bodies to one static body, per pose.

        A covering sphere's distance to the body's sampled points, less the sphere's radius and
        the sampling bound, is a lower bound on the moving body's distance; coal measures the
        distance exactly only where that bound is below ``cap``.

        Parameters
        ----------
        link2base : (n, n_frames, 4, 4) float
            The chain's frames in the base frame, m.
        static : str
            Name of the static body (e.g. ``"the part"``).
        cap : float
            Distances at or above this need not be exact, m.

        Returns
        -------
        distance : (n,) float
            Per pose, the smallest distance of any moving body (the pairs the collision check
            skips included) to the static body, m: exact below ``cap``, a lower bound at or above it (0 where they touch).
        body : list of str
            Per pose, the moving body nearest it.
        """
        coal = _coal()
        s = self._static_index(static)
        geom_b, tf_b = self._static_geom[s]
        link2base = np.asarray(link2base, dtype=float)
        n = len(link2base)
        best = np.full(n, np.inf)
        who = np.full(n, -1)
        req = coal.DistanceRequest()
        res = coal.DistanceResult()
        for i, t, bound in self._lower_bounds(link2base, s, cap):
            geom_a = self._moving_geom[i]
            exact = bound.copy()
            for k in np.flatnonzero((bound < cap) & (bound < best)):
                res.clear()
                tf_a = coal.Transform3s(t[k, :3, :3].copy(), t[k, :3, 3].copy())
                exact[k] = max(float(coal.distance(geom_a, tf_a, geom_b, tf_b, req, res)), 0.0)
            closer = exact < best
            best = np.where(closer, exact, best)
            who = np.where(closer, i, who)
        return best, [self.moving[i].body.name if i >= 0 else "" for i in who]

    def min_distance(self, link2base, static: str, *, cap: float = 0.1) -> tuple[float, str, int]:
        """The smallest distance of the moving bodies to one static body over all poses.

        The same figure as the minimum of :meth:`distances` (exact below ``cap``, a lower bound at
        or above it), with far fewer exact queries: the (body, pose) pairs are measured exactly in
        the order of their lower bounds, and the search stops at the first bound not below the
        smallest distance found.

        Returns
        -------
        distance : float
            m (inf without moving bodies or poses).
        body : str
            The moving body nearest it ("" when none).
        pose : int
            The pose where it is nearest (-1 when none).
        """
        coal = _coal()
        s = self._static_index(static)
        geom_b, tf_b = self._static_geom[s]
        link2base = np.asarray(link2base, dtype=float)
        best, who, where = math.inf, -1, -1
        todo = []
        for i, t, bound in self._lower_bounds(link2base, s, cap):
            k = int(np.argmin(bound)) if len(bound) else -1
            if k >= 0 and bound[k] < best and bound[k] >= cap:
                best, who, where = float(bound[k]), i, k          # a lower bound: no exact query above the cap
            near = np.flatnonzero(bound < cap)
            todo += [(float(bound[j]), i, int(j), t[j]) for j in near]
        todo.sort(key=lambda c: c[0])
        req = coal.DistanceRequest()
        res = coal.DistanceResult()
        for bound_k, i, k, t_k in todo:
            if bound_k >= best:
                break
            res.clear()
            tf_a = coal.Transform3s(t_k[:3, :3].copy(), t_k[:3, 3].copy())
            d = max(float(coal.distance(self._moving_geom[i], tf_a, geom_b, tf_b, req, res)), 0.0)
            if d < best:
                best, who, where = d, i, k
        return best, (self.moving[who].body.name if who >= 0 else ""), where

    def _static_index(self, static: str) -> int:
        names = [b.name for b in self.static]
        if static not in names:
            raise InputError(f"no static body named {static!r} in the scene; it has {', '.join(names)}")
        return names.index(static)

    def _lower_bounds(self, link2base, s: int, cap: float):
        """Per moving body ``i``: ``(i, body2base (n, 4, 4), bound (n,))``, a lower bound (≥ 0, m) on
        its distance to static body ``s`` at each pose, from its covering spheres (for a mesh, at most
        ``cap``: a body farther than the cap is given the cap)."""
        kind, cull, extra, lo, hi = self._static_cull[s]
        for i, m in enumerate(self.moving):
            t = link2base[:, m.link] @ m.body.body2frame
            cov_c, cov_r = self._cover[i]
            c = np.swapaxes(t[:, :3, :3] @ cov_c.T, 1, 2) + t[:, None, :3, 3]          # (n, k, 3)
            if kind == "mesh":
                # no sampled point within reach of the cap: the body is at least the cap away
                d, _ = cull.query(c.reshape(-1, 3), distance_upper_bound=cap + extra + float(cov_r.max()))
                bound = np.minimum((d.reshape(c.shape[:2]) - extra - cov_r[None]).min(axis=1), cap)
            elif kind == "box":
                local = c @ cull[:3, :3].T + cull[:3, 3]
                bound = (np.linalg.norm(np.maximum(np.abs(local) - extra, 0.0), axis=2) - cov_r[None]).min(axis=1)
            else:
                out = np.maximum(np.maximum(lo - c, c - hi), 0.0)
                bound = (np.linalg.norm(out, axis=2) - cov_r[None]).min(axis=1)
            yield i, t, np.maximum(bound, 0.0)


def surface_points(vertices, faces, *, spacing: float):
    """Points on a triangle mesh such that every point of the mesh lies near one of them.

    Each triangle is split into ``n²`` similar triangles (``n`` = its longest edge over ``spacing``,
    rounded up) whose corners are the points; every point of a triangle lies within its longest
    edge over √3 of a corner, so of a returned point within the returned bound.

    Parameters
    ----------
    vertices : (n, 3) float
        m.
    faces : (m, 3) int
    spacing : float
        Largest edge of the small triangles, m.

    Returns
    -------
    points : (k, 3) float
        m (duplicates on shared edges are kept).
    bound : float
        Every point of the mesh is within this distance of a returned point, m.
    """
    v = np.asarray(vertices, dtype=float)
    tri = v[np.asarray(faces)]
    longest = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max(axis=1)
    n_sub = np.maximum(1, np.ceil(longest / spacing).astype(int))
    out = [v]
    bound = 0.0
    for n in np.unique(n_sub):
        group = tri[n_sub == n]
        bound = max(bound, float((longest[n_sub == n] / n).max()) / np.sqrt(3.0))
        if n == 1:
            continue
        i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
        keep = i + j <= n
        a, b = i[keep] / n, j[keep] / n
        w = np.column_stack([1 - a - b, a, b])                       # barycentric weights (p, 3)
        out.append(np.einsum("pk,tkd->tpd", w, group).reshape(-1, 3))
    return np.vstack(out), bound * (1 + 1e-9) + 1e-12
