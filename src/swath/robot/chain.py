"""A serial chain of revolute joints: batch forward kinematics and the geometric Jacobian.

A chain is ``flange2base(q) = A_1 R(u_1, θ_1) A_2 R(u_2, θ_2) … A_6 R(u_6, θ_6) A_7`` with fixed
transforms ``A_i`` (m), unit joint axes ``u_i`` in the local frame, and joint angles
``θ_i = sign_i · q_i + offset_i`` (rad) mapping the maker's joint values ``q`` to the chain.  Both the
Denavit–Hartenberg arms (UR, generic) and the ortho-parallel-wrist arms (ABB, KUKA) are written so.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .pose import make_transform, rot_x

_AXIS_VEC = {"x": np.array([1.0, 0, 0]), "y": np.array([0, 1.0, 0]), "z": np.array([0, 0, 1.0])}


@dataclass(frozen=True, eq=False)
class Chain:
    """Fixed transforms and joint axes of a revolute serial arm.

    Attributes
    ----------
    fixed : (n_joints + 1, 4, 4) float
        ``A_1 … A_{n+1}``: the transform before each joint and the last one to the flange (m).
    axes : tuple of str
        Joint axis of each joint in its local frame, ``"x"``, ``"y"`` or ``"z"``.
    sign : (n_joints,) float
        ±1 per joint: chain angle = sign · joint value + offset.
    offset : (n_joints,) float
        Chain angle at joint value 0, rad.
    """

    fixed: np.ndarray
    axes: tuple
    sign: np.ndarray
    offset: np.ndarray

    @property
    def n_joints(self) -> int:
        return len(self.axes)

    def chain_angles(self, q) -> np.ndarray:
        """Chain angles θ (rad) of joint values ``q`` ``(..., n_joints)`` (rad)."""
        return np.asarray(q, dtype=float) * self.sign + self.offset

    def joint_values(self, theta) -> np.ndarray:
        """Joint values q (rad) of chain angles θ ``(..., n_joints)`` (rad)."""
        return (np.asarray(theta, dtype=float) - self.offset) * self.sign

    def frames(self, q) -> np.ndarray:
        """(n, n_joints + 1, 4, 4) base2frame of each joint frame (after its rotation) and the flange.

        Parameters
        ----------
        q : (n, n_joints) float
            Joint values, rad.
        """
        q = np.atleast_2d(np.asarray(q, dtype=float))
        theta = self.chain_angles(q)
        n = len(q)
        out = np.empty((n, self.n_joints + 1, 4, 4))
        current = np.broadcast_to(self.fixed[0], (n, 4, 4))
        for i, axis in enumerate(self.axes):
            current = current @ _joint_rotation(axis, theta[:, i])
            out[:, i] = current
            current = current @ self.fixed[i + 1]
        out[:, -1] = current
        return out

    def fk(self, q) -> np.ndarray:
        """(n, 4, 4) flange2base for joint values ``q`` ``(n, n_joints)`` (rad)."""
        return self.frames(q)[:, -1]

    def jacobian(self, q) -> np.ndarray:
        """(n, 6, n_joints) geometric Jacobian of the flange in the base frame.

        Rows 0–2 map joint speeds (rad/s) to flange linear velocity (m/s), rows 3–5 to angular
        velocity (rad/s); columns are per joint value (the sign convention included).
        """
        frames = self.frames(q)
        p_end = frames[:, -1, :3, 3]
        jac = np.empty((len(frames), 6, self.n_joints))
        for i, axis in enumerate(self.axes):
            w = frames[:, i, :3, :3] @ _AXIS_VEC[axis] * self.sign[i]
            jac[:, :3, i] = np.cross(w, p_end - frames[:, i, :3, 3])
            jac[:, 3:, i] = w
        return jac

    def joint_axes(self, q) -> np.ndarray:
        """(n, n_joints, 3) unit joint axes in the base frame (turning sense of the joint values)."""
        frames = self.frames(q)
        return np.stack([frames[:, i, :3, :3] @ _AXIS_VEC[a] * self.sign[i] for i, a in enumerate(self.axes)], axis=1)


_AXIS_PLANE = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}


def _joint_rotation(axis: str, angle) -> np.ndarray:
    """(n, 4, 4) homogeneous rotations about the local ``axis`` by ``angle`` (n,) rad."""
    c, s = np.cos(angle), np.sin(angle)
    out = np.zeros((len(c), 4, 4))
    a, b = _AXIS_PLANE[axis]
    k = 3 - a - b
    out[:, k, k] = 1.0
    out[:, 3, 3] = 1.0
    out[:, a, a] = c
    out[:, b, b] = c
    out[:, a, b] = -s
    out[:, b, a] = s
    return out


def dh_chain(d, a, alpha, *, sign=None, offset=None) -> Chain:
    """A chain from standard Denavit–Hartenberg parameters (each joint turns about its z).

    Parameters
    ----------
    d, a : (n,) float
        Link offsets and lengths, m.
    alpha : (n,) float
        Link twists, rad.
    sign, offset : (n,) float, optional
        Joint value to DH angle mapping (default +1 and 0).
    """
    d, a, alpha = (np.asarray(v, dtype=float) for v in (d, a, alpha))
    n = len(d)
    fixed = [np.eye(4)]
    for i in range(n):
        # T_i = Rz(θ_i) · Tz(d_i) · Tx(a_i) · Rx(α_i): the fixed part follows the joint rotation.
        fixed.append(make_transform(np.eye(3), [0, 0, d[i]]) @ make_transform(rot_x(alpha[i]), [a[i], 0, 0]))
    return Chain(fixed=np.array(fixed), axes=("z",) * n,
                 sign=np.ones(n) if sign is None else np.asarray(sign, dtype=float),
                 offset=np.zeros(n) if offset is None else np.asarray(offset, dtype=float))


def wrap_angle(angle) -> np.ndarray:
    """Angles wrapped to (-pi, pi], rad."""
    return -(np.mod(-np.asarray(angle, dtype=float) + np.pi, 2 * np.pi) - np.pi)
