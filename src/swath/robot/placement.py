"""Placement search: where to put the part in front of the robot so the whole job is reachable.

The part stands on a table (its lowest point at ``table_z`` in the base frame) and may turn about the
base z-axis; the search chooses its position ``x, y``, its yaw, and the rotation of the TCP about the
tool axis (a pad is round, so the controller's TCP frame may turn about z freely: RoboDK's ±180°
tool-axis freedom), to stay away from joint limits and singularities.

1. **Size against reach** (:func:`check_fits_reach`, milliseconds): the part's footprint must stay
   outside the *keep-out cylinder*, a vertical cylinder of radius ``keep_out`` about the base axis
   where the robot stands (default :func:`default_keep_out`), so the side of the part away from the
   robot lies at least ``max(r + w(θ), hypot(r, L(θ)/2))`` from the base axis, with ``w`` the
   footprint's width seen from the robot and ``L`` its length across, for the best direction θ.
   When that exceeds the horizontal reach (nominal reach plus the TCP offset) no placement can work
   and the search refuses at once, saying what would: a robot with that reach, splitting the part
   into setups, or a positioner.
2. **Grid** over ``x, y`` and yaw: cells where the footprint enters the keep-out cylinder are
   dropped; the rest are ranked by the fraction of the part within horizontal reach, and the best
   ``n_ik`` are scored by IK on ``n_sample`` contact samples (fraction reached on one branch, then
   how many of the warning thresholds on manipulability, wrist sine and joint-limit margin the
   reached configurations keep, then manipulability), followed by a local refinement and the
   tool-axis rotations.
3. The best few cells are solved on the trajectory (decimated to at most ``refine_samples``
   samples) with :func:`swath.robot.solve.solve_trajectory`; the best of those by the same ranking
   (with fewer shoulder/elbow changes, then a joint-limit margin up to twice its warning threshold,
   preferred before manipulability) wins.

The search's work is counted, not timed (a fixed number of cells scored and at most ``max_refine``
solved), so its answer does not depend on the machine's speed or load; a wall-clock safety cap
(:data:`SAFETY_CAP_S`) is a last resort, warned when reached.  The arm-in-part test runs on a
distance grid (:mod:`swath.robot.placement_grid`), which gives the k-d tree's answers faster.
``progress(message, done, total)`` hears about the search in poses put through inverse kinematics.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, replace

import numpy as np

from ..cell import Cell
from ..errors import InfeasibleError, InputError
from .models import ROBOTS, RobotModel
from .pose import make_transform, poses_from_trajectory, rot_z
from .solve import Margins, branch_table, solve_trajectory

log = logging.getLogger(__name__)


#: Thresholds of the robot stage's warnings, which the search also steers clear of: the Yoshikawa
#: manipulability (linear rows divided by the reach), |sin| of the wrist angle (between the axes of
#: joints 4 and 6), and the smallest distance of any joint from its limit, rad.
WARN_MANIPULABILITY = 0.01
WARN_WRIST_SIN = math.sin(math.radians(10.0))
WARN_JOINT_LIMIT_MARGIN = math.radians(5.0)


def _clear_of_warnings(model: RobotModel, q) -> int:
    """How many of the three warning thresholds joint rows ``q`` (n, 6) all keep (0..3)."""
    if not len(q):
        return 0
    m = model.singularity_measures(q)
    return (int(np.min(m["manipulability"]) >= WARN_MANIPULABILITY) + int(np.min(m["wrist"]) >= WARN_WRIST_SIN)
            + int(np.min(model.joint_limit_margin(q)) >= WARN_JOINT_LIMIT_MARGIN))


def default_keep_out(model: RobotModel) -> float:
    """Radius of the keep-out cylinder about the base axis, m: 0.2 m plus a tenth of the reach
    (UR10e 0.33 m, IRB 4600 0.41 m, KR 120 0.47 m), the robot's base and its shoulder's sweep."""
    return 0.2 + 0.1 * model.reach


@dataclass(frozen=True, eq=False)
class Placement:
    """Result of :func:`search_placement`.

    Attributes
    ----------
    cell : Cell
        The cell with the part placed (and the TCP turned by ``tool_rotation`` about its z-axis).
    x, y, z : float
        Part frame origin in the base frame, m.
    yaw : float
        Part rotation about the base z-axis, rad.
    reachable_fraction : float
        Fraction of the solved samples reached on one continuous branch.
    score : float
        Mean manipulability over the reached samples (dimensionless).
    evaluated : int
        Grid cells scored by IK.
    solved : int
        Best cells solved on the (decimated) trajectory.
    tool_rotation : float
        Rotation of the TCP frame about its z-axis, rad (the cell's ``tcp2flange`` includes it).
    keep_out : float
        Radius of the keep-out cylinder about the base axis, m.
    clearance : float
        Horizontal distance of the part's footprint from the base axis, m (≥ ``keep_out``).
    time_s : float
        Wall time of the search, s.
    ik_poses : int
        Poses put through inverse kinematics by the search (its work).
    trials : tuple of dict
        The cells solved on the trajectory, in order: ``x_m``, ``y_m``, ``yaw_rad``,
        ``tool_rotation_rad``, ``reachable_fraction``, ``thresholds_kept`` (0..3),
        ``arm_changes`` (shoulder/elbow branch changes), ``min_joint_limit_margin_rad``,
        ``mean_manipulability``.
    warnings : tuple of str
        The search's warnings (the safety cap reached).
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
    tool_rotation: float = 0.0
    keep_out: float = 0.0
    clearance: float = float("nan")
    time_s: float = 0.0
    ik_poses: int = 0
    trials: tuple = ()
    warnings: tuple = ()

    def as_record(self) -> dict:
        return {"x_m": self.x, "y_m": self.y, "z_m": self.z, "yaw_rad": self.yaw,
                "reachable_fraction": self.reachable_fraction, "placement_score": self.score,
                "placements_evaluated": self.evaluated, "placements_solved": self.solved,
                "tool_rotation_rad": self.tool_rotation, "keep_out_m": self.keep_out,
                "part_clearance_from_base_axis_m": self.clearance, "placement_search_s": self.time_s,
                "placement_ik_poses": self.ik_poses}


def _placement(x, y, z_origin, yaw) -> np.ndarray:
    return make_transform(rot_z(yaw), [x, y, z_origin])


def _hull(xy: np.ndarray) -> np.ndarray:
    """(h, 2) convex hull vertices of points (n, 2), counter-clockwise."""
    from scipy.spatial import ConvexHull

    if len(xy) < 3:
        return xy
    try:
        return xy[ConvexHull(xy).vertices]
    except Exception:                    # degenerate (collinear) footprint: its extreme points
        return xy[[np.argmin(xy[:, 0]), np.argmax(xy[:, 0])]]


def footprint_need(xy, keep_out: float, *, step_deg: float = 1.0):
    """Smallest horizontal reach that can serve a footprint kept out of the keep-out cylinder.

    Parameters
    ----------
    xy : (n, 2) float
        Footprint points (the part seen from above), m.
    keep_out : float
        Keep-out radius about the base axis, m.
    step_deg : float
        Directions tried, deg.

    Returns
    -------
    need : float
        ``min over θ of max(r + w(θ), hypot(r, L(θ)/2))``, m: with the footprint outside a disc of
        radius ``r`` about the base, the farthest footprint point is at least this far from it
        (``w`` the width along θ, the direction from the robot, ``L`` the length across it).
    theta : float
        The best direction, rad.
    width, length : float
        ``w`` and ``L`` there, m.
    """
    hull = _hull(np.asarray(xy, dtype=float))
    th = np.radians(np.arange(0.0, 180.0, step_deg))
    d = np.c_[np.cos(th), np.sin(th)]
    proj = hull @ d.T
    w = proj.max(axis=0) - proj.min(axis=0)
    across = hull @ np.c_[-np.sin(th), np.cos(th)].T
    length = across.max(axis=0) - across.min(axis=0)
    need = np.maximum(keep_out + w, np.hypot(keep_out, length / 2))
    k = int(np.argmin(need))
    return float(need[k]), float(th[k]), float(w[k]), float(length[k])


def horizontal_reach(model: RobotModel, cell: Cell) -> float:
    """Farthest the TCP gets from the base axis, m: the nominal reach plus the TCP's offset from the flange."""
    return float(model.reach + np.linalg.norm(cell.tcp2flange[:3, 3]))


def check_fits_reach(points, model: RobotModel, cell: Cell, *, keep_out: float) -> dict:
    """Refuse a part whose footprint cannot lie within reach outside the keep-out cylinder.

    Parameters
    ----------
    points : (n, 3) float
        The part's points (vertices or TCP positions) in the part frame, m, z up.
    model : RobotModel
    cell : Cell
        Its tool offset counts toward the reach.
    keep_out : float
        Keep-out radius, m.

    Returns
    -------
    dict
        ``need_m``, ``reach_m``, ``width_m``, ``length_m`` (the check's figures).

    Raises
    ------
    InfeasibleError
        Naming the figures and what would place the part: a robot with the reach needed (catalogue
        robots that have it), splitting the part into setups, or a positioner.
    """
    pts = np.asarray(points, dtype=float)
    need, theta, width, length = footprint_need(pts[:, :2], keep_out)
    reach = horizontal_reach(model, cell)
    info = {"need_m": need, "reach_m": reach, "width_m": width, "length_m": length}
    if need <= reach:
        return info
    tool = reach - model.reach
    models = {m.name: m.reach for m in (f() for f in ROBOTS.values())}
    bigger = [f"{name} ({r:.2f} m)" for name, r in sorted(models.items(), key=lambda kv: kv[1]) if r + tool >= need]
    # setups: split the footprint across its length until each piece fits
    pieces = None
    across = pts[:, :2] @ np.array([-math.sin(theta), math.cos(theta)])
    along = pts[:, :2] @ np.array([math.cos(theta), math.sin(theta)])
    for k in range(2, 7):
        edges = np.linspace(across.min(), across.max(), k + 1)
        ok = True
        for a, b in zip(edges[:-1], edges[1:]):
            sel = (across >= a) & (across <= b)
            if sel.sum() >= 3 and footprint_need(np.c_[along[sel], across[sel]], keep_out)[0] > reach:
                ok = False
                break
        if ok:
            pieces = k
            break
    ways = []
    if bigger:
        ways.append(f"a robot with at least {need:.2f} m reach (e.g. {', '.join(bigger[:3])})")
    else:
        ways.append(f"a robot with at least {need:.2f} m reach")
    if pieces is not None:
        ways.append(f"splitting the job into {pieces} setups of strips {length / pieces:.2f} m wide "
                    "(re-clamping the part between them)")
    ways.append("a positioner (turntable or track) that brings each side of the part to the robot")
    raise InfeasibleError(
        f"the part does not fit the reach of {model.name}: its footprint is {width:.2f} m deep and {length:.2f} m "
        f"long at best, so with the part outside the {keep_out:.2f} m keep-out cylinder about the robot's base "
        f"its far side lies at least {need:.2f} m from the base axis, beyond the {reach:.2f} m the TCP reaches. "
        f"What would work: {'; '.join(ways)}")


def _decimate(trajectory, max_samples: int):
    """The trajectory on at most about ``max_samples`` samples (every k-th, keeping each pass's ends)."""
    n = len(trajectory)
    if n <= max_samples:
        return trajectory
    from dataclasses import replace

    k = int(math.ceil(n / max_samples))
    keep = np.zeros(n, bool)
    keep[::k] = True
    change = np.flatnonzero(np.diff(trajectory.pass_index) != 0)
    keep[change] = keep[np.minimum(change + 1, n - 1)] = True
    keep[-1] = True
    idx = np.flatnonzero(keep)
    return replace(trajectory, t=trajectory.t[idx], position=trajectory.position[idx],
                   quaternion=trajectory.quaternion[idx], contact=trajectory.contact[idx],
                   feed=trajectory.feed[idx], pass_index=trajectory.pass_index[idx],
                   extra={k_: v[idx] for k_, v in trajectory.extra.items()})


#: Wall-clock cap of the placement search, s: a last resort only (the search stops by counting its
#: work, so its answer does not depend on the machine's speed or load); reaching it is warned.
SAFETY_CAP_S = 600.0

_now = time.perf_counter          # the clock of the safety cap (a test replaces it)


def _arm_changes(solution) -> int:
    """Branch changes of a solution that change the shoulder or the elbow (not only the wrist)."""
    def arm(name: str) -> str:
        return name.rsplit("-wrist", 1)[0]
    return sum(arm(s["from"]) != arm(s["to"]) for s in solution.switches)


def _fast_margins(margins: Margins) -> Margins:
    """``margins`` with its arm-in-part check answered from a distance grid (the same answers,
    :mod:`swath.robot.placement_grid`), when it is an :class:`ArmPartCheck`."""
    check = margins.arm_part
    if check is None or not (hasattr(check, "tree") and hasattr(check, "links")) or hasattr(check, "distance"):
        return margins
    from .placement_grid import GridArmPartCheck

    return replace(margins, arm_part=GridArmPartCheck(check))


def search_placement(trajectory, model: RobotModel, cell: Cell | None = None, *, table_z: float = 0.0,
                     n_xy: int = 9, yaws=None, margins: Margins | None = None, n_sample: int = 150,
                     n_refine: int = 4, max_refine: int = 8, keep_out: float | None = None,
                     tool_rotations=None, n_ik: int = 48, refine_samples: int = 6000,
                     safety_cap_s: float = SAFETY_CAP_S, points=None, progress=None) -> Placement:
    """Search the part placement that reaches the whole job with the largest margin.

    The search's work is counted, not timed: ``n_ik`` grid cells, at most 26 neighbours of the best
    and 3 × (tool rotations) cells are scored on ``n_sample`` contact samples, and at most
    ``max_refine`` cells are solved on the trajectory, so the same input gives the same placement on
    any machine under any load.

    Parameters
    ----------
    trajectory : Trajectory
        TCP poses in the part frame, m.
    model : RobotModel
    cell : Cell, optional
        Its tool (``tcp2flange``) is kept; its placement is replaced (default: TCP on the flange).
    table_z : float
        Height of the part's lowest point in the base frame, m (default 0: the robot stands on the table).
    n_xy : int
        Grid points per axis over ``x`` and ``y`` in [−1, 1]·(horizontal reach).
    yaws : sequence of float, optional
        Part yaw angles, rad (default 0, 90°, 180°, 270°).
    margins : Margins, optional
        Default :class:`Margins`.  Its arm-in-part check, if any, is answered from a distance grid
        during the search (:mod:`swath.robot.placement_grid`; the same answers).
    n_sample : int
        Contact samples scored per grid cell.
    n_refine : int
        Best cells solved on the (decimated) trajectory at least.
    max_refine : int
        The work budget: while none of the cells solved so far reaches every pose, further cells
        are solved, up to this many in all; then the other tool rotations are solved on the best
        of them (unless it already reaches every pose, keeps the three warning thresholds and
        changes neither shoulder nor elbow).
    keep_out : float, optional
        Keep-out radius about the base axis, m (default :func:`default_keep_out`).
    tool_rotations : sequence of float, optional
        TCP rotations about the tool axis tried on the best cells, rad (default 0, ±90°, 180°).
    n_ik : int
        Grid cells scored by IK (the best by the fraction of the part within reach).
    refine_samples : int
        The trajectory is decimated to about this many samples for the refinement solves.
    safety_cap_s : float
        Wall-clock last resort, s: no further solve starts after this (default :data:`SAFETY_CAP_S`,
        far above what the budget takes); reaching it is warned (``W-ROBOT-PLACE-CAPPED``), since
        the answer then depends on the machine's speed.
    points : (n, 3) float, optional
        The part's points for the footprint, part frame, m (default: the trajectory's positions).
    progress : callable, optional
        ``progress(message, done, total)``: one message for the whole search, with ``done`` and
        ``total`` in poses put through inverse kinematics (``total`` the budget's, reached at the end).

    Returns
    -------
    Placement

    Raises
    ------
    InfeasibleError
        When the part cannot fit the reach (:func:`check_fits_reach`) or no grid cell keeps it out of
        the keep-out cylinder.
    """
    t_start = time.perf_counter()
    t_cap = _now()
    cell = Cell() if cell is None else cell
    margins = Margins() if margins is None else margins
    keep_out = default_keep_out(model) if keep_out is None else float(keep_out)
    yaws = (0.0, math.pi / 2, math.pi, 1.5 * math.pi) if yaws is None else tuple(yaws)
    rotations = (0.0, math.pi / 2, -math.pi / 2, math.pi) if tool_rotations is None else tuple(tool_rotations)
    pts = trajectory.position if points is None else np.asarray(points, dtype=float)
    check_fits_reach(pts, model, cell, keep_out=keep_out)
    margins = _fast_margins(margins)
    hull = _hull(pts[:, :2])
    tcp2part = poses_from_trajectory(trajectory)
    centre = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    z_origin = table_z - pts[:, 2].min()
    pick = np.flatnonzero(trajectory.contact)
    if len(pick) == 0:
        pick = np.arange(len(trajectory))
    pick = pick[np.linspace(0, len(pick) - 1, min(n_sample, len(pick))).astype(int)]
    sample = tcp2part[pick]
    reach = horizontal_reach(model, cell)
    no_pass = np.zeros(len(sample), bool)
    far_pts = pts[np.linspace(0, len(pts) - 1, min(len(pts), 2000)).astype(int), :2]

    def part2base_of(x, y, yaw):
        # the part centre (not its origin) goes on the grid point
        c_rot = rot_z(yaw) @ centre
        return _placement(x - c_rot[0], y - c_rot[1], z_origin, yaw)

    def clearance(part2base) -> float:
        """Horizontal distance of the footprint hull from the base axis (0 when the axis is inside)."""
        h = hull @ part2base[:2, :2].T + part2base[:2, 3]
        inside = len(h) >= 3 and _point_in_convex(h)
        if inside:
            return 0.0
        a, b = h, np.roll(h, -1, axis=0)
        ab = b - a
        t = np.clip(-(a * ab).sum(1) / np.maximum((ab * ab).sum(1), 1e-18), 0, 1)
        return float(np.min(np.linalg.norm(a + t[:, None] * ab, axis=1)))

    def within_reach(part2base) -> float:
        p = far_pts @ part2base[:2, :2].T + part2base[:2, 3]
        return float(np.mean(np.linalg.norm(p, axis=1) <= reach))

    work = 0

    def score(x, y, yaw, rotation=0.0):
        nonlocal work
        work += len(sample)
        part2base = part2base_of(x, y, yaw)
        tool = cell.tcp2flange @ make_transform(rot_z(rotation))
        q, feas, _ = branch_table(part2base @ sample @ np.linalg.inv(tool), model, margins, same_pass=no_pass,
                                  part2base=part2base, tool=cell.tool)
        best = feas.sum(axis=0).argmax()
        ok = feas[:, best]
        manip = model.singularity_measures(q[ok, best])["manipulability"].mean() if ok.any() else 0.0
        # reached fraction first, then how many warning thresholds the reached rows keep, then manipulability
        return (ok.mean(), _clear_of_warnings(model, q[ok, best]), feas.any(axis=1).mean() + manip, part2base,
                (x, y, yaw, rotation))

    xs = np.linspace(-1.0, 1.0, n_xy) * reach
    candidates = []
    for yaw in yaws:
        for x in xs:
            for y in xs:
                b2p = part2base_of(x, y, yaw)
                if clearance(b2p) >= keep_out:
                    candidates.append((within_reach(b2p), x, y, yaw))
    if not candidates:
        raise InfeasibleError(f"no placement on the search grid keeps the part outside the {keep_out:.2f} m keep-out "
                              f"cylinder within {reach:.2f} m of the base; lower the keep-out (--keep-out) or "
                              "give the placement (--base)")
    # a stable sort on the reach alone: ties keep the grid's order, so the same cells are scored every time
    candidates.sort(key=lambda c: c[0], reverse=True)
    candidates = candidates[:n_ik]
    coarse = _decimate(trajectory, refine_samples)
    n_rot = sum(r != 0.0 for r in rotations)
    # the work budget in poses through inverse kinematics: the grid cells, the 26 neighbours of the best,
    # the tool rotations on the best 3, and the trajectory solves
    limit = max(n_refine, max_refine)
    total = (len(candidates) + 26 + 3 * n_rot) * len(sample) + (limit + n_rot) * len(coarse)
    message = (f"placement search for {model.name}: {len(candidates)} + 26 + {3 * n_rot} cells scored on "
               f"{len(sample)} poses, up to {limit} + {n_rot} solved on {len(coarse)} poses")
    done = 0
    say = progress or (lambda message, done, total: None)
    say(message, 0, total)
    scored = []
    for _, x, y, yaw in candidates:
        scored.append(score(x, y, yaw))
        done += len(sample)
        say(message, done, total)
    key = lambda s: (s[0], s[1], s[2])                      # noqa: E731
    scored.sort(key=key, reverse=True)
    # local refinement around the best cell: half steps in x, y and 22.5° in yaw (kept out of the cylinder)
    x0, y0, yaw0, _ = scored[0][4]
    dx = 0.5 * (xs[1] - xs[0]) if len(xs) > 1 else 0.1
    local = [(x0 + i * dx, y0 + j * dx, yaw0 + k * math.pi / 8)
             for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1) if (i, j, k) != (0, 0, 0)]
    for c in local:
        if clearance(part2base_of(*c)) >= keep_out:
            scored.append(score(*c))
        done += len(sample)
        say(message, done, total)
    scored.sort(key=key, reverse=True)
    # the tool-axis rotation: tried on the best few cells
    top = [s[4] for s in scored[:3]]
    for x, y, yaw, _ in top:
        for r in rotations:
            if r != 0.0:
                scored.append(score(x, y, yaw, r))
                done += len(sample)
                say(message, done, total)
    done = (len(candidates) + 26 + 3 * n_rot) * len(sample)
    scored.sort(key=key, reverse=True)
    # the cells solved: distinct positions in score order, each with its best-scoring tool rotation; then
    # the other tool rotations on the best of them
    order, seen = [], set()
    for s_ in scored:
        x_, y_, yaw_, _ = s_[4]
        where = (round(x_, 6), round(y_, 6), round(math.remainder(yaw_, 2 * math.pi), 6))
        if where not in seen:
            seen.add(where)
            order.append(s_)
    best: tuple | None = None
    warnings: list[str] = []
    trials: list[dict] = []

    def capped() -> bool:
        if not trials or _now() - t_cap <= safety_cap_s:
            return False
        warnings.append(f"robot: the placement search reached its {safety_cap_s:.0f} s safety cap after solving "
                        f"{len(trials)} of up to {limit + n_rot} cells (the machine is slow or loaded), so it stopped "
                        "early and its answer may differ from the same search on a quicker machine; give the "
                        "placement (--base) to be sure of it [W-ROBOT-PLACE-CAPPED]")
        return True

    def solve(part2base, params):
        nonlocal best, done, work
        work += len(coarse)
        trial = replace(cell.with_base(part2base), tcp2flange=cell.tcp2flange @ make_transform(rot_z(params[3])))
        sol = solve_trajectory(coarse, model, trial, margins=margins, warn=False)   # a trial, not the answer
        done += len(coarse)
        ok = sol.reachable
        m = float(np.nanmean(sol.measures["manipulability"])) if ok.any() else 0.0
        margin = float(np.nanmin(sol.measures["joint_limit_margin_rad"])) if ok.any() else 0.0
        # reached first, then the thresholds kept, then fewest shoulder/elbow changes, then the joint-limit
        # margin up to twice its warning threshold, then manipulability
        k = (sol.reachable_fraction, _clear_of_warnings(model, sol.q[ok]), -_arm_changes(sol),
             min(margin, 2 * WARN_JOINT_LIMIT_MARGIN), m)
        trials.append({"x_m": float(part2base[0, 3]), "y_m": float(part2base[1, 3]), "yaw_rad": float(params[2]),
                       "tool_rotation_rad": float(params[3]), "reachable_fraction": k[0], "thresholds_kept": k[1],
                       "arm_changes": -k[2], "min_joint_limit_margin_rad": margin, "mean_manipulability": m})
        if best is None or k > best[0]:
            best = (k, trial, part2base, params)
        say(message, done, total)

    stopped = False
    for i, (_, _, _, part2base, params) in enumerate(order[:limit]):
        if i >= n_refine and best is not None and best[0][0] >= 1.0:
            break
        if capped():
            stopped = True
            break
        solve(part2base, params)
    if best is not None and not stopped and best[0][:3] != (1.0, 3, 0):
        x_, y_, yaw_, r0 = best[3]
        part2base = best[2]
        for r in rotations:
            if r != r0 and not capped():
                solve(part2base, (x_, y_, yaw_, r))
    if done < total:                    # stopped early: the step is done
        say(message, total, total)
    if best is None:
        raise InputError("placement search solved no cell; give n_refine or max_refine >= 1")
    (frac, _, _, _, m), trial, part2base, params = best
    yaw = math.atan2(part2base[1, 0], part2base[0, 0])
    elapsed = time.perf_counter() - t_start
    log.info("placement for %s: (%.3f, %.3f, %.3f) m, yaw %.0f deg, tool turned %.0f deg, %.2f %% reachable "
             "(%d cells solved, %.1f s)", model.name, *part2base[:3, 3], math.degrees(yaw), math.degrees(params[3]),
             100 * frac, len(trials), elapsed)
    return Placement(cell=trial, x=float(part2base[0, 3]), y=float(part2base[1, 3]), z=float(part2base[2, 3]),
                     yaw=yaw, reachable_fraction=float(frac), score=float(m), evaluated=len(scored),
                     solved=len(trials), tool_rotation=float(params[3]), keep_out=keep_out,
                     clearance=clearance(part2base), time_s=elapsed, ik_poses=work, trials=tuple(trials),
                     warnings=tuple(warnings))


def _point_in_convex(poly: np.ndarray) -> bool:
    """Whether the origin lies inside a convex polygon (h, 2) given counter-clockwise."""
    a, b = poly, np.roll(poly, -1, axis=0)
    cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return bool(np.all(cross >= 0) or np.all(cross <= 0))
