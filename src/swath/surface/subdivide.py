"""Conforming subdivision that splits only the edges longer than a limit.

:func:`split_long_edges` refines a triangle mesh until no edge is longer than ``max_edge``.  Each
round marks the edges longer than ``max_edge`` of the faces that still have one, closes the marks
so that every face with a marked edge has its longest edge marked too (longest-edge bisection,
Rivara: the angles stay bounded below by the input's), puts one new vertex on every marked edge
(shared by both faces of the edge, so the mesh stays conforming) and bisects each marked face
through its longest edge, each half again through its other marked edge if it has one (2, 3 or 4
triangles, winding kept).

The new vertex is not the midpoint: an edge that needs ``n = ceil(length / max_edge)`` pieces is cut
at ``(n // 2) / n`` of its length, so that in the end it is cut into ``n`` equal pieces just under
``max_edge`` instead of ``2^k`` pieces down to half of it.  Only long edges are split, so a face
whose edges are all short is final and each round works on the faces still active.

Against the uniform 1-to-4 split (``trimesh.remesh.subdivide_to_size``) this gives 10-30 % fewer
vertices on the CAD meshes measured (crs_part_5: 1.78 against 2.44 times
``area / (0.433 max_edge²)`` at 2 mm, in 6.5 s against 17 s; on a fine grid it can give a few
per cent more); bisection keeps the shape of a sliver, so meshes of slivers narrower
than ``max_edge`` still get several times the vertices their area needs (a re-triangulation, not
a subdivision, would be needed there).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError

#: Rounds after which the refinement gives up (each round cuts every long edge it splits in two).
MAX_ROUNDS = 64


def split_long_edges(vertices, faces, max_edge: float) -> tuple[np.ndarray, np.ndarray]:
    """Split the edges longer than ``max_edge`` until none is left (longest-edge bisection).

    Parameters
    ----------
    vertices : (n, 3) float
        Vertex positions, m.
    faces : (m, 3) int
        Triangles as vertex indices; the winding of every new triangle is that of its parent.
    max_edge : float
        Longest edge allowed in the result, m (> 0).

    Returns
    -------
    vertices : (n + k, 3) float
        The input vertices (unchanged, same order) followed by the ``k`` points added on edges, m.
    faces : (p, 3) int64
        The triangles; faces that needed no split come first, in their input order.

    Raises
    ------
    InputError
        When ``max_edge`` is not a positive finite length, or the mesh still has long edges after
        :data:`MAX_ROUNDS` rounds (non-finite or enormous coordinates).
    """
    max_edge = float(max_edge)
    if not (np.isfinite(max_edge) and max_edge > 0):
        raise InputError(f"max_edge must be a positive length in m, got {max_edge!r}")
    xyz = np.asarray(vertices, dtype=float)
    n_points = len(xyz)
    active = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    done = []
    limit2 = max_edge * max_edge
    for round_ in range(MAX_ROUNDS + 1):
        # edge k of a face runs from corner k to corner k + 1 (``following``)
        following = np.concatenate([active[:, 1:], active[:, :1]], axis=1)
        corners = np.take(xyz, active.ravel(), axis=0).reshape(-1, 3, 3)
        d = np.concatenate([corners[:, 1:], corners[:, :1]], axis=1) - corners
        length2 = np.einsum("fkc,fkc->fk", d, d)
        long_edge = length2 > limit2
        # a face with no long edge is final: only long edges are ever split (a longest edge of a
        # face with a long edge is long itself)
        final = ~long_edge.any(axis=1)
        if final.any():
            done.append(active[final])
            keep = ~final
            active, following, long_edge, length2 = active[keep], following[keep], long_edge[keep], length2[keep]
        if len(active) == 0:
            break
        if round_ == MAX_ROUNDS:
            raise InputError(f"subdivision to {max_edge * 1e3:.3g} mm still had {len(active)} faces with long "
                             f"edges after {MAX_ROUNDS} rounds; check the mesh for huge or non-finite "
                             "coordinates, or use a larger max_edge")
        # unique (undirected) edges of the active faces
        lo = np.minimum(active, following).ravel()
        hi = np.maximum(active, following).ravel()
        unique_keys, edge_of = np.unique(lo * np.int64(n_points) + hi, return_inverse=True)
        edge_of = edge_of.reshape(-1, 3)
        # longest-edge closure: a face with any split edge has its longest edge split too, so every
        # face is bisected through its longest edge first (bounded angles, no slivers cascading)
        longest = np.argmax(length2, axis=1)
        longest_edge = edge_of[np.arange(len(active)), longest]
        marked = np.zeros(len(unique_keys), dtype=bool)
        marked[edge_of[long_edge]] = True
        while True:
            face_marked = marked[edge_of].any(axis=1)
            missing = face_marked & ~marked[longest_edge]
            if not missing.any():
                break
            marked[longest_edge[missing]] = True
        u_lo, u_hi = unique_keys[marked] // n_points, unique_keys[marked] % n_points
        new_index = np.full(len(unique_keys), -1, dtype=np.int64)
        new_index[marked] = n_points + np.arange(int(marked.sum()))
        # split at k/n of the way from the lower-numbered end, n = ceil(length / max_edge) pieces
        # in the end, k = n // 2: the two parts need k and n - k pieces, so an edge is finally cut
        # into n equal pieces (each at most max_edge, not down to half of it as halving would)
        length = np.linalg.norm(xyz[u_hi] - xyz[u_lo], axis=1)
        pieces = np.maximum(np.ceil(length / max_edge * (1.0 - 1e-12)), 2.0)
        fraction = (pieces // 2) / pieces
        new_xyz = xyz[u_lo] + fraction[:, None] * (xyz[u_hi] - xyz[u_lo])
        xyz = np.concatenate([xyz, new_xyz])
        n_points = len(xyz)
        mid = new_index[edge_of]
        split = face_marked
        done.append(active[~split])
        active = _bisect_faces(active[split], mid[split], longest[split])
    out_faces = np.concatenate(done) if done else np.zeros((0, 3), dtype=np.int64)
    return xyz, out_faces


def _rotated(faces: np.ndarray, mid: np.ndarray, shift: np.ndarray):
    """Corners and edge midpoints of each face, rotated left by ``shift`` (0..2) positions."""
    k = (np.arange(3)[None, :] + shift[:, None]) % 3
    rows = np.arange(len(faces))[:, None]
    return faces[rows, k], mid[rows, k]


def _bisect_faces(faces, mid, longest) -> np.ndarray:
    """The triangles replacing ``faces`` given their edge midpoints ``mid`` (-1 = edge not split;
    the longest edge, ``longest``, is always split): rotated so the longest edge is edge 0 (a -> b,
    point m0), the face is bisected by m0 -> c and each half split again at its own split edge
    (m1 on b -> c, m2 on c -> a)."""
    corner, point = _rotated(faces, mid, longest)
    a, b, c = corner[:, 0], corner[:, 1], corner[:, 2]
    m0, m1, m2 = point[:, 0], point[:, 1], point[:, 2]
    out = []
    # the half (m0, b, c): whole, or (m0, b, m1) + (m0, m1, c)
    right = m1 >= 0
    out += [np.stack([m0, b, c], 1)[~right], np.stack([m0, b, m1], 1)[right], np.stack([m0, m1, c], 1)[right]]
    # the half (a, m0, c): whole, or (a, m0, m2) + (m2, m0, c)
    left = m2 >= 0
    out += [np.stack([a, m0, c], 1)[~left], np.stack([a, m0, m2], 1)[left], np.stack([m2, m0, c], 1)[left]]
    return np.concatenate(out)
