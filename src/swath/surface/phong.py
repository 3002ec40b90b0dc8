"""A smooth surface through a mesh's vertices: Phong tessellation of a subdivided copy.

A coarse CAD tessellation is a set of flat facets whose corners lie on the designed surface.  To
ask what the facets themselves cost (the pressure a pad puts on their kinks), the same vertices are
given a smooth surface: every point ``p`` of a facet, with barycentric coordinates ``b`` on its
corners ``v_i`` (unit normals ``n_i``), moves to

    ``p' = (1 − α) p + α Σ_i b_i π_i(p)``,  ``π_i(p) = p − ((p − v_i) · n_i) n_i``

(Boubekeur and Alexa's Phong tessellation: ``p`` projected on each corner's tangent plane, the
projections blended).  The corners stay where they are; along an edge only its two corners count,
so neighbouring facets meet.  With ``α = 1/2`` an edge of length ``L`` on a circle of radius ``r``
(normals radial) bulges by ``L² / (8 r)`` at its middle, the circle's own sagitta: the facets'
chord error is taken back to second order.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .geometry import normalize
from .surface import Surface


def angle_weighted_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(n, 3) unit vertex normals, each face's normal weighted by its angle at the vertex.

    Unlike area weighting, a fan of slivers round a vertex does not outweigh one wide facet.
    """
    v = np.asarray(vertices, float)
    f = np.asarray(faces, np.int64)
    fn = normalize(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]))
    out = np.zeros_like(v)
    for c in range(3):
        a = v[f[:, (c + 1) % 3]] - v[f[:, c]]
        b = v[f[:, (c + 2) % 3]] - v[f[:, c]]
        cos = np.einsum("ij,ij->i", a, b) / np.maximum(np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1), 1e-300)
        ang = np.arccos(np.clip(cos, -1.0, 1.0))
        np.add.at(out, f[:, c], fn * ang[:, None])
    return normalize(out)


def phong_smoothed(surface: Surface, max_edge: float, *, alpha: float = 0.5) -> Surface:
    """The mesh subdivided to edges of at most ``max_edge`` with its new vertices on the Phong patches.

    Parameters
    ----------
    surface : Surface
        The facets (their vertices lie on the designed surface).
    max_edge : float
        Longest edge of the subdivided copy, m.
    alpha : float
        Blend of the tangent-plane projections, 0 (the flat facets) .. 1; 1/2 restores a circle's
        sagitta (module notes).

    Returns
    -------
    Surface
        The subdivided copy: the original vertices first and unmoved, the new ones on the smooth
        patch of the facet they were made on.
    """
    if not (np.isfinite(max_edge) and max_edge > 0):
        raise InputError(f"max_edge must be a positive length in m, got {max_edge!r}")
    if not (0.0 <= alpha <= 1.0):
        raise InputError(f"alpha must lie in 0..1, got {alpha!r}")
    fine = surface.subdivided(max_edge)
    n0 = len(surface.vertices)
    new = fine.vertices[n0:]
    if len(new) == 0:
        return fine
    V, F = surface.vertices, surface.faces
    normals = angle_weighted_normals(V, F)
    # orient the corner normals like the surface's (toward the tool)
    flip = np.einsum("ij,ij->i", normals, surface.vertex_normals) < 0
    normals[flip] *= -1.0
    _, _, face = surface.closest_points(new)
    tri = V[F[face]]                                              # (k, 3, 3)
    e1, e2, d = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], new - tri[:, 0]
    d11, d12, d22 = (np.einsum("ij,ij->i", e1, e1), np.einsum("ij,ij->i", e1, e2), np.einsum("ij,ij->i", e2, e2))
    d1, d2 = np.einsum("ij,ij->i", d, e1), np.einsum("ij,ij->i", d, e2)
    den = np.maximum(d11 * d22 - d12**2, 1e-300)
    b1 = (d22 * d1 - d12 * d2) / den
    b2 = (d11 * d2 - d12 * d1) / den
    bary = np.clip(np.stack([1.0 - b1 - b2, b1, b2], axis=1), 0.0, 1.0)
    bary /= bary.sum(axis=1, keepdims=True)
    # a point on an edge: the third corner's weight is exactly zero, so neighbouring facets agree
    bary[bary < 1e-9] = 0.0
    bary /= bary.sum(axis=1, keepdims=True)
    nrm = normals[F[face]]                                        # (k, 3, 3)
    off = np.einsum("kij,kij->ki", new[:, None, :] - tri, nrm)    # (p − v_i) · n_i
    proj = new[:, None, :] - off[:, :, None] * nrm                # π_i(p)
    blended = np.einsum("ki,kij->kj", bary, proj)
    moved = (1.0 - alpha) * new + alpha * blended
    vertices = np.concatenate([V, moved])
    return Surface(vertices, fine.faces, name=surface.name, normal_smoothing=surface.normal_smoothing,
                   curvature_neighbours=surface.curvature_neighbours)
