"""Closed-form inverse kinematics of ortho-parallel arms with a spherical wrist (OPW).

The OPW model (Brandstötter, Angerer & Hofbaur, "An analytical solution of the inverse kinematics
problem of industrial serial manipulators with an ortho-parallel basis and a spherical wrist",
Austrian Robotics Workshop 2014) describes most six-axis industrial arms by seven lengths:

``c1`` height of axis 2 above the base, ``a1`` its forward offset, ``b`` a sideways offset, ``c2``
the upper arm (axis 2 to axis 3), ``a2`` the forearm's offset across the arm, ``c3`` axis 3 to the
wrist centre along the forearm, ``c4`` wrist centre to flange.  In the model's zero pose the arm
stands straight up; axes 2, 3, 5 turn about y (positive tilts forward, toward +x) and axes 1, 4, 6
about z.  The maker's joint values map to the model angles through a sign and an offset per axis
(:class:`swath.robot.chain.Chain`).

The 8 solutions are indexed ``4 · shoulder + 2 · elbow + wrist`` (each 0 or 1): shoulder 0 faces
the wrist centre, 1 reaches over backwards; elbow 0 / 1 are the two triangle solutions; wrist 1 is
the flipped wrist (θ4 + π, −θ5, θ6 + π).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .chain import Chain, wrap_angle
from .pose import make_transform


@dataclass(frozen=True)
class OPWParameters:
    """OPW lengths (m) and the maker's joint sign/offset (rad) per axis."""

    a1: float
    a2: float
    b: float
    c1: float
    c2: float
    c3: float
    c4: float
    sign: tuple = (1, 1, 1, 1, 1, 1)
    offset: tuple = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)

    def chain(self) -> Chain:
        """The arm as a :class:`Chain` (flange z out of the flange)."""
        t = lambda x, y, z: make_transform(np.eye(3), [x, y, z])
        fixed = np.array([np.eye(4), t(self.a1, self.b, self.c1), t(0, 0, self.c2), t(self.a2, 0, 0),
                          t(0, 0, self.c3), np.eye(4), t(0, 0, self.c4)])
        return Chain(fixed=fixed, axes=("z", "y", "y", "z", "y", "z"), sign=np.asarray(self.sign, dtype=float),
                     offset=np.asarray(self.offset, dtype=float))


def opw_ik(params: OPWParameters, flange2base) -> np.ndarray:
    """All 8 inverse-kinematics solutions of flange2base poses, in the maker's joint values.

    Parameters
    ----------
    params : OPWParameters
    flange2base : (n, 4, 4) float
        Flange poses in the base frame, m.

    Returns
    -------
    (n, 8, 6) float
        Joint values (rad, wrapped to (-pi, pi]); NaN rows where the branch has no solution
        (the wrist centre out of reach of that branch).
    """
    p = params
    t = np.asarray(flange2base, dtype=float).reshape(-1, 4, 4)
    n = len(t)
    r = t[:, :3, :3]
    wc = t[:, :3, 3] - p.c4 * r[:, :, 2]
    cx, cy, cz = wc.T
    # Planar problem in the plane of axis 1: distances from axis 2 to the wrist centre.
    with np.errstate(invalid="ignore"):
        rho = np.sqrt(np.maximum(cx * cx + cy * cy - p.b * p.b, 0.0))
        nx1 = rho - p.a1
        cz0 = cz - p.c1
        s1 = np.hypot(nx1, cz0)                  # shoulder facing the wrist centre
        s2 = np.hypot(nx1 + 2 * p.a1, cz0)       # shoulder turned over backwards
        k2 = p.a2 * p.a2 + p.c3 * p.c3
        k = np.sqrt(k2)
        psi3 = np.arctan2(p.a2, p.c3)
        base_angle = np.arctan2(cy, cx)
        off_b = np.arctan2(p.b, nx1 + p.a1)
        theta1 = [base_angle - off_b, base_angle + off_b - np.pi]
        out = np.full((n, 8, 6), np.nan)
        for shoulder, (s, lean) in enumerate([(s1, np.arctan2(nx1, cz0)), (s2, -np.arctan2(nx1 + 2 * p.a1, cz0))]):
            cos_a = (s * s + p.c2 * p.c2 - k2) / (2 * s * p.c2)
            cos_b = (s * s - p.c2 * p.c2 - k2) / (2 * p.c2 * k)
            ok = (np.abs(cos_a) <= 1 + 1e-12) & (np.abs(cos_b) <= 1 + 1e-12)
            acos_a = np.arccos(np.clip(cos_a, -1, 1))
            acos_b = np.arccos(np.clip(cos_b, -1, 1))
            for elbow, sgn in enumerate((-1.0, 1.0)):
                th2 = sgn * acos_a + lean
                th3 = -sgn * acos_b - psi3
                th = _wrist(r, theta1[shoulder], th2, th3)
                for wrist in range(2):
                    idx = 4 * shoulder + 2 * elbow + wrist
                    q = wrap_angle((th[wrist] - np.asarray(p.offset)) * np.asarray(p.sign))
                    q[~ok] = np.nan
                    out[:, idx] = q
    return out


def _wrist(r, th1, th2, th3):
    """The two wrist solutions (θ4, θ5, θ6) for given arm angles; returns two (n, 6) arrays of θ."""
    c1, s1 = np.cos(th1), np.sin(th1)
    c23, s23 = np.cos(th2 + th3), np.sin(th2 + th3)
    # Wrist base orientation R0c = Rz(θ1) Ry(θ2 + θ3); the wrist rotation is Rz(θ4) Ry(θ5) Rz(θ6) = R0cᵀ R.
    r13, r23, r33 = r[:, 0, 2], r[:, 1, 2], r[:, 2, 2]
    m = r13 * s23 * c1 + r23 * s23 * s1 + r33 * c23
    th5 = np.arctan2(np.sqrt(np.maximum(1 - m * m, 0.0)), m)
    th4 = np.arctan2(r23 * c1 - r13 * s1, r13 * c23 * c1 + r23 * c23 * s1 - r33 * s23)
    th6 = np.arctan2(r[:, 0, 1] * s23 * c1 + r[:, 1, 1] * s23 * s1 + r[:, 2, 1] * c23,
                     -(r[:, 0, 0] * s23 * c1 + r[:, 1, 0] * s23 * s1 + r[:, 2, 0] * c23))
    a = np.stack([th1, th2, th3, th4, th5, th6], axis=1)
    b = np.stack([th1, th2, th3, th4 + np.pi, -th5, th6 + np.pi], axis=1)
    return a, b
