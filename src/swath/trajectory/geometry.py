"""Differential geometry of sampled tool paths: arc length, smoothed derivatives, curvature,
tool-frame rotation rates and the Darboux frame of a curve on a surface.

Scales.  A path sampled from a mesh or a scan is a polyline: its raw second differences are
spikes at the vertices (mesh facets) and noise (scans).  Every derivative here is therefore read
at a stated length scale ``scale`` (m): the coordinates are fitted, around each sample, by a
quadratic in arc length with Gaussian weights of standard deviation ``scale`` (local quadratic
regression, window truncated at 3·scale and at the ends of the path).  A local quadratic
reproduces circles closely — the curvature of a 6.3 mm leading-edge radius is read within 1 % at
``scale`` = 1 mm — while noise of amplitude ε raises the curvature only by roughly ε / scale².

Darboux frame.  For a unit-speed curve on a surface with unit normal ``n`` (toward the tool),
tangent ``T`` and ``B = n × T``::

    dT/ds =           κ_g B + κ_n n
    dB/ds = −κ_g T          + τ_g n
    dn/ds = −κ_n T − τ_g B

with geodesic curvature κ_g, normal curvature κ_n and geodesic torsion τ_g.  Each of the three
vectors turns as ``dX/ds = D × X`` with the Darboux vector ``D = τ_g T − κ_n B + κ_g n`` (rad/m).
The tool frame of FORMATS.md is ``(x, y, z) = (T, −B, −n)``, a fixed re-labelling of the Darboux
frame, so it turns with the same ``D``: its angular velocity in the part frame is ``ω = v·D``.
With swath's curvature sign (positive = convex toward the tool) and the shape tensor
``K = k1 d1 d1ᵀ + k2 d2 d2ᵀ``: ``dn/ds = K T``, so ``κ_n = −Tᵀ K T`` and ``τ_g = −Tᵀ K B``.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import correlate1d
from scipy.spatial.transform import Rotation

from ..surface.geometry import normalize
from ..surface.polyline import arc_length, resample_uniform  # noqa: F401  (re-exported: the timing grid)


def local_quadratic(values: np.ndarray, spacing: float, scale: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gaussian-weighted local quadratic regression on a uniform grid.

    Parameters
    ----------
    values : (n, d) float
        Samples at equal spacing (for example coordinates of a path resampled by
        :func:`resample_uniform`).
    spacing : float
        Grid spacing, m.
    scale : float
        Standard deviation of the Gaussian weights, m (window truncated at 3·scale and at the ends).

    Returns
    -------
    value, first, second : (n, d) float
        The fitted value and its first and second derivatives with respect to arc length
        (units of ``values`` per m and per m²).  With fewer than three samples the second
        derivative is zero and the first is the chord slope.
    """
    y = np.asarray(values, float)
    n = len(y)
    if n < 3:
        d1 = np.repeat((y[-1:] - y[:1]) / max(spacing * (n - 1), 1e-300), n, axis=0)
        return y.copy(), d1, np.zeros_like(y)
    half = max(int(np.ceil(3.0 * scale / spacing)), 1)
    j = np.arange(-half, half + 1, dtype=float)
    w = np.exp(-0.5 * (j * spacing / max(scale, 1e-300)) ** 2)
    # Moments of the weights over the (end-truncated) window, and of the data.
    ones = np.ones(n)
    m = [correlate1d(ones, w * j**k, mode="constant") for k in range(5)]
    d = [correlate1d(y, w * j**k, axis=0, mode="constant") for k in range(3)]
    A = np.stack([np.stack([m[0], m[1], m[2]], -1), np.stack([m[1], m[2], m[3]], -1),
                  np.stack([m[2], m[3], m[4]], -1)], axis=1)                      # (n, 3, 3)
    rhs = np.stack(d, axis=1)                                                      # (n, 3, d)
    A = A + 1e-12 * np.trace(A, axis1=1, axis2=2)[:, None, None] * np.eye(3)
    c = np.linalg.solve(A, rhs)                                                    # (n, 3, d)
    return c[:, 0], c[:, 1] / spacing, 2.0 * c[:, 2] / spacing**2


def curvature_vectors(points: np.ndarray, spacing: float, scale: float) -> tuple[np.ndarray, np.ndarray]:
    """Unit tangents and curvature vectors of a uniformly resampled path, read at ``scale``.

    Parameters
    ----------
    points : (n, 3) float
        Path at equal arc-length spacing, m.
    spacing, scale : float
        Grid spacing and smoothing scale (see :func:`local_quadratic`), m.

    Returns
    -------
    tangents : (n, 3) float
        Unit tangents.
    curvature : (n, 3) float
        Curvature vectors ``dT/ds`` (1/m), perpendicular to the tangents; their length is the
        curvature κ and they point toward the centre of the osculating circle.
    """
    _, d1, d2 = local_quadratic(points, spacing, scale)
    speed = np.maximum(np.linalg.norm(d1, axis=1), 1e-300)
    t = d1 / speed[:, None]
    k = (d2 - np.einsum("ij,ij->i", d2, t)[:, None] * t) / speed[:, None] ** 2
    return t, k


def path_curvature(points: np.ndarray, spacing: float, scale: float) -> np.ndarray:
    """Curvature ``(n,)`` (1/m) of a uniformly resampled path ``(n, 3)``, read at ``scale`` (m)."""
    return np.linalg.norm(curvature_vectors(points, spacing, scale)[1], axis=1)


def smoothed_directions(points: np.ndarray, spacing: float, scale: float) -> np.ndarray:
    """Unit travel directions ``(n, 3)`` averaged over a Gaussian window of standard deviation
    ``scale`` (m) in arc length: the chord directions of the uniformly spaced path ``(n, 3)`` are
    averaged with Gaussian weights and normalised.  Where a path turns sharply (the corner of a
    zig-zag) the direction so turns gradually over about ±2·scale; on a smooth path it is the
    tangent.  ``scale = 0`` gives central differences.  A zero average (a path that reverses on
    itself) leaves a zero vector, which :func:`tool_frames` bridges.
    """
    n = len(points)
    if n < 2:
        return np.zeros_like(points)
    chords = normalize(np.diff(points, axis=0))                                  # (n−1, 3)
    # Directions at the samples: the mean of the adjacent chords (one chord at the ends).
    node = np.vstack([chords[:1], chords[:-1] + chords[1:], chords[-1:]])
    if scale > 0 and n > 2:
        half = max(int(np.ceil(3.0 * scale / spacing)), 1)
        j = np.arange(-half, half + 1, dtype=float)
        w = np.exp(-0.5 * (j * spacing / scale) ** 2)
        node = correlate1d(node, w, axis=0, mode="constant")
    norm = np.linalg.norm(node, axis=1, keepdims=True)
    return np.divide(node, norm, out=np.zeros_like(node), where=norm > 1e-9)


def rotation_steps(frames: np.ndarray) -> np.ndarray:
    """Rotation vectors ``(k−1, 3)`` (rad, part frame) taking each frame ``(k, 3, 3)`` to the next:
    ``R[i+1] = exp([r_i]×) R[i]``."""
    if len(frames) < 2:
        return np.zeros((0, 3))
    r = Rotation.from_matrix(frames)
    return (r[1:] * r[:-1].inv()).as_rotvec()


def shape_tensors(surface, points: np.ndarray, face: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Shape tensors ``K`` ``(k, 3, 3)`` (1/m) at ``points`` on ``face`` of ``surface``.

    ``K = k1 d1 d1ᵀ + k2 d2 d2ᵀ`` (swath's sign: positive = convex toward the tool), interpolated
    barycentrically between the face's vertices and projected onto the tangent plane of
    ``normals`` ``(k, 3)``; ``dn/ds = K T`` along any unit tangent ``T``.
    """
    import trimesh

    c = surface.curvature
    Kv = (c.k1[:, None, None] * np.einsum("ni,nj->nij", c.d1, c.d1)
          + c.k2[:, None, None] * np.einsum("ni,nj->nij", c.d2, c.d2))
    tri = surface.vertices[surface.faces[face]]
    bary = np.clip(trimesh.triangles.points_to_barycentric(tri, points), 0.0, None)
    bary /= np.maximum(bary.sum(axis=1, keepdims=True), 1e-300)
    K = np.einsum("ki,kiab->kab", bary, Kv[surface.faces[face]])
    P = np.eye(3) - np.einsum("ki,kj->kij", normals, normals)
    return P @ K @ P


def darboux(tangents: np.ndarray, normals: np.ndarray, curvature: np.ndarray,
            shape: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The Darboux vector of a curve on a surface (see the module notes).

    Parameters
    ----------
    tangents : (k, 3) float
        Unit tangents of the curve (projected onto the tangent plane here).
    normals : (k, 3) float
        Unit surface normals toward the tool.
    curvature : (k, 3) float
        Curvature vectors ``dT/ds`` of the curve, 1/m (:func:`curvature_vectors`); only their
        component along ``B = n × T`` (the geodesic curvature) is used.
    shape : (k, 3, 3) float
        Shape tensors (:func:`shape_tensors`), 1/m; they give κ_n and τ_g.

    Returns
    -------
    D : (k, 3) float
        ``τ_g T − κ_n B + κ_g n``, rad/m, part frame: the tool frame's angular velocity per metre
        of travel.
    kappa_g, kappa_n, tau_g : (k,) float
        Geodesic curvature, normal curvature and geodesic torsion, 1/m.
    """
    n = normalize(normals)
    t = normalize(tangents - np.einsum("ij,ij->i", tangents, n)[:, None] * n)
    b = np.cross(n, t)
    kappa_g = np.einsum("ij,ij->i", curvature, b)
    kt = np.einsum("kab,kb->ka", shape, t)
    kappa_n = -np.einsum("ij,ij->i", kt, t)
    tau_g = -np.einsum("ij,ij->i", kt, b)
    D = tau_g[:, None] * t - kappa_n[:, None] * b + kappa_g[:, None] * n
    return D, kappa_g, kappa_n, tau_g
