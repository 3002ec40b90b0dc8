"""The robot stage's entry point: trajectory in, joints, re-timed trajectory, reachability and programs out.

CLI flags / job keys the stage reads (the lead wires them; see :func:`robot_options_from_mapping`):

``--robot ur10e`` (a name from :data:`swath.robot.ROBOTS`), ``--base "x,y,z,rx,ry,rz"`` (part placement
in the robot base frame; mm/m and deg/rad suffixes, bare numbers m and deg), ``--tcp "x,y,z,rx,ry,rz"``
(TCP in the flange frame), ``--program urscript,rapid,krl,ros,csv``, ``--place`` (search the
placement; ``--table-z`` the part's lowest point height), ``--robot-strict`` (fail on any unreachable pose),
``--force-program native|position`` (the controller's force control presses the pad, or a
position-only program that states the compliance it relies on).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..cell import Cell, parse_pose
from ..errors import InputError
from .joint_moves import insert_joint_moves
from .models import RobotModel, get_robot
from .placement import (  # noqa: F401  (the thresholds are the stage's too)
    WARN_JOINT_LIMIT_MARGIN,
    WARN_MANIPULABILITY,
    WARN_WRIST_SIN,
    Placement,
    search_placement,
)
from .pose import pose_error, poses_from_trajectory
from .programs import ProgramInput, check_program_formats, write_programs
from .retime import joint_speed_ratio, resample_contact, retime_trajectory
from .solve import JointSolution, Margins, flips_inside_passes, solve_trajectory

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class RobotResult:
    """What :func:`run_robot_stage` returns.

    Attributes
    ----------
    model : RobotModel
    cell : Cell
        The cell used (the placement found when searched).
    solution : JointSolution
        Joint values on the original trajectory's samples.
    trajectory : Trajectory
        The re-timed trajectory (same samples, new times).
    placement : Placement or None
    reach_map : ReachMap or None
        Reachability over the part's vertices (when a surface was given).
    files : list of Path
    metrics : dict
        Units in the keys: ``ik_time_s``, ``reachable_fraction``, ``n_unreachable_stretches``,
        ``n_branch_switches``, ``configuration_flips_in_passes``, ``max_fk_position_error_m``,
        ``max_fk_angle_error_rad``, ``max_joint_speed_ratio``, ``max_joint_accel_ratio``,
        ``retime_added_s``, ``min_manipulability``, ``min_joint_limit_margin_rad`` …
    gaps : list of Gap
        Unreachable stretches the robot skips in air (:mod:`swath.robot.gaps`).
    program_view : (Trajectory, Cell) or None
        With a rotary positioner (:mod:`swath.robot.positioner`): the base-frame trajectory with the
        axis angle and the cell the programs are written from; None: ``trajectory`` and ``cell``.
    warnings : list of str
        What the user must know before running the programs, one sentence each: poses no
        configuration reaches (the programs leave them out) and configuration changes inside a
        contact pass.
    """

    model: RobotModel
    cell: Cell
    solution: JointSolution
    trajectory: object
    placement: Placement | None = None
    reach_map: object = None
    files: list = field(default_factory=list)
    metrics: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)
    gaps: list = field(default_factory=list)
    program_view: tuple | None = None


def fk_errors(trajectory, solution: JointSolution, model: RobotModel, cell: Cell):
    """Position (m) and angle (rad) errors of FK of every reachable joint row against its TCP pose."""
    idx = np.flatnonzero(solution.reachable)
    if not len(idx):
        return np.zeros(0), np.zeros(0)
    got = cell.tcp2part(model.fk(solution.q[idx]))
    return pose_error(got, poses_from_trajectory(trajectory)[idx])


def run_robot_stage(trajectory, *, robot: str | RobotModel = "ur10e", cell: Cell | None = None,
                    programs=("csv",), out_dir=None, place: bool = False, table_z: float = 0.0,
                    margins: Margins | None = None, strict: bool = False, force: float = 20.0,
                    surface=None, reach_vertices: int = 1500, warn: bool = True, keep_out: float | None = None,
                    split_gaps: bool = True, clearance: float = 0.02, progress=None,
                    force_program: str = "native", pad_radius: float = 0.0381) -> RobotResult:
    """Solve, re-time and write robot programs for a trajectory.

    Parameters
    ----------
    trajectory : Trajectory
        TCP poses in the part frame, m.
    robot : str or RobotModel
        Catalogue name (``ur10e``, ``irb4600``, ``kr120`` …) or a model.
    cell : Cell, optional
        Part placement and tool (default: part at the base origin, TCP on the flange).
    programs : sequence of str
        Formats to write: ``urscript``, ``rapid``, ``krl``, ``ros``, ``csv``.
    out_dir : path, optional
        Where the programs go (nothing written when None).
    place : bool
        Search the part placement first (:func:`search_placement`; ``cell``'s tool is kept).
    table_z : float
        Height of the part's lowest point for the placement search, m.
    margins : Margins
    strict : bool
        Raise :class:`swath.errors.UnreachableError` on any unreachable pose.
    force : float
        Contact force for URScript ``force_mode``, N.
    surface : Surface, optional
        The part; when given, a reachability map over its vertices is added (tool normal to the
        surface; :func:`swath.robot.reachability_map`), the joint moves are checked along their
        sweep, and with a table (the cell's, or the one assumed under the part's lowest point) the
        arm is kept above it (:attr:`Margins.floor_z`; the placement search too).
    reach_vertices : int
        At most this many vertices in the reachability map.
    warn : bool
        Log the result's warnings (default); they are the result's ``warnings`` either way.
    keep_out : float, optional
        With ``place``: radius of the keep-out cylinder about the base axis, m
        (default :func:`swath.robot.placement.default_keep_out`).
    split_gaps : bool
        Split passes at unreachable stretches with a retract and an approach (default); the returned
        trajectory is then what the robot runs (:func:`swath.robot.gaps.split_unreachable`).
    clearance : float
        Retract/approach height at a split, m, and the distance from the part every configuration
        change keeps: with a ``surface``, every joint move is checked along its sweep and lifted
        where it comes nearer the part than this or hits the cell (:mod:`swath.robot.sweep`).
    progress : callable, optional
        ``progress(message, done, total)`` for the placement search and the solves.
    force_program : str
        ``native`` (force control of the controller) or ``position`` (position-only programs).
    pad_radius : float
        Radius of the pad, m: its rim counts in the distance a swept joint move keeps from the part.

    Returns
    -------
    RobotResult
    """
    margins = Margins() if margins is None else margins
    model = get_robot(robot) if isinstance(robot, str) else robot
    cell = Cell() if cell is None else cell
    if not len(trajectory):
        raise InputError("the robot stage needs a trajectory with at least one sample")
    check_program_formats(model, programs or (), force_program)
    placement = None
    t0 = time.perf_counter()
    say = progress or (lambda message, done, total: None)
    # with the part's mesh and a table (given, or assumed under the part's lowest point), the arm stays above it
    on_table = surface is not None and margins.floor_z is None and (cell.table is not None or cell.auto_table)
    if surface is not None and margins.arm_part is None:
        from .arm_part import ArmPartCheck
        from .placement_grid import GridArmPartCheck

        # the branches and the placement keep the arm's links out of the part (the check's answers,
        # looked up in a distance grid)
        margins = replace(margins, arm_part=GridArmPartCheck(ArmPartCheck(model, surface.vertices, surface.faces)))
    if place:
        floor = (cell.table.top_z if cell.table is not None else table_z) if on_table else None
        placement = search_placement(trajectory, model, cell, table_z=table_z, keep_out=keep_out,
                                     margins=margins if floor is None else replace(margins, floor_z=floor),
                                     points=None if surface is None else np.asarray(surface.vertices),
                                     progress=progress)
        cell = placement.cell
    if on_table:
        # the table the part stands on; a table top above the part's lowest point is a cell error that
        # the collision check names (the part would be in it), not a floor
        part_z = float((np.asarray(surface.vertices) @ cell.part2base[2, :3] + cell.part2base[2, 3]).min())
        top = cell.table.top_z if cell.table is not None else part_z
        if top <= part_z + 1e-3:
            margins = replace(margins, floor_z=top)
    t_place = time.perf_counter() - t0
    t0 = time.perf_counter()
    say(f"robot: inverse kinematics on {len(trajectory)} poses", 0, 1)
    solution = solve_trajectory(trajectory, model, cell, margins=margins, strict=strict, warn=False)
    first_warning, gaps, n_unreachable = solution.warning, [], int((~solution.reachable).sum())
    n_planned, planned_fraction, planned_stretches = len(trajectory), solution.reachable_fraction, len(solution.stretches)
    check = None
    n_low, n_air = 0, 0
    if surface is not None:
        from .sweep import SweepCheck

        check = SweepCheck(model, cell, np.asarray(surface.vertices), np.asarray(surface.faces), pad_radius=pad_radius)
        if split_gaps and solution.reachable.any():
            from .gaps import air_splits

            # configuration changes too low to retract from, and air links that hit something, become gaps
            drop, n_low, n_air = air_splits(trajectory, solution, model, cell, check, clearance=clearance)
            if drop.any():
                solution = replace(solution, reachable=solution.reachable & ~drop,
                                   q=np.where(drop[:, None], np.nan, solution.q),
                                   branch=np.where(drop, -1, solution.branch))
    n_dropped = int((~solution.reachable).sum())
    if split_gaps and n_dropped and solution.reachable.any():
        from .gaps import solution_after_split, split_unreachable

        say(f"robot: {n_dropped} poses become air moves (retract, joint move, approach)", 0, 1)
        trajectory, q_moves, gaps, src = split_unreachable(trajectory, solution, model, cell, clearance=clearance,
                                                           floor_z=margins.floor_z)
        solution = solution_after_split(solution, trajectory, q_moves, src, model)
    sweeps = None
    if check is not None and solution.joint_moves.any():
        from .sweep import clear_joint_moves

        say(f"robot: {int(solution.joint_moves.sum())} joint moves checked along their sweep", 0, 1)
        trajectory, solution, sweeps = clear_joint_moves(trajectory, solution, model, cell, check, clearance=clearance)
    t_ik = time.perf_counter() - t0
    retimed, solution, rt = retime_and_resample(trajectory, solution, model, cell)
    dp, da = fk_errors(retimed, solution, model, cell)
    idx = np.flatnonzero(solution.reachable)
    speed_ratio = joint_speed_ratio(retimed.t[idx], solution.q[idx], model.max_speed) if len(idx) > 1 else np.zeros(1)
    meas = solution.measures
    metrics = {
        **continuity_metrics(retimed, solution),
        # the planned trajectory's poses and how many the robot reaches (the split trajectory it runs has
        # n_poses_run samples, all reached)
        "robot": model.name, "n_poses": n_planned, "ik_time_s": t_ik, "placement_time_s": t_place,
        "reachable_fraction": planned_fraction, "n_unreachable_stretches": planned_stretches,
        "n_poses_run": len(trajectory),
        "n_branch_switches": len(solution.switches),
        "configuration_flips_in_passes": flips_inside_passes(solution, retimed),
        "max_fk_position_error_m": float(dp.max(initial=0.0)), "max_fk_angle_error_rad": float(da.max(initial=0.0)),
        "max_joint_speed_ratio": float(np.max(speed_ratio, initial=0.0)), "max_joint_accel_ratio": rt.max_accel_ratio,
        "retime_added_s": retimed.duration - trajectory.duration, "retime_stretched_steps": rt.stretched_steps,
        "duration_s": retimed.duration,
        "min_manipulability": float(np.nanmin(meas["manipulability"])) if len(idx) else float("nan"),
        "min_joint_limit_margin_rad": float(np.nanmin(meas["joint_limit_margin_rad"])) if len(idx) else float("nan"),
        "min_wrist_sin": float(np.nanmin(meas["wrist"])) if len(idx) else float("nan"),
        "n_unreachable_poses": n_unreachable, "n_gaps": len(gaps),
        "n_low_switch_gaps": n_low, "n_air_collision_gaps": n_air,
        "gap_contact_length_m": float(sum(g.contact_length for g in gaps)),
        "gaps": [g.as_record() for g in gaps],
        **cell.as_record(),
    }
    if placement is not None:
        metrics.update(placement.as_record())
    metrics["force_program"] = force_program
    metrics["clearance_m"] = clearance
    if sweeps is not None:
        from .sweep import sweep_metrics, sweep_warnings

        metrics.update(sweep_metrics(sweeps))
    warnings = robot_warnings(solution, metrics, first_warning=first_warning, split=split_gaps, programs=programs,
                              cell=cell)
    if sweeps:
        warnings += sweep_warnings(sweeps, clearance)
    if placement is not None:
        warnings += list(placement.warnings)
    if warn:
        for w in warnings:
            log.warning("%s", w)
    reach_map = None
    if surface is not None:
        from .reach import reachability_map

        reach_map = reachability_map(surface, model, cell, max_vertices=reach_vertices, margins=margins)
        metrics["surface_reachable_fraction"] = reach_map.reachable_fraction
    files = []
    if out_dir is not None and programs:
        if not len(idx):
            raise InputError(f"no pose of the trajectory is reachable for {model.name}; no program written")
        files = write_programs(ProgramInput(retimed, solution, model, cell, force=force, force_program=force_program),
                               Path(out_dir), programs)
    return RobotResult(model=model, cell=cell, solution=solution, trajectory=retimed, placement=placement,
                       reach_map=reach_map, files=files, metrics=metrics, warnings=warnings, gaps=gaps)


def retime_and_resample(trajectory, solution: JointSolution, model: RobotModel, cell: Cell, *, rounds: int = 6):
    """Joint moves interpolated, re-timed to the joint limits, contact steps resampled to ≤ 20 ms.

    :func:`insert_joint_moves` puts the swept joints of every joint move on the trajectory;
    :func:`retime_trajectory` stretches time where a joint limit binds; :func:`resample_contact`
    then splits the contact steps that became longer than FORMATS.md's 20 ms (or turn a joint more
    than 0.045 rad), and the re-timing runs again on the new samples, up to ``rounds`` times.

    Returns
    -------
    (Trajectory, JointSolution, Retiming)
        The re-timed trajectory, the solution on its samples, the first re-timing's figures.
    """
    tr, sol = insert_joint_moves(trajectory, solution, model, cell)
    retimed, rt = retime_trajectory(tr, sol, model)
    for _ in range(rounds):
        n_before = len(retimed)
        retimed, sol = resample_contact(retimed, sol, model, cell)
        if len(retimed) == n_before:
            break
        retimed, _ = retime_trajectory(retimed, sol, model)
    else:
        retimed, sol = resample_contact(retimed, sol, model, cell)     # the last word: no step over 16 ms
    return retimed, sol, rt


def continuity_metrics(trajectory, solution: JointSolution) -> dict:
    """What the configuration and timing rules promise, measured on the final samples.

    Keys: ``max_contact_dt_s`` (longest step between contact samples of one pass, s),
    ``max_contact_joint_step_rad`` (largest joint change between them), ``n_joint_moves`` (joint
    moves written as such, each a branch change or a large turn on an air link),
    ``branch_changes_in_contact`` (steps inside a pass whose branch changes),
    ``min_switch_clearance_m`` (smallest distance from the part at which the branch changes; NaN
    without a change).
    """
    tr, sol = trajectory, solution
    n = len(tr)
    out = {"max_contact_dt_s": 0.0, "max_contact_joint_step_rad": 0.0, "n_joint_moves": 0,
           "branch_changes_in_contact": 0, "min_switch_clearance_m": float("nan")}
    if n < 2:
        return out
    same = (tr.contact[1:] & tr.contact[:-1] & (tr.pass_index[1:] == tr.pass_index[:-1]) & (tr.pass_index[1:] >= 0)
            & sol.reachable[1:] & sol.reachable[:-1])
    if same.any():
        out["max_contact_dt_s"] = float(np.diff(tr.t)[same].max())
        out["max_contact_joint_step_rad"] = float(np.abs(np.diff(sol.q, axis=0))[same].max())
    jm = sol.joint_moves
    out["n_joint_moves"] = int(np.sum(jm[1:] & ~jm[:-1]) + int(jm[0]))
    b = sol.branch
    change = (b[1:] != b[:-1]) & (b[1:] >= 0) & (b[:-1] >= 0)
    out["branch_changes_in_contact"] = int(np.sum(change & same))
    if change.any() and sol.clearance is not None:
        c = sol.clearance
        out["min_switch_clearance_m"] = float(np.min(np.minimum(c[1:], c[:-1])[change]))
    return out


def robot_warnings(solution: JointSolution, metrics: dict, *, first_warning: str | None = None,
                   split: bool = False, programs=(), cell: Cell | None = None) -> list[str]:
    """The robot stage's warnings: unreachable poses (the first solve's sentence; with ``split`` the
    passes were split there with a retract and an approach, else the programs skip those samples and
    the robot moves straight across them), branch changes inside a contact pass (the arm reconfigures
    with the pad on the part), manipulability, wrist sine or joint-limit margin below the thresholds
    :data:`WARN_MANIPULABILITY`, :data:`WARN_WRIST_SIN`, :data:`WARN_JOINT_LIMIT_MARGIN`, position-only
    vendor programs (the compliance they rely on), and a TCP on the flange face (no tool given)."""
    out = []
    sentence = first_warning if first_warning is not None else solution.warning
    if sentence and split and metrics.get("n_gaps"):
        out.append(f"robot: {sentence} The passes are split there with a retract and an approach "
                   f"({metrics['n_gaps']} gap(s), {1e3 * metrics.get('gap_contact_length_m', 0.0):.0f} mm of contact "
                   "path left unsanded); coverage and removal are computed on what the robot runs.")
    elif sentence:
        out.append(f"robot: {sentence} The programs leave these samples out, so the robot moves straight "
                   "across them.")
    low, air = int(metrics.get("n_low_switch_gaps", 0)), int(metrics.get("n_air_collision_gaps", 0))
    if low or air:
        out.append(f"robot: {low} configuration change(s) the old configuration could not retract from, and {air} "
                   "air link(s) that hit the cell or the robot, run as gaps instead (retract, joint move at the "
                   "clearance, approach); coverage and removal are computed on what the robot runs "
                   "[W-ROBOT-SWITCH-GAP]")
    flips = int(metrics.get("configuration_flips_in_passes", 0))
    if flips:
        out.append(f"robot: the arm changes configuration {flips} time(s) inside a contact pass ({metrics['robot']}), "
                   "with the pad on the part; move the part (--base, or --place) or choose another robot")
    name = metrics.get("robot", "the robot")
    manip = metrics.get("min_manipulability", float("nan"))
    if np.isfinite(manip) and manip < WARN_MANIPULABILITY:
        out.append(f"robot: {name} comes close to a singularity: manipulability falls to {manip:.2g} (warned below "
                   f"{WARN_MANIPULABILITY:g}); small path errors become large joint speeds there; move the part "
                   "(--base, or --place)")
    wrist = metrics.get("min_wrist_sin", float("nan"))
    if np.isfinite(wrist) and wrist < WARN_WRIST_SIN:
        out.append(f"robot: {name}'s wrist comes near its singularity: sin of the wrist angle falls to {wrist:.2f} "
                   f"({math.degrees(math.asin(min(wrist, 1.0))):.1f} deg; warned below 10 deg); wrist joints 4 and "
                   "6 may spin fast; move the part or turn the tool about its axis")
    margin = metrics.get("min_joint_limit_margin_rad", float("nan"))
    if np.isfinite(margin) and margin < WARN_JOINT_LIMIT_MARGIN:
        out.append(f"robot: a joint of {name} comes within {math.degrees(margin):.2f} deg of its limit (warned below "
                   "5 deg); the controller may stop on a limit with a small path or calibration error")
    vendor = [p for p in (str(x).strip().lower() for x in programs) if p in ("urscript", "rapid", "krl")]
    if vendor and metrics.get("force_program") == "position":
        out.append(f"robot: the {', '.join(vendor)} program(s) are position only (--force-program position): they hold "
                   "the pad face on the nominal surface and rely on a compliant tool (active contact flange or spring "
                   "mount) to press with the planned force; with a rigid tool the force is whatever the part's "
                   "placement errors make")
    if cell is not None and np.allclose(cell.tcp2flange, np.eye(4)):
        out.append("robot: no tool given (--tcp), so the TCP is the flange face: the programs put the flange, not a "
                   "pad, on the part; give the pad face's pose in the flange frame with --tcp x,y,z,rx,ry,rz")
    return out


def robot_options_from_mapping(values: dict) -> dict:
    """Keyword arguments of :func:`run_robot_stage` from CLI/TOML text values.

    Keys: ``robot`` (a catalogue name or a ``.urdf`` file, loaded here), ``base``, ``tcp``, ``program``
    (comma list), ``place`` (``auto`` or absent), ``table_z`` (length), ``robot_strict`` (bool), ``tip``
    (the URDF's flange frame), ``keep_out`` (length: the placement's keep-out radius), ``force_program``
    (``native`` or ``position``).  Program formats the robot's controller would not take are refused
    here, before any work.
    """
    from ..units import parse_quantity

    known = {"robot", "base", "tcp", "program", "place", "table_z", "table-z", "robot_strict", "robot-strict", "tip",
             "keep_out", "keep-out", "force_program", "force-program"}
    unknown = set(values) - known
    if unknown:
        raise InputError(f"unknown robot setting(s) {', '.join(sorted(unknown))}; known: {', '.join(sorted(known))}")
    place = str(values.get("place", "")).strip().lower()
    if place not in ("", "auto", "none", "false"):
        raise InputError(f"--place takes 'auto' (search the part placement), got {values['place']!r}")
    programs = values.get("program", "csv")
    programs = [p.strip() for p in programs.split(",")] if isinstance(programs, str) else list(programs)
    base = values.get("base")
    tcp = values.get("tcp")
    table = values.get("table_z", values.get("table-z"))
    robot = values.get("robot", "ur10e")
    if str(robot).strip().lower().endswith(".urdf") or values.get("tip"):
        robot = get_robot(robot, tip=values.get("tip"))       # a URDF robot is loaded (and checked) here
    force_program = str(values.get("force_program", values.get("force-program")) or "native").strip().lower()
    check_program_formats(robot if not isinstance(robot, str) else get_robot(robot), programs, force_program)
    keep = values.get("keep_out", values.get("keep-out"))
    return {"robot": robot, "keep_out": None if keep is None else parse_quantity(keep, "length"),
            "cell": Cell(part2base=np.eye(4) if base is None else parse_pose(base),
                         tcp2flange=np.eye(4) if tcp is None else parse_pose(tcp)),
            "programs": programs, "place": place == "auto",
            "table_z": 0.0 if table is None else parse_quantity(table, "length"),
            "strict": bool(values.get("robot_strict", values.get("robot-strict", False))),
            "force_program": force_program}
