"""Simulated point-laser scans, and exact spline versions of the built-in parts to scan.

A point laser on a robot measures one point at a time; the robot sweeps it in *rows*.  The
simulation reproduces what matters for surface fitting (Jaeger §3.2.1):

* rows of points along one direction, ``row_spacing`` apart, points ``point_spacing`` apart
  along each row (each row starts at a random phase);
* Gaussian noise of standard deviation ``sigma`` along the surface normal (or along the laser's
  view direction);
* a row-to-row positional offset: every row is displaced as a whole by a Gaussian random vector
  with standard deviation ``row_offset`` per axis (the robot's repositioning error between rows).

:func:`blade_patch` and :func:`panel_patch` give the geometry of :func:`swath.examples.blade` and
:func:`swath.examples.doubly_curved_panel` as smooth :class:`~swath.surface.bspline.BSplinePatch`
objects (the panel exactly, the blade to well under a micrometre), so scans of them come with
true normals and curvatures for accuracy studies.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..surface.bspline import BSplinePatch
from ..surface.bspline_basis import clamped_knots, span_samples
from ..surface.exact_shapes import circle_arc, naca00_thickness, translational


@dataclass(frozen=True)
class LaserScan:
    """A simulated scan.

    Attributes
    ----------
    points : (n, 3) float
        Measured points, m (noise and row offsets included), row by row in scan order.
    rows : (n,) int
        Row id of each point (0, 1, … in scan order).
    true_points : (n, 3) float
        The surface points that were aimed at, m.
    true_normals : (n, 3) float
        Unit surface normals there.
    uv : (n, 2) float or None
        Patch parameters of ``true_points`` when a patch was scanned.
    """

    points: np.ndarray
    rows: np.ndarray
    true_points: np.ndarray
    true_normals: np.ndarray
    uv: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.points)


def simulate_laser_scan(target, *, row_spacing: float, point_spacing: float, sigma: float = 1e-4,
                        row_offset: float = 2e-4, rng=None, along: str = "u", across_direction=None,
                        view_direction=None, bidirectional: bool = False) -> LaserScan:
    """Scan a patch or a triangulated surface with a simulated point laser.

    Parameters
    ----------
    target : BSplinePatch or Surface
        What to scan.  A patch is scanned in rows along one parameter direction (``along``); a
        :class:`~swath.surface.Surface` in rows that are its sections by parallel planes.
    row_spacing : float
        Distance between rows, m.
    point_spacing : float
        Distance between points along a row (arc length), m.
    sigma : float
        Standard deviation of the measurement noise, m (default 0.1 mm).
    row_offset : float
        Standard deviation, per axis, of the rigid displacement of each row, m (default 0.2 mm).
    rng : numpy.random.Generator or int, optional
        Random generator or seed.
    along : {"u", "v"}
        Patch only: the parameter direction the rows follow.  For the blade (u round the profile)
        ``"u"`` scans round the leading edge.
    across_direction : (3,) float, optional
        Surface only: normal of the section planes, i.e. the direction rows advance in (default:
        the surface's longest principal axis, so rows run across it).
    view_direction : (3,) float, optional
        Direction the laser looks (from the scanner toward the part).  Noise is then along it and
        points whose normal faces away from the laser are not measured.  Default: noise along the
        surface normal, everything measured (the laser follows the surface).
    bidirectional : bool
        Scan every other row backwards (as a zig-zag scan does).

    Returns
    -------
    LaserScan
    """
    from ..surface.surface import Surface

    for name, val in (("row_spacing", row_spacing), ("point_spacing", point_spacing)):
        if not (isinstance(val, (int, float)) and np.isfinite(val) and val > 0):
            raise InputError(f"{name} must be a positive length in metres, got {val!r}")
    for name, val in (("sigma", sigma), ("row_offset", row_offset)):
        if not (isinstance(val, (int, float)) and np.isfinite(val) and val >= 0):
            raise InputError(f"{name} must be a non-negative length in metres, got {val!r}")
    rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    if isinstance(target, BSplinePatch):
        if along not in ("u", "v"):
            raise InputError(f"along must be 'u' or 'v', got {along!r}")
        pts, nrm, rows, uv = _scan_patch(target, row_spacing, point_spacing, along, rng)
    elif isinstance(target, Surface):
        pts, nrm, rows = _scan_surface(target, row_spacing, point_spacing, across_direction, rng)
        uv = None
    else:
        raise InputError(f"can scan a BSplinePatch or a Surface, got {type(target).__name__}")
    if view_direction is not None:
        view = np.asarray(view_direction, float)
        if view.shape != (3,) or not np.linalg.norm(view) > 0:
            raise InputError(f"view_direction must be a non-zero 3-vector, got {view_direction!r}")
        view = view / np.linalg.norm(view)
        seen = nrm @ view < 0
        pts, nrm, rows = pts[seen], nrm[seen], rows[seen]
        uv = None if uv is None else uv[seen]
        noise_dir = np.broadcast_to(view, pts.shape)
    else:
        noise_dir = nrm
    if len(pts) == 0:
        raise InputError("the scan measured no points; check the spacings and the view direction")
    # Renumber rows 0.. in order, optionally reverse every other row.
    _, rows = np.unique(rows, return_inverse=True)
    rows = rows.ravel()
    if bidirectional:
        order = np.lexsort((np.where(rows % 2 == 1, -np.arange(len(rows)), np.arange(len(rows))), rows))
        pts, nrm, rows, noise_dir = pts[order], nrm[order], rows[order], noise_dir[order]
        uv = None if uv is None else uv[order]
    offsets = rng.normal(0.0, row_offset, size=(rows.max() + 1, 3)) if row_offset > 0 else np.zeros((rows.max() + 1, 3))
    measured = pts + sigma * rng.standard_normal(len(pts))[:, None] * noise_dir + offsets[rows]
    return LaserScan(measured, rows.astype(np.int64), pts, nrm, uv)


def _arc_table(patch: BSplinePatch, direction: int, n_other: int = 5):
    """Parameters along ``direction`` and the mean arc length of the iso-curves there."""
    knots = patch.knots_u if direction == 0 else patch.knots_v
    g = span_samples(knots, patch.degree[direction], 8, cap=4000)
    (u0, u1), (v0, v1) = patch.domain
    other = np.linspace(*((v0, v1) if direction == 0 else (u0, u1)), n_other)
    A, O = np.meshgrid(g, other, indexing="ij")
    P = patch.evaluate(A.ravel(), O.ravel()) if direction == 0 else patch.evaluate(O.ravel(), A.ravel())
    seg = np.linalg.norm(np.diff(P.reshape(len(g), n_other, 3), axis=0), axis=2).mean(axis=1)
    return g, np.concatenate([[0.0], np.cumsum(seg)])


def _scan_patch(patch: BSplinePatch, row_spacing, point_spacing, along, rng):
    d_along = 0 if along == "u" else 1
    g_across, s_across = _arc_table(patch, 1 - d_along)
    L_across = s_across[-1]
    n_rows = int(np.floor(L_across / row_spacing)) + 1
    first = 0.5 * (L_across - (n_rows - 1) * row_spacing)
    across = np.interp(first + row_spacing * np.arange(n_rows), s_across, g_across)
    # Arc length along every row on a dense grid (vectorised over rows).
    g_along, s_mean = _arc_table(patch, d_along)
    n_dense = int(min(max(len(g_along), 3 * s_mean[-1] / point_spacing), 20000))
    dense = np.interp(np.linspace(0, s_mean[-1], n_dense), s_mean, g_along)
    A, C = np.meshgrid(dense, across, indexing="ij")                  # (n_dense, n_rows)
    uu, vv = (A, C) if d_along == 0 else (C, A)
    P = patch.evaluate(uu.ravel(), vv.ravel()).reshape(n_dense, n_rows, 3)
    s = np.concatenate([np.zeros((1, n_rows)), np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=2), axis=0)])
    along_p, across_p, row_id = [], [], []
    for r in range(n_rows):       # one short loop per row (not per point)
        phase = rng.uniform(0.0, point_spacing)
        sk = np.arange(phase, s[-1, r], point_spacing)
        along_p.append(np.interp(sk, s[:, r], dense))
        across_p.append(np.full(len(sk), across[r]))
        row_id.append(np.full(len(sk), r))
    a, c, rows = np.concatenate(along_p), np.concatenate(across_p), np.concatenate(row_id)
    u, v = (a, c) if d_along == 0 else (c, a)
    D = patch.derivatives(u, v, 1)
    nrm = np.cross(D[:, 1, 0], D[:, 0, 1])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    return D[:, 0, 0], nrm, rows, np.stack([u, v], axis=1)


def _scan_surface(surface, row_spacing, point_spacing, across_direction, rng):
    if across_direction is None:
        axis = surface.principal_axes[1][0]
    else:
        axis = np.asarray(across_direction, float)
        if axis.shape != (3,) or not np.linalg.norm(axis) > 0:
            raise InputError(f"across_direction must be a non-zero 3-vector, got {across_direction!r}")
        axis = axis / np.linalg.norm(axis)
    h = surface.vertices @ axis
    lo, hi = h.min(), h.max()
    n_rows = int(np.floor((hi - lo) / row_spacing)) + 1
    first = lo + 0.5 * ((hi - lo) - (n_rows - 1) * row_spacing)
    mesh = surface.trimesh
    pts, rows = [], []
    for r in range(n_rows):       # one plane section per row
        origin = axis * (first + r * row_spacing)
        section = mesh.section(plane_normal=axis, plane_origin=origin)
        if section is None:
            continue
        lines = [np.asarray(e.discrete(section.vertices)) for e in section.entities]
        lines = [d for d in lines if len(d) >= 2]
        if not lines:
            continue
        line = max(lines, key=lambda d: np.linalg.norm(np.diff(d, axis=0), axis=1).sum())
        seg = np.linalg.norm(np.diff(line, axis=0), axis=1)
        s = np.concatenate([[0.0], np.cumsum(seg)])
        sk = np.arange(rng.uniform(0.0, point_spacing), s[-1], point_spacing)
        if len(sk) == 0:
            continue
        pts.append(np.stack([np.interp(sk, s, line[:, c]) for c in range(3)], axis=1))
        rows.append(np.full(len(sk), r))
    if not pts:
        raise InputError("no section of the surface is long enough for one point; reduce point_spacing")
    P = np.concatenate(pts)
    closest, _, face = surface.closest_points(P)
    nrm = surface.interpolate_normals(closest, face)
    return closest, nrm, np.concatenate(rows)


# ----------------------------------------------------------------------------------------------
# Spline versions of the built-in parts
# ----------------------------------------------------------------------------------------------
def blade_patch(*, chord: float = 0.4, span: float = 0.6, thickness: float = 0.12,
                lower_start: float = 0.3) -> BSplinePatch:
    """The blade of :func:`swath.examples.blade` as a smooth patch: u round the NACA 00xx profile
    (from the lower surface at chord fraction ``lower_start`` round the leading edge to the
    trailing edge, parameterised by arc length, m), v along the span (m); normals out of the
    material.  The profile is a cubic spline interpolating ~5000 exact profile points (position
    error well below 1 µm)."""
    from scipy.interpolate import make_interp_spline

    if not (0.05 <= thickness <= 0.3 and 0.0 < lower_start <= 1.0 and chord > 0 and span > 0):
        raise InputError("blade_patch needs chord, span > 0, thickness in [0.05, 0.3] and lower_start in (0, 1]")
    beta = np.linspace(0.0, np.pi, 4001)
    xc = 0.5 * (1.0 - np.cos(beta))
    lower = xc[xc <= lower_start][::-1]
    xs = np.concatenate([lower, xc[1:]])
    zs = np.concatenate([-naca00_thickness(lower, thickness), naca00_thickness(xc[1:], thickness)])
    prof = np.stack([xs, zs], axis=1) * chord
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(prof, axis=0), axis=1))])
    spl = make_interp_spline(s, prof, k=3)
    ctrl = np.zeros((len(spl.c), 2, 3))
    ctrl[:, :, 0] = spl.c[:, None, 0]
    ctrl[:, 1, 1] = span
    ctrl[:, :, 2] = spl.c[:, None, 1]
    return BSplinePatch(ctrl, spl.t, clamped_knots([], 1, (0.0, span)), (3, 1), name="blade")


def panel_patch(*, size_x: float = 0.5, size_y: float = 0.4, radius_x: float = 0.35,
                radius_y: float = 0.9) -> BSplinePatch:
    """The panel of :func:`swath.examples.doubly_curved_panel` as an exact NURBS: the translational
    surface ``z = (√(rx² − x²) − rx) + (√(ry² − y²) − ry)`` of two circle arcs; u along x, v along
    y, normals +z."""
    if not (0 < size_x < 2 * radius_x and 0 < size_y < 2 * radius_y):
        raise InputError("panel_patch needs sizes smaller than twice the radii")

    def arc(size, radius, axis):
        alpha = np.arcsin(0.5 * size / radius)
        c2, w, k = circle_arc(radius, np.pi / 2 + alpha, -2 * alpha, centre=(0.0, -radius))
        c3 = np.zeros((len(c2), 3))
        c3[:, axis] = c2[:, 0]
        c3[:, 2] = c2[:, 1]
        return c3, w, k, 2

    return translational(arc(size_x, radius_x, 0), arc(size_y, radius_y, 1), name="panel")
