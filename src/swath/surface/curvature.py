"""Principal curvatures and directions by a local quadric fit.

At each vertex the neighbours are expressed in a local frame (tangent ``t1, t2``, normal ``n``)
and the height function ``h(x, y) = a x² + b x y + c y² + d x + e y`` is fitted by weighted least
squares.  The shape operator of that graph at the origin gives the principal curvatures and
directions.  Fitting over a neighbourhood, rather than using one ring of triangles, is what keeps
the result stable on noisy scans: the neighbourhood is the scale at which the curvature is read.

Sign convention (used everywhere in swath): **curvature is positive where the surface bends away
from the tool side** — the outside of a sphere seen by the tool has ``k1 = k2 = +1/r``; the inside
of a bowl has negative curvatures.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from .geometry import normalize


@dataclass(frozen=True)
class PrincipalCurvature:
    """Principal curvatures (1/m) and unit directions at each vertex.

    Attributes
    ----------
    k1, k2 : (n,) float
        Principal curvatures, ``k1 >= k2``; positive = convex toward the tool.
    d1, d2 : (n, 3) float
        Unit tangent directions of ``k1`` and ``k2``.
    """

    k1: np.ndarray
    k2: np.ndarray
    d1: np.ndarray
    d2: np.ndarray

    @property
    def mean(self) -> np.ndarray:
        """Mean curvature ``(k1 + k2) / 2``, 1/m."""
        return 0.5 * (self.k1 + self.k2)

    @property
    def gaussian(self) -> np.ndarray:
        """Gaussian curvature ``k1 * k2``, 1/m²."""
        return self.k1 * self.k2


def tangent_frames(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangents ``(n, 3)`` each, with ``t1 × t2 = n`` for unit normals ``(n, 3)``."""
    helper = np.where(np.abs(normals[:, [0]]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t1 = normalize(np.cross(helper, normals))
    t2 = np.cross(normals, t1)
    return t1, t2


def principal_curvatures(points: np.ndarray, normals: np.ndarray, *, neighbours: int = 24,
                         radius: float | None = None, cloud: np.ndarray | None = None,
                         cloud_normals: np.ndarray | None = None, tree: cKDTree | None = None,
                         chunk: int = 20000) -> PrincipalCurvature:
    """Principal curvatures at ``points`` ``(n, 3)`` with unit ``normals`` ``(n, 3)``.

    Parameters
    ----------
    points, normals : (n, 3) float
        Where to evaluate, and the unit normal there (pointing to the tool side).
    neighbours : int
        Number of nearest cloud points used in each fit (at least 6).
    radius : float, optional
        If given (m), neighbours farther than this are ignored, so the fit scale is at most
        ``radius``; fits with fewer than 6 neighbours inside it use the 6 nearest anyway.
    cloud, cloud_normals : (N, 3) float, optional
        The points to fit to (default: ``points``/``normals`` themselves).  Neighbours whose
        normal points away from the centre's normal (the far side of a thin part) are ignored.
    tree : cKDTree, optional
        A KD-tree over ``cloud``, if the caller already has one.

    Returns
    -------
    PrincipalCurvature
    """
    cloud = points if cloud is None else cloud
    cloud_normals = normals if cloud_normals is None else cloud_normals
    tree = tree if tree is not None else cKDTree(cloud)
    k = int(min(max(neighbours, 6), len(cloud)))
    out = [np.empty(len(points)), np.empty(len(points)), np.empty((len(points), 3)), np.empty((len(points), 3))]
    for lo in range(0, len(points), chunk):
        hi = min(lo + chunk, len(points))
        res = _fit_chunk(points[lo:hi], normals[lo:hi], cloud, cloud_normals, tree, k, radius)
        for o, r in zip(out, res):
            o[lo:hi] = r
    return PrincipalCurvature(*out)


def _fit_chunk(p, n, cloud, cloud_normals, tree, k, radius):
    dist, idx = tree.query(p, k=k)
    t1, t2 = tangent_frames(n)
    rel = cloud[idx] - p[:, None, :]                      # (c, k, 3)
    x = np.einsum("ckj,cj->ck", rel, t1)
    y = np.einsum("ckj,cj->ck", rel, t2)
    h = np.einsum("ckj,cj->ck", rel, n)
    # Gaussian weights at the scale of the neighbourhood; far side of thin parts excluded.
    scale = dist[:, -1:] if radius is None else np.minimum(dist[:, -1:], radius)
    scale = np.maximum(scale, 1e-12)
    w = np.exp(-((dist / scale) ** 2))
    if radius is not None:
        w[:, 6:] *= dist[:, 6:] <= radius
    w *= np.einsum("ckj,cj->ck", cloud_normals[idx], n) > 0.0
    A = np.stack([x * x, x * y, y * y, x, y], axis=-1)     # (c, k, 5)
    Aw = A * w[..., None]
    M = np.einsum("cki,ckj->cij", Aw, A)
    rhs = np.einsum("cki,ck->ci", Aw, h)
    # Tiny ridge term keeps degenerate neighbourhoods (collinear points) solvable.
    M += np.eye(5) * (1e-12 * np.trace(M, axis1=1, axis2=2)[:, None, None] + 1e-300)
    a, b, c, d, e = np.linalg.solve(M, rhs[..., None])[..., 0].T
    # First and second fundamental forms of the graph (x, y, h(x, y)) at the origin.
    E, F, G = 1 + d * d, d * e, 1 + e * e
    W = np.sqrt(1 + d * d + e * e)
    L, Mf, N = 2 * a / W, b / W, 2 * c / W
    inv_det = 1.0 / (E * G - F * F)
    # Shape operator S = I^-1 II, sign flipped so convex-toward-tool is positive.
    S = -np.stack([
        np.stack([(G * L - F * Mf) * inv_det, (G * Mf - F * N) * inv_det], -1),
        np.stack([(E * Mf - F * L) * inv_det, (E * N - F * Mf) * inv_det], -1),
    ], -2)
    evals, evecs = np.linalg.eig(S)
    evals, evecs = evals.real, evecs.real
    order = np.argsort(-evals, axis=1)
    evals = np.take_along_axis(evals, order, 1)
    evecs = np.take_along_axis(evecs, order[:, None, :], 2)
    # Map parameter directions (du, dv) to 3D tangents (du, dv, d du + e dv) in the local frame.
    def to3d(v):
        du, dv = v[:, 0], v[:, 1]
        dh = d * du + e * dv
        return normalize(du[:, None] * t1 + dv[:, None] * t2 + dh[:, None] * n)
    d1 = to3d(evecs[:, :, 0])
    d2 = to3d(evecs[:, :, 1])
    return evals[:, 0], evals[:, 1], d1, d2
