"""Load part meshes (STL, PLY, OBJ) as a :class:`~swath.surface.Surface`, and save one as PLY.

Everything a mesh file can get wrong is caught here, at the edge, with a message that names the
problem and the fix: unreadable files, NaN coordinates, point clouds given as meshes, the wrong
unit, non-manifold edges, non-orientable pieces, stray pieces and closed solids.  What is
repaired (merged vertices, dropped faces, flipped windings) is logged on the ``swath.io`` logger.

The cleaning steps are pure, vectorised functions on ``(vertices, faces)`` arrays; the loader
strings them together.
"""

from __future__ import annotations

import io
import logging
import re
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..units import length_unit_factor
from .atomic import atomic_file

log = logging.getLogger("swath.io")

#: Mesh file extensions load_mesh reads.
MESH_EXTENSIONS = (".stl", ".ply", ".obj")
#: Accepted part size (largest bounding-box extent) in metres, and the comfortable range.
SIZE_LIMITS = (0.005, 20.0)
PREFERRED_SIZE = (0.05, 3.0)
#: A part larger than this (m) is accepted with a warning that the file may not be in metres.
LARGE_PART = 5.0
#: A part smaller than this (m) is accepted with the same warning.
SMALL_PART = 0.02
#: Units suggested when the size is implausible, in order of preference.
SUGGESTED_UNITS = ("m", "mm", "in")
#: Faces of a closed solid kept for ``side`` d: those whose outward unit normal n has n·d > this.
SIDE_DOT = 0.2
#: Non-manifold repair limits: refuse when more than this many edges and this fraction of the
#: edges are non-manifold, or when the faces to drop carry more than this fraction of the area.
NONMANIFOLD_EDGES_TOLERATED = 20
MAX_NONMANIFOLD_EDGE_FRACTION = 0.01
MAX_DROPPED_AREA_FRACTION = 0.05
#: Vertices closer than this fraction of the part size are merged (about exact duplicates: float32
#: neighbours one ulp apart, 6e-8 of the size, stay apart so no boundary gets pinched).
MERGE_TOLERANCE = 1e-9

_AXES = {"x": 0, "y": 1, "z": 2}


# --------------------------------------------------------------------------------------------
# public API
# --------------------------------------------------------------------------------------------
def parse_side(text) -> np.ndarray:
    """The tool side as a unit vector ``(3,)``: the direction the tool comes FROM.

    Parameters
    ----------
    text : str or (3,) float
        ``"+z"``, ``"-x"``, ``"y"`` (an axis with optional sign), ``"0,0,1"`` / ``"0 0 1"`` (a
        vector, any length > 0), or a 3-sequence of numbers.

    Returns
    -------
    (3,) float
        Unit vector.

    Raises
    ------
    InputError
        If the text is neither a signed axis nor three finite numbers, or the vector is zero.
    """
    if isinstance(text, str):
        s = text.strip().lower().strip("[]()")
        m = re.fullmatch(r"\s*([+-]?)\s*([xyz])\s*", s)
        if m:
            v = np.zeros(3)
            v[_AXES[m.group(2)]] = -1.0 if m.group(1) == "-" else 1.0
            return v
        parts = [p for p in re.split(r"[,\s]+", s) if p]
        try:
            vec = np.array([float(p) for p in parts])
        except ValueError:
            vec = np.zeros(0)
    else:
        try:
            vec = np.asarray(text, dtype=float).ravel()
        except (TypeError, ValueError):
            vec = np.zeros(0)
    if vec.shape != (3,) or not np.isfinite(vec).all():
        raise InputError(f"expected a tool side such as '+z', '-x' or '0,0,1', got {text!r}")
    norm = float(np.linalg.norm(vec))
    if norm == 0.0:
        raise InputError(f"the tool side {text!r} is a zero vector; give a direction such as '+z'")
    return vec / norm


def load_mesh(path, *, units: str = "m", side=None, all_pieces: bool = False, force_units: bool = False,
              name: str | None = None):
    """Load an STL, PLY or OBJ part mesh as an open :class:`~swath.surface.Surface` in metres.

    Steps: read; refuse NaN/infinite coordinates; convert ``units`` to metres; merge duplicate
    vertices, drop degenerate and duplicate faces and unreferenced vertices; check the size;
    repair a few non-manifold edges; make the winding consistent; keep the largest piece; cut a
    closed solid down to the faces that look toward ``side``; orient the normals toward the tool.

    Parameters
    ----------
    path : str or Path
        The mesh file (``.stl``, ``.ply``, ``.obj``; case-insensitive).
    units : str
        The file's length unit (``m``, ``mm``, ``cm``, ``in``); coordinates are converted to m.
    side : str or (3,) float, optional
        The direction the tool comes FROM (see :func:`parse_side`), e.g. ``"+z"``.  Required for a
        closed solid (its faces with outward normal n·side > 0.2 are kept); for an open surface
        the normals of each piece are flipped to face it (area-weighted majority).  Without it
        the file's own orientation is kept: its vertex normals if it has them, else the
        area-weighted majority of its windings.
    all_pieces : bool
        Keep every connected piece instead of the largest by area.
    force_units : bool
        Accept a part whose largest extent is outside 5 mm .. 20 m.
    name : str, optional
        The surface's name; default the file stem.

    Returns
    -------
    Surface
        Vertices in metres, faces wound so that normals face the tool.

    Raises
    ------
    InputError
        For a missing, empty, unreadable or unsupported file; NaN/infinite coordinates; no faces
        or no area; an implausible size (naming the likely unit); a badly non-manifold or
        non-orientable mesh; a closed solid without ``side``.
    """
    from ..surface import Surface

    path = Path(path)
    ext = _check_file(path, MESH_EXTENSIONS, "mesh")
    side_vec = None if side is None else parse_side(side)
    factor = length_unit_factor(units)
    label = path.name

    v, f, face_file_normals = _read_mesh_file(path, ext)
    bad = int((~np.isfinite(v)).any(axis=1).sum())
    if bad:
        raise InputError(f"{label}: {bad} of {len(v)} vertices have NaN or infinite coordinates; "
                         "repair or re-export the mesh")
    if len(f) == 0:
        raise InputError(f"{label} has {len(v)} vertices but no faces: it is a point cloud, not a mesh; "
                         "use `swath fit` to fit a surface to it")
    if f.min() < 0 or f.max() >= len(v):
        raise InputError(f"{label}: face indices run {f.min()}..{f.max()} but there are {len(v)} vertices; "
                         "the file is corrupt, re-export it")
    v = v * factor

    # --- cleaning -------------------------------------------------------------------------
    n_raw_v, n_raw_f = len(v), len(f)
    used = np.unique(f)
    extent_m = float(np.ptp(v[used], axis=0).max()) if len(used) else 0.0
    v, f = merge_vertices(v, f, tolerance=MERGE_TOLERANCE * max(extent_m, 1e-300))
    orig = np.arange(len(f))                       # index of each face in the file
    keep = ~degenerate_faces(v, f, scale=extent_m)
    n_degenerate = int((~keep).sum())
    f, orig = f[keep], orig[keep]
    keep = ~duplicate_faces(f)
    n_duplicate = int((~keep).sum())
    f, orig = f[keep], orig[keep]
    if len(f) == 0:
        raise InputError(f"{label}: all {n_raw_f} faces are degenerate (zero area); it is not a surface — "
                         "re-export the mesh, or use `swath fit` if it is a point cloud")
    v, f = remove_unreferenced(v, f)
    log.info("%s: %d vertices, %d faces read; merged to %d vertices; dropped %d degenerate and %d "
             "duplicate faces", label, n_raw_v, n_raw_f, len(v), n_degenerate, n_duplicate)

    _check_extent(np.ptp(v, axis=0).max() / factor, units, force_units, label)

    # --- non-manifold edges ---------------------------------------------------------------
    areas = _face_areas(v, f)
    total = float(areas.sum())
    drop, n_bad_edges, n_edges = nonmanifold_faces(f, areas)
    if n_bad_edges:
        frac_e = n_bad_edges / n_edges
        frac_a = float(areas[drop].sum()) / total
        too_many = n_bad_edges > max(NONMANIFOLD_EDGES_TOLERATED, MAX_NONMANIFOLD_EDGE_FRACTION * n_edges)
        if too_many or frac_a > MAX_DROPPED_AREA_FRACTION:
            raise InputError(
                f"{label} is badly broken: {n_bad_edges} edges ({100 * frac_e:.1f}%) are shared by more than "
                f"two faces; repair the mesh (e.g. MeshLab 'Repair non manifold edges') and load it again")
        log.warning("%s: %d non-manifold edges (shared by more than two faces); dropped the %d smallest "
                    "faces on them (%.3g%% of the area)", label, n_bad_edges, int(drop.sum()), 100 * frac_a)
        f, orig, areas = f[~drop], orig[~drop], areas[~drop]

    # --- consistent winding, pieces ---------------------------------------------------------
    flip, comp, orientable = orient_faces(f, areas)
    if flip.any():
        log.info("%s: flipped %d faces to make the winding consistent", label, int(flip.sum()))
    f = np.where(flip[:, None], f[:, ::-1], f)
    n_comp = int(comp.max()) + 1
    comp_area = np.bincount(comp, weights=areas, minlength=n_comp)
    if not orientable.all():
        bad_area = float(comp_area[~orientable].sum())
        if bad_area > MAX_DROPPED_AREA_FRACTION * total:
            raise InputError(
                f"{label} is non-orientable (a piece of {bad_area:.4g} m² cannot be wound consistently, like "
                "a Möbius strip); repair the mesh (e.g. MeshLab 'Re-orient all faces coherently')")
        log.warning("%s: dropped %d non-orientable piece(s) of %.4g m² in all", label,
                    int((~orientable).sum()), bad_area)
        comp_area = np.where(orientable, comp_area, 0.0)
    pieces = np.flatnonzero(comp_area > 0)
    pieces = pieces[np.argsort(-comp_area[pieces], kind="stable")]
    if len(pieces) > 1 and not all_pieces:
        dropped = comp_area[pieces[1:]]
        log.warning("%s has %d pieces: kept the largest (%.4g m²), dropped %d (%.4g m² in all, largest "
                    "%.4g m²); pass all_pieces / --all-pieces to keep them all", label, len(pieces),
                    comp_area[pieces[0]], len(pieces) - 1, dropped.sum(), dropped.max())
        pieces = pieces[:1]
    keep = np.isin(comp, pieces)
    f, orig, areas, comp = f[keep], orig[keep], areas[keep], comp[keep]

    # --- closed solids: keep the faces that look toward the tool -----------------------------
    closed = closed_components(f, comp)
    if closed.size:
        if side_vec is None:
            raise InputError(f"{label} is a closed solid; swath finishes open surfaces: pass --side +z (or "
                             "side='+z', the direction the tool comes from) to keep the faces facing it")
        f, orig, areas, comp = _cut_closed(v, f, orig, areas, comp, closed, side_vec, all_pieces, label)

    # --- orientation toward the tool --------------------------------------------------------
    fn = _face_normals(v, f)
    pieces = np.unique(comp)
    if side_vec is not None:
        score = np.bincount(comp, weights=areas * np.sign(fn @ side_vec), minlength=comp.max() + 1)
        why = f"toward side {np.round(side_vec, 3).tolist()}"
    elif face_file_normals is not None:
        vote = np.sign(np.einsum("ij,ij->i", fn, face_file_normals[orig]))
        score = np.bincount(comp, weights=areas * vote, minlength=comp.max() + 1)
        agree = float(areas[vote * np.sign(score[comp]) > 0].sum() / areas.sum())
        why = f"to agree with the file's vertex normals (they agree on {100 * agree:.1f}% of the area)"
    else:
        score = np.zeros(comp.max() + 1)      # winding already follows the file's majority by area
        why = "as the file's majority winding (by area)"
    flip_piece = score < 0
    if flip_piece.any():
        f = np.where(flip_piece[comp][:, None], f[:, ::-1], f)
    log.info("%s: normals oriented %s (%d of %d pieces flipped)", label, why, int(flip_piece[pieces].sum()),
             len(pieces))

    v, f = remove_unreferenced(v, f)
    surface = Surface(v, f, name=path.stem if name is None else name)
    log.info("%s: loaded %d vertices, %d faces, area %.4g m², extents %s m", label, len(v), len(f),
             surface.area, np.round(np.ptp(v, axis=0), 4).tolist())
    return surface


def save_surface_ply(surface, path) -> None:
    """Write ``surface`` as a binary little-endian PLY with per-vertex normals, atomically.

    Vertices are stored as doubles (metres), normals (``surface.normals``, toward the tool) as
    floats, faces as triangles wound toward the tool.

    Parameters
    ----------
    surface : Surface
        The surface to write.
    path : str or Path
        Output file; written to a temporary sibling and renamed into place.
    """
    v = np.asarray(surface.vertices, dtype="<f8")
    n = np.asarray(surface.normals, dtype="<f4")
    f = np.asarray(surface.faces)
    vert = np.empty(len(v), dtype=[("x", "<f8"), ("y", "<f8"), ("z", "<f8"),
                                   ("nx", "<f4"), ("ny", "<f4"), ("nz", "<f4")])
    vert["x"], vert["y"], vert["z"] = v.T
    vert["nx"], vert["ny"], vert["nz"] = n.T
    face = np.empty(len(f), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    face["n"] = 3
    face["i"] = f
    name = re.sub(r"[\r\n]", " ", str(surface.name))
    header = ("ply\nformat binary_little_endian 1.0\n"
              f"comment swath surface {name}, metres, normals toward the tool\n"
              f"element vertex {len(v)}\n"
              "property double x\nproperty double y\nproperty double z\n"
              "property float nx\nproperty float ny\nproperty float nz\n"
              f"element face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n")
    with atomic_file(path, "wb") as fh:
        fh.write(header.encode("ascii"))
        fh.write(vert.tobytes())
        fh.write(face.tobytes())


# --------------------------------------------------------------------------------------------
# pure, vectorised cleaning steps
# --------------------------------------------------------------------------------------------
def merge_vertices(vertices: np.ndarray, faces: np.ndarray, *, tolerance: float = 0.0):
    """Merge vertices closer than ``tolerance``.

    Parameters
    ----------
    vertices : (n, 3) float
        Positions, m.
    faces : (m, 3) int
        Triangles.
    tolerance : float
        Merge distance, m (0 merges exact duplicates only).

    Returns
    -------
    vertices : (k, 3) float
        The merged vertices (the first of each group), k <= n.
    faces : (m, 3) int
        Faces re-indexed to them.
    """
    vertices = np.asarray(vertices, dtype=float)
    first, inverse = _group_rows(vertices)
    uniq = vertices[first]
    if tolerance > 0 and len(uniq) > 1:
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components
        from scipy.spatial import cKDTree

        pairs = cKDTree(uniq).query_pairs(tolerance, output_type="ndarray")
        if len(pairs):
            k = len(uniq)
            graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(k, k))
            _, lab = connected_components(graph, directed=False)
            # relabel groups by their first member so the order stays the file's
            first_of = np.full(lab.max() + 1, k)
            np.minimum.at(first_of, lab, np.arange(k))
            order = np.argsort(first_of, kind="stable")
            newlab = np.empty_like(order)
            newlab[order] = np.arange(len(order))
            uniq = uniq[first_of[order]]
            inverse = newlab[lab[inverse]]
    return uniq, inverse[np.asarray(faces)]


def degenerate_faces(vertices: np.ndarray, faces: np.ndarray, *, scale: float = 1.0) -> np.ndarray:
    """(m,) bool: faces with a repeated vertex or an area below ``1e-14 · scale²``."""
    f = np.asarray(faces)
    repeated = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 2] == f[:, 0])
    return repeated | (_face_areas(vertices, f) <= 1e-14 * scale**2)


def duplicate_faces(faces: np.ndarray) -> np.ndarray:
    """(m,) bool: faces using the same three vertices as an earlier face (either winding)."""
    first, _ = _group_rows(np.sort(np.asarray(faces), axis=1))
    dup = np.ones(len(faces), dtype=bool)
    dup[first] = False
    return dup


def remove_unreferenced(vertices: np.ndarray, faces: np.ndarray):
    """Drop vertices no face uses; returns ``(vertices (k, 3), faces (m, 3))`` re-indexed."""
    used, inverse = np.unique(np.asarray(faces), return_inverse=True)
    return np.asarray(vertices)[used], inverse.reshape(-1, 3)


def edge_table(faces: np.ndarray):
    """Undirected edges of a triangle mesh.

    Returns
    -------
    edge_of : (3m,) int
        Edge id of each half-edge ``(f0,f1), (f1,f2), (f2,f0)`` of each face, face-major.
    counts : (e,) int
        Number of faces on each edge.
    forward : (3m,) bool
        Whether the half-edge runs from the lower to the higher vertex index.
    """
    f = np.asarray(faces, dtype=np.int64)
    half = f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    lo, hi = np.minimum(half[:, 0], half[:, 1]), np.maximum(half[:, 0], half[:, 1])
    key = lo * (int(f.max()) + 1 if len(f) else 1) + hi
    _, edge_of, counts = np.unique(key, return_inverse=True, return_counts=True)
    return edge_of.ravel(), counts, half[:, 0] < half[:, 1]


def nonmanifold_faces(faces: np.ndarray, areas: np.ndarray):
    """Faces to drop so that no edge has more than two faces: all but the two largest on each.

    Parameters
    ----------
    faces : (m, 3) int
        Triangles.
    areas : (m,) float
        Face areas, m².

    Returns
    -------
    drop : (m,) bool
        Faces to drop.
    n_bad : int
        Number of non-manifold edges (more than two faces).
    n_edges : int
        Number of edges.
    """
    edge_of, counts, _ = edge_table(faces)
    drop = np.zeros(len(faces), dtype=bool)
    bad_half = np.flatnonzero(counts[edge_of] > 2)
    n_bad = int((counts > 2).sum())
    if n_bad:
        face_of = bad_half // 3
        order = np.lexsort((-areas[face_of], edge_of[bad_half]))
        e_sorted = edge_of[bad_half][order]
        start = np.r_[0, np.flatnonzero(np.diff(e_sorted)) + 1]
        group_start = np.repeat(start, np.diff(np.r_[start, len(e_sorted)]))
        rank = np.arange(len(e_sorted)) - group_start
        drop[face_of[order][rank >= 2]] = True
    return drop, n_bad, len(counts)


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


# --------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------
def _check_file(path: Path, extensions, what: str) -> str:
    ext = path.suffix.lower()
    if ext not in extensions:
        raise InputError(f"{path.name}: unsupported {what} file type {ext or '(no extension)'!r}; "
                         f"use one of {', '.join(extensions)}")
    if not path.exists():
        raise InputError(f"{path}: no such file; check the path")
    if not path.is_file():
        raise InputError(f"{path} is not a file; give the path of a {what} file")
    if path.stat().st_size == 0:
        raise InputError(f"{path.name} is empty (0 bytes); re-export the {what}")
    return ext


def _read_mesh_file(path: Path, ext: str):
    """Raw ``(vertices (n,3) float, faces (m,3) int, per-face file normals (m,3) or None)``."""
    from trimesh.exchange import obj, ply, stl

    data = path.read_bytes()
    if ext == ".stl":
        _sniff_stl(data, path.name)
    elif ext == ".ply" and not data.lstrip()[:3] == b"ply":
        raise InputError(f"{path.name} is not a PLY file (it does not start with 'ply'); check the file")
    elif ext == ".obj" and b"\x00" in data[:65536]:
        raise InputError(f"{path.name} holds binary data, not a text OBJ; check the file or re-export it")
    loader = {".stl": stl.load_stl, ".ply": ply.load_ply, ".obj": obj.load_obj}[ext]
    try:
        kw = loader(io.BytesIO(data))
    except Exception as exc:  # noqa: BLE001 - any parser failure is an unreadable file
        raise InputError(f"could not read {path.name} as {ext[1:].upper()}: {exc}; check the file or "
                         "re-export it") from None
    parts = list(kw["geometry"].values()) if isinstance(kw, dict) and "geometry" in kw else [kw]
    vs, fs, ns = [], [], []
    offset = 0
    for part in parts:
        if not isinstance(part, dict) or part.get("vertices") is None:
            continue
        vv = np.asarray(part["vertices"], dtype=float).reshape(-1, 3)
        ff = _triangulate(part.get("faces"), path.name)
        vn = part.get("vertex_normals")
        vn = None if vn is None else np.asarray(vn, dtype=float)
        if vn is not None and vn.shape != vv.shape:
            vn = None
        vs.append(vv)
        fs.append(ff + offset)
        ns.append(vn)
        offset += len(vv)
    if not vs:
        raise InputError(f"{path.name} holds no geometry; check the file or re-export it")
    v = np.concatenate(vs)
    f = np.concatenate(fs).astype(np.int64)
    face_normals = None
    if all(n is not None for n in ns) and len(f):
        vn = np.concatenate(ns)
        with np.errstate(invalid="ignore", divide="ignore"):
            vn = vn / np.linalg.norm(vn, axis=1, keepdims=True)
        vn = np.nan_to_num(vn, nan=0.0, posinf=0.0, neginf=0.0)
        if f.max() < len(vn) and f.min() >= 0:
            face_normals = vn[f].sum(axis=1)
            if not np.abs(face_normals).sum() > 0:
                face_normals = None
    return v, f, face_normals


def _triangulate(faces, label: str) -> np.ndarray:
    """Polygon faces (m,k) array or ragged list → (t, 3) int triangles (fan)."""
    if faces is None:
        return np.zeros((0, 3), dtype=np.int64)
    try:
        arr = np.asarray(faces, dtype=np.int64)
        rows = None if arr.ndim != 2 else arr
    except (ValueError, TypeError):
        rows = None
    if rows is not None:
        if rows.shape[1] < 3:
            return np.zeros((0, 3), dtype=np.int64)
        k = rows.shape[1]
        idx = np.stack([np.zeros(k - 2, int), np.arange(1, k - 1), np.arange(2, k)], axis=1)
        return rows[:, idx].reshape(-1, 3)
    polys = [np.asarray(p, dtype=np.int64).ravel() for p in faces]
    out = [p[np.stack([np.zeros(len(p) - 2, int), np.arange(1, len(p) - 1), np.arange(2, len(p))], 1)]
           for p in polys if len(p) >= 3]
    return np.concatenate(out) if out else np.zeros((0, 3), dtype=np.int64)


def _sniff_stl(data: bytes, label: str) -> None:
    if len(data) >= 84:
        n = int(np.frombuffer(data[80:84], dtype="<u4")[0])
        if 84 + 50 * n == len(data):
            return
    if data.lstrip()[:5].lower() == b"solid" and b"\x00" not in data[:4096]:
        return
    raise InputError(f"{label} is not an STL file (neither binary, whose size matches its triangle count, "
                     "nor ASCII starting with 'solid'); check the file or re-export it")


def _check_extent(extent_file_units: float, units: str, force_units: bool, label: str) -> None:
    """Refuse or warn about an implausible part size (largest extent in the file's unit)."""
    size = float(extent_file_units) * length_unit_factor(units)
    lo, hi = SIZE_LIMITS
    guess = likely_unit(extent_file_units, exclude=units)
    hint = ""
    if guess is not None:
        hint = f"; in {guess} it would be {extent_file_units * length_unit_factor(guess):.3g} m"
    if not lo <= size <= hi:
        if force_units:
            log.warning("%s: part is %.4g m across read in %s (outside %g mm .. %g m); accepted because "
                        "units were forced%s", label, size, units, lo * 1e3, hi, hint)
            return
        fix = (f"it is probably in {guess} ({extent_file_units * length_unit_factor(guess):.3g} m): pass "
               f"--units {guess}, or --force-units to keep {units}" if guess is not None else
               f"no unit among {', '.join(SUGGESTED_UNITS)} gives a plausible size: check the file, or pass "
               f"--force-units to keep {units}")
        raise InputError(f"{label}: part is {size:.4g} m across when read in {units}, outside "
                         f"{lo * 1e3:g} mm .. {hi:g} m; {fix}")
    if size > LARGE_PART or size < SMALL_PART:
        log.warning("%s: part is %.4g m across read in %s; the file may not be in %s%s%s", label, size, units,
                    "metres" if units == "m" else units, hint,
                    f" (pass --units {guess})" if guess is not None else "")


def likely_unit(extent_file_units: float, *, exclude: str | None = None) -> str | None:
    """The unit among m, mm, in that makes a part of this extent (file units) 5 mm .. 20 m across,
    preferring 0.05 .. 3 m; None when no unit does."""
    sizes = {u: extent_file_units * length_unit_factor(u) for u in SUGGESTED_UNITS if u != exclude}
    ok = [u for u, s in sizes.items() if SIZE_LIMITS[0] <= s <= SIZE_LIMITS[1]]
    good = [u for u in ok if PREFERRED_SIZE[0] <= sizes[u] <= PREFERRED_SIZE[1]]
    return (good or ok or [None])[0]


def _group_rows(a: np.ndarray):
    """Group equal rows of ``a`` (k, d).

    Returns ``first`` (g,) the index of each group's first row, groups in order of first
    appearance, and ``inverse`` (k,) the group of each row (``a[first][inverse] == a``).
    """
    a = np.asarray(a)
    if len(a) == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    order = np.lexsort(a.T[::-1])                  # stable: a group's first member comes first
    sa = a[order]
    new = np.r_[True, (sa[1:] != sa[:-1]).any(axis=1)]
    first = order[new]
    rank = np.argsort(first, kind="stable")
    group_of_sorted = np.cumsum(new) - 1
    relabel = np.empty_like(rank)
    relabel[rank] = np.arange(len(rank))
    inverse = np.empty(len(a), dtype=np.int64)
    inverse[order] = relabel[group_of_sorted]
    return first[rank], inverse


def _face_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    tri = np.asarray(vertices)[np.asarray(faces)]
    return 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)


def _face_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    tri = np.asarray(vertices)[np.asarray(faces)]
    c = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    return c / np.maximum(np.linalg.norm(c, axis=1, keepdims=True), 1e-300)


def _cut_closed(v, f, orig, areas, comp, closed, side_vec, all_pieces, label):
    """Replace each closed piece by its faces whose outward normal looks toward ``side_vec``."""
    tri = v[f] - v[f].reshape(-1, 3).mean(axis=0)      # about the centroid, for precision
    signed = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])) / 6.0
    volume = np.bincount(comp, weights=signed, minlength=comp.max() + 1)
    is_closed = np.isin(comp, closed)
    inward = is_closed & (volume[comp] < 0)
    f = np.where(inward[:, None], f[:, ::-1], f)         # closed pieces: outward normals
    fn = _face_normals(v, f)
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
