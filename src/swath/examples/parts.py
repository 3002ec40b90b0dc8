"""Built-in example parts, generated in code (no data files).

* :func:`blade` — a helicopter-blade section: a symmetric NACA 00xx profile extruded along the
  span, as an open patch that starts on the lower surface, wraps round the leading edge and runs
  along the upper surface to the trailing edge (the setting of Jaeger's thesis).
* :func:`flat_plate` — a flat rectangle (contact patch = whole pad; an analytic reference).
* :func:`doubly_curved_panel` — a convex panel with two different principal curvatures.

All are in metres, part frame, normals pointing out of the material toward the tool.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..surface import Surface
from ..surface.exact_shapes import naca00_thickness
from ..surface.grid import grid_faces


def _resample_by_size(curve: np.ndarray, size: np.ndarray) -> np.ndarray:
    """Resample a dense polyline ``(k, d)`` so that the local spacing follows ``size`` ``(k,)`` (m)."""
    seg = np.linalg.norm(np.diff(curve, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    # u(s) = ∫ ds / size(s): uniform steps in u give steps of about size(s) in s.
    u = np.concatenate([[0.0], np.cumsum(seg / (0.5 * (size[1:] + size[:-1])))])
    n = max(int(np.ceil(u[-1])), 2) + 1
    s_new = np.interp(np.linspace(0, u[-1], n), u, s)
    return np.stack([np.interp(s_new, s, curve[:, k]) for k in range(curve.shape[1])], axis=1)


def blade(*, chord: float = 0.4, span: float = 0.6, thickness: float = 0.12, lower_start: float = 0.3,
          max_spacing: float = 4e-3, min_spacing: float = 0.4e-3) -> Surface:
    """A helicopter-blade section (NACA 00xx), open patch wrapping round the leading edge.

    Part frame: x along the chord (leading edge at x = 0), y along the span, z through the
    thickness (upper surface at z > 0).  The patch runs from the lower surface at chord fraction
    ``lower_start`` round the leading edge to the trailing edge on the upper surface.

    Parameters
    ----------
    chord, span : float
        Chord length and span, m (defaults 0.4 m and 0.6 m).
    thickness : float
        Thickness as a fraction of the chord (0.12 = NACA 0012).
    lower_start : float
        Chord fraction on the lower surface where the patch begins.
    max_spacing, min_spacing : float
        Mesh spacing bounds, m; the profile is refined where its radius of curvature is small.
    """
    if not (0.05 <= thickness <= 0.3 and 0.0 < lower_start <= 1.0 and chord > 0 and span > 0):
        raise InputError("blade needs chord, span > 0, thickness in [0.05, 0.3] and lower_start in (0, 1]")
    beta = np.linspace(0.0, np.pi, 4001)
    xc = 0.5 * (1.0 - np.cos(beta))                     # cosine spacing, dense at the leading edge
    lower = xc[xc <= lower_start][::-1]
    xs = np.concatenate([lower, xc[1:]])
    zs = np.concatenate([-naca00_thickness(lower, thickness), naca00_thickness(xc[1:], thickness)])
    profile = np.stack([xs * chord, zs * chord], axis=1)
    # Radius of curvature along the dense profile sets the mesh size (finer at the leading edge).
    d1 = np.gradient(profile, axis=0)
    d2 = np.gradient(d1, axis=0)
    curv = np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) / np.maximum(np.linalg.norm(d1, axis=1) ** 3, 1e-300)
    size = np.clip(0.08 / np.maximum(curv, 1e-9), min_spacing, max_spacing)
    prof = _resample_by_size(profile, size)
    ys = np.linspace(0.0, span, max(int(np.ceil(span / max_spacing)), 1) + 1)
    n_u, n_v = len(prof), len(ys)
    vertices = np.empty((n_u, n_v, 3))
    vertices[..., 0] = prof[:, None, 0]
    vertices[..., 1] = ys[None, :]
    vertices[..., 2] = prof[:, None, 1]
    faces = grid_faces(n_u, n_v)
    # Profile runs lower surface -> LE -> upper surface; with u along the profile and v along +y the
    # grid winding gives normals out of the material: flip if a test point says otherwise.
    surf = Surface(vertices.reshape(-1, 3), faces, name="blade")
    top = np.argmax(surf.vertices[:, 2])
    if surf.vertex_normals[top, 2] < 0:
        surf = Surface(surf.vertices, faces[:, ::-1], name="blade")
    return surf


def flat_plate(*, size_x: float = 0.4, size_y: float = 0.3, spacing: float = 5e-3) -> Surface:
    """A flat rectangular plate in the plane z = 0, normals +z, corner at the origin (m)."""
    if not (size_x > 0 and size_y > 0 and spacing > 0):
        raise InputError("flat_plate needs positive sizes and spacing")
    xs = np.linspace(0, size_x, max(int(np.ceil(size_x / spacing)), 1) + 1)
    ys = np.linspace(0, size_y, max(int(np.ceil(size_y / spacing)), 1) + 1)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    v = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], axis=1)
    return Surface(v, grid_faces(len(xs), len(ys)), name="plate")


def doubly_curved_panel(*, size_x: float = 0.5, size_y: float = 0.4, radius_x: float = 0.35,
                        radius_y: float = 0.9, spacing: float = 4e-3) -> Surface:
    """A convex doubly curved panel: the ellipsoid-like cap ``z = f(x, y)`` with radii of curvature
    ``radius_x`` (across x) and ``radius_y`` (across y) at its crown, centred at the origin, normals +z.

    The surface is the product of two circular arcs (a "barrel" shape): each x-section is an arc of
    radius ``radius_x`` and the crown line along y is an arc of radius ``radius_y``, so the principal
    curvatures vary slowly over the panel.
    """
    if not (0 < size_x < 2 * radius_x and 0 < size_y < 2 * radius_y and spacing > 0):
        raise InputError("doubly_curved_panel needs sizes smaller than twice the radii and positive spacing")
    xs = np.linspace(-size_x / 2, size_x / 2, max(int(np.ceil(size_x / spacing)), 1) + 1)
    ys = np.linspace(-size_y / 2, size_y / 2, max(int(np.ceil(size_y / spacing)), 1) + 1)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    Z = (np.sqrt(radius_x**2 - X**2) - radius_x) + (np.sqrt(radius_y**2 - Y**2) - radius_y)
    v = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)
    return Surface(v, grid_faces(len(xs), len(ys)), name="panel")
