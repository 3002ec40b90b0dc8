"""A built-in wheel-hub face, generated in code (Wang's grinding object): a dished face with a
centre bore, five spoke windows and a rim that rises toward the outer edge.

Part frame: z along the wheel axis toward the tool (the face is seen from +z), origin at the
centre of the bore at the bottom of the dish; metres.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..surface import Surface


def wheel_hub(*, diameter: float = 0.45, bore_diameter: float = 0.07, dish_depth: float = 0.035,
              rim_width: float = 0.035, rim_height: float = 0.02, windows: int = 5,
              window_inner: float = 0.09, window_outer: float = 0.165, window_angle: float = 0.75,
              corner_radius: float = 0.012, edge: float = 5e-3) -> Surface:
    """The front face of a wheel hub, triangulated with edges of about ``edge``.

    Parameters
    ----------
    diameter : float
        Outer diameter, m (default 0.45 m, an 18-inch wheel).
    bore_diameter : float
        Diameter of the centre bore, m.
    dish_depth : float
        Height the face rises from the bore edge to the start of the rim, m (a cosine profile).
    rim_width, rim_height : float
        Radial width and rise of the rim at the outer edge, m (a cosine ramp, about 30 degrees steep
        at its middle with the defaults).
    windows : int
        Number of spoke windows (holes through the face), evenly spaced.
    window_inner, window_outer : float
        Inner and outer radius of the windows, m.
    window_angle : float
        Angular width of each window, rad (the spokes between them take the rest).
    corner_radius : float
        Rounding of the window corners, m.
    edge : float
        Target edge length of the triangles, m (default 5 mm).

    Returns
    -------
    Surface
        Normals toward +z (the tool side), name ``"wheel_hub"``.

    Raises
    ------
    InputError
        On radii that do not nest (bore < windows < rim < outer edge) or a non-positive size.
    """
    r_out = 0.5 * diameter
    r_bore = 0.5 * bore_diameter
    r_face = r_out - rim_width
    for name, v in (("diameter", diameter), ("bore_diameter", bore_diameter), ("edge", edge),
                    ("rim_width", rim_width), ("window_angle", window_angle)):
        if not (np.isfinite(v) and v > 0):
            raise InputError(f"wheel_hub {name} must be positive, got {v!r}")
    if not (r_bore + edge < window_inner < window_outer < r_face - edge):
        raise InputError(f"wheel_hub radii must nest: bore {r_bore} < window inner {window_inner} < window outer "
                         f"{window_outer} < rim start {r_face} m")
    if windows < 0 or windows * window_angle >= 2 * np.pi:
        raise InputError(f"{windows} windows of {window_angle} rad do not fit round the hub")

    # Boundary curves sampled at the edge length; interior points on a hexagonal grid kept away
    # from the curves by half an edge.
    curves = [_circle(r_out, edge), _circle(r_bore, edge)]
    curves += [_window(k * 2 * np.pi / max(windows, 1), window_inner, window_outer, window_angle, corner_radius, edge)
               for k in range(windows)]
    boundary = np.vstack(curves)
    xs = np.arange(-r_out, r_out + edge, edge)
    ys = np.arange(-r_out, r_out + edge, edge * np.sqrt(3) / 2)
    gx, gy = np.meshgrid(xs, ys)
    gx = gx + 0.5 * edge * (np.arange(len(ys))[:, None] % 2)
    grid = np.stack([gx.ravel(), gy.ravel()], axis=1)
    from scipy.spatial import Delaunay, cKDTree

    inside = _inside(grid, r_out, r_bore, windows, window_inner, window_outer, window_angle, corner_radius)
    d, _ = cKDTree(boundary).query(grid)
    pts = np.vstack([boundary, grid[inside & (d > 0.6 * edge)]])
    tri = Delaunay(pts).simplices
    centroid = pts[tri].mean(axis=1)
    keep = _inside(centroid, r_out, r_bore, windows, window_inner, window_outer, window_angle, corner_radius)
    tri = tri[keep]
    # Counter-clockwise in the plane so the normals point to +z.
    a, b, c = pts[tri[:, 0]], pts[tri[:, 1]], pts[tri[:, 2]]
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    tri[cross < 0] = tri[cross < 0][:, ::-1]
    tri = tri[np.abs(cross) > 1e-12 * edge**2]
    used = np.unique(tri)
    remap = np.full(len(pts), -1)
    remap[used] = np.arange(len(used))
    pts = pts[used]
    tri = remap[tri]
    r = np.linalg.norm(pts, axis=1)
    z = _height(r, r_bore, r_face, r_out, dish_depth, rim_height)
    return Surface(np.column_stack([pts, z]), tri, name="wheel_hub")


def _height(r, r_bore, r_face, r_out, dish_depth, rim_height):
    """Face height (m) at radius r: a cosine dish from the bore to the rim, then a cosine rim ramp."""
    s = np.clip((r - r_bore) / (r_face - r_bore), 0.0, 1.0)
    t = np.clip((r - r_face) / (r_out - r_face), 0.0, 1.0)
    return dish_depth * 0.5 * (1 - np.cos(np.pi * s)) + rim_height * 0.5 * (1 - np.cos(np.pi * t))


def _circle(radius, edge):
    n = max(int(np.ceil(2 * np.pi * radius / edge)), 8)
    a = 2 * np.pi * np.arange(n) / n
    return radius * np.stack([np.cos(a), np.sin(a)], axis=1)


def _window(phi, r_in, r_out, width, corner, step):
    """Outline (k, 2) of the window centred on angle ``phi``, points about ``step`` apart: the edge of
    :func:`_in_window` found by bisection along rays from the window's centre (it is star-shaped)."""
    ri, ro = r_in + corner, r_out - corner
    if ri >= ro or 0.5 * width - corner / r_in <= 0:
        raise InputError("wheel_hub windows are too small for their corner radius")
    centre = 0.5 * (r_in + r_out) * np.array([np.cos(phi), np.sin(phi)])
    ang = np.linspace(0, 2 * np.pi, 2000, endpoint=False)
    ray = np.stack([np.cos(ang), np.sin(ang)], 1)
    lo, hi = np.zeros(len(ang)), np.full(len(ang), r_out)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        inside = _in_window(centre + mid[:, None] * ray, r_in, r_out, width, corner, phi)
        lo, hi = np.where(inside, mid, lo), np.where(inside, hi, mid)
    dense = centre + lo[:, None] * ray
    closed = np.vstack([dense, dense[:1]])
    cum = np.r_[0, np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))]
    n = max(int(np.ceil(cum[-1] / step)), 8)
    s_new = np.linspace(0, cum[-1], n, endpoint=False)
    return np.stack([np.interp(s_new, cum, closed[:, 0]), np.interp(s_new, cum, closed[:, 1])], 1)


def _in_window(p, r_in, r_out, width, corner, phi):
    """Points (k, 2) inside the rounded window centred on angle phi: within `corner` of the shrunk sector."""
    r = np.linalg.norm(p, axis=1)
    ang = (np.arctan2(p[:, 1], p[:, 0]) - phi + np.pi) % (2 * np.pi) - np.pi
    ri, ro = r_in + corner, r_out - corner
    half_in = 0.5 * width - corner / r_in
    # distance to the shrunk sector {ri <= r <= ro, |ang| <= half_in}
    ang_c = np.clip(ang, -half_in, half_in)
    r_c = np.clip(r, ri, ro)
    q = np.stack([r_c * np.cos(ang_c), r_c * np.sin(ang_c)], 1)
    local = np.stack([r * np.cos(ang), r * np.sin(ang)], 1)
    return np.linalg.norm(local - q, axis=1) < corner


def _inside(p, r_out, r_bore, windows, w_in, w_out, w_angle, corner):
    r = np.linalg.norm(p, axis=1)
    ok = (r < r_out) & (r > r_bore)
    for k in range(windows):
        ok &= ~_in_window(p, w_in, w_out, w_angle, corner, k * 2 * np.pi / max(windows, 1))
    return ok
