"""Exact analytic test surfaces (meshes whose vertices lie exactly on the shape)."""

from __future__ import annotations

import numpy as np

from swath.examples import grid_faces
from swath.surface import Surface


def sphere_cap(radius: float, half_angle: float, n: int = 120) -> Surface:
    """A spherical cap around +z (outward normals), vertices exactly on the sphere."""
    u = np.linspace(-half_angle, half_angle, n)
    U, V = np.meshgrid(u, u, indexing="ij")
    # Gnomonic-like grid: directions (tan U, tan V, 1) normalised, exactly on the sphere.
    d = np.stack([np.tan(U), np.tan(V), np.ones_like(U)], -1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    return Surface((radius * d).reshape(-1, 3), grid_faces(n, n), name="sphere")


def cylinder_patch(radius: float, half_angle: float, length: float, n_theta: int = 200, n_len: int = 60,
                   concave: bool = False) -> Surface:
    """An open patch of a cylinder along y, seen from +z (convex) or from inside (concave)."""
    th = np.linspace(-half_angle, half_angle, n_theta)
    ys = np.linspace(-length / 2, length / 2, n_len)
    T, Y = np.meshgrid(th, ys, indexing="ij")
    sign = -1.0 if concave else 1.0
    v = np.stack([radius * np.sin(T), Y, sign * radius * np.cos(T)], -1).reshape(-1, 3)
    f = grid_faces(n_theta, n_len)
    s = Surface(v, f)
    # Orient toward the tool: +z on the convex cap, toward the axis (−z side) from inside.
    top = np.argmin(np.abs(v[:, 0]) + np.abs(v[:, 1]))
    want = 1.0 if not concave else 1.0
    if s.vertex_normals[top, 2] * want < 0:
        s = Surface(v, f[:, ::-1])
    return s


def grooved_plate(width: float = 0.3, depth: float = 5e-3, sigma: float = 0.01, n: int = 151) -> Surface:
    """A square plate ``width`` wide (m) with a Gaussian groove along x through its middle:
    z = −depth · exp(−y² / (2 sigma²)); the bottom's radius of curvature is sigma² / depth."""
    xs = np.linspace(-width / 2, width / 2, n)
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    Z = -depth * np.exp(-Y ** 2 / (2 * sigma ** 2))
    return Surface(np.stack([X, Y, Z], -1).reshape(-1, 3), grid_faces(n, n), name="grooved plate")


def sliver_plate(size_x: float = 0.4, size_y: float = 0.3, strip: float = 1.5e-3) -> Surface:
    """A flat plate in z = 0 (m) meshed as strips ``strip`` wide, each two triangles ``size_x`` long:
    slivers, which a per-triangle sample lattice gives one row of samples each."""
    ys = np.arange(0.0, size_y + 1e-12, strip)
    n = len(ys)
    v = np.concatenate([np.stack([np.zeros(n), ys, np.zeros(n)], 1), np.stack([np.full(n, size_x), ys, np.zeros(n)], 1)])
    i = np.arange(n - 1)
    faces = np.concatenate([np.stack([i, n + i, n + i + 1], 1), np.stack([i, n + i + 1, i + 1], 1)])
    return Surface(v, faces, name="slivers")


def bowl(size: float = 0.4, radius: float = 0.35, n: int = 101) -> Surface:
    """A concave bowl ``z = (x² + y²) / (2 radius)`` over a ``size`` square (m), normals +z (the
    tool looks into it): concave everywhere, curvature ``1 / radius`` at the centre."""
    t = np.linspace(-size / 2, size / 2, n)
    X, Y = np.meshgrid(t, t, indexing="ij")
    v = np.stack([X.ravel(), Y.ravel(), ((X**2 + Y**2) / (2 * radius)).ravel()], axis=1)
    return Surface(v, grid_faces(n, n), name="bowl")


def saddle(size: float = 0.4, radius: float = 0.4, n: int = 101) -> Surface:
    """A saddle ``z = (x² − y²) / (2 radius)`` over a ``size`` square (m), normals +z: convex along
    y, concave along x, principal curvatures ``±1 / radius`` at the centre."""
    t = np.linspace(-size / 2, size / 2, n)
    X, Y = np.meshgrid(t, t, indexing="ij")
    v = np.stack([X.ravel(), Y.ravel(), ((X**2 - Y**2) / (2 * radius)).ravel()], axis=1)
    return Surface(v, grid_faces(n, n), name="saddle")


#: Two tangent arcs (two_radius_part)
R1, A1, R2, A2 = 0.15, 0.8, 0.6, 0.4          # two tangent arcs: radius (m) and the angle each turns (rad)
START = -0.6                                   # tangent angle at the start (rad): the profile stays within ±0.6 rad


def two_radius_part(step: float = 1.5e-3, length: float = 0.24) -> tuple[Surface, np.ndarray, np.ndarray]:
    """A convex part whose cross-section is an arc of radius R1 followed, tangent to it, by an arc of
    radius R2, extruded along y; returns the surface and the profile's x and arc length (m)."""
    th1 = START + np.arange(0.0, R1 * A1, step) / R1
    th2 = START + A1 + np.arange(0.0, R2 * A2 + step / 2, step) / R2
    x1, z1 = R1 * (np.sin(th1) - np.sin(START)), R1 * (np.cos(th1) - np.cos(START))
    xj, zj = R1 * (np.sin(START + A1) - np.sin(START)), R1 * (np.cos(START + A1) - np.cos(START))
    x2 = xj + R2 * (np.sin(th2) - np.sin(START + A1))
    z2 = zj + R2 * (np.cos(th2) - np.cos(START + A1))
    x, z = np.concatenate([x1, x2[1:]]), np.concatenate([z1, z2[1:]])
    ys = np.linspace(0.0, length, 25)
    v = np.stack([np.repeat(x, len(ys)), np.tile(ys, len(x)), np.repeat(z, len(ys))], 1)
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(x), np.diff(z)))])
    return Surface(v, grid_faces(len(x), len(ys))), x, arc


def plate_with_straight_passes(spacing: float, margin: float, *, n_passes: int = 6, length: float = 0.3):
    """A flat plate and ``n_passes`` straight passes along x across it, ``spacing`` (m) apart, the
    outermost ``margin`` (m) in from either side, run back and forth with points 1 mm apart:
    ``(Surface, ToolPath)``.  The plate is ``length`` long and ``2 margin + (n_passes − 1) spacing``
    wide, meshed every 5 mm."""
    from swath.core import Pass, ToolPath
    from swath.examples.parts import flat_plate

    width = 2 * margin + (n_passes - 1) * spacing
    surface = flat_plate(size_x=length, size_y=width, spacing=5e-3)
    lo = surface.bounds[0]
    xs = lo[0] + np.arange(0.0, length + 1e-9, 1e-3)
    passes = []
    for k in range(n_passes):
        x = xs if k % 2 == 0 else xs[::-1]
        pts = np.column_stack([x, np.full_like(x, lo[1] + margin + k * spacing), np.full_like(x, lo[2])])
        passes.append(Pass(pts, np.tile([0.0, 0.0, 1.0], (len(x), 1)), level=k))
    return surface, ToolPath(surface, passes, "raster", {})


def timed_plate_raster(spacing: float):
    """The built-in plate's raster at ``spacing`` (m), passes along x, timed as a job times it:
    ``(Surface, Tool, Trajectory)``."""
    from swath.cli.job import JobSettings, make_plan
    from swath.examples import example_part
    from swath.trajectory import time_path

    settings = JobSettings(part="example:plate", out="unused", spacing=spacing)
    surface = example_part("plate")
    trajectory = time_path(make_plan(surface, settings), settings.constraints(), links=settings.links())
    return surface, settings.tool(), trajectory
