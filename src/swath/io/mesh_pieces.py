"""Winding, pieces and closed solids: consistent orientation per piece, closed pieces, cutting a solid."""

from __future__ import annotations

import logging

import numpy as np

from ..errors import InputError
from .mesh_repair import edge_table, face_normals

log = logging.getLogger("swath.io")
#: Faces of a closed solid kept for ``side`` d: those whose outward unit normal n has n·d > this.
SIDE_DOT = 0.2

def orient_faces(faces: np.ndarray, areas: np.ndarray):
    """Make the winding consistent within each edge-connected piece.

    Each piece is wound so that the faces keeping the file's winding carry the larger area.
    Works on the orientation double cover (face, ±): faces sharing an edge in opposite
    directions agree, in the same direction disagree; a piece is non-orientable when a face's
    two copies fall in one component.

    Parameters
    ----------
    faces : (m, 3) int
        Triangles; every edge on at most two faces.
    areas : (m,) float
        Face areas, m².

    Returns
    -------
    flip : (m,) bool
        Faces to reverse.
    piece : (m,) int
        Edge-connected piece of each face, 0..p-1.
    orientable : (p,) bool
        Whether each piece can be wound consistently (non-orientable pieces are not flipped).
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    m = len(faces)
    edge_of, counts, forward = edge_table(faces)
    half = np.flatnonzero(counts[edge_of] == 2)
    order = half[np.argsort(edge_of[half], kind="stable")]
    h1, h2 = order[0::2], order[1::2]
    fi, fj = h1 // 3, h2 // 3
    agree = forward[h1] != forward[h2]
    piece_graph = coo_matrix((np.ones(len(fi)), (fi, fj)), shape=(m, m))
    _, piece = connected_components(piece_graph, directed=False)
    # double cover: node i = (face i, as is), node i + m = (face i, flipped)
    rows = np.concatenate([fi, fi + m])
    cols = np.concatenate([np.where(agree, fj, fj + m), np.where(agree, fj + m, fj)])
    cover = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(2 * m, 2 * m))
    _, lab = connected_components(cover, directed=False)
    n_pieces = int(piece.max()) + 1
    bad_face = lab[:m] == lab[m:]
    orientable = np.bincount(piece, weights=bad_face, minlength=n_pieces) == 0
    root = np.full(n_pieces, m)
    np.minimum.at(root, piece, np.arange(m))
    flip = (lab[:m] != lab[root[piece]]) & orientable[piece]
    # keep the majority (by area) of the file's winding in each piece
    flipped_area = np.bincount(piece, weights=areas * flip, minlength=n_pieces)
    piece_area = np.bincount(piece, weights=areas, minlength=n_pieces)
    invert = (flipped_area > 0.5 * piece_area) & orientable
    flip ^= invert[piece]
    return flip, piece, orientable


def closed_components(faces: np.ndarray, piece: np.ndarray) -> np.ndarray:
    """Labels of the pieces that have no boundary edge (closed, watertight)."""
    edge_of, counts, _ = edge_table(faces)
    open_face = (counts[edge_of] == 1).reshape(-1, 3).any(axis=1)
    has_open = np.bincount(piece, weights=open_face, minlength=piece.max() + 1) > 0
    present = np.bincount(piece, minlength=piece.max() + 1) > 0
    return np.flatnonzero(present & ~has_open)



def cut_closed(v, f, orig, areas, comp, closed, side_vec, all_pieces, label):
    """Replace each closed piece by its faces whose outward normal looks toward ``side_vec``."""
    tri = v[f] - v[f].reshape(-1, 3).mean(axis=0)      # about the centroid, for precision
    signed = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])) / 6.0
    volume = np.bincount(comp, weights=signed, minlength=comp.max() + 1)
    is_closed = np.isin(comp, closed)
    inward = is_closed & (volume[comp] < 0)
    f = np.where(inward[:, None], f[:, ::-1], f)         # closed pieces: outward normals
    fn = face_normals(v, f)
    keep = ~is_closed | (fn @ side_vec > SIDE_DOT)
    if not keep[is_closed].any():
        raise InputError(f"{label} is a closed solid and none of its faces faces the side "
                         f"{np.round(side_vec, 3).tolist()}; pass another --side")
    f, orig, areas, comp = f[keep], orig[keep], areas[keep], comp[keep]
    # the kept faces of a closed piece may fall apart; split them into pieces again
    _, piece, _ = orient_faces(f, np.zeros(len(f)))
    piece_area = np.bincount(piece, weights=areas)
    from_closed = np.bincount(piece, weights=np.isin(comp, closed), minlength=len(piece_area)) > 0
    kept_area = float(piece_area[from_closed].sum())
    if not all_pieces and from_closed.sum() > 1:
        cand = np.flatnonzero(from_closed)
        best = cand[np.argmax(piece_area[cand])]
        log.warning("%s: the faces of the closed solid facing %s form %d pieces; kept the largest (%.4g of "
                    "%.4g m²)", label, np.round(side_vec, 3).tolist(), len(cand), piece_area[best], kept_area)
        keep = ~from_closed[piece] | (piece == best)
        f, orig, areas, piece = f[keep], orig[keep], areas[keep], piece[keep]
        kept_area = float(piece_area[best])
    log.info("%s is a closed solid: kept %.4g m² of faces whose outward normal faces %s (n·side > %g)",
             label, kept_area, np.round(side_vec, 3).tolist(), SIDE_DOT)
    return f, orig, areas, piece
