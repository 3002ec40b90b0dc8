"""Coordinated motion of the robot and a rotary positioner: the part turns, the arm follows.

:func:`run_positioner_stage` runs a job whose cell has a :class:`swath.cell.Positioner`:

1. **Axis angles** (:func:`facing_angles`): at every sample the axis turns the part so that the
   contact point's outward normal points at ``facing`` (default: from the axis toward the robot's
   base, tilted up by ``elevation``), unwrapped along the job so the axis never jumps a turn; the
   whole run is shifted by whole turns into the axis limits (refused when it cannot fit).
2. **The axis limits** (:func:`slow_for_axis`): steps where the axis would turn faster than its
   ``max_speed`` or change speed faster than its ``max_accel`` are slowed (their times stretched),
   before the arm is re-timed.
3. **The arm**: the TCP poses are carried into the robot base frame with the part at its
   rotated pose (``tcp2base = part2base(θ) @ tcp2part``), and the robot stage
   (:func:`swath.robot.run_robot_stage`) solves, splits, re-times and resamples them as for a
   fixed part whose frame is the base; the axis angle rides along as the extra column
   :data:`swath.robot.external_axis.AXIS_COLUMN`, interpolated wherever samples are added.
4. **Back to the part frame**: the re-timed samples go back into the part frame with their own
   angle (``tcp2part = base2part(θ) @ tcp2base``), so ``trajectory.csv`` stays in the part frame
   (FORMATS.md) with the ``positioner`` column (rad) after the others; the FK check is made there:
   FK of every written joint row with its axis angle against its row's pose.
5. **Collisions** (:func:`check_positioner_collisions`): the arm and the tool against the part at
   its rotated pose at every checked step (≤ 2° per joint), and against the table, the fixtures
   and themselves in the base frame.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import replace
from typing import Any

import numpy as np

from ..cell import Body, Cell, CollisionScene, Mesh, Positioner
from ..errors import InputError
from .external_axis import AXIS_COLUMN, check_axis_formats
from .pose import make_transform, matrix_to_quat, pose_error, poses_from_trajectory, quat_to_matrix

log = logging.getLogger(__name__)

__all__ = ["check_positioner_collisions", "facing_angles", "run_positioner_stage", "to_base_frame", "to_part_frame"]


def default_facing(positioner: Positioner, elevation: float = 0.0) -> np.ndarray:
    """(3,) unit direction in the base frame the contact point is turned to face: from the axis toward
    the robot base's z-axis, tilted by ``elevation`` (rad) toward the base's +z (both made
    orthogonal to the axis); straight up when the axis passes through the base's z-axis."""
    d = positioner.axis_direction
    toward = -positioner.axis_point.copy()
    toward[2] = 0.0
    toward -= np.dot(toward, d) * d
    up = np.array([0.0, 0.0, 1.0]) - d[2] * d
    if np.linalg.norm(toward) < 1e-6:
        toward = up
    if np.linalg.norm(toward) < 1e-9:
        raise InputError("the positioner's axis points at the robot base along its z-axis; give `facing` "
                         "(the direction the contact point should face, base frame)")
    toward /= np.linalg.norm(toward)
    if np.linalg.norm(up) > 1e-9 and elevation:
        up_ortho = up - np.dot(up, toward) * toward
        if np.linalg.norm(up_ortho) > 1e-9:
            up_ortho /= np.linalg.norm(up_ortho)
            toward = math.cos(elevation) * toward + math.sin(elevation) * up_ortho
    return toward


def facing_angles(trajectory, positioner: Positioner, *, facing=None, elevation: float = math.radians(30.0)
                  ) -> np.ndarray:
    """(n,) axis angles, rad, that turn each sample's contact point to face the robot.

    Parameters
    ----------
    trajectory : Trajectory
        TCP poses in the part frame.
    positioner : Positioner
    facing : (3,) float, optional
        The direction (base frame) the contact point's outward normal should point along; default
        :func:`default_facing` with ``elevation``.
    elevation : float
        Tilt of the default facing direction above the horizontal toward the robot, rad (default 30°).

    Returns
    -------
    (n,) float
        Continuous (unwrapped) angles, shifted by whole turns into the axis limits.

    Raises
    ------
    InputError
        When the angles span more than the axis limits allow, or no sample has a direction about the axis.
    """
    d = positioner.axis_direction
    f = default_facing(positioner, elevation) if facing is None else np.asarray(facing, dtype=float)
    f = f - np.dot(f, d) * d
    if np.linalg.norm(f) < 1e-9:
        raise InputError("the positioner's facing direction is along its axis; give one across the axis")
    zero = positioner.faceplate_zero2base
    beta = math.atan2(np.dot(f, zero[:3, 1]), np.dot(f, zero[:3, 0]))
    # the sample's outward direction (minus tool z), and its position, in the faceplate frame at angle 0
    p2f = positioner.part2faceplate
    normal_f = -trajectory.tool_z() @ p2f[:3, :3].T
    pos_f = trajectory.position @ p2f[:3, :3].T + p2f[:3, 3]
    use = np.where((np.hypot(normal_f[:, 0], normal_f[:, 1]) > 0.5)[:, None], normal_f, pos_f)
    ok = np.hypot(use[:, 0], use[:, 1]) > 1e-4
    if not ok.any():
        raise InputError("no sample of the trajectory lies away from the positioner's axis; check part2faceplate")
    alpha = np.arctan2(use[:, 1], use[:, 0])
    idx = np.flatnonzero(ok)
    alpha = np.interp(np.arange(len(alpha)), idx, np.unwrap(alpha[idx]))
    theta = beta - alpha
    lo, hi = positioner.limits
    span = float(theta.max() - theta.min())
    if span > hi - lo:
        raise InputError(f"the job turns the positioner through {math.degrees(span):.0f} deg but its limits allow "
                         f"{math.degrees(hi - lo):.0f} deg; plan rings (wrap mode rings) or widen the limits")
    mid = 0.5 * (theta.max() + theta.min())
    shift = 2 * math.pi * round((0.5 * (lo + hi) - mid) / (2 * math.pi))
    theta = theta + shift
    if theta.min() < lo or theta.max() > hi:          # whole turns do not fit: shift by what does
        theta = theta + (lo - theta.min() if theta.min() < lo else hi - theta.max())
    return theta


def slow_for_axis(trajectory, theta, max_speed: float, max_accel: float, *, safety: float = 0.95):
    """The trajectory re-timed so the axis keeps within ``safety`` times its speed and acceleration limits.

    The axis speed on each step is capped by ``safety · max_speed`` and by a forward and a backward
    pass that bounds the change of speed between steps (``|ω_i − ω_{i−1}| ≤ a (dt_i + dt_{i−1}) / 2``,
    through rest where the axis reverses or stands still); a step whose nominal speed is above its cap is
    stretched in time and its ``feed`` (and ``wx, wy, wz``) scaled down with it.

    Parameters
    ----------
    trajectory : Trajectory
    theta : (n,) float
        Axis angle per sample, rad.
    max_speed, max_accel : float
        rad/s and rad/s².
    """
    t = np.asarray(trajectory.t, dtype=float)
    if len(t) < 2:
        return trajectory
    dt = np.diff(t)
    step = np.diff(np.asarray(theta, dtype=float))
    turn = np.abs(step)
    sign = np.sign(step)
    nominal = np.where(dt > 0, turn / np.where(dt > 0, dt, 1.0), np.inf)
    cap = np.minimum(nominal, safety * max_speed)
    a = safety * max_accel
    for order in (range(len(cap)), range(len(cap) - 1, -1, -1)):
        prev, prev_sign, prev_dt = 0.0, 0.0, 0.0
        for i in order:
            if sign[i] != prev_sign:
                prev = 0.0
            # ω_i − ω_prev ≤ a (dt_i + dt_prev) / 2 with dt_i = |Δθ_i| / ω_i: the root of a quadratic
            b = prev + 0.5 * a * prev_dt
            cap[i] = min(cap[i], 0.5 * (b + math.sqrt(b * b + 2.0 * a * turn[i])))
            prev, prev_sign = cap[i], sign[i]
            prev_dt = turn[i] / cap[i] if turn[i] > 0 and cap[i] > 0 else dt[i]
    new_dt = np.where(turn > 0, np.maximum(dt, turn / np.maximum(cap, 1e-12)), dt)
    if np.all(new_dt <= dt):
        return trajectory
    scale = np.ones(len(t))
    slow = dt / np.maximum(new_dt, 1e-300)
    scale[1:] = np.minimum(scale[1:], slow)
    scale[:-1] = np.minimum(scale[:-1], slow)
    extra = {k: (v * scale if k in ("wx", "wy", "wz") else v) for k, v in trajectory.extra.items()}
    return replace(trajectory, t=t[0] + np.concatenate([[0.0], np.cumsum(new_dt)]), feed=trajectory.feed * scale,
                   extra=extra)


def axis_speed_accel(t, theta) -> tuple[np.ndarray, np.ndarray]:
    """The axis speed per step (rad/s) and its acceleration between steps (rad/s²).

    Samples added by linear interpolation inside a step (the robot stage's resampling) share that
    step's speed, so runs of equal speed count as one step: the acceleration is the change of speed
    between consecutive runs over the time between their midpoints.
    """
    t = np.asarray(t, dtype=float)
    dt = np.diff(t)
    w = np.diff(np.asarray(theta, dtype=float)) / np.where(dt > 0, dt, np.inf)
    if len(w) < 2:
        return np.abs(w), np.zeros(0)
    new = np.concatenate([[True], np.abs(np.diff(w)) > 1e-3 * np.abs(w[1:]) + 1e-6])
    run = np.cumsum(new) - 1
    t_mid = np.bincount(run, weights=0.5 * (t[:-1] + t[1:]) * dt) / np.maximum(np.bincount(run, weights=dt), 1e-300)
    w_run = w[new]
    accel = np.abs(np.diff(w_run)) / np.maximum(np.diff(t_mid), 1e-9)
    return np.abs(w), accel


def to_base_frame(trajectory, positioner: Positioner, theta):
    """The trajectory's TCP poses in the robot base frame with the part turned to ``theta`` (n,) rad;
    the angle is kept in the extra column :data:`AXIS_COLUMN`."""
    tcp2base = positioner.part2base(theta) @ poses_from_trajectory(trajectory)
    return replace(trajectory, position=tcp2base[:, :3, 3].copy(), quaternion=matrix_to_quat(tcp2base[:, :3, :3]),
                   extra={**trajectory.extra, AXIS_COLUMN: np.asarray(theta, dtype=float)})


def to_part_frame(trajectory, positioner: Positioner):
    """The inverse of :func:`to_base_frame`: TCP poses back in the part frame, each with its own angle."""
    theta = trajectory.extra[AXIS_COLUMN]
    tcp2base = make_transform(quat_to_matrix(trajectory.quaternion), trajectory.position)
    tcp2part = positioner.base2part(theta) @ tcp2base
    return replace(trajectory, position=tcp2part[:, :3, 3].copy(), quaternion=matrix_to_quat(tcp2part[:, :3, :3]))


def fixed_cell(cell: Cell) -> Cell:
    """The cell the arm is solved in: the part frame is the base frame (the positioner's turn is in
    the poses), no table assumed under the part."""
    return replace(cell, part2base=np.eye(4), positioner=None, auto_table=False)


def check_positioner_collisions(base_trajectory, solution, model, cell: Cell, *, part_vertices=None,
                                part_faces=None, max_step: float = math.radians(2.0)):
    """Collision check of a job on a positioner.

    The arm and tool against the table, the fixtures and themselves go through
    :func:`swath.robot.collision.check_job_collisions` in the base frame; against the part, every
    checked pose (the written samples and joint steps of at most ``max_step``) has its own axis
    angle (interpolated like the joints), and the arm's links are carried into the part frame with
    it, where the part stands still.

    Returns
    -------
    CollisionReport
        Events of both checks, in time order; ``n_poses`` the poses checked against the part.
    """
    from ..cell import MovingBody
    from .collision import CollisionEvent, check_job_collisions, interpolate_joints, link_bodies

    positioner = cell.positioner
    fixed = fixed_cell(cell)
    report = check_job_collisions(base_trajectory, solution, model, fixed, max_step=max_step)
    if part_vertices is None or positioner is None:
        return report
    t0 = time.perf_counter()
    idx = np.flatnonzero(solution.reachable)
    if not len(idx):
        return report
    theta_all = np.asarray(base_trajectory.extra[AXIS_COLUMN], dtype=float)
    q_and_theta = np.column_stack([solution.q[idx], theta_all[idx]])
    fine, src = interpolate_joints(q_and_theta, max_step=max_step)
    n = model.chain.n_joints
    moving = link_bodies(model) + [MovingBody(b, link=n) for b in (cell.tool.bodies if cell.tool is not None else ())]
    scene = CollisionScene([Body("the part", Mesh(part_vertices, part_faces), np.eye(4))], moving)
    events: list = []
    k0 = np.floor(src).astype(int)
    t_all = np.asarray(base_trajectory.t)
    pass_all = np.asarray(base_trajectory.pass_index)
    contact_all = np.asarray(base_trajectory.contact, bool)
    last_pass = np.maximum.accumulate(np.where(pass_all >= 0, pass_all, -1))
    n_queries = 0
    for s in range(0, len(fine), 20000):
        chunk = fine[s:s + 20000]
        frames = positioner.base2part(chunk[:, -1])[:, None] @ model.chain.frames(chunk[:, :-1])
        hits = scene.check(frames)
        n_queries += hits.n_queries
        for pose, a, b, p, depth in zip(hits.pose + s, hits.body_a, hits.body_b, hits.point_base, hits.depth):
            i = idx[k0[pose]]
            if events and events[-1].body_a == a and events[-1].sample == i:
                continue
            events.append(CollisionEvent(body_a=a, body_b=b, pass_index=int(pass_all[i]), after_pass=int(last_pass[i]),
                                         t_start=float(t_all[i]), t_end=float(t_all[i]), sample=int(i),
                                         point_part=np.asarray(p, dtype=float), depth=float(depth),
                                         contact=bool(contact_all[i])))
    all_events = sorted(list(report.events) + events, key=lambda e: e.t_start)
    log.info("positioner collision check: %d poses against the turning part, %d collision(s), %.2f s", len(fine),
             len(events), time.perf_counter() - t0)
    return replace(report, events=all_events, n_poses=report.n_poses + len(fine),
                   n_queries=report.n_queries + n_queries, seconds=report.seconds + time.perf_counter() - t0,
                   cell=cell)


def run_positioner_stage(trajectory, *, cell: Cell, robot="ur10e", programs=("csv",), out_dir=None,
                         facing=None, elevation: float = math.radians(30.0), surface=None, **options):
    """The robot stage for a cell with a rotary positioner (module notes).

    Parameters
    ----------
    trajectory : Trajectory
        TCP poses in the part frame, m.
    cell : Cell
        With ``positioner`` set.
    robot : str or RobotModel
    programs : sequence of str
        ``rapid``, ``krl``, ``ros``, ``csv`` (URScript is refused: it has no standard external axis).
    out_dir : path, optional
        Where the programs go (nothing written when None).
    facing : (3,) float, optional
        Direction (base frame) the contact point is turned to face (:func:`facing_angles`).
    elevation : float
        Tilt of the default facing direction, rad.
    surface : Surface, optional
        The part; the reachability map is not made on a positioner (the part has no one pose).
    **options
        Passed on to :func:`swath.robot.run_robot_stage` (``margins``, ``strict``, ``force``,
        ``force_program``, ``split_gaps``, ``clearance``, ``progress``, ``warn``); ``place`` is refused.

    Returns
    -------
    RobotResult
        ``trajectory`` in the part frame with the ``positioner`` column (rad); ``program_view`` the
        (base-frame trajectory, fixed cell) the programs are written from; ``cell`` the cell with
        ``part2base`` the part's pose at the first reached contact sample (what the report draws); ``metrics`` as the robot
        stage's plus ``positioner_*`` figures and the FK check in the part frame.
    """
    from .programs import ProgramInput, write_programs
    from .stage import run_robot_stage

    positioner = cell.positioner
    if positioner is None:
        raise InputError("run_positioner_stage needs a cell with a [positioner]")
    if options.pop("place", False):
        raise InputError("--place searches where a fixed part should stand; with a positioner the part's place is "
                         "the positioner's axis and part2faceplate in the cell file")
    check_axis_formats(programs or ())
    theta = facing_angles(trajectory, positioner, facing=facing, elevation=elevation)
    trajectory = slow_for_axis(trajectory, theta, positioner.max_speed, positioner.max_accel)
    base_tr = to_base_frame(trajectory, positioner, theta)
    fixed = fixed_cell(cell)
    result = run_robot_stage(base_tr, robot=robot, cell=fixed, programs=programs, out_dir=None, **options)
    base_run: Any = result.trajectory
    part_run = to_part_frame(base_run, positioner)
    sol = result.solution
    ok = np.flatnonzero(sol.reachable)
    th = base_run.extra[AXIS_COLUMN]
    got = positioner.base2part(th[ok]) @ result.model.fk(sol.q[ok]) @ cell.tcp2flange
    dp, da = pose_error(got, poses_from_trajectory(part_run)[ok])
    w, accel = axis_speed_accel(base_run.t, th)
    metrics = dict(result.metrics)
    metrics.update({
        "max_fk_position_error_m": float(dp.max(initial=0.0)), "max_fk_angle_error_rad": float(da.max(initial=0.0)),
        "positioner": positioner.as_record(),
        "positioner_min_rad": float(th.min()), "positioner_max_rad": float(th.max()),
        "positioner_range_rad": float(th.max() - th.min()),
        "positioner_max_speed_ratio": float(w.max(initial=0.0) / positioner.max_speed),
        "positioner_max_accel_ratio": float(accel.max(initial=0.0) / positioner.max_accel),
    })
    metrics.pop("part2base", None)
    # the part's place is the positioner's: its advice replaces --base / --place
    warnings = [w.replace("move the part (--base, or --place)", "move the positioner or the part on it (the cell "
                          "file's [positioner])") for w in result.warnings]
    if metrics["positioner_max_accel_ratio"] > 1.0:
        warnings.append(f"robot: the positioner's acceleration reaches {metrics['positioner_max_accel_ratio']:.2f} "
                        f"times its max_accel ({math.degrees(positioner.max_accel):.0f} deg/s²) on the job's "
                        "sharpest turn; the controller will slow there [W-POSITIONER-ACCEL]")
        log.warning("%s", warnings[-1])
    files = []
    if out_dir is not None and programs:
        from pathlib import Path

        files = write_programs(ProgramInput(base_run, sol, result.model, fixed, force=options.get("force", 20.0),
                                            force_program=options.get("force_program", "native")),
                               Path(out_dir), programs)
    # the cell as the report draws it: the part at the axis angle of the first reached contact sample
    drawn = np.flatnonzero(sol.reachable & base_run.contact)
    first = int(drawn[0]) if len(drawn) else (int(ok[0]) if len(ok) else 0)
    shown = replace(cell, part2base=positioner.part2base(th[first:first + 1])[0])
    return replace(result, cell=shown, trajectory=part_run, metrics=metrics, warnings=warnings, files=files,
                   program_view=(base_run, fixed))
