"""Collision checking of a solved robot job in its cell: links, tool, part, table, fixtures.

The robot's links are capsules along its kinematic chain (:func:`link_bodies`): link ``i`` runs from
joint ``i``'s frame to joint ``i + 1``'s along the chain's fixed offset, with a radius that scales
with the robot's reach (5 % for the three main links, 3.5 % for the wrist; 65 and 46 mm on a UR10e,
about the size of its tubes).  The tool's bodies ride on the flange; the pad is never checked against
the part (it is meant to touch it), but its centre (the TCP, a 1 mm body) is checked against the
fixtures, the robot and, out of contact, the table.  The joint path is interpolated so that no joint moves more than
``max_step`` (2° by default) between checked poses, in contact and in air moves alike.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..cell import Body, Capsule, Cell, CollisionScene, Cylinder, Mesh, MovingBody, default_table
from ..errors import SwathError

log = logging.getLogger(__name__)

#: Largest joint step between two checked poses, rad (2°).
MAX_JOINT_STEP = math.radians(2.0)

#: Name of the small body at the TCP in a scene built with ``tcp_radius`` (:func:`job_scene`).
TCP_BODY = "tool centre point"

#: Radius of that body in the job's collision check, m: the TCP itself, so that a pad driven into a
#: fixture, the table or the robot is found (against the part it is never checked).
TCP_RADIUS = 1e-3

#: Name of the pad disc in a scene built with ``pad_radius`` (:func:`job_scene`).
PAD_BODY = "tool pad"

#: Thickness of that disc behind the pad face, m.
PAD_THICKNESS = 2e-3


class CollisionError(SwathError):
    """The plan drives a body of the robot or tool into the part, the cell or the robot itself."""


def link_bodies(model, *, main_radius: float | None = None, wrist_radius: float | None = None) -> list[MovingBody]:
    """Capsules for the robot's links from its kinematic chain.

    Parameters
    ----------
    model : RobotModel
    main_radius, wrist_radius : float, optional
        Capsule radii of links 1–3 and 4–6, m (default 5 % and 3.5 % of the reach).

    Returns
    -------
    list of MovingBody
        ``link`` = index of the chain frame the capsule rides on (0 = after joint 1); links whose
        offset is zero (an intersecting wrist's) are left out.
    """
    main = 0.05 * model.reach if main_radius is None else main_radius
    wrist = 0.035 * model.reach if wrist_radius is None else wrist_radius
    out = []
    for i in range(model.chain.n_joints):
        seg = model.chain.fixed[i + 1][:3, 3]
        length = float(np.linalg.norm(seg))
        if length < 1e-6:
            continue
        z = seg / length
        helper = np.array([1.0, 0, 0]) if abs(z[0]) < 0.9 else np.array([0, 1.0, 0])
        x = np.cross(helper, z)
        x /= np.linalg.norm(x)
        pose = np.eye(4)
        pose[:3, :3] = np.column_stack([x, np.cross(z, x), z])
        pose[:3, 3] = seg / 2
        radius = main if i < 3 else wrist
        out.append(MovingBody(Body(f"robot link {i + 1}", Capsule(radius, length), pose), link=i))
    return out


@dataclass(frozen=True, eq=False)
class CollisionEvent:
    """One run of consecutive checked poses where the same two bodies touch.

    Attributes
    ----------
    body_a, body_b : str
    pass_index : int
        The contact pass (trajectory ``pass`` column), or -1 in an approach/retract/air move.
    after_pass : int
        The last contact pass before it (-1 before the first).
    t_start, t_end : float
        Trajectory time of the first and last touching pose, s.
    sample : int
        The trajectory sample at or before the first touching pose.
    point_part : (3,) float
        Where it touches first, in the part frame, m.
    depth : float
        The deepest penetration coal reports along the run, m.
    contact : bool
        Whether the pad is on the part there.
    """

    body_a: str
    body_b: str
    pass_index: int
    after_pass: int
    t_start: float
    t_end: float
    sample: int
    point_part: np.ndarray
    depth: float
    contact: bool

    def where(self) -> str:
        if self.pass_index >= 0:
            return f"pass {self.pass_index}"
        return "the air move before the first pass" if self.after_pass < 0 else f"the air move after pass {self.after_pass}"

    def sentence(self) -> str:
        span = f"t = {self.t_start:.2f} s" if self.t_end - self.t_start < 5e-3 else \
            f"t = {self.t_start:.2f}–{self.t_end:.2f} s"
        p = self.point_part * 1e3
        return (f"{self.body_a} hits {self.body_b} in {self.where()} at {span} (sample {self.sample}, "
                f"part frame {p[0]:.0f}, {p[1]:.0f}, {p[2]:.0f} mm)")

    def as_record(self) -> dict:
        return {"body_a": self.body_a, "body_b": self.body_b, "pass": self.pass_index, "after_pass": self.after_pass,
                "t_start_s": self.t_start, "t_end_s": self.t_end, "sample": self.sample,
                "point_part_m": [float(v) for v in self.point_part], "depth_m": self.depth, "contact": self.contact}


@dataclass(frozen=True, eq=False)
class CollisionReport:
    """What :func:`check_job_collisions` found.

    Attributes
    ----------
    events : list of CollisionEvent
    n_poses : int
        Checked poses (written samples plus the interpolated ones).
    n_queries : int
        Narrow-phase queries made by coal.
    seconds : float
        Time the check took, s.
    cell : Cell
        The cell checked (with the table assumed, if any).
    """

    events: list
    n_poses: int
    n_queries: int
    seconds: float
    cell: Cell
    timings: dict = field(default_factory=dict)

    def metrics(self) -> dict:
        return {"collision_count": len(self.events), "collision_poses_checked": self.n_poses,
                "collision_queries": self.n_queries, "collision_check_s": self.seconds,
                "collisions": [e.as_record() for e in self.events[:50]]}

    def message(self, *, limit: int = 3) -> str:
        head = "; ".join(e.sentence() for e in self.events[:limit])
        more = f" (and {len(self.events) - limit} more)" if len(self.events) > limit else ""
        return f"{len(self.events)} collision(s): {head}{more}"


def job_scene(model, cell: Cell, part_vertices=None, part_faces=None, *,
              tcp_radius: float | None = None, pad_radius: float | None = None) -> tuple[CollisionScene, Cell]:
    """The collision scene of a job and its cell (with the default table put in when assumed).

    Parameters
    ----------
    model : RobotModel
    cell : Cell
        ``part2base`` places the part; ``tool``, ``table`` and ``fixtures`` are checked.
    part_vertices : (n, 3) float, optional
        The part in the part frame, m.
    part_faces : (m, 3) int, optional
    tcp_radius : float, optional
        Also a small body at the TCP (a capsule of this radius, m), named ``"tool centre point"``,
        never checked against the part (the pad is meant to touch it): for measuring how far the
        TCP stays from the part (:meth:`CollisionScene.distances`) on air moves.
    pad_radius : float, optional
        Also the pad: a disc of this radius (m) and :data:`PAD_THICKNESS` behind the pad face,
        centred on the TCP and normal to the tool z-axis, named ``"tool pad"``.  It is measured by
        :meth:`CollisionScene.distances` (how near the pad's rim comes to the part on an air move)
        but never checked for collisions (in contact it lies on the part, and on a part standing on
        its table at its lowest point, on the table).
    """
    from dataclasses import replace

    static = []
    if part_vertices is not None:
        static.append(Body("the part", Mesh(part_vertices, part_faces), cell.part2base))
        if cell.table is None and cell.auto_table:
            v_base = np.asarray(part_vertices) @ cell.part2base[:3, :3].T + cell.part2base[:3, 3]
            cell = replace(cell, table=default_table(v_base, model.reach))
    if cell.table is not None:
        static.append(cell.table.body())
    static.extend(cell.fixtures)
    links = link_bodies(model)
    n = model.chain.n_joints
    tools = [MovingBody(b, link=n) for b in (cell.tool.bodies if cell.tool is not None else ())]
    skip = set()
    if tcp_radius is not None:
        tools.append(MovingBody(Body(TCP_BODY, Capsule(tcp_radius, tcp_radius), cell.tcp2flange), link=n))
        skip.add((TCP_BODY, "the part"))
    if pad_radius is not None:
        pad2tcp = np.eye(4)
        pad2tcp[2, 3] = -0.5 * PAD_THICKNESS                 # behind the face, away from the part
        tools.append(MovingBody(Body(PAD_BODY, Cylinder(pad_radius, PAD_THICKNESS), cell.tcp2flange @ pad2tcp),
                                link=n))
        skip.update((PAD_BODY, b.name) for b in static)
    moving = links + tools
    if links and links[0].link == 0:        # the robot stands on (or through) its table
        skip.add((links[0].body.name, "table"))
    self_pairs = []
    for i, a in enumerate(moving):
        for j in range(i + 1, len(moving)):
            b = moving[j]
            if PAD_BODY in (a.body.name, b.body.name):
                continue
            if b.link - a.link >= 3 and not (b.link == n and a.link >= n - 2):
                self_pairs.append((i, j))
    return CollisionScene(static, moving, skip=skip, self_pairs=self_pairs), cell


def tcp_grazes_table(body_a, body_b, depth, *, invert: bool = False) -> np.ndarray:
    """(h,) bool: hits of the TCP on the table whose centre is no more than its radius below the top
    (the pad on, or just off, a part whose lowest point is the table top); ``invert``: the others."""
    graze = np.array([a == TCP_BODY and b == "table" and d <= 2 * TCP_RADIUS + 1e-9
                      for a, b, d in zip(body_a, body_b, np.asarray(depth, dtype=float))], dtype=bool)
    return ~graze if invert else graze


def interpolate_joints(q, *, max_step: float = MAX_JOINT_STEP):
    """Joint path with no joint step above ``max_step``.

    Parameters
    ----------
    q : (n, d) float
        Joint values of consecutive written samples, rad.
    max_step : float
        rad.

    Returns
    -------
    q_fine : (N, d) float
        The samples and the points linearly interpolated between them.
    source : (N,) float
        Fractional sample index of each row (``k + s`` between samples ``k`` and ``k + 1``).
    """
    q = np.asarray(q, dtype=float)
    if len(q) < 2:
        return q.copy(), np.arange(len(q), dtype=float)
    steps = np.maximum(1, np.ceil(np.abs(np.diff(q, axis=0)).max(axis=1) / max_step).astype(int))
    seg = np.repeat(np.arange(len(q) - 1), steps)
    start = np.repeat(np.cumsum(steps) - steps, steps)
    frac = (np.arange(len(seg)) - start) / steps[seg]
    q_fine = q[seg] + frac[:, None] * (q[seg + 1] - q[seg])
    return np.vstack([q_fine, q[-1:]]), np.concatenate([seg + frac, [len(q) - 1]])


def check_job_collisions(trajectory, solution, model, cell: Cell, *, part_vertices=None, part_faces=None,
                         max_step: float = MAX_JOINT_STEP, chunk: int = 20000) -> CollisionReport:
    """Check a solved job for collisions along its whole joint path.

    Parameters
    ----------
    trajectory : Trajectory
        The (re-timed) trajectory the solution belongs to: times and pass indices.
    solution : JointSolution
        Joint values per sample (NaN where unreachable: those samples are skipped, and the path
        runs straight in joint space from the last reachable sample to the next, as the programs do).
    model : RobotModel
    cell : Cell
    part_vertices, part_faces : arrays, optional
        The part mesh in the part frame (m); without it only the cell and self-collisions are checked.
    max_step : float
        Largest joint step between checked poses, rad (default 2°).
    chunk : int
        Poses per batch (memory bound).

    Returns
    -------
    CollisionReport
    """
    t0 = time.perf_counter()
    scene, cell = job_scene(model, cell, part_vertices, part_faces, tcp_radius=TCP_RADIUS)
    t_scene = time.perf_counter() - t0
    idx = np.flatnonzero(solution.reachable)
    if not len(idx):
        return CollisionReport([], 0, 0, time.perf_counter() - t0, cell)
    q_fine, src = interpolate_joints(solution.q[idx], max_step=max_step)
    k0 = np.floor(src).astype(int)
    k1 = np.minimum(k0 + 1, len(idx) - 1)
    w = src - k0
    t_all = np.asarray(trajectory.t, dtype=float)
    t_fine = (1 - w) * t_all[idx[k0]] + w * t_all[idx[k1]]
    sample_fine = idx[k0]
    pass_all = np.asarray(trajectory.pass_index)
    contact_all = np.asarray(trajectory.contact, dtype=bool)
    # a pose between two samples of the same pass belongs to the pass; anything else is an air move
    same = (pass_all[idx[k0]] == pass_all[idx[k1]]) | (w == 0)
    pass_fine = np.where(same, pass_all[idx[k0]], -1)
    contact_fine = contact_all[idx[k0]] & (contact_all[idx[k1]] | (w == 0))
    last_pass = np.maximum.accumulate(np.where(pass_all >= 0, pass_all, -1))
    after_fine = last_pass[idx[k0]]
    hits_pose, hits_a, hits_b, hits_p, hits_d = [], [], [], [], []
    n_queries = 0
    t_fk = t_check = 0.0
    for s in range(0, len(q_fine), chunk):
        t1 = time.perf_counter()
        frames = model.chain.frames(q_fine[s:s + chunk])
        t2 = time.perf_counter()
        hits = scene.check(frames)
        t_check += time.perf_counter() - t2
        t_fk += t2 - t1
        n_queries += hits.n_queries
        hits_pose.append(hits.pose + s)
        hits_a += hits.body_a
        hits_b += hits.body_b
        hits_p.append(hits.point_base)
        hits_d.append(hits.depth)
    pose = np.concatenate(hits_pose)
    point = np.vstack(hits_p) if hits_p else np.zeros((0, 3))
    depth = np.concatenate(hits_d)
    # the TCP touches the table where the pad is on the part at its lowest point (the table's top)
    keep = tcp_grazes_table(hits_a, hits_b, depth, invert=True)
    keep &= np.array([not (a == TCP_BODY and b == "table" and contact_fine[p]) for a, b, p in zip(hits_a, hits_b, pose)],
                     dtype=bool)
    if not keep.all():
        pose, point, depth = pose[keep], point[keep], depth[keep]
        hits_a = [a for a, k in zip(hits_a, keep) if k]
        hits_b = [b for b, k in zip(hits_b, keep) if k]
    base2part = cell.base2part
    events = _events(pose, hits_a, hits_b, point @ base2part[:3, :3].T + base2part[:3, 3], depth,
                     t_fine, sample_fine, pass_fine, after_fine, contact_fine)
    seconds = time.perf_counter() - t0
    log.info("collision check: %d poses (%d written samples), %d coal queries, %d collision(s), %.2f s",
             len(q_fine), len(idx), n_queries, len(events), seconds)
    return CollisionReport(events, len(q_fine), n_queries, seconds, cell,
                           timings={"scene_s": t_scene, "fk_s": t_fk, "check_s": t_check})


def _events(pose, body_a, body_b, point_part, depth, t, sample, pass_index, after, contact) -> list[CollisionEvent]:
    """Group hits into runs of consecutive poses on the same pair of bodies (gaps of one pose merged)."""
    runs: dict = {}
    out: list[CollisionEvent] = []
    for k in np.argsort(pose, kind="stable"):
        key = (body_a[k], body_b[k])
        p = int(pose[k])
        run = runs.get(key)
        if run is not None and p - run["last"] <= 2 and pass_index[p] == pass_index[run["first"]]:
            run["last"] = p
            run["depth"] = max(run["depth"], float(depth[k]))
            continue
        if run is not None:
            out.append(_event(key, run, t, sample, pass_index, after, contact))
        runs[key] = {"first": p, "last": p, "depth": float(depth[k]), "point": point_part[k]}
    out += [_event(key, run, t, sample, pass_index, after, contact) for key, run in runs.items()]
    out.sort(key=lambda e: e.t_start)
    return out


def _event(key, run, t, sample, pass_index, after, contact) -> CollisionEvent:
    f = run["first"]
    return CollisionEvent(body_a=key[0], body_b=key[1], pass_index=int(pass_index[f]), after_pass=int(after[f]),
                          t_start=float(t[f]), t_end=float(t[run["last"]]), sample=int(sample[f]),
                          point_part=np.asarray(run["point"], dtype=float), depth=run["depth"],
                          contact=bool(contact[f]))
