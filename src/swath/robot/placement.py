"""Placement search: where to put the part in front of the robot so the whole job is reachable.

A grid over the part's position ``x, y`` (m, base frame) and yaw about the base z-axis, at a fixed
table height (the part's lowest point at ``table_z``), scored on a subsample of the trajectory:
first the fraction of poses some allowed branch reaches, then the mean of the smallest normalised
singularity/limit measure.  The best few grid cells are scored again on the whole trajectory with
:func:`swath.robot.solve.solve_trajectory` (one continuous branch); the best of those wins.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from ..cell import Cell
from ..errors import InputError
from .models import RobotModel
from .pose import make_transform, poses_from_trajectory, rot_z
from .solve import Margins, branch_table, solve_trajectory

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class Placement:
    """Result of :func:`search_placement`.

    Attributes
    ----------
    cell : Cell
        The cell with the part placed.
    x, y, z : float
        Part frame origin in the base frame, m.
    yaw : float
        Part rotation about the base z-axis, rad.
    reachable_fraction : float
        Fraction of all trajectory samples reached on one continuous branch.
    score : float
        Mean manipulability over the reached samples (dimensionless).
    evaluated : int
        Grid cells scored.
    solved : int
        Best cells solved on the whole trajectory (``n_refine``, more while none reached every pose).
    """

    cell: Cell
    x: float
    y: float
    z: float
    yaw: float
    reachable_fraction: float
    score: float
    evaluated: int
    solved: int = 0

    def as_record(self) -> dict:
        return {"x_m": self.x, "y_m": self.y, "z_m": self.z, "yaw_rad": self.yaw,
                "reachable_fraction": self.reachable_fraction, "placement_score": self.score,
                "placements_evaluated": self.evaluated, "placements_solved": self.solved}


def _placement(x, y, z_origin, yaw) -> np.ndarray:
    return make_transform(rot_z(yaw), [x, y, z_origin])


def search_placement(trajectory, model: RobotModel, cell: Cell | None = None, *, table_z: float = 0.0,
                     n_xy: int = 9, yaws=None, margins: Margins | None = None, n_sample: int = 150,
                     n_refine: int = 4, max_refine: int = 32) -> Placement:
    """Search the part placement that reaches the whole job with the largest margin.

    Parameters
    ----------
    trajectory : Trajectory
        TCP poses in the part frame, m.
    model : RobotModel
    cell : Cell, optional
        Its tool (``tcp2flange``) is kept; its placement is replaced (default: TCP on the flange).
    table_z : float
        Height of the part's lowest trajectory point in the base frame, m (default 0: the robot
        stands on the table).
    n_xy : int
        Grid points per axis over ``x`` in [0.25, 0.95]·reach and ``y`` in [−0.6, 0.6]·reach.
    yaws : sequence of float, optional
        Part yaw angles, rad (default 0, 90°, 180°, 270°).
    margins : Margins, optional
        Default :class:`Margins`.
    n_sample : int
        Contact samples scored per grid cell.
    n_refine : int
        Best grid cells solved on the whole trajectory (after a local refinement of the best
        cell: half grid steps in x and y, 22.5° in yaw).
    max_refine : int
        While none of the cells solved so far reaches every pose, the next best cells are solved
        too, up to this many in all (about 0.25 s each for 2700 poses on a UR5e): the sampled
        score sees ``n_sample`` poses, so a lone unreachable pose between them can hide in its
        best cells (bezier_dac_cad on a UR5e: the best 8 cells each miss one pose of 2667, the 9th reaches all).

    Returns
    -------
    Placement
    """
    cell = Cell() if cell is None else cell
    margins = Margins() if margins is None else margins
    yaws = (0.0, math.pi / 2, math.pi, 1.5 * math.pi) if yaws is None else tuple(yaws)
    tcp2part = poses_from_trajectory(trajectory)
    centre = 0.5 * (trajectory.position.min(axis=0) + trajectory.position.max(axis=0))
    z_origin = table_z - trajectory.position[:, 2].min()
    pick = np.flatnonzero(trajectory.contact)
    if len(pick) == 0:
        pick = np.arange(len(trajectory))
    pick = pick[np.linspace(0, len(pick) - 1, min(n_sample, len(pick))).astype(int)]
    sample = tcp2part[pick]
    reach = model.reach
    inv_tool = np.linalg.inv(cell.tcp2flange)
    no_pass = np.zeros(len(sample), bool)

    def score(x, y, yaw):
        # place the part centre (not its origin) on the grid point
        c_rot = rot_z(yaw) @ centre
        part2base = _placement(x - c_rot[0], y - c_rot[1], z_origin, yaw)
        q, feas, _ = branch_table(part2base @ sample @ inv_tool, model, margins, same_pass=no_pass)
        best = feas.sum(axis=0).argmax()
        ok = feas[:, best]
        manip = model.singularity_measures(q[ok, best])["manipulability"].mean() if ok.any() else 0.0
        return (ok.mean(), feas.any(axis=1).mean(), manip, part2base, (x, y, yaw))

    xs = np.linspace(0.25, 0.95, n_xy) * reach
    ys = np.linspace(-0.6, 0.6, n_xy) * reach
    scored = [score(x, y, yaw) for yaw in yaws for x in xs for y in ys]
    # local refinement around the best grid cell: half steps in x, y and 22.5° in yaw
    scored.sort(key=lambda s: (s[0], s[1], s[2]), reverse=True)
    x0, y0, yaw0 = scored[0][4]
    dx, dy = 0.5 * (xs[1] - xs[0]), 0.5 * (ys[1] - ys[0])
    scored += [score(x0 + i * dx, y0 + j * dy, yaw0 + k * math.pi / 8)
               for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1) if (i, j, k) != (0, 0, 0)]
    scored.sort(key=lambda s: (s[0], s[1], s[2]), reverse=True)
    best: tuple | None = None
    solved = 0
    for i, (frac_branch, frac, manip, part2base, _) in enumerate(scored[:max(n_refine, max_refine)]):
        if i >= n_refine and best is not None and best[0][0] >= 1.0:
            break
        trial = cell.with_base(part2base)
        sol = solve_trajectory(trajectory, model, trial, margins=margins, warn=False)   # a trial, not the answer
        solved += 1
        m = np.nanmean(sol.measures["manipulability"]) if sol.reachable.any() else 0.0
        key = (sol.reachable_fraction, m)
        if best is None or key > best[0]:
            best = (key, trial, part2base)
    if best is None:
        raise InputError("placement search solved no cell; give n_refine or max_refine >= 1")
    (frac, m), trial, part2base = best
    yaw = math.atan2(part2base[1, 0], part2base[0, 0])
    log.info("placement for %s: (%.3f, %.3f, %.3f) m, yaw %.0f deg, %.2f %% reachable (%d cells solved)", model.name,
             *part2base[:3, 3], math.degrees(yaw), 100 * frac, solved)
    return Placement(cell=trial, x=float(part2base[0, 3]), y=float(part2base[1, 3]), z=float(part2base[2, 3]),
                     yaw=yaw, reachable_fraction=float(frac), score=float(m), evaluated=len(scored),
                     solved=solved)
