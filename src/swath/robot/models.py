"""Robot models: kinematic chain, closed-form or numerical IK, joint limits from the makers' datasheets.

Every model maps joint values ``q`` (the maker's convention, rad) to ``flange2base``, the flange
frame (z out of the flange, the ISO 9409 / ROS ``tool0`` convention) in the robot base frame
(z up, x forward at joint 1 = 0), and back through :meth:`RobotModel.ik`, which returns every
configuration branch in a fixed slot so that a branch can be followed along a path.

The catalogue (:data:`ROBOTS`, :func:`get_robot`):

* ``ur3e ur5e ur10e ur16e`` — Universal Robots DH parameters (UR's "DH parameters for calculations
  of kinematics and dynamics" page); IK from the ``ur_analytic_ik`` package, checked against this
  module's own DH forward kinematics.  Joint ranges ±360°, speeds from the e-Series datasheets.
* ``irb4600-60/2.05`` — ABB IRB 4600-60/2.05 (product specification 3HAC032885): OPW closed form.
* ``kr120r2700-2`` — KUKA KR 120 R2700-2 (KR QUANTEC datasheet): OPW closed form, KUKA's signs
  (A1, A4, A6 turn the other way) and zero (A2 = −90°, A3 = +90° is the upright home).
* :func:`dh_robot` — any serial arm from DH parameters, numerical IK (scipy least squares, seeded).

Joint **accelerations** are not published in these datasheets; the values here are conservative
assumptions (stated per model in :attr:`RobotModel.source`), to be overridden per cell.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from functools import partial
from typing import Any

import numpy as np

from ..errors import InputError
from .chain import Chain, dh_chain, wrap_angle
from .opw import OPWParameters, opw_ik
from .pose import pose_error

DEG = math.pi / 180.0

#: Names of the 8 closed-form branches, slot ``4·shoulder + 2·elbow + wrist``.
BRANCH_NAMES_8 = tuple(f"shoulder{s}-elbow{e}-wrist{w}" for s in (0, 1) for e in (0, 1) for w in (0, 1))


@dataclass(frozen=True, eq=False)
class RobotModel:
    """A six-axis arm: kinematics, IK and limits.

    Attributes
    ----------
    name : str
    chain : Chain
        Forward kinematics (flange2base, m).
    lower, upper : (6,) float
        Joint position limits, rad.
    max_speed : (6,) float
        Joint speed limits, rad/s.
    max_accel : (6,) float
        Joint acceleration limits, rad/s² (assumed; see module docstring).
    reach : float
        Nominal reach (wrist centre), m; scales the manipulability measure.
    kind : str
        ``"ur"``, ``"opw"`` or ``"numeric"``.
    source : str
        Where the numbers come from.
    """

    name: str
    chain: Chain
    lower: np.ndarray
    upper: np.ndarray
    max_speed: np.ndarray
    max_accel: np.ndarray
    reach: float
    kind: str
    source: str = ""
    opw: OPWParameters | None = None
    ur_solver: Any = None
    dh: Any = None
    extra: dict = field(default_factory=dict)

    @property
    def n_branches(self) -> int:
        return 1 if self.kind == "numeric" else 8

    @property
    def branch_names(self) -> tuple:
        return ("numeric",) if self.kind == "numeric" else BRANCH_NAMES_8

    def fk(self, q) -> np.ndarray:
        """(n, 4, 4) flange2base of joint values ``q`` ``(n, 6)`` (rad); m."""
        return self.chain.fk(q)

    def jacobian(self, q) -> np.ndarray:
        """(n, 6, 6) geometric Jacobian (m/rad rows 0–2, rad/rad rows 3–5)."""
        return self.chain.jacobian(q)

    def ik(self, flange2base, *, seed=None) -> np.ndarray:
        """Every branch's joint values for flange poses.

        Parameters
        ----------
        flange2base : (n, 4, 4) float
            Flange poses in the base frame, m.
        seed : (6,) float, optional
            Start of the numerical solver (numeric models only; each later pose starts from the
            previous solution), rad.

        Returns
        -------
        (n, n_branches, 6) float
            Joint values in (-pi, pi] (closed form) or near the seed (numeric), rad; NaN where the
            branch has no solution.  Joint limits are not applied here.
        """
        t = np.asarray(flange2base, dtype=float).reshape(-1, 4, 4)
        if "ik" in self.extra:                  # a URDF model's own solver (swath.robot.urdf)
            return self.extra["ik"](t, seed)
        if self.kind == "opw" and self.opw is not None:
            return opw_ik(self.opw, t)
        if self.kind == "ur":
            return _ur_ik(self, t)
        return _numeric_ik(self, t, seed)

    def with_limits(self, *, max_speed=None, max_accel=None, lower=None, upper=None) -> RobotModel:
        """A copy with other limits (rad, rad/s, rad/s²; scalars or (6,))."""
        def arr(v, old):
            return old if v is None else np.broadcast_to(np.asarray(v, dtype=float), (6,)).copy()
        return replace(self, max_speed=arr(max_speed, self.max_speed), max_accel=arr(max_accel, self.max_accel),
                       lower=arr(lower, self.lower), upper=arr(upper, self.upper))

    def singularity_measures(self, q) -> dict:
        """Distances from the singularities for joint values ``q`` ``(n, 6)`` (rad).

        Returns
        -------
        dict of (n,) float
            ``wrist`` |sin θ5| (0 at the wrist singularity), ``elbow`` |sin| of the elbow's stretch
            angle (0 with the arm stretched or folded), ``shoulder_m`` distance (m) of the wrist
            centre from the singular line near axis 1, and ``manipulability`` the Yoshikawa measure
            of the Jacobian with its linear rows divided by the reach (dimensionless).
        """
        q = np.atleast_2d(q)
        theta = self.chain.chain_angles(q)
        frames = self.chain.frames(q)
        jac = self.jacobian(q)
        jac[:, :3] /= self.reach
        manip = np.sqrt(np.maximum(np.linalg.det(jac @ np.swapaxes(jac, 1, 2)), 0.0))
        if self.kind == "opw" and self.opw is not None:
            p = self.opw
            wc = frames[:, 4, :3, 3]
            wrist = np.abs(np.sin(theta[:, 4]))
            elbow = np.abs(np.sin(theta[:, 2] + math.atan2(p.a2, p.c3)))
            shoulder = np.sqrt(np.maximum(wc[:, 0] ** 2 + wc[:, 1] ** 2 - p.b ** 2, 0.0))
        elif self.kind == "ur":
            d4 = self.dh[0][3]
            p05 = frames[:, 4, :3, 3]
            wrist = np.abs(np.sin(theta[:, 4]))
            elbow = np.abs(np.sin(theta[:, 2]))
            shoulder = np.sqrt(np.maximum(p05[:, 0] ** 2 + p05[:, 1] ** 2 - d4 ** 2, 0.0))
        else:
            # a general arm: the wrist is singular when the axes of joints 4 and 6 line up
            axes = self.chain.joint_axes(q)
            wrist = np.linalg.norm(np.cross(axes[:, 3], axes[:, 5]), axis=1)
            elbow = np.full(len(q), np.inf)
            shoulder = np.full(len(q), np.inf)
        return {"wrist": wrist, "elbow": elbow, "shoulder_m": shoulder, "manipulability": manip}

    def joint_limit_margin(self, q) -> np.ndarray:
        """(n,) smallest distance of any joint from its position limit, rad (negative outside)."""
        q = np.atleast_2d(q)
        return np.min(np.minimum(q - self.lower, self.upper - q), axis=1)


# --- Universal Robots -------------------------------------------------------------------------------------------
_UR_DH = {  # d (m), a (m); alpha = (pi/2, 0, 0, pi/2, -pi/2, 0)
    "ur3e": ((0.15185, 0, 0, 0.13105, 0.08535, 0.0921), (0, -0.24355, -0.2132, 0, 0, 0)),
    "ur5e": ((0.1625, 0, 0, 0.1333, 0.0997, 0.0996), (0, -0.425, -0.3922, 0, 0, 0)),
    "ur10e": ((0.1807, 0, 0, 0.17415, 0.11985, 0.11655), (0, -0.6127, -0.57155, 0, 0, 0)),
    "ur16e": ((0.1807, 0, 0, 0.17415, 0.11985, 0.11655), (0, -0.4784, -0.36, 0, 0, 0)),
}
_UR_SPEED_DEG = {  # e-Series datasheets, deg/s per joint
    "ur3e": (180, 180, 180, 360, 360, 360),
    "ur5e": (180, 180, 180, 180, 180, 180),
    "ur10e": (120, 120, 180, 180, 180, 180),
    "ur16e": (120, 120, 180, 180, 180, 180),
}
_UR_REACH = {"ur3e": 0.5, "ur5e": 0.85, "ur10e": 1.3, "ur16e": 0.9}
_UR_ALPHA = (math.pi / 2, 0, 0, math.pi / 2, -math.pi / 2, 0)


def _ur_model(name: str) -> RobotModel:
    import ur_analytic_ik

    d, a = _UR_DH[name]
    # the elbow turns ±180° at most: beyond it the forearm would fold through the upper arm (UR's own
    # software and ROS description limit it the same); the other joints turn ±360°
    upper = np.array([2, 2, 1, 2, 2, 2]) * math.pi
    return RobotModel(
        name=name, chain=dh_chain(d, a, _UR_ALPHA), lower=-upper, upper=upper,
        max_speed=np.array(_UR_SPEED_DEG[name]) * DEG, max_accel=np.full(6, 4 * math.pi), reach=_UR_REACH[name],
        kind="ur", ur_solver=getattr(ur_analytic_ik, name), dh=(d, a, _UR_ALPHA),
        source=f"UR {name} DH parameters and e-Series datasheet (±360°, the elbow ±180°; speeds); acceleration 720°/s² assumed",
    )


def _ur_ik(model: RobotModel, t: np.ndarray) -> np.ndarray:
    """UR IK through ur_analytic_ik, each solution put in its branch slot."""
    d4 = model.dh[0][3]
    d6 = model.dh[0][5]
    out = np.full((len(t), 8, 6), np.nan)
    solve = model.ur_solver.inverse_kinematics
    for i, pose in enumerate(t):
        sols = solve(np.ascontiguousarray(pose))
        if not len(sols):
            continue
        sols = wrap_angle(np.array(sols))
        sols = sols[np.all(np.isfinite(sols), axis=1)]
        if not len(sols):
            continue
        p05 = pose[:3, 3] - d6 * pose[:3, 2]
        r = math.hypot(p05[0], p05[1])
        base = math.atan2(p05[1], p05[0]) + math.pi / 2
        shoulder = (wrap_angle(sols[:, 0] - base) < 0).astype(int) if r > d4 else np.zeros(len(sols), int)
        elbow = (sols[:, 2] < 0).astype(int)
        wrist = (sols[:, 4] < 0).astype(int)
        slot = 4 * shoulder + 2 * elbow + wrist
        for s, q in zip(slot, sols):
            if np.isnan(out[i, s, 0]):
                out[i, s] = q
    return out


# --- OPW arms ---------------------------------------------------------------------------------------------------
def _irb4600() -> RobotModel:
    p = OPWParameters(a1=0.175, a2=-0.175, b=0.0, c1=0.495, c2=0.900, c3=0.960, c4=0.135,
                      offset=(0, 0, math.pi / 2, 0, 0, 0))
    return RobotModel(
        name="irb4600-60/2.05", chain=p.chain(), opw=p, kind="opw", reach=2.05,
        lower=np.array([-180, -90, -180, -400, -125, -400]) * DEG, upper=np.array([180, 150, 75, 400, 120, 400]) * DEG,
        max_speed=np.array([175, 175, 175, 250, 250, 360]) * DEG, max_accel=np.array([400, 400, 400, 800, 800, 1200]) * DEG,
        source="ABB IRB 4600-60/2.05 product specification (dimensions, axis ranges, max axis speeds); "
               "accelerations assumed",
    )


def _kr120r2700() -> RobotModel:
    p = OPWParameters(a1=0.350, a2=-0.041, b=0.0, c1=0.675, c2=1.150, c3=1.200, c4=0.215,
                      sign=(-1, 1, 1, -1, 1, -1), offset=(0, math.pi / 2, 0, 0, 0, 0))
    return RobotModel(
        name="kr120r2700-2", chain=p.chain(), opw=p, kind="opw", reach=2.696,
        lower=np.array([-185, -140, -120, -350, -125, -350]) * DEG, upper=np.array([185, -5, 168, 350, 125, 350]) * DEG,
        max_speed=np.array([136, 130, 120, 292, 258, 284]) * DEG, max_accel=np.array([300, 300, 300, 700, 700, 900]) * DEG,
        source="KUKA KR 120 R2700-2 (KR QUANTEC) datasheet (dimensions, axis ranges, speeds); accelerations assumed",
    )


# --- generic DH arm, numerical IK --------------------------------------------------------------------------------
def dh_robot(name: str, d, a, alpha, *, lower, upper, max_speed, max_accel, reach: float | None = None,
             offset=None) -> RobotModel:
    """A generic six-axis arm from standard DH parameters with numerical IK.

    Parameters
    ----------
    d, a : (6,) float
        DH offsets and lengths, m.
    alpha : (6,) float
        DH twists, rad.
    lower, upper : (6,) float
        Joint limits, rad.
    max_speed : (6,) float
        Joint speed limits, rad/s.
    max_accel : (6,) float
        Joint acceleration limits, rad/s².
    reach : float, optional
        Nominal reach, m (default: sum of |a| and |d|).
    offset : (6,) float, optional
        DH angle at joint value 0, rad.

    Notes
    -----
    No well-kept kinematics library (pinocchio, roboticstoolbox) is installed in this environment;
    the IK is a damped Newton iteration on the pose error with the geometric Jacobian (with
    ``scipy.optimize.least_squares`` as a bounded fallback), seeded from the previous pose, so it
    follows one branch but cannot enumerate branches.
    """
    arrs = [np.asarray(v, dtype=float) for v in (d, a, alpha, lower, upper, max_speed, max_accel)]
    if any(v.shape != (6,) for v in arrs):
        raise InputError("a DH robot needs six values for each of d, a, alpha, lower, upper, max_speed, max_accel")
    d, a, alpha, lower, upper, max_speed, max_accel = arrs
    return RobotModel(name=name, chain=dh_chain(d, a, alpha, offset=offset), lower=lower, upper=upper,
                      max_speed=max_speed, max_accel=max_accel,
                      reach=float(reach if reach is not None else np.abs(a).sum() + np.abs(d).sum()),
                      kind="numeric", dh=(tuple(d), tuple(a), tuple(alpha)), source="user DH parameters")


def _pose_residual(model: RobotModel, q, target) -> np.ndarray:
    """(6,) target minus current: position (m, divided by the reach) and rotation vector (rad), base frame."""
    cur = model.chain.fk(q[None])[0]
    rel = cur[:3, :3].T @ target[:3, :3]
    ang_axis = np.array([rel[2, 1] - rel[1, 2], rel[0, 2] - rel[2, 0], rel[1, 0] - rel[0, 1]]) / 2
    s = np.linalg.norm(ang_axis)
    angle = math.atan2(s, (np.trace(rel) - 1) / 2)
    rot = cur[:3, :3] @ (ang_axis * (angle / s) if s > 1e-15 else ang_axis)
    return np.concatenate([(target[:3, 3] - cur[:3, 3]) / model.reach, rot])


def _newton(model: RobotModel, q, target, *, iterations: int = 30):
    """Newton steps on the pose residual (damped far from the answer); returns (q, converged)."""
    for _ in range(iterations):
        r = _pose_residual(model, q, target)
        err = np.max(np.abs(r))
        if err < 1e-14:
            return q, True
        j = model.chain.jacobian(q[None])[0].copy()
        j[:3] /= model.reach
        if err < 1e-4:
            step = np.linalg.lstsq(j, r, rcond=None)[0]
        else:
            step = np.linalg.solve(j.T @ j + 1e-4 * np.eye(6), j.T @ r)
        q = np.clip(q + step, model.lower, model.upper)
    return q, np.max(np.abs(_pose_residual(model, q, target))) < 1e-11


def _numeric_ik(model: RobotModel, t: np.ndarray, seed) -> np.ndarray:
    """Seeded IK along a pose sequence: damped Newton, then scipy least squares (bounded) as fallback."""
    q = np.clip(np.zeros(6) if seed is None else np.asarray(seed, dtype=float), model.lower, model.upper)
    out = np.full((len(t), 1, 6), np.nan)
    lo, hi = model.lower, model.upper

    def jac(x, target):
        j = model.chain.jacobian(x[None])[0].copy()
        j[:3] /= model.reach
        return -j

    for i, target in enumerate(t):
        best, ok = _newton(model, q.copy(), target)
        if not ok:
            from scipy.optimize import least_squares

            for start in (q, np.clip(q + 0.3, lo, hi), np.clip(q - 0.3, lo, hi)):
                sol = least_squares(lambda x, tg: _pose_residual(model, x, tg), start, jac=jac, args=(target,),
                                    bounds=(lo, hi), xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=200, method="trf")
                best, ok = _newton(model, sol.x, target, iterations=5)
                if ok:
                    break
        if ok:
            dp, da = pose_error(model.chain.fk(best[None])[0], target)
            ok = dp < 1e-10 and da < 1e-10
        if ok:
            out[i, 0] = best
            q = best
    return out


#: Model name -> factory.
ROBOTS: dict[str, Callable[[], RobotModel]] = {name: partial(_ur_model, name) for name in _UR_DH}
ROBOTS.update({"irb4600-60/2.05": _irb4600, "irb4600": _irb4600, "kr120r2700-2": _kr120r2700,
               "kr120": _kr120r2700})


def get_robot(name: str, *, tip: str | None = None) -> RobotModel:
    """The catalogue model called ``name`` (case-insensitive; see :data:`ROBOTS`), or the robot of a
    URDF file when ``name`` ends in ``.urdf`` (``tip``: its flange frame, default ``tool0``; see
    :func:`swath.robot.urdf.urdf_robot`)."""
    if str(name).strip().lower().endswith(".urdf"):
        from .urdf import urdf_robot

        return urdf_robot(str(name).strip(), tip=tip or "tool0")
    if tip is not None:
        raise InputError(f"--tip names a frame of a URDF robot; {name!r} is a catalogue robot (drop --tip)")
    key = str(name).strip().lower()
    if key not in ROBOTS:
        raise InputError(f"unknown robot {name!r}; choose one of {', '.join(sorted(ROBOTS))}")
    return ROBOTS[key]()
