"""Rigid transforms: 4x4 matrices, scalar-first quaternions, and the Euler angles robot makers use.

Every function works on stacks: a ``(..., 4, 4)`` array of homogeneous transforms, a ``(..., 4)``
array of unit quaternions ``(qw, qx, qy, qz)``.  Lengths in metres, angles in radians.

Euler conventions (all describe ``R = Rz(a) @ Ry(b) @ Rx(c)``, rotations about the fixed axes x, then
y, then z, or equivalently about the moving z, y', x''):

* KUKA ``A, B, C``: ``A`` about z, ``B`` about y, ``C`` about x (KRL ``FRAME``/``POS``).
* ``rx, ry, rz`` of :func:`pose_from_xyzrpy` use the same matrix with ``(c, b, a) = (rx, ry, rz)``
  (roll-pitch-yaw, as ROS ``rpy``).
"""

from __future__ import annotations

import numpy as np


def quat_to_matrix(quaternion) -> np.ndarray:
    """Rotation matrices of unit quaternions.

    Parameters
    ----------
    quaternion : (..., 4) float
        Scalar first ``(qw, qx, qy, qz)``; normalised here.

    Returns
    -------
    (..., 3, 3) float
    """
    q = np.asarray(quaternion, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)


def matrix_to_quat(rotation) -> np.ndarray:
    """Unit quaternions ``(qw, qx, qy, qz)`` with ``qw >= 0`` of rotation matrices ``(..., 3, 3)``."""
    r = np.asarray(rotation, dtype=float)
    shape = r.shape[:-2]
    r = r.reshape(-1, 3, 3)
    out = np.empty((len(r), 4))
    tr = np.trace(r, axis1=1, axis2=2)
    # Pick, per matrix, the largest of the four squared components to divide by (stable branch).
    cand = np.stack([tr, r[:, 0, 0], r[:, 1, 1], r[:, 2, 2]], axis=1)
    k = np.argmax(cand, axis=1)
    for i in range(4):
        m = r[k == i]
        if not len(m):
            continue
        if i == 0:
            s = 2.0 * np.sqrt(1.0 + np.trace(m, axis1=1, axis2=2))
            q = np.stack([0.25 * s, (m[:, 2, 1] - m[:, 1, 2]) / s, (m[:, 0, 2] - m[:, 2, 0]) / s,
                          (m[:, 1, 0] - m[:, 0, 1]) / s], axis=1)
        elif i == 1:
            s = 2.0 * np.sqrt(1.0 + m[:, 0, 0] - m[:, 1, 1] - m[:, 2, 2])
            q = np.stack([(m[:, 2, 1] - m[:, 1, 2]) / s, 0.25 * s, (m[:, 0, 1] + m[:, 1, 0]) / s,
                          (m[:, 0, 2] + m[:, 2, 0]) / s], axis=1)
        elif i == 2:
            s = 2.0 * np.sqrt(1.0 + m[:, 1, 1] - m[:, 0, 0] - m[:, 2, 2])
            q = np.stack([(m[:, 0, 2] - m[:, 2, 0]) / s, (m[:, 0, 1] + m[:, 1, 0]) / s, 0.25 * s,
                          (m[:, 1, 2] + m[:, 2, 1]) / s], axis=1)
        else:
            s = 2.0 * np.sqrt(1.0 + m[:, 2, 2] - m[:, 0, 0] - m[:, 1, 1])
            q = np.stack([(m[:, 1, 0] - m[:, 0, 1]) / s, (m[:, 0, 2] + m[:, 2, 0]) / s,
                          (m[:, 1, 2] + m[:, 2, 1]) / s, 0.25 * s], axis=1)
        out[k == i] = q
    out *= np.where(out[:, :1] < 0, -1.0, 1.0)
    out /= np.linalg.norm(out, axis=1, keepdims=True)
    return out.reshape(shape + (4,))


def rot_x(angle) -> np.ndarray:
    """(..., 3, 3) rotation about x by ``angle`` (rad)."""
    c, s = np.cos(angle), np.sin(angle)
    o, z = np.ones_like(c), np.zeros_like(c)
    return np.stack([np.stack([o, z, z], -1), np.stack([z, c, -s], -1), np.stack([z, s, c], -1)], -2)


def rot_y(angle) -> np.ndarray:
    """(..., 3, 3) rotation about y by ``angle`` (rad)."""
    c, s = np.cos(angle), np.sin(angle)
    o, z = np.ones_like(c), np.zeros_like(c)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2)


def rot_z(angle) -> np.ndarray:
    """(..., 3, 3) rotation about z by ``angle`` (rad)."""
    c, s = np.cos(angle), np.sin(angle)
    o, z = np.ones_like(c), np.zeros_like(c)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def zyx_to_matrix(a, b, c) -> np.ndarray:
    """``Rz(a) @ Ry(b) @ Rx(c)`` (KUKA A, B, C; rad)."""
    return rot_z(a) @ rot_y(b) @ rot_x(c)


def matrix_to_zyx(rotation) -> np.ndarray:
    """``(..., 3)`` angles ``(a, b, c)`` with ``R = Rz(a) Ry(b) Rx(c)``, ``b`` in [-pi/2, pi/2] (rad).

    At ``|b| = pi/2`` (gimbal lock) ``c`` is set to 0 and ``a`` carries the whole rotation.
    """
    r = np.asarray(rotation, dtype=float)
    cb = np.sqrt(r[..., 2, 1] ** 2 + r[..., 2, 2] ** 2)
    lock = cb < 1e-9
    a = np.where(lock, np.arctan2(-r[..., 0, 1], r[..., 1, 1]), np.arctan2(r[..., 1, 0], r[..., 0, 0]))
    c = np.where(lock, 0.0, np.arctan2(r[..., 2, 1], r[..., 2, 2]))
    b = np.arctan2(-r[..., 2, 0], cb)
    return np.stack([a, b, c], axis=-1)


def make_transform(rotation=None, translation=None) -> np.ndarray:
    """(..., 4, 4) homogeneous transforms from ``(..., 3, 3)`` rotations and ``(..., 3)`` translations (m)."""
    if rotation is None:
        rotation = np.eye(3)
    rotation = np.asarray(rotation, dtype=float)
    translation = np.zeros(3) if translation is None else np.asarray(translation, dtype=float)
    shape = np.broadcast_shapes(rotation.shape[:-2], translation.shape[:-1])
    out = np.zeros(shape + (4, 4))
    out[..., :3, :3] = rotation
    out[..., :3, 3] = translation
    out[..., 3, 3] = 1.0
    return out


def pose_from_xyzrpy(x, y, z, rx, ry, rz) -> np.ndarray:
    """4x4 transform: translation ``(x, y, z)`` m, rotation ``Rz(rz) Ry(ry) Rx(rx)`` (rad)."""
    return make_transform(zyx_to_matrix(rz, ry, rx), [x, y, z])


def xyzrpy_from_pose(transform) -> np.ndarray:
    """Inverse of :func:`pose_from_xyzrpy`: ``(..., 6)`` ``x, y, z`` (m), ``rx, ry, rz`` (rad)."""
    t = np.asarray(transform, dtype=float)
    a, b, c = np.moveaxis(matrix_to_zyx(t[..., :3, :3]), -1, 0)
    return np.concatenate([t[..., :3, 3], np.stack([c, b, a], axis=-1)], axis=-1)


def invert(transform) -> np.ndarray:
    """Inverse of rigid transforms ``(..., 4, 4)``."""
    t = np.asarray(transform, dtype=float)
    rt = np.swapaxes(t[..., :3, :3], -1, -2)
    return make_transform(rt, -np.einsum("...ij,...j->...i", rt, t[..., :3, 3]))


def poses_from_trajectory(trajectory) -> np.ndarray:
    """(n, 4, 4) tcp2part transforms of a :class:`swath.trajectory.Trajectory` (m)."""
    return make_transform(quat_to_matrix(trajectory.quaternion), trajectory.position)


def pose_error(a, b) -> tuple[np.ndarray, np.ndarray]:
    """Position error (m) and rotation angle error (rad) between transform stacks ``a`` and ``b``."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    dp = np.linalg.norm(a[..., :3, 3] - b[..., :3, 3], axis=-1)
    rel = np.swapaxes(a[..., :3, :3], -1, -2) @ b[..., :3, :3]
    cos = np.clip((np.trace(rel, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0)
    # arccos is ill-conditioned near 0; use the skew part for small angles.
    skew = np.stack([rel[..., 2, 1] - rel[..., 1, 2], rel[..., 0, 2] - rel[..., 2, 0],
                     rel[..., 1, 0] - rel[..., 0, 1]], axis=-1)
    ang = np.arctan2(0.5 * np.linalg.norm(skew, axis=-1), cos)
    return dp, ang
