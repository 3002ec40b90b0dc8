"""Readers for the programs :mod:`swath.robot.programs` writes (own parsers; used by the round-trip tests).

Each returns plain arrays in SI units (m, rad, s) and the frames the program states, so a test can
compare them with the trajectory and joint solution they were written from.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from ..errors import InputError
from .pose import make_transform, quat_to_matrix, zyx_to_matrix

_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


def _rotvec_to_matrix(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    ang = np.linalg.norm(v, axis=-1, keepdims=True)
    axis = np.where(ang > 0, v / np.where(ang > 0, ang, 1), 0.0)
    half = ang[..., 0] / 2
    q = np.concatenate([np.cos(half)[..., None], axis * np.sin(half)[..., None]], axis=-1)
    return quat_to_matrix(q)


def _nums(text: str) -> list[float]:
    return [float(x) for x in re.findall(_NUM, text)]


def read_urscript(path) -> dict:
    """Parse a URScript written by swath.

    Returns
    -------
    dict
        ``tcp`` (4, 4) tcp2flange; ``tcp2base`` (m, 4, 4) movel targets (m); ``blend`` (m,) m;
        ``speed`` (m,) m/s; ``in_force`` (m,) bool (target inside force_mode); ``movej`` list of (6,)
        joint values (rad); ``force`` list of wrench z values (N); ``force_frame`` (m, 4, 4) the task
        frame of the force_mode in effect on the move to each movel target (base frame; NaN
        outside force_mode); ``movej_after`` list of int: how many movel targets precede each movej.
    """
    text = Path(path).read_text(encoding="utf-8")
    tcp = None
    poses: list = []
    blend: list = []
    speed: list = []
    in_force: list = []
    movej: list = []
    forces: list = []
    frames: list = []
    movej_after: list = []
    force = False
    frame = np.full((4, 4), np.nan)
    for line in text.splitlines():
        s = line.strip()
        if s.startswith("set_tcp("):
            v = _nums(s[s.index("p[") + 2: s.index("]")])
            tcp = make_transform(_rotvec_to_matrix(v[3:]), v[:3])
        elif s.startswith("movej(["):
            movej.append(np.array(_nums(s[7: s.index("]")])))
            movej_after.append(len(poses))
        elif s.startswith("force_mode("):
            force = True
            groups = re.findall(r"\[([^\[\]]*)\]", s)     # [task frame,] selection, wrench, limits
            forces.append(_nums(groups[-2])[2])
            if s.startswith("force_mode(p["):
                v = _nums(s[13: s.index("]")])
                frame = make_transform(_rotvec_to_matrix(v[3:6]), v[:3])
            else:
                frame = np.full((4, 4), np.nan)
        elif s.startswith("end_force_mode"):
            force = False
            frame = np.full((4, 4), np.nan)
        elif s.startswith("movel(p["):
            v = _nums(s[8: s.index("]")])
            opts = dict(re.findall(r"(\w)=(" + _NUM + ")", s[s.index("]"):]))
            poses.append(make_transform(_rotvec_to_matrix(v[3:6]), v[:3]))
            blend.append(float(opts["r"]))
            speed.append(float(opts["v"]))
            in_force.append(force)
            frames.append(frame)
    if tcp is None:
        raise InputError(f"{path}: no set_tcp line; not a swath URScript")
    return {"tcp": tcp, "tcp2base": np.array(poses), "blend": np.array(blend), "speed": np.array(speed),
            "in_force": np.array(in_force), "movej": movej, "force": forces, "force_frame": np.array(frames),
            "movej_after": movej_after}


def _rapid_frame(text: str) -> np.ndarray:
    v = _nums(text)
    return make_transform(quat_to_matrix(v[3:7]), np.array(v[:3]) * 1e-3)


def read_rapid(path) -> dict:
    """Parse a RAPID module written by swath.

    Returns
    -------
    dict
        ``tool`` (4, 4) tcp2flange, ``wobj`` (4, 4) part2base (m); ``targets`` (m, 4, 4) tcp2part in
        move order (m); ``conf`` (m, 4) int; ``speed`` (m,) TCP speed, m/s (MoveJ: nan); ``zone`` list;
        ``instruction`` list (``MoveL``, ``MoveJ``, ``FCPress1LStart``, ``FCPressL``, ``FCPressEnd``) per
        target; ``force`` (m,) N pressed on the move to each target (0 without force control);
        ``joint_moves`` list of (index of the next target, (6,) joint values rad) per ``MoveAbsJ``.
    """
    text = Path(path).read_text(encoding="utf-8")
    tool = re.search(r"tooldata\s+\w+\s*:=\s*\[TRUE,(\[\[.*?\]\])", text)
    wobj = re.search(r"wobjdata\s+\w+\s*:=\s*\[FALSE,TRUE,\"[^\"]*\",(\[\[.*?\]\])", text)
    if tool is None or wobj is None:
        raise InputError(f"{path}: no tooldata/wobjdata; not a swath RAPID module")
    robt: dict = {}
    for name, body in re.findall(r"CONST robtarget (\w+) := \[(.*?)\];", text):
        groups = re.findall(r"\[([^\[\]]*)\]", body)
        pos, quat, cf = _nums(groups[0]), _nums(groups[1]), _nums(groups[2])
        robt[name] = (make_transform(quat_to_matrix(quat), np.array(pos) * 1e-3), np.array(cf, dtype=int))
    speeds = {n: _nums(b)[0] * 1e-3 for n, b in re.findall(r"CONST speeddata (\w+) := \[(.*?)\];", text)}
    joints = {n: np.radians(_nums(b)[:6]) for n, b in re.findall(r"CONST jointtarget (\w+) := \[\[(.*?)\]", text)}
    targets: list = []
    conf: list = []
    speed: list = []
    zone: list = []
    instruction: list = []
    force: list = []
    joint_moves: list = []
    for line in text.splitlines():
        s = line.strip()
        m = re.match(r"MoveAbsJ (\w+),", s)
        if m:
            joint_moves.append((len(targets), joints[m.group(1)]))
            continue
        m = re.match(r"(MoveL|MoveJ|FCPress1LStart|FCPressL|FCPressEnd) (\w+), (\w+), (.*)", s)
        if not m:
            continue
        kind, name, sp, rest = m.groups()
        t, c = robt[name]
        targets.append(t)
        conf.append(c)
        speed.append(speeds.get(sp, math.nan) if kind != "MoveJ" else math.nan)
        args = [a.strip() for a in rest.split(",")]
        if kind == "FCPress1LStart":
            force.append(float(_nums(args[0])[0]))
            zone.append(args[3])
        elif kind == "FCPressL":
            force.append(float(args[0]))
            zone.append(args[1])
        else:
            force.append(0.0)
            zone.append("fine" if kind == "FCPressEnd" else args[0])
        instruction.append(kind)
    return {"tool": _rapid_frame(tool.group(1)), "wobj": _rapid_frame(wobj.group(1)), "targets": np.array(targets),
            "conf": np.array(conf), "speed": np.array(speed), "zone": zone, "instruction": instruction,
            "force": np.array(force), "joint_moves": joint_moves}


def _krl_frame(body: str) -> tuple[np.ndarray, dict]:
    vals = {k: float(v) for k, v in re.findall(r"([A-Z]\d?)\s+(" + _NUM + ")", body)}
    rot = zyx_to_matrix(*np.radians([vals["A"], vals["B"], vals["C"]]))
    return make_transform(rot, np.array([vals["X"], vals["Y"], vals["Z"]]) * 1e-3), vals


def read_krl(src_path, dat_path) -> dict:
    """Parse a KRL .src/.dat pair written by swath.

    Returns
    -------
    dict
        ``base`` (4, 4) part2base, ``tool`` (4, 4) KUKA tcp2flange (m); ``targets`` (m, 4, 4) TCP poses in
        $BASE in move order; ``status``, ``turn`` (m,) int; ``speed`` (m,) $VEL.CP in force (m/s);
        ``approx`` (m,) bool (C_DIS); ``motion`` list (``LIN``/``PTP``) per target; ``force`` (m,) N
        pressed on the move to each target (SWATH_FTC_ON … SWATH_FTC_OFF; 0 outside).
    """
    dat = Path(dat_path).read_text(encoding="utf-8")
    src = Path(src_path).read_text(encoding="utf-8")
    frames = dict(re.findall(r"DECL FRAME (\w+)=\{(.*?)\}", dat))
    points = dict(re.findall(r"DECL E6POS (\w+)=\{(.*?)\}", dat))
    if "BASE_SWATH" not in frames or "TOOL_SWATH" not in frames:
        raise InputError(f"{dat_path}: no BASE_SWATH/TOOL_SWATH frames; not a swath KRL program")
    targets, status, turn, speed, approx, motion, force = [], [], [], [], [], [], []
    v = math.nan
    pressing = 0.0
    for line in src.splitlines():
        s = line.strip()
        if s.startswith("$VEL.CP="):
            v = float(s.split("=")[1])
        if s.startswith("SWATH_FTC_ON("):
            pressing = _nums(s)[0]
        if s.startswith("SWATH_FTC_OFF("):
            pressing = 0.0
        m = re.match(r"(LIN|PTP) (\w+)( C_DIS)?", s)
        if m:
            t, vals = _krl_frame(points[m.group(2)])
            targets.append(t)
            status.append(int(vals["S"]))
            turn.append(int(vals["T"]))
            speed.append(v if m.group(1) == "LIN" else math.nan)
            approx.append(bool(m.group(3)))
            motion.append(m.group(1))
            force.append(pressing)
    return {"base": _krl_frame(frames["BASE_SWATH"])[0], "tool": _krl_frame(frames["TOOL_SWATH"])[0],
            "targets": np.array(targets), "status": np.array(status), "turn": np.array(turn),
            "speed": np.array(speed), "approx": np.array(approx), "motion": motion, "force": np.array(force)}


def read_ros_yaml(path) -> dict:
    """Parse a ROS 2 JointTrajectory YAML (``time_from_start`` as ``sec``/``nanosec``): ``joint_names``,
    ``t`` (m,) s, ``q`` (m, 6) rad, ``qd`` (m, 6) rad/s, ``durations`` list of the ``time_from_start``
    mappings as written.

    The line layout :func:`swath.robot.programs.ros_yaml_text` writes is read directly (fast on long
    files); any other layout goes through a YAML parser.
    """
    text = Path(path).read_text(encoding="utf-8")
    pos = re.findall(r"^- positions: \[(.*)\]$", text, flags=re.M)
    vel = re.findall(r"^  velocities: \[(.*)\]$", text, flags=re.M)
    dur = re.findall(r"^  time_from_start: \{(.*)\}$", text, flags=re.M)
    names = re.search(r"^joint_names: \[(.*)\]$", text, flags=re.M)
    if names and pos and len(pos) == len(vel) == len(dur):
        durations = [{k.strip(): int(v) for k, v in (kv.split(":") for kv in d.split(","))} for d in dur]
        joint_names = [x.strip() for x in names.group(1).split(",")]
        q = np.array([[float(x) for x in p.split(",")] for p in pos])
        qd = np.array([[float(x) for x in v.split(",")] for v in vel])
    else:
        import yaml

        loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
        msg = yaml.load(text, Loader=loader)
        pts = msg["points"]
        durations = [p["time_from_start"] for p in pts]
        joint_names = msg["joint_names"]
        q = np.array([p["positions"] for p in pts])
        qd = np.array([p["velocities"] for p in pts])
    t = np.array([d["sec"] + d["nanosec"] * 1e-9 for d in durations])
    return {"joint_names": joint_names, "t": t, "q": q, "qd": qd, "durations": durations}


def read_joint_csv(path) -> dict:
    """Parse ``joints.csv``: ``t`` (m,) s, ``q`` (m, 6) rad, ``contact``, ``pass_index``, ``branch`` (m,), and
    ``media`` (m,) int where the file has that column (else absent)."""
    path = Path(path)
    header = path.read_text(encoding="utf-8").splitlines()[0].split(",")
    if header[:7] != ["t", "q1", "q2", "q3", "q4", "q5", "q6"]:
        raise InputError(f"{path}: expected columns t,q1..q6 first, got {','.join(header[:7])}")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    out = {"t": data[:, 0], "q": data[:, 1:7], "contact": data[:, 7] > 0.5, "pass_index": data[:, 8].astype(int),
           "branch": data[:, 9].astype(int)}
    if "media" in header:
        out["media"] = data[:, header.index("media")].astype(int)
    return out
