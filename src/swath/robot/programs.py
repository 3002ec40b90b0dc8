"""Robot programs from a solved trajectory: URScript, ABB RAPID, KUKA KRL, ROS JointTrajectory YAML, joint CSV.

Every writer writes atomically and takes a :class:`ProgramInput` (re-timed trajectory, joint
solution, model, cell).  Joint-space files (``joints.csv``, ROS YAML) carry every reachable sample;
the vendor programs (Cartesian moves) carry the samples kept by :func:`decimate`, which keeps each
pass's and link's first and last sample and drops a sample only where the straight line between
its kept neighbours stays within ``tol_position`` (m) and ``tol_angle`` (rad) of every dropped one.

Which formats a robot gets: URScript only for Universal Robots arms, RAPID only for ABB arms, KRL
only for KUKA arms (each encodes its maker's configuration rules); ROS YAML and CSV for every arm
(:func:`check_program_formats`, called before any work).

Configurations: a linear move never changes the arm's configuration; a change of branch (and any
large joint turn on an air link) is a *joint move* at the air move's highest point
(:attr:`JointSolution.joint_move`), written as ``movej`` / ``MoveAbsJ`` / ``PTP`` with the new
configuration, its target reached at rest (no blend before it).

Force (``force_program``): ``native`` presses the pad along the tool z-axis with the controller's
force control in every contact pass — URScript ``force_mode`` re-issued before every move of the
pass with the tool frame of the move's start (type 2, the frame not transformed), decimation keeping
a target wherever the tool axis has turned ``max_force_turn`` (2°) since the last one, so the
commanded force stays within 2° of the pad axis (:func:`commanded_force_angles`); RAPID through ABB
Force Control (``FCCalib``, ``FCPress1LStart`` … ``FCPressL`` … ``FCPressEnd`` with
``FC_REFFRAME_TOOL``); KRL through KUKA.ForceTorqueControl, started and stopped per pass by the
cell's ``SWATH_FTC_ON(force)`` / ``SWATH_FTC_OFF()``.  ``position`` writes position-only programs whose
header states the compliance they rely on.

Units and frames per format (the readers in :mod:`swath.robot.readers` parse them back):

* URScript — ``p[x, y, z, rx, ry, rz]`` TCP poses in the robot base frame, m and rotation vector
  (rad); ``set_tcp`` from ``tcp2flange``; ``movej`` to the first configuration and at every joint
  move (``t`` = its re-timed duration, s); ``movel`` with blend radius ``r`` (0 at pass ends) and
  speed ``v`` = the timed feed (m/s).
* RAPID — TCP poses in the part frame (``wobjdata`` user frame = the part placement), mm and
  quaternions; ``confdata [cf1, cf4, cf6, cfx]`` from the joint values (ABB's quadrant and cfx
  rules); ``ConfL\\On``; ``MoveL`` with a ``speeddata`` per feed and ``z1`` (``fine`` at pass ends);
  ``MoveAbsJ`` to a ``jointtarget`` (deg) with ``\\T`` its duration at a joint move.
* KRL — ``.dat`` with ``FRAME`` base/tool and ``E6POS`` points (X, Y, Z mm; A, B, C deg, ``Rz(A)
  Ry(B) Rx(C)``; S status, T turn); ``.src`` sets ``$BASE``, ``$TOOL``, ``$VEL.CP`` (m/s) and runs
  ``LIN … C_DIS``, ``PTP`` at a joint move.  KUKA's flange frame has x out of the flange:
  ``$TOOL = Ry(90°) · tcp2flange``.
* ROS 2 ``trajectory_msgs/JointTrajectory`` YAML — joint names, positions (rad), velocities (rad/s;
  0 at the first and last point), ``time_from_start`` ``{sec, nanosec}``
  (``builtin_interfaces/Duration``).
* ``joints.csv`` — ``t,q1..q6,contact,pass,branch`` (s, rad); with a positioner ``positioner`` (rad) after ``q6``.

Media changes (a ``media`` column on the trajectory, :mod:`swath.process.media`) stop the vendor
programs for the operator (URScript ``popup``, RAPID ``TPWrite`` + ``Stop``, KRL ``HALT``, each after a
comment); the ROS YAML lists them in comment lines at its top.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..cell import Cell
from ..io.atomic import write_text_atomic
from ..process.media import media_header, media_stops
from .external_axis import AXIS_COLUMN, axis_samples, e1_text, eax_text, header_lines
from .models import RobotModel
from .pose import (
    make_transform,
    matrix_to_quat,
    matrix_to_zyx,
    poses_from_trajectory,
    rot_y,
)
from .solve import JointSolution, segments

#: Formats and their writers' file names.
PROGRAM_FILES = {"urscript": ("swath_job.script",), "rapid": ("SwathJob.mod",), "krl": ("swath_job.src", "swath_job.dat"),
                 "ros": ("joint_trajectory.yaml",), "csv": ("joints.csv",)}

#: KUKA's $FLANGE (x out of the flange) from the model flange (z out): base2flange_kuka = flange2base · this.
FLANGE2KUKA_FLANGE = make_transform(rot_y(-math.pi / 2))


#: Vendor whose configuration rules (confdata, status/turn, joint order) each vendor format encodes.
FORMAT_VENDOR = {"urscript": "ur", "rapid": "abb", "krl": "kuka"}

#: Ways of pressing the pad in a contact pass (``--force-program``).
FORCE_PROGRAMS = ("native", "position")


def robot_vendor(model: RobotModel) -> str | None:
    """``"ur"``, ``"abb"``, ``"kuka"`` or None (a generic or URDF arm: joint-space files only)."""
    name = model.name.lower()
    if model.kind == "ur":
        return "ur"
    if name.startswith("irb"):
        return "abb"
    if name.startswith("kr"):
        return "kuka"
    return None


def check_program_formats(model: RobotModel, formats, force_program: str = "native") -> None:
    """Refuse, before any work, programs the robot's controller would not take.

    RAPID encodes ABB's ``confdata`` quadrant and ``cfx`` rules, KRL KUKA's ``S``/``T`` bits and
    axis signs, URScript UR's joint order and ``force_mode``: each is written only for its maker's
    arms; ``ros`` and ``csv`` (joint space) for every arm.

    Raises
    ------
    InputError
        Naming the format, the robot, the reason and the formats that fit.
    """
    from ..errors import InputError

    if force_program not in FORCE_PROGRAMS:
        raise InputError(f"--force-program takes {' or '.join(FORCE_PROGRAMS)} (native: the controller's force "
                         f"control presses the pad; position: a position-only program), got {force_program!r}")
    vendor = robot_vendor(model)
    makers = {"ur": "Universal Robots", "abb": "ABB", "kuka": "KUKA"}
    rules = {"rapid": "ABB's confdata (axis quadrants and cfx)", "krl": "KUKA's status and turn bits",
             "urscript": "UR's joint order and force_mode"}
    for fmt in formats:
        fmt = str(fmt).strip().lower()
        need = FORMAT_VENDOR.get(fmt)
        if need is not None and need != vendor:
            fits = [f for f, v in FORMAT_VENDOR.items() if v == vendor] + ["ros", "csv"]
            raise InputError(f"cannot write {fmt} for {model.name}: a {fmt} program carries {rules[fmt]}, which only "
                             f"{makers[need]} arms follow, and {model.name} is "
                             f"{'a ' + makers[vendor] + ' arm' if vendor else 'not one of them'}; "
                             f"choose from {', '.join(fits)} (--program)")


@dataclass(frozen=True, eq=False)
class ProgramInput:
    """What every writer needs.

    Attributes
    ----------
    trajectory : Trajectory
        Re-timed, on the solution's samples.
    solution : JointSolution
    model : RobotModel
    cell : Cell
    force : float
        Pad force, N.
    tol_position, tol_angle : float
        Decimation tolerances of the Cartesian programs, m and rad.
    blend : float
        Blend radius between Cartesian moves, m.
    force_program : str
        ``native`` (the controller's force control presses the pad along the tool axis, which
        follows the surface) or ``position`` (position only; the header states the compliance
        the program relies on).
    max_force_turn : float
        Largest angle between the tool axis of a contact sample and the force direction in
        effect there, rad (URScript re-issues its force frame at least this often).
    """

    trajectory: Any
    solution: JointSolution
    model: RobotModel
    cell: Cell
    force: float = 20.0
    tol_position: float = 1e-4
    tol_angle: float = math.radians(0.5)
    blend: float = 1e-3
    force_program: str = "native"
    max_force_turn: float = math.radians(2.0)

    def kept(self) -> np.ndarray:
        if AXIS_COLUMN in getattr(self.trajectory, "extra", {}):
            return axis_samples(self.solution.reachable, self.solution.joint_moves)
        return decimate(self.trajectory, self.solution.reachable, tol_position=self.tol_position,
                        tol_angle=self.tol_angle, joint_move=self.solution.joint_moves,
                        max_turn=self.max_force_turn, via=self.solution.vias)


def joint_names(model: RobotModel) -> list[str]:
    """ROS joint names of the model (UR driver names, ROS-Industrial names for ABB and KUKA)."""
    if model.kind == "ur":
        return ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
                "wrist_3_joint"]
    if model.name.startswith("kr"):
        return [f"joint_a{i}" for i in range(1, 7)]
    return [f"joint_{i}" for i in range(1, 7)]


def decimate(trajectory, keep, *, tol_position: float = 1e-4, tol_angle: float = math.radians(0.5),
             joint_move=None, max_turn: float | None = None, via=None) -> np.ndarray:
    """Indices of the samples a Cartesian program needs.

    Parameters
    ----------
    trajectory : Trajectory
    keep : (n,) bool
        Samples allowed at all (reachable ones).
    tol_position : float
        Largest distance of a dropped sample from the chord of its kept neighbours, m.
    tol_angle : float
        Largest angle between a dropped sample's tool z and the interpolated one, rad.
    joint_move : (n,) bool, optional
        :attr:`JointSolution.joint_move`: the interpolated rows of a joint move are left out (the
        controller interpolates the joints itself) and its target is kept.
    via : (n,) bool, optional
        :attr:`JointSolution.via`: via-points of a joint move, kept (each a joint-move target).
    max_turn : float, optional
        In contact passes, also keep samples so that every sample's tool z lies within this angle
        (rad) of the tool z of the last kept sample before it (where the force frame is re-issued).

    Returns
    -------
    (m,) int
        Sorted indices; each pass's and link's first and last allowed sample always included.
    """
    pos = trajectory.position
    zax = trajectory.tool_z()
    keep = np.asarray(keep, bool).copy()
    jm = np.zeros(len(keep), bool) if joint_move is None else np.asarray(joint_move, bool)
    inner = jm.copy()
    inner[:-1] &= jm[1:]
    inner[-1:] = False
    if via is not None:
        inner &= ~np.asarray(via, bool)
    keep &= ~inner
    out = []
    for s, e, is_pass in segments(trajectory):
        idx = np.flatnonzero(keep[s:e]) + s
        # split at gaps (unreachable samples, interpolated joint moves) and at joint-move targets
        cut = np.flatnonzero((np.diff(idx) > 1) | jm[idx[1:]]) + 1 if len(idx) else np.zeros(0, int)
        for run in np.split(idx, cut):
            if len(run):
                kept = _douglas_peucker(run, pos, zax, tol_position, tol_angle)
                if is_pass and max_turn is not None:
                    kept = _limit_turn(run, kept, zax, max_turn)
                out.extend(kept)
    return np.array(sorted(set(out)), dtype=int)


def _limit_turn(run, kept, zax, max_turn: float) -> list[int]:
    """``kept`` plus the samples that keep every sample of ``run`` within ``max_turn`` of the last kept one."""
    kept_set = set(kept)
    cos_max = math.cos(max_turn)
    last = int(run[0])
    prev = last
    for i in run[1:]:
        i = int(i)
        if float(zax[last] @ zax[i]) < cos_max and prev != last:
            kept_set.add(prev)
            last = prev
        if i in kept_set:
            last = i
        prev = i
    return sorted(kept_set)


def force_frame_samples(data: ProgramInput) -> np.ndarray:
    """(n,) index of the sample whose tool frame is the force frame in effect at each sample (-1 where
    no force is commanded).

    The URScript writer issues ``force_mode`` before every move to a contact target, with the tool
    frame of the target before it in the same pass (of the pass's first target on the move onto
    it, or after an unreachable gap in the pass); a sample between two targets is pressed along the
    frame issued for the move that reaches the later one.
    """
    tr = data.trajectory
    idx = data.kept()
    n = len(tr)
    out = np.full(n, -1)
    on = tr.contact & (tr.pass_index >= 0)
    reach = data.solution.reachable
    for k, i in enumerate(idx):
        if not on[i]:
            continue
        prev = idx[k - 1] if k else -1
        frame = prev if _pressed_from(data, prev, i) else i
        lo = prev + 1 if k else 0
        out[lo:i + 1] = np.where(on[lo:i + 1] & reach[lo:i + 1], frame, -1)
    return out


def _pressed_from(data: ProgramInput, prev: int, i: int) -> bool:
    """True when the move from kept sample ``prev`` to ``i`` runs along one contact pass without a gap
    (then the force frame for it is ``prev``'s tool frame; else ``i``'s own)."""
    tr, reach = data.trajectory, data.solution.reachable
    if prev < 0:
        return False
    on = tr.contact & (tr.pass_index >= 0)
    return bool(on[prev] and tr.pass_index[prev] == tr.pass_index[i] and reach[prev:i + 1].all())


def commanded_force_angles(data: ProgramInput) -> np.ndarray:
    """(n,) angle between each contact sample's tool z (the pad axis, minus the surface normal without
    a lead angle) and the force direction the program commands there, rad; NaN off contact and on
    unreachable samples (the programs leave those out).

    URScript: the tool z of the re-issued force frame (:func:`force_frame_samples`); RAPID and KRL
    with native force control press along the tool z of the interpolated path (the force frame is
    the tool), which is the sample's own within the decimation tolerance: 0 here.
    """
    tr = data.trajectory
    frame = force_frame_samples(data)
    z = tr.tool_z()
    out = np.full(len(tr), np.nan)
    on = frame >= 0
    out[on] = np.arccos(np.clip(np.sum(z[on] * z[frame[on]], axis=1), -1.0, 1.0))
    return out


def _douglas_peucker(run, pos, zax, tol_p, tol_a) -> list[int]:
    keep = {int(run[0]), int(run[-1])}
    stack = [(0, len(run) - 1)]
    while stack:
        a, b = stack.pop()
        if b - a < 2:
            continue
        ia, ib = run[a], run[b]
        mid = run[a + 1:b]
        u = (pos[ib] - pos[ia])
        L2 = float(u @ u)
        w = np.clip(((pos[mid] - pos[ia]) @ u) / L2, 0, 1) if L2 > 0 else np.zeros(len(mid))
        dist = np.linalg.norm(pos[mid] - (pos[ia] + w[:, None] * u), axis=1)
        zi = zax[ia] * (1 - w[:, None]) + zax[ib] * w[:, None]
        zi /= np.maximum(np.linalg.norm(zi, axis=1, keepdims=True), 1e-12)
        ang = np.arccos(np.clip(np.sum(zi * zax[mid], axis=1), -1, 1))
        err = np.maximum(dist / tol_p, ang / tol_a)
        k = int(np.argmax(err))
        if err[k] > 1.0:
            keep.add(int(run[a + 1 + k]))
            stack += [(a, a + 1 + k), (a + 1 + k, b)]
    return sorted(keep)


def _rotvec(r) -> np.ndarray:
    """(..., 3) rotation vectors (axis · angle, rad) of rotation matrices."""
    q = matrix_to_quat(r)
    v = q[..., 1:]
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    ang = 2 * np.arctan2(s, q[..., :1])
    return np.where(s > 1e-15, v / np.where(s > 0, s, 1) * ang, 2 * v)


def _fmt(values, digits: int) -> str:
    return ",".join(f"{v:.{digits}f}" for v in values)


# --- URScript ---------------------------------------------------------------------------------------------------
def _position_only_note(data: ProgramInput) -> str:
    """The compliance a position-only program relies on, one sentence."""
    return (f"position only: no force control; the path holds the pad face at its nominal contact and the "
            f"{data.force:.0f} N the plan assumes must come from a compliant tool (active contact flange or spring "
            "mount) that follows the surface along the pad axis; a rigid tool presses with whatever force the "
            "part's placement errors make")


def urscript_text(data: ProgramInput) -> str:
    tr, sol, cell = data.trajectory, data.solution, data.cell
    idx = data.kept()
    jm = sol.joint_moves
    native = data.force_program == "native"
    tcp2base = cell.part2base @ poses_from_trajectory(tr)[idx]
    rv = _rotvec(tcp2base[:, :3, :3])
    tcp = np.concatenate([cell.tcp2flange[:3, 3], _rotvec(cell.tcp2flange[:3, :3])])
    lines = ["def swath_job():", f"  # swath robot program for {data.model.name}; poses in the base frame (m, rotation vector)"]
    if native:
        lines += ["  # force: force_mode presses the pad along the tool z-axis (into the part) with "
                  f"{data.force:.1f} N; the force frame is re-issued before every move in a pass, so it",
                  f"  # stays within {math.degrees(data.max_force_turn):.1f} deg of the surface normal; "
                  "other axes keep within 5 mm / 5 deg of the path"]
    else:
        lines.append(f"  # {_position_only_note(data)}")
    lines.append(f"  set_tcp(p[{_fmt(tcp, 7)}])")
    lines.append(f"  movej([{_fmt(sol.q[idx[0]], 8)}], a=0.5, v=0.3)")
    in_force = False
    ends = {s for s, e, p in segments(tr) if p} | {e - 1 for s, e, p in segments(tr) if p}
    on = tr.contact & (tr.pass_index >= 0)
    t = tr.t
    stops = media_stops("urscript", tr, idx)           # media changes (swath.process.media)
    for k, i in enumerate(idx):
        lines += stops.get(k, [])
        c = bool(on[i])
        if k and jm[i]:
            if in_force:                    # (a joint move straight off a pass: lift the force first)
                lines.append("  end_force_mode()")
                in_force = False
            dur = float(t[i] - t[idx[k - 1]])
            lines.append(f"  movej([{_fmt(sol.q[i], 8)}], a=1.0, v=1.0, t={dur:.4f}, r=0)  # joint move"
                         + (" (configuration change)" if sol.branch[i] != sol.branch[idx[k - 1]] else ""))
            continue
        if c and native:
            frame_k = k - 1 if (k and _pressed_from(data, idx[k - 1], i)) else k
            frame = f"p[{_fmt(tcp2base[frame_k, :3, 3], 7)},{_fmt(rv[frame_k], 9)}]"
            lines.append(f"  force_mode({frame}, [0,0,1,0,0,0], [0,0,{data.force:.3f},0,0,0], 2, "
                         "[0.005,0.005,0.1,0.0873,0.0873,0.0873])" + ("" if in_force else f"  # pass {tr.pass_index[i]}"))
            in_force = True
        v = max(float(tr.feed[i]), 1e-3)
        r = 0.0 if (i in ends or k == len(idx) - 1 or jm[idx[k + 1]]) else data.blend
        lines.append(f"  movel(p[{_fmt(tcp2base[k, :3, 3], 7)},{_fmt(rv[k], 9)}], a=1.0, v={v:.5f}, r={r:.4f})")
        nxt_c = k + 1 < len(idx) and bool(on[idx[k + 1]]) and tr.pass_index[idx[k + 1]] == tr.pass_index[i]
        if in_force and not nxt_c:
            lines.append("  end_force_mode()")
            in_force = False
    lines += ["end", "swath_job()", ""]
    return "\n".join(lines)


# --- ABB RAPID ---------------------------------------------------------------------------------------------------
def abb_confdata(model: RobotModel, q) -> np.ndarray:
    """(n, 4) int ABB ``[cf1, cf4, cf6, cfx]`` of joint values ``q`` (rad).

    ``cf1, cf4, cf6`` are the quadrants ``floor(q / 90°)``; ``cfx`` is 4·(wrist centre behind axis 1)
    + 2·(wrist centre behind the lower arm) + (axis 5 negative), ABB's numbering for serial arms.
    """
    q = np.atleast_2d(q)
    quad = np.floor(q[:, [0, 3, 5]] / (math.pi / 2)).astype(int)
    frames = model.chain.frames(q)
    wc = frames[:, 4, :3, 3]
    th = model.chain.chain_angles(q)
    c1, s1 = np.cos(th[:, 0]), np.sin(th[:, 0])
    x_arm = wc[:, 0] * c1 + wc[:, 1] * s1           # wrist centre along the arm plane's forward axis
    p2 = frames[:, 1, :3, 3]
    x2 = p2[:, 0] * c1 + p2[:, 1] * s1
    up = np.stack([np.sin(th[:, 1]), np.cos(th[:, 1])], 1)   # lower arm direction (forward, up)
    rel = np.stack([x_arm - x2, wc[:, 2] - p2[:, 2]], 1)
    behind_arm = (up[:, 1] * rel[:, 0] - up[:, 0] * rel[:, 1]) < 0
    cfx = 4 * (x_arm < 0) + 2 * behind_arm + (q[:, 4] < 0)
    return np.column_stack([quad, cfx]).astype(int)


def rapid_text(data: ProgramInput) -> str:
    tr, cell, sol = data.trajectory, data.cell, data.solution
    idx = data.kept()
    jm = sol.joint_moves
    native = data.force_program == "native"
    tcp2part = poses_from_trajectory(tr)[idx]
    quat = matrix_to_quat(tcp2part[:, :3, :3])
    conf = abb_confdata(data.model, sol.q[idx])
    on = tr.contact & (tr.pass_index >= 0)

    def frame(t):
        return f"[[{_fmt(t[:3, 3] * 1e3, 4)}],[{_fmt(matrix_to_quat(t[:3, :3]), 9)}]]"

    speeds: dict[float, str] = {}
    ends = {s for s, e, p in segments(tr) if p} | {e - 1 for s, e, p in segments(tr) if p}
    lines = ["MODULE SwathJob", f"  ! swath robot program for {data.model.name}: TCP poses in the part frame (mm, quaternion)",
             "  ! configuration: ConfL\\On, so a linear move never changes the arm's configuration; every change is a "
             "MoveAbsJ in the air"] + header_lines(tr, "  !")
    if native:
        lines += [f"  ! force: ABB Force Control (option 'Force Control Pressure'): each pass starts with FCPress1LStart, "
                  f"presses {data.force:.1f} N along the tool z-axis",
                  "  ! (FC_REFFRAME_TOOL, so the force turns with the tool along the surface) with FCPressL and lifts "
                  "off with FCPressEnd; lSwath must be the real tool load"]
    else:
        lines.append(f"  ! {_position_only_note(data)}")
    lines += [f"  PERS tooldata tSwath := [TRUE,{frame(cell.tcp2flange)},[1,[0,0,0.001],[1,0,0,0],0,0,0]];",
              f"  PERS wobjdata wSwath := [FALSE,TRUE,\"\",{frame(cell.part2base)},[[0,0,0],[1,0,0,0]]];"]
    if native:
        lines.append("  PERS loaddata lSwath := [1,[0,0,0.001],[1,0,0,0],0,0,0];")
    for k in range(len(idx)):
        lines.append(f"  CONST robtarget p{k} := [[{_fmt(tcp2part[k, :3, 3] * 1e3, 4)}],[{_fmt(quat[k], 9)}],"
                     f"[{','.join(str(int(c)) for c in conf[k])}],{eax_text(tr, idx[k])}];")
    for k, i in enumerate(idx):
        if k and jm[i]:
            lines.append(f"  CONST jointtarget j{k} := [[{_fmt(np.degrees(sol.q[i]), 6)}],{eax_text(tr, i)}];")
    body = ["    ConfL\\On;", "    ConfJ\\On;"]
    if native:
        body.append("    FCCalib lSwath;")
    body.append("    MoveJ p0, v100, fine, tSwath\\WObj:=wSwath;")
    pressing = False
    stops = media_stops("rapid", tr, idx, indent="    ")   # media changes (swath.process.media)
    for k, i in enumerate(idx[1:], start=1):
        body += stops.get(k, [])
        if jm[i]:
            if pressing:                    # (a joint move straight off a pass: lift off where the pass ended)
                body.append(f"    FCPressEnd p{k - 1}, v100, tSwath\\WObj:=wSwath;")
                pressing = False
            dur = float(tr.t[i] - tr.t[idx[k - 1]])
            body.append(f"    MoveAbsJ j{k}, v1000\\T:={dur:.3f}, fine, tSwath\\WObj:=wSwath;"
                        + ("  ! configuration change" if sol.branch[i] != sol.branch[idx[k - 1]] else ""))
            continue
        v = round(max(float(tr.feed[i]), 1e-3) * 1e3, 1)
        name = speeds.setdefault(v, f"vSw{len(speeds)}")
        zone = "fine" if (i in ends or k == len(idx) - 1 or jm[idx[k + 1]]) else "z1"
        wobj = "tSwath\\WObj:=wSwath;"
        if native and on[i] and not pressing:
            body.append(f"    FCPress1LStart p{k}, {name}, \\Fz:={data.force:.1f}, {0.5 * data.force:.1f}, "
                        f"\\ForceFrameRef:=FC_REFFRAME_TOOL, fine, {wobj}  ! pass {tr.pass_index[i]}")
            pressing = True
        elif native and pressing and on[i]:
            body.append(f"    FCPressL p{k}, {name}, {data.force:.1f}, {zone}, {wobj}")
        elif native and pressing:
            body.append(f"    FCPressEnd p{k}, {name}, {wobj}")
            pressing = False
        else:
            body.append(f"    MoveL p{k}, {name}, {zone}, {wobj}")
    for v, name in speeds.items():
        lines.append(f"  CONST speeddata {name} := [{v:.1f},500,5000,1000];")
    lines += ["  PROC main()"] + body + ["  ENDPROC", "ENDMODULE", ""]
    return "\n".join(lines)


# --- KUKA KRL ------------------------------------------------------------------------------------------------------
def kuka_status_turn(model: RobotModel, q) -> tuple[np.ndarray, np.ndarray]:
    """KUKA ``S`` (status) and ``T`` (turn) of joint values ``q`` (rad).

    T bit i is set where axis i+1 is negative.  S bit 0: wrist centre behind axis 1 (overhead);
    bit 1: the elbow past its stretched position (θ3 + atan2(a2, c3) < 0 in the OPW model); bit 2:
    A5 ≤ 0.
    """
    q = np.atleast_2d(q)
    turn = np.sum((q < 0) * (1 << np.arange(6)), axis=1)
    wc = model.chain.frames(q)[:, 4, :3, 3]
    th = model.chain.chain_angles(q)
    x_arm = wc[:, 0] * np.cos(th[:, 0]) + wc[:, 1] * np.sin(th[:, 0])
    psi = math.atan2(model.opw.a2, model.opw.c3) if model.opw is not None else 0.0
    status = 1 * (x_arm < 0) + 2 * ((th[:, 2] + psi) < 0) + 4 * (q[:, 4] <= 0)
    return status.astype(int), turn.astype(int)


def _abc(t) -> str:
    a, b, c = np.degrees(matrix_to_zyx(t[:3, :3]))
    x, y, z = t[:3, 3] * 1e3
    return f"X {x:.4f},Y {y:.4f},Z {z:.4f},A {a:.6f},B {b:.6f},C {c:.6f}"


def krl_texts(data: ProgramInput, name: str = "swath_job") -> tuple[str, str]:
    tr, cell, sol = data.trajectory, data.cell, data.solution
    idx = data.kept()
    jm = sol.joint_moves
    native = data.force_program == "native"
    on = tr.contact & (tr.pass_index >= 0)
    tcp2part = poses_from_trajectory(tr)[idx]
    status, turn = kuka_status_turn(data.model, sol.q[idx])
    kuka_tool = np.linalg.inv(FLANGE2KUKA_FLANGE) @ cell.tcp2flange
    dat = ["&ACCESS RVP", f"DEFDAT {name}", f"; swath robot program for {data.model.name}: TCP poses in $BASE (mm, deg)",
           f"DECL FRAME BASE_SWATH={{{_abc(cell.part2base)}}}", f"DECL FRAME TOOL_SWATH={{{_abc(kuka_tool)}}}"]
    for k in range(len(idx)):
        dat.append(f"DECL E6POS XP{k + 1}={{{_abc(tcp2part[k])},S {status[k]},T {turn[k]},"
                   f"E1 {e1_text(tr, idx[k])},E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}}")
    dat += ["ENDDAT", ""]
    ends = {s for s, e, p in segments(tr) if p} | {e - 1 for s, e, p in segments(tr) if p}
    head = ["&ACCESS RVP", f"DEF {name}()",
            "  ; configuration: LIN keeps the arm's configuration (S and T apply to PTP only); every change is a "
            "PTP with S and T in the air"] + header_lines(tr, "  ;")
    if native:
        head += [f"  ; force: KUKA.ForceTorqueControl presses {data.force:.1f} N along $TOOL z (the pad axis, into the "
                 "part) in every pass; the force frame is the tool, so it turns with the tool along the surface.",
                 "  ; SWATH_FTC_ON(force N) and SWATH_FTC_OFF() must start and stop the cell's ForceTorqueControl "
                 "path task (force-controlled $TOOL z, other axes position-controlled)",
                 "  EXT SWATH_FTC_ON(REAL :IN)", "  EXT SWATH_FTC_OFF()"]
    else:
        head.append(f"  ; {_position_only_note(data)}")
    src = head + ["  $BASE=BASE_SWATH", "  $TOOL=TOOL_SWATH", f"  $APO.CDIS={data.blend * 1e3:.3f}", "  PTP XP1"]
    last_v = None
    pressing = False
    stops = media_stops("krl", tr, idx)                # media changes (swath.process.media)
    for k, i in enumerate(idx[1:], start=2):
        src += stops.get(k - 1, [])
        if jm[i]:
            if pressing:
                src.append("  SWATH_FTC_OFF()")
                pressing = False
            src.append(f"  PTP XP{k}" + ("  ; configuration change" if sol.branch[i] != sol.branch[idx[k - 2]] else ""))
            continue
        if native and on[i] and not pressing:
            src.append(f"  SWATH_FTC_ON({data.force:.1f})  ; pass {tr.pass_index[i]}")
            pressing = True
        v = max(float(tr.feed[i]), 1e-3)
        if last_v is None or abs(v - last_v) > 1e-6:
            src.append(f"  $VEL.CP={v:.5f}")
            last_v = v
        approx = "" if (i in ends or k == len(idx) or jm[idx[k]]) else " C_DIS"
        src.append(f"  LIN XP{k}{approx}")
        nxt_on = k < len(idx) and bool(on[idx[k]]) and tr.pass_index[idx[k]] == tr.pass_index[i]
        if native and pressing and not nxt_on:
            src.append("  SWATH_FTC_OFF()")
            pressing = False
    src += ["END", ""]
    return "\n".join(src), "\n".join(dat)


# --- joint-space files ---------------------------------------------------------------------------------------------
def ros_yaml_text(data: ProgramInput) -> str:
    """ROS 2 ``trajectory_msgs/JointTrajectory`` as YAML: ``time_from_start`` a ``builtin_interfaces/Duration``
    (``sec``, ``nanosec``); velocities by central differences, zero at the first and last point (the
    motion starts and ends at rest).  Written line by line (block style, flow lists; numbers as
    Python's shortest round-trip repr), which any YAML 1.1/1.2 reader parses."""
    tr, sol = data.trajectory, data.solution
    idx = np.flatnonzero(sol.reachable)
    t = tr.t[idx] - tr.t[idx[0]]
    q = sol.q[idx]
    vel = np.gradient(q, t, axis=0) if len(idx) > 1 else np.zeros_like(q)
    vel = np.where(np.isfinite(vel), vel, 0.0)
    vel[0] = 0.0
    vel[-1] = 0.0

    def flow(values) -> str:
        return "[" + ", ".join(repr(float(v)) for v in values) + "]"

    lines = ["header:", "  stamp: {sec: 0, nanosec: 0}", "  frame_id: base_link",
             "joint_names: [" + ", ".join(joint_names(data.model)) + "]", "points:"]
    for ti, qi, vi in zip(t, q, vel):
        sec = math.floor(ti)
        nanosec = round((ti - sec) * 1e9)
        if nanosec >= 1_000_000_000:
            sec, nanosec = sec + 1, nanosec - 1_000_000_000
        lines += [f"- positions: {flow(qi)}", f"  velocities: {flow(vi)}",
                  f"  time_from_start: {{sec: {int(sec)}, nanosec: {int(nanosec)}}}"]
    return media_header(tr) + "\n".join(lines) + "\n"


def joint_csv_text(data: ProgramInput) -> str:
    """``joints.csv``: ``t,q1..q6,contact,pass,branch`` per reached sample, and with media changes
    (:mod:`swath.process.media`) a ``media`` column, the abrasive in use (0 = the first): a new value
    is a stop for the operator before that row."""
    tr, sol = data.trajectory, data.solution
    idx = np.flatnonzero(sol.reachable)
    media = tr.extra.get("media") if hasattr(tr, "extra") else None
    axis = tr.extra.get(AXIS_COLUMN) if hasattr(tr, "extra") else None     # a positioner's angle, rad
    rows = ["t,q1,q2,q3,q4,q5,q6" + (",positioner" if axis is not None else "") + ",contact,pass,branch"
            + (",media" if media is not None else "")]
    for i in idx:
        rows.append(f"{tr.t[i]:.9f}," + _fmt(sol.q[i], 12) + (f",{axis[i]:.12g}" if axis is not None else "")
                    + f",{int(tr.contact[i])},{int(tr.pass_index[i])},{int(sol.branch[i])}"
                    + (f",{int(round(float(media[i])))}" if media is not None else ""))
    return "\n".join(rows) + "\n"


def write_programs(data: ProgramInput, out_dir, formats) -> list:
    """Write the programs named in ``formats`` (keys of :data:`PROGRAM_FILES`) atomically; returns their paths."""
    from pathlib import Path

    from ..errors import InputError

    out_dir = Path(out_dir)
    check_program_formats(data.model, formats, data.force_program)
    written = []
    for fmt in formats:
        fmt = fmt.strip().lower()
        if fmt not in PROGRAM_FILES:
            raise InputError(f"unknown program format {fmt!r}; choose from {', '.join(PROGRAM_FILES)}")
        files = [out_dir / f for f in PROGRAM_FILES[fmt]]
        texts: tuple[str, ...]
        if fmt == "krl":
            texts = krl_texts(data)
        else:
            texts = ({"urscript": urscript_text, "rapid": rapid_text, "ros": ros_yaml_text, "csv": joint_csv_text}[fmt](data),)
        for path, text in zip(files, texts):
            write_text_atomic(path, text)
            written.append(path)
    return written
