"""Exact test geometry as rational B-spline patches (circle arcs, surfaces of revolution and
translation, cylinder, sphere, torus), and the NACA 00xx thickness law of the example blade."""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .bspline import BSplinePatch
from .bspline_basis import clamped_knots


# ----------------------------------------------------------------------------------------------
# Exact constructions
# ----------------------------------------------------------------------------------------------
def circle_arc(radius: float, start: float, sweep: float, *, centre=(0.0, 0.0)):
    """An exact rational quadratic circle arc in the plane.

    Parameters
    ----------
    radius : float
        Radius, m.
    start, sweep : float
        Start angle and signed sweep, rad (``|sweep| <= 2π``); split into arcs of at most 90°.
    centre : (2,) float
        Centre, m.

    Returns
    -------
    control : (n, 2) float
    weights : (n,) float
    knots : (n + 3,) float
        Clamped, on ``[0, 1]``, double interior knots between the sub-arcs.
    """
    if not (radius > 0 and 0 < abs(sweep) <= 2 * np.pi + 1e-12):
        raise InputError("circle_arc needs radius > 0 and 0 < |sweep| <= 2π")
    n_arcs = int(np.ceil(abs(sweep) / (np.pi / 2) - 1e-9))
    delta = sweep / n_arcs
    ang = start + delta * np.arange(2 * n_arcs + 1) / 2
    rad = np.where(np.arange(2 * n_arcs + 1) % 2 == 1, radius / np.cos(delta / 2), radius)
    ctrl = np.stack([np.cos(ang), np.sin(ang)], axis=1) * rad[:, None] + np.asarray(centre, float)
    weights = np.where(np.arange(2 * n_arcs + 1) % 2 == 1, np.cos(delta / 2), 1.0)
    interior = np.repeat(np.arange(1, n_arcs) / n_arcs, 2)
    return ctrl, weights, clamped_knots(interior, 2, (0.0, 1.0))


def revolve(profile, weights, knots, degree: int, *, start: float = 0.0, sweep: float = 2 * np.pi,
            name: str = "") -> BSplinePatch:
    """Surface of revolution about the z-axis: u along the profile, v around the axis.

    Parameters
    ----------
    profile : (m, 2) float
        Control points ``(r, z)`` of the generating curve, m (``r >= 0``).
    weights : (m,) float
        Its weights (ones for a polynomial curve).
    knots : (m + degree + 1,) float
        Its knot vector.
    degree : int
        Its degree.
    start, sweep : float
        Angular range of the revolution, rad.
    """
    prof = np.asarray(profile, float)
    wp = np.asarray(weights, float)
    circ, wc, kc = circle_arc(1.0, start, sweep)
    ctrl = np.empty((len(prof), len(circ), 3))
    ctrl[..., 0] = prof[:, None, 0] * circ[None, :, 0]
    ctrl[..., 1] = prof[:, None, 0] * circ[None, :, 1]
    ctrl[..., 2] = prof[:, None, 1]
    return BSplinePatch(ctrl, knots, kc, (degree, 2), wp[:, None] * wc[None, :], name=name)


def translational(curve_u, curve_v, *, name: str = "") -> BSplinePatch:
    """The translational surface ``S(u, v) = C(u) + D(v)`` of two (rational) space curves.

    Each curve is ``(control (n, 3), weights (n,), knots, degree)``.  With weights ``w_i`` and
    ``ω_j`` the surface is exactly the NURBS with control points ``C_i + D_j`` and weights
    ``w_i ω_j`` (the sum of two rational curves over a common denominator).
    """
    cu, wu, ku, pu = curve_u
    cv, wv, kv, pv = curve_v
    cu, cv = np.asarray(cu, float), np.asarray(cv, float)
    ctrl = cu[:, None, :] + cv[None, :, :]
    return BSplinePatch(ctrl, ku, kv, (pu, pv), np.outer(wu, wv), name=name)


def nurbs_cylinder(radius: float, height: float, *, sweep: float = np.pi, outward: bool = True) -> BSplinePatch:
    """An exact cylinder patch about the z-axis from ``z = 0`` to ``height``, angles ``[0, sweep]``.

    u runs along the axis, v around it; normals point away from the axis when ``outward``.
    """
    if not (radius > 0 and height > 0):
        raise InputError("nurbs_cylinder needs radius > 0 and height > 0")
    prof = np.array([[radius, height], [radius, 0.0]])     # downward, so S_u × S_v points outward
    patch = revolve(prof, [1.0, 1.0], [0.0, 0.0, 1.0, 1.0], 1, sweep=sweep, name="cylinder")
    return patch if outward else patch.flipped()


def nurbs_sphere(radius: float, *, lat=(-np.pi / 3, np.pi / 3), lon=(0.0, np.pi), outward: bool = True) -> BSplinePatch:
    """An exact sphere patch centred at the origin between latitudes ``lat`` and longitudes ``lon`` (rad)."""
    if not (radius > 0 and -np.pi / 2 <= lat[0] < lat[1] <= np.pi / 2 and lon[1] > lon[0]):
        raise InputError("nurbs_sphere needs radius > 0, -π/2 <= lat0 < lat1 <= π/2 and lon1 > lon0")
    # Meridian from lat1 down to lat0 in the (r, z) half plane: S_u × S_v then points outward.
    prof, w, k = circle_arc(radius, lat[1], lat[0] - lat[1])
    patch = revolve(prof, w, k, 2, start=lon[0], sweep=lon[1] - lon[0], name="sphere")
    return patch if outward else patch.flipped()


def nurbs_torus(major: float, minor: float, *, tube=(0.0, 2 * np.pi), sweep: float = 2 * np.pi,
                outward: bool = True) -> BSplinePatch:
    """An exact torus patch about the z-axis: tube centre at distance ``major`` (m), tube radius
    ``minor`` (m), tube angles ``tube`` (rad, 0 on the outer equator, π/2 on top) and revolution
    angles ``[0, sweep]``.  Principal curvatures (outward normals): ``1/minor`` round the tube and
    ``cos θ / (major + minor cos θ)`` round the axis."""
    if not (major > minor > 0):
        raise InputError("nurbs_torus needs major > minor > 0")
    prof, w, k = circle_arc(minor, tube[1], tube[0] - tube[1], centre=(major, 0.0))
    patch = revolve(prof, w, k, 2, sweep=sweep, name="torus")
    return patch if outward else patch.flipped()


def naca00_thickness(x: np.ndarray, thickness: float) -> np.ndarray:
    """Half-thickness of a symmetric NACA 00xx profile of unit chord at chord fractions ``x``
    (closed trailing edge variant), as a fraction of the chord."""
    x = np.clip(x, 0.0, 1.0)
    return 5.0 * thickness * (0.2969 * np.sqrt(x) - 0.1260 * x - 0.3516 * x**2 + 0.2843 * x**3 - 0.1036 * x**4)
