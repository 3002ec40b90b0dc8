"""Reachability map over a part: can the robot put the tool normal to the surface at each vertex?

For each (sub-sampled) surface vertex the TCP is placed on the vertex with z along minus the vertex
normal and turned about that axis to ``n_headings`` headings; the vertex is reachable if some
heading and branch is feasible (:func:`swath.robot.solve.branch_table` rules).  The best feasible
configuration gives the manipulability and the joint-limit margin shown in the report.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..cell import Cell
from .models import RobotModel
from .pose import make_transform, rot_z
from .solve import Margins, branch_table


@dataclass(frozen=True, eq=False)
class ReachMap:
    """Per-vertex reachability.

    Attributes
    ----------
    vertex_index : (m,) int
        Surface vertices evaluated.
    points : (m, 3) float
        Their positions, part frame, m.
    reachable : (m,) bool
    manipulability : (m,) float
        Best feasible manipulability (0 where unreachable), dimensionless.
    joint_limit_margin : (m,) float
        Joint-limit margin of that configuration, rad (NaN where unreachable).
    """

    vertex_index: np.ndarray
    points: np.ndarray
    reachable: np.ndarray
    manipulability: np.ndarray
    joint_limit_margin: np.ndarray

    @property
    def reachable_fraction(self) -> float:
        return float(self.reachable.mean()) if len(self.reachable) else 0.0


def _frames_along(normals) -> np.ndarray:
    """(m, 3, 3) rotations with z = −normal and some x perpendicular to it."""
    z = -normals / np.linalg.norm(normals, axis=1, keepdims=True)
    helper = np.where(np.abs(z[:, :1]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
    x = np.cross(helper, z)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=2)


def reachability_map(surface, model: RobotModel, cell: Cell, *, max_vertices: int = 1500, n_headings: int = 8,
                     margins: Margins | None = None, seed: int = 0) -> ReachMap:
    """Reachability of the surface with the tool normal to it.

    Parameters
    ----------
    surface : Surface
        The part (``vertices`` (V, 3) m, ``vertex_normals`` outward).
    model : RobotModel
    cell : Cell
    max_vertices : int
        At most this many vertices (a seeded random subset when the surface has more).
    n_headings : int
        Tool headings tried about the normal.
    margins : Margins, optional
        Default :class:`Margins`.
    seed : int
        Seed of the vertex subset.
    """
    verts = np.asarray(surface.vertices)
    normals = np.asarray(surface.vertex_normals)
    idx = np.arange(len(verts))
    if len(idx) > max_vertices:
        idx = np.sort(np.random.default_rng(seed).choice(len(verts), max_vertices, replace=False))
    margins = Margins() if margins is None else margins
    rot = _frames_along(normals[idx])
    m = len(idx)
    best_manip = np.zeros(m)
    margin = np.full(m, np.nan)
    reach = np.zeros(m, bool)
    for h in range(n_headings):
        r = rot @ rot_z(2 * math.pi * h / n_headings)
        tcp2part = make_transform(r, verts[idx])
        q, feas, _ = branch_table(cell.flange2base(tcp2part), model, margins, same_pass=np.zeros(m, bool),
                                  part2base=cell.part2base, tool=cell.tool)
        flat = q.reshape(-1, 6)
        ok = feas.reshape(-1)
        manip = np.zeros(len(flat))
        if ok.any():
            manip[ok] = model.singularity_measures(flat[ok])["manipulability"]
        manip = manip.reshape(feas.shape)
        b = np.argmax(manip, axis=1)
        mb = manip[np.arange(m), b]
        better = feas.any(axis=1) & (mb > best_manip)
        reach |= feas.any(axis=1)
        best_manip = np.where(better, mb, best_manip)
        if better.any():
            margin[better] = model.joint_limit_margin(q[np.arange(m), b][better])
    return ReachMap(vertex_index=idx, points=verts[idx], reachable=reach, manipulability=best_manip,
                    joint_limit_margin=margin)
