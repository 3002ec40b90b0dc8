"""Robots from URDF files through pinocchio: forward kinematics, Jacobians and a numerical IK.

``urdf_robot("robot.urdf", tip="tool0")`` reads the file with ``pinocchio.buildModelFromUrdf``, keeps
the six revolute joints between the URDF's root link (the robot base frame) and the ``tip`` frame
(the flange; joints off that path are locked at zero) and returns a :class:`RobotModel` of kind
``"numeric"``: the rest of the robot stage (branch table, placement, re-timing, programs) treats it
like any other model.

The IK (:func:`dls_ik`) is damped least squares on the tip pose error (``log6`` of the current pose's
inverse times the target, the body Jacobian from ``computeFrameJacobian``), started from the
previous solution so that a pose sequence stays on one configuration branch: each step of the joints
is capped, the joints are kept inside their limits, and a pose the solver cannot reach from the
previous solution is approached through intermediate poses before it is given up (NaN).  Only the
first pose (and the first after a gap) is solved from several seeded starts, keeping the converged
configuration with the largest manipulability.

pinocchio is the optional ``robot`` extra (``pip install 'swath[robot]'``, PyPI package ``pin``).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..errors import InputError
from .models import RobotModel

#: Joint acceleration assumed when a URDF gives none (URDF has no acceleration limits), rad/s².
DEFAULT_ACCEL = 4 * math.pi
#: Joint speed assumed when a URDF's ``velocity`` limit is missing or zero, rad/s.
DEFAULT_SPEED = math.pi / 2


def _pinocchio():
    try:
        import pinocchio
    except ImportError as exc:                       # pragma: no cover - the robot extra is in the test extra
        raise InputError("URDF robots need pinocchio: pip install 'swath[robot]' (PyPI package 'pin')") from exc
    return pinocchio


class PinocchioChain:
    """Tip-frame kinematics of a pinocchio model with six revolute joints, shaped like :class:`Chain`.

    Attributes
    ----------
    model : pinocchio.Model
        Reduced to the six joints that move the tip.
    frame_id : int
        The tip frame.
    n_joints : int
        6.
    """

    def __init__(self, model, frame_id: int):
        pin = _pinocchio()
        self.model = model
        self.data = model.createData()
        self.frame_id = int(frame_id)
        self.n_joints = int(model.nq)
        self.sign = np.ones(self.n_joints)
        self.offset = np.zeros(self.n_joints)
        self._pin = pin
        # each joint's axis in its own frame (revolute joints: unit vector of RX/RY/RZ or unaligned)
        axes = []
        for j in range(1, model.njoints):
            sub = model.joints[j].shortname()
            if sub.endswith(("RX", "RY", "RZ")):
                axes.append(np.eye(3)["XYZ".index(sub[-1])])
            else:
                axes.append(np.asarray(model.joints[j].extract().axis, dtype=float).copy())
        self._axes_local = np.array(axes)

    def chain_angles(self, q) -> np.ndarray:
        return np.asarray(q, dtype=float)

    def joint_values(self, theta) -> np.ndarray:
        return np.asarray(theta, dtype=float)

    def _update(self, q) -> None:
        pin = self._pin
        pin.forwardKinematics(self.model, self.data, q)
        pin.updateFramePlacement(self.model, self.data, self.frame_id)

    def frames(self, q) -> np.ndarray:
        """(n, 7, 4, 4) base2frame of each joint (after its rotation) and the tip, m; ``q`` (n, 6) rad."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        out = np.empty((len(q), self.n_joints + 1, 4, 4))
        for i, qi in enumerate(q):
            self._update(qi)
            for j in range(self.n_joints):
                out[i, j] = self.data.oMi[j + 1].homogeneous
            out[i, -1] = self.data.oMf[self.frame_id].homogeneous
        return out

    def fk(self, q) -> np.ndarray:
        """(n, 4, 4) base2tip for joint values ``q`` (n, 6), rad; m."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        out = np.empty((len(q), 4, 4))
        for i, qi in enumerate(q):
            self._update(qi)
            out[i] = self.data.oMf[self.frame_id].homogeneous
        return out

    def jacobian(self, q) -> np.ndarray:
        """(n, 6, 6) geometric Jacobian of the tip in the base frame (linear m/rad, then angular rad/rad)."""
        pin = self._pin
        q = np.atleast_2d(np.asarray(q, dtype=float))
        out = np.empty((len(q), 6, self.n_joints))
        for i, qi in enumerate(q):
            out[i] = pin.computeFrameJacobian(self.model, self.data, qi, self.frame_id,
                                              pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        return out

    def body_jacobian(self, q) -> np.ndarray:
        """(6, 6) Jacobian of the tip in the tip frame for one ``q`` (6,), rad."""
        pin = self._pin
        return pin.computeFrameJacobian(self.model, self.data, q, self.frame_id, pin.ReferenceFrame.LOCAL)

    def joint_axes(self, q) -> np.ndarray:
        """(n, 6, 3) unit joint axes in the base frame."""
        f = self.frames(q)[:, :-1, :3, :3]
        return np.einsum("njab,jb->nja", f, self._axes_local)


def _chain_joints(model, frame_id: int) -> list[int]:
    """Joint ids from the root to the tip frame's parent joint."""
    j = model.frames[frame_id].parentJoint
    out = []
    while j > 0:
        out.append(int(j))
        j = model.parents[j]
    return out[::-1]


def urdf_robot(path, *, tip: str = "tool0", name: str | None = None, reach: float | None = None,
               max_accel=None) -> RobotModel:
    """A six-axis robot from a URDF file.

    Parameters
    ----------
    path : path
        The URDF file.  Its root link is the robot base frame.
    tip : str
        The frame (link or joint name) that carries the tool, the flange (default ``tool0``, the
        ROS-Industrial convention).
    name : str, optional
        Model name (default: the URDF's robot name).
    reach : float, optional
        Nominal reach, m (default: the largest distance of the tip from the second joint's origin
        over 2,000 seeded random configurations inside the limits).
    max_accel : float or (6,) float, optional
        Joint acceleration limits, rad/s² (URDF has none; default :data:`DEFAULT_ACCEL`, stated in
        the model's ``source``).

    Raises
    ------
    InputError
        When the file is missing or unreadable, the tip frame is unknown, or the tip is not moved by
        exactly six revolute joints with finite limits.
    """
    pin = _pinocchio()
    path = Path(path)
    if not path.is_file():
        raise InputError(f"URDF file {path} not found; give --robot a .urdf file or a catalogue name")
    try:
        full = pin.buildModelFromUrdf(str(path))
    except Exception as exc:    # pinocchio raises ValueError/RuntimeError on a malformed file
        raise InputError(f"could not read URDF {path.name}: {exc}") from exc
    if not full.existFrame(tip):
        frames = sorted({f.name for f in full.frames if f.name != "universe"})
        raise InputError(f"URDF {path.name} has no frame {tip!r} for --tip; its frames: {', '.join(frames)}")
    joints = _chain_joints(full, full.getFrameId(tip))
    lock = [j for j in range(1, full.njoints) if j not in joints]
    model = pin.buildReducedModel(full, lock, pin.neutral(full)) if lock else full
    kinds = [model.joints[j].shortname() for j in range(1, model.njoints)]
    if model.njoints - 1 != 6 or model.nq != 6 or any("R" not in k or "RUB" in k for k in kinds):
        raise InputError(f"URDF {path.name}: the tip {tip!r} must be moved by six revolute joints with limits, "
                         f"found {model.njoints - 1} joints ({', '.join(kinds)}); continuous joints need a "
                         "revolute type with limits")
    lower = np.asarray(model.lowerPositionLimit, dtype=float).copy()
    upper = np.asarray(model.upperPositionLimit, dtype=float).copy()
    if not (np.all(np.isfinite(lower)) and np.all(np.isfinite(upper)) and np.all(upper > lower)):
        raise InputError(f"URDF {path.name}: every joint needs finite position limits (lower < upper), "
                         f"got lower {lower.round(3).tolist()}, upper {upper.round(3).tolist()}")
    speed = np.asarray(model.velocityLimit, dtype=float).copy()
    notes = []
    bad = ~(np.isfinite(speed) & (speed > 0))
    if bad.any():
        speed[bad] = DEFAULT_SPEED
        notes.append(f"joint speed {math.degrees(DEFAULT_SPEED):.0f} deg/s assumed where the URDF gives none")
    accel = np.full(6, DEFAULT_ACCEL) if max_accel is None else np.broadcast_to(
        np.asarray(max_accel, dtype=float), (6,)).copy()
    chain = PinocchioChain(model, model.getFrameId(tip))
    if reach is None:
        rng = np.random.default_rng(0)
        qs = rng.uniform(np.maximum(lower, -math.pi), np.minimum(upper, math.pi), size=(2000, 6))
        shoulder = chain.frames(qs[:1])[0, 1, :3, 3]
        reach = float(np.max(np.linalg.norm(chain.fk(qs)[:, :3, 3] - shoulder, axis=1)))
    source = (f"URDF {path.name}, tip {tip}: limits and speeds from the file; "
              + ("acceleration assumed " + f"{math.degrees(DEFAULT_ACCEL):.0f} deg/s²" if max_accel is None
                 else "acceleration given") + ("; " + "; ".join(notes) if notes else ""))
    robot = RobotModel(name=name or model.name or path.stem, chain=chain, lower=lower, upper=upper,  # type: ignore[arg-type]
                       max_speed=speed, max_accel=accel, reach=reach, kind="numeric", source=source,
                       extra={"urdf": str(path), "tip": tip})
    robot.extra["ik"] = lambda poses, seed: numeric_ik(robot, poses, seed=seed)
    return robot


# --- numerical IK -------------------------------------------------------------------------------------------------
def dls_ik(chain: PinocchioChain, target, q0, lower, upper, *, iterations: int = 60, tol: float = 1e-12,
           max_step: float = 0.2):
    """Damped least squares from ``q0`` toward one tip pose.

    Parameters
    ----------
    chain : PinocchioChain
    target : (4, 4) float
        base2tip, m.
    q0 : (6,) float
        Start, rad.
    lower, upper : (6,) float
        Joint limits, rad (every iterate is clipped into them).
    iterations : int
    tol : float
        Converged when the pose error (``log6``: m and rad) is below this norm.
    max_step : float
        Largest joint change per iteration, rad (keeps the solver on the start's branch).

    Returns
    -------
    q : (6,) float
    converged : bool
    """
    pin = chain._pin
    goal = pin.SE3(np.asarray(target[:3, :3]), np.asarray(target[:3, 3]))
    q = np.clip(np.asarray(q0, dtype=float).copy(), lower, upper)
    for _ in range(iterations):
        chain._update(q)
        err = pin.log6(chain.data.oMf[chain.frame_id].actInv(goal)).vector
        e = float(np.linalg.norm(err))
        if e < tol:
            return q, True
        jac = chain.body_jacobian(q)
        # damping grows with the error: Gauss-Newton near the answer, a short gradient-like step far from it
        lam2 = 1e-10 + 1e-3 * min(e, 1.0) ** 2
        dq = jac.T @ np.linalg.solve(jac @ jac.T + lam2 * np.eye(6), err)
        big = np.max(np.abs(dq))
        if big > max_step:
            dq *= max_step / big
        q = _wrap_into(q + dq, lower, upper)
    chain._update(q)
    return q, float(np.linalg.norm(pin.log6(chain.data.oMf[chain.frame_id].actInv(goal)).vector)) < tol * 100


def _wrap_into(q, lower, upper) -> np.ndarray:
    """Joint values past a limit turned by one full turn where that lands inside (the same pose),
    else clipped to the limit, rad."""
    two_pi = 2 * math.pi
    q = np.where((q > upper) & (q - two_pi >= lower), q - two_pi, q)
    q = np.where((q < lower) & (q + two_pi <= upper), q + two_pi, q)
    return np.clip(q, lower, upper)


def _best_start(robot: RobotModel, target, seed, rng) -> np.ndarray | None:
    """Solve one pose from the seed and 24 seeded random starts; the converged one with the largest
    manipulability, or None."""
    chain = robot.chain
    lo, hi = robot.lower, robot.upper
    starts = [np.clip(seed, lo, hi)] + list(rng.uniform(np.maximum(lo, -math.pi), np.minimum(hi, math.pi),
                                                         size=(24, 6)))
    found = []
    for s in starts:
        q, ok = dls_ik(chain, target, s, lo, hi, iterations=150)   # type: ignore[arg-type]
        if ok:
            found.append(q)
    if not found:
        return None
    manip = robot.singularity_measures(np.array(found))["manipulability"]
    return found[int(np.argmax(manip))]


def numeric_ik(robot: RobotModel, poses, *, seed=None, max_jump: float = 0.5) -> np.ndarray:
    """IK of a pose sequence on one branch: each pose from the previous solution.

    Parameters
    ----------
    robot : RobotModel
        A :func:`urdf_robot` model.
    poses : (n, 4, 4) float
        base2tip, m.
    seed : (6,) float, optional
        Start of the first pose, rad (default: the middle of the limits, wrapped into ±π).
    max_jump : float
        A solution farther than this (rad, any joint) from the previous one is a different branch:
        the pose is then approached through intermediate poses from the previous one.

    Returns
    -------
    (n, 1, 6) float
        Joint values, rad; NaN where no solution continues the branch.
    """
    pin = _pinocchio()
    chain = robot.chain
    lo, hi = robot.lower, robot.upper
    poses = np.asarray(poses, dtype=float).reshape(-1, 4, 4)
    out = np.full((len(poses), 1, 6), np.nan)
    rng = np.random.default_rng(0)
    start = np.clip(0.5 * (lo + hi), -math.pi, math.pi) if seed is None else np.asarray(seed, dtype=float)
    prev: np.ndarray | None = None
    prev_pose = np.eye(4)
    for i, target in enumerate(poses):
        if prev is None:
            q = _best_start(robot, target, start, rng)
            if q is not None:
                out[i, 0] = q
                prev, prev_pose = q, target
            continue
        q, ok = dls_ik(chain, target, prev, lo, hi)          # type: ignore[arg-type]
        if not (ok and np.max(np.abs(q - prev)) <= max_jump):
            # walk from the previous pose to this one in small steps (keeps the branch)
            a = pin.SE3(prev_pose[:3, :3], prev_pose[:3, 3])
            b = pin.SE3(target[:3, :3], target[:3, 3])
            dist = np.linalg.norm(pin.log6(a.actInv(b)).vector)
            q = prev
            ok = True
            for s in np.linspace(0, 1, int(np.clip(np.ceil(dist / 0.02), 4, 200)) + 1)[1:]:
                mid = pin.SE3.Interpolate(a, b, float(s)).homogeneous
                q, ok = dls_ik(chain, mid, q, lo, hi)         # type: ignore[arg-type]
                if not ok:
                    break
        if ok:
            out[i, 0] = q
            prev, prev_pose = q, target
    return out
