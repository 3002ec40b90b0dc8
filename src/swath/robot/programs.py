"""Robot programs from a solved trajectory: URScript, ABB RAPID, KUKA KRL, ROS JointTrajectory YAML, joint CSV.

Every writer writes atomically and takes a :class:`ProgramInput` (re-timed trajectory, joint
solution, model, cell).  Joint-space files (``joints.csv``, ROS YAML) carry every reachable sample;
the vendor programs (Cartesian moves) carry the samples kept by :func:`decimate`, which keeps each
pass's and link's first and last sample and drops a sample only where the straight line between
its kept neighbours stays within ``tol_position`` (m) and ``tol_angle`` (rad) of every dropped one.

Units and frames per format (the readers in :mod:`swath.robot.readers` parse them back):

* URScript — ``p[x, y, z, rx, ry, rz]`` TCP poses in the robot base frame, m and rotation vector
  (rad); ``set_tcp`` from ``tcp2flange``; ``movej`` to the first configuration and at every branch
  switch; ``force_mode`` along the tool z-axis around each contact pass; ``movel`` with blend
  radius ``r`` (0 at pass ends) and speed ``v`` = the timed feed (m/s).
* RAPID — TCP poses in the part frame (``wobjdata`` user frame = the part placement), mm and
  quaternions; ``confdata [cf1, cf4, cf6, cfx]`` from the joint values (ABB's quadrant and cfx
  rules); ``MoveL`` with a ``speeddata`` per feed and ``z1`` (``fine`` at pass ends).
* KRL — ``.dat`` with ``FRAME`` base/tool and ``E6POS`` points (X, Y, Z mm; A, B, C deg, ``Rz(A)
  Ry(B) Rx(C)``; S status, T turn); ``.src`` sets ``$BASE``, ``$TOOL``, ``$VEL.CP`` (m/s) and runs
  ``LIN … C_DIS``.  KUKA's flange frame has x out of the flange: ``$TOOL = Ry(90°) · tcp2flange``.
* ROS ``trajectory_msgs/JointTrajectory`` YAML — joint names, positions (rad), velocities (rad/s),
  ``time_from_start`` {secs, nsecs}.
* ``joints.csv`` — ``t,q1..q6,contact,pass,branch`` (s, rad).

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


@dataclass(frozen=True, eq=False)
class ProgramInput:
    """What every writer needs."""

    trajectory: Any
    solution: JointSolution
    model: RobotModel
    cell: Cell
    force: float = 20.0
    tol_position: float = 1e-4
    tol_angle: float = math.radians(0.5)
    blend: float = 1e-3

    def kept(self) -> np.ndarray:
        return decimate(self.trajectory, self.solution.reachable, tol_position=self.tol_position,
                        tol_angle=self.tol_angle)


def joint_names(model: RobotModel) -> list[str]:
    """ROS joint names of the model (UR driver names, ROS-Industrial names for ABB and KUKA)."""
    if model.kind == "ur":
        return ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
                "wrist_3_joint"]
    if model.name.startswith("kr"):
        return [f"joint_a{i}" for i in range(1, 7)]
    return [f"joint_{i}" for i in range(1, 7)]


def decimate(trajectory, keep, *, tol_position: float = 1e-4, tol_angle: float = math.radians(0.5)) -> np.ndarray:
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

    Returns
    -------
    (m,) int
        Sorted indices; each pass's and link's first and last allowed sample always included.
    """
    pos = trajectory.position
    zax = trajectory.tool_z()
    out = []
    for s, e, _ in segments(trajectory):
        idx = np.flatnonzero(keep[s:e]) + s
        # split at gaps (unreachable samples) so no chord spans one
        for run in np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1):
            if len(run):
                out.extend(_douglas_peucker(run, pos, zax, tol_position, tol_angle))
    return np.array(sorted(set(out)), dtype=int)


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
def urscript_text(data: ProgramInput) -> str:
    tr, sol, cell = data.trajectory, data.solution, data.cell
    idx = data.kept()
    tcp2base = cell.part2base @ poses_from_trajectory(tr)[idx]
    rv = _rotvec(tcp2base[:, :3, :3])
    tcp = np.concatenate([cell.tcp2flange[:3, 3], _rotvec(cell.tcp2flange[:3, :3])])
    lines = ["def swath_job():", f"  # swath robot program for {data.model.name}; poses in the base frame (m, rotation vector)",
             f"  set_tcp(p[{_fmt(tcp, 7)}])"]
    lines.append(f"  movej([{_fmt(sol.q[idx[0]], 8)}], a=0.5, v=0.3)")
    in_force = False
    ends = {s for s, e, p in segments(tr) if p} | {e - 1 for s, e, p in segments(tr) if p}
    stops = media_stops("urscript", tr, idx)           # media changes (swath.process.media)
    for k, i in enumerate(idx):
        lines += stops.get(k, [])
        c = bool(tr.contact[i]) and tr.pass_index[i] >= 0
        if k and sol.branch[i] != sol.branch[idx[k - 1]]:
            lines.append(f"  movej([{_fmt(sol.q[i], 8)}], a=0.5, v=0.3)  # branch switch")
        if c and not in_force:
            lines.append(f"  force_mode(get_actual_tcp_pose(), [0,0,1,0,0,0], [0,0,{data.force:.3f},0,0,0], 2, "
                         "[0.1,0.1,0.15,0.3491,0.3491,0.3491])  # pass %d" % tr.pass_index[i])
            in_force = True
        v = max(float(tr.feed[i]), 1e-3)
        r = 0.0 if (i in ends or k == len(idx) - 1) else data.blend
        lines.append(f"  movel(p[{_fmt(tcp2base[k, :3, 3], 7)},{_fmt(rv[k], 9)}], a=1.0, v={v:.5f}, r={r:.4f})")
        nxt_c = k + 1 < len(idx) and bool(tr.contact[idx[k + 1]]) and tr.pass_index[idx[k + 1]] == tr.pass_index[i]
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
    tr, cell = data.trajectory, data.cell
    idx = data.kept()
    tcp2part = poses_from_trajectory(tr)[idx]
    quat = matrix_to_quat(tcp2part[:, :3, :3])
    conf = abb_confdata(data.model, data.solution.q[idx])

    def frame(t):
        return f"[[{_fmt(t[:3, 3] * 1e3, 4)}],[{_fmt(matrix_to_quat(t[:3, :3]), 9)}]]"

    speeds: dict[float, str] = {}
    ends = {s for s, e, p in segments(tr) if p} | {e - 1 for s, e, p in segments(tr) if p}
    lines = ["MODULE SwathJob", f"  ! swath robot program for {data.model.name}: TCP poses in the part frame (mm, quaternion)",
             f"  PERS tooldata tSwath := [TRUE,{frame(cell.tcp2flange)},[1,[0,0,0.001],[1,0,0,0],0,0,0]];",
             f"  PERS wobjdata wSwath := [FALSE,TRUE,\"\",{frame(cell.part2base)},[[0,0,0],[1,0,0,0]]];"]
    for k in range(len(idx)):
        lines.append(f"  CONST robtarget p{k} := [[{_fmt(tcp2part[k, :3, 3] * 1e3, 4)}],[{_fmt(quat[k], 9)}],"
                     f"[{','.join(str(int(c)) for c in conf[k])}],[9E9,9E9,9E9,9E9,9E9,9E9]];")
    body = ["    MoveJ p0, v100, fine, tSwath\\WObj:=wSwath;"]
    stops = media_stops("rapid", tr, idx, indent="    ")   # media changes (swath.process.media)
    for k, i in enumerate(idx[1:], start=1):
        body += stops.get(k, [])
        v = round(max(float(tr.feed[i]), 1e-3) * 1e3, 1)
        name = speeds.setdefault(v, f"vSw{len(speeds)}")
        zone = "fine" if (i in ends or k == len(idx) - 1) else "z1"
        body.append(f"    MoveL p{k}, {name}, {zone}, tSwath\\WObj:=wSwath;")
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
    tr, cell = data.trajectory, data.cell
    idx = data.kept()
    tcp2part = poses_from_trajectory(tr)[idx]
    status, turn = kuka_status_turn(data.model, data.solution.q[idx])
    kuka_tool = np.linalg.inv(FLANGE2KUKA_FLANGE) @ cell.tcp2flange
    dat = ["&ACCESS RVP", f"DEFDAT {name}", f"; swath robot program for {data.model.name}: TCP poses in $BASE (mm, deg)",
           f"DECL FRAME BASE_SWATH={{{_abc(cell.part2base)}}}", f"DECL FRAME TOOL_SWATH={{{_abc(kuka_tool)}}}"]
    for k in range(len(idx)):
        dat.append(f"DECL E6POS XP{k + 1}={{{_abc(tcp2part[k])},S {status[k]},T {turn[k]},"
                   "E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}")
    dat += ["ENDDAT", ""]
    ends = {s for s, e, p in segments(tr) if p} | {e - 1 for s, e, p in segments(tr) if p}
    src = ["&ACCESS RVP", f"DEF {name}()", "  $BASE=BASE_SWATH", "  $TOOL=TOOL_SWATH", f"  $APO.CDIS={data.blend * 1e3:.3f}",
           "  PTP XP1"]
    last_v = None
    stops = media_stops("krl", tr, idx)                # media changes (swath.process.media)
    for k, i in enumerate(idx[1:], start=2):
        src += stops.get(k - 1, [])
        v = max(float(tr.feed[i]), 1e-3)
        if last_v is None or abs(v - last_v) > 1e-6:
            src.append(f"  $VEL.CP={v:.5f}")
            last_v = v
        approx = "" if (i in ends or k == len(idx)) else " C_DIS"
        src.append(f"  LIN XP{k}{approx}")
    src += ["END", ""]
    return "\n".join(src), "\n".join(dat)


# --- joint-space files ---------------------------------------------------------------------------------------------
def ros_yaml_text(data: ProgramInput) -> str:
    import yaml

    tr, sol = data.trajectory, data.solution
    idx = np.flatnonzero(sol.reachable)
    t = tr.t[idx] - tr.t[idx[0]]
    q = sol.q[idx]
    vel = np.gradient(q, t, axis=0) if len(idx) > 1 else np.zeros_like(q)
    vel = np.where(np.isfinite(vel), vel, 0.0)
    points = []
    for ti, qi, vi in zip(t, q, vel):
        secs = math.floor(ti)
        points.append({"positions": [float(v) for v in qi], "velocities": [float(v) for v in vi],
                       "time_from_start": {"secs": secs, "nsecs": round((ti - secs) * 1e9)}})
    msg = {"header": {"frame_id": "base_link"}, "joint_names": joint_names(data.model), "points": points}
    return media_header(tr) + yaml.safe_dump(msg, sort_keys=False, default_flow_style=None)


def joint_csv_text(data: ProgramInput) -> str:
    tr, sol = data.trajectory, data.solution
    idx = np.flatnonzero(sol.reachable)
    rows = ["t,q1,q2,q3,q4,q5,q6,contact,pass,branch"]
    for i in idx:
        rows.append(f"{tr.t[i]:.9f}," + _fmt(sol.q[i], 12) + f",{int(tr.contact[i])},{int(tr.pass_index[i])},{int(sol.branch[i])}")
    return "\n".join(rows) + "\n"


def write_programs(data: ProgramInput, out_dir, formats) -> list:
    """Write the programs named in ``formats`` (keys of :data:`PROGRAM_FILES`) atomically; returns their paths."""
    from pathlib import Path

    from ..errors import InputError

    out_dir = Path(out_dir)
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
