"""Load part meshes (STL, PLY, OBJ) as a :class:`~swath.surface.Surface`, and save one as PLY.

Everything a mesh file can get wrong is caught here, at the edge, with a message that names the
problem and the fix: unreadable files, NaN coordinates, point clouds given as meshes, the wrong
unit, non-manifold edges, non-orientable pieces, stray pieces and closed solids.  What is
repaired (merged vertices, dropped faces, flipped windings) is logged on the ``swath.io`` logger.

The work is split by job: :mod:`~swath.io.mesh_read` reads the raw triangles,
:mod:`~swath.io.mesh_repair` cleans them (pure, vectorised functions on ``(vertices, faces)``
arrays), :mod:`~swath.io.mesh_pieces` winds, splits and cuts them, :mod:`~swath.io.checks` holds
the file and size checks; :func:`load_mesh` strings them together.
"""

from __future__ import annotations

import logging
import re
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..units import canonical_length_unit, length_unit_factor
from .atomic import atomic_file
from .checks import (  # noqa: F401 - re-exported: the public names of the mesh stage
    LARGE_PART,
    PREFERRED_SIZE,
    SIZE_LIMITS,
    SMALL_PART,
    SUGGESTED_UNITS,
    check_extent,
    check_file,
    likely_unit,
)
from .facing import facing_warning
from .mesh_pieces import SIDE_DOT, closed_components, cut_closed, orient_faces  # noqa: F401
from .mesh_read import read_mesh_file
from .mesh_repair import (  # noqa: F401
    degenerate_faces,
    duplicate_faces,
    edge_table,
    face_areas,
    face_normals,
    merge_vertices,
    nonmanifold_faces,
    remove_unreferenced,
)

log = logging.getLogger("swath.io")

#: Mesh file extensions load_mesh reads.
MESH_EXTENSIONS = (".stl", ".ply", ".obj")
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

    Steps: read (exactly: relative OBJ indices resolved, malformed text rows refused with their
    line number, positions in float64); refuse NaN/infinite coordinates and out-of-range faces;
    convert ``units`` to metres; merge duplicate vertices, drop degenerate and duplicate faces and
    unreferenced vertices; check the size; repair a few non-manifold edges (keep on each the two
    faces that continue the surface, drop what branches off, such as a fin); make the winding
    consistent; keep the largest piece; cut a closed solid down to the faces that look toward
    ``side``; orient the normals toward the tool.

    Parameters
    ----------
    path : str or Path
        The mesh file (``.stl``, ``.ply``, ``.obj``; case-insensitive).
    units : str
        The file's length unit: ``m``, ``mm``, ``cm``, ``in`` or a spelled-out name in any case
        (``"MM"``, ``"inches"``, ``"millimetres"``, ``"meter"``); coordinates are converted to m.
    side : str or (3,) float, optional
        The direction the tool comes FROM (see :func:`parse_side`), e.g. ``"+z"``.  Required for a
        closed solid (its faces with outward normal n·side > 0.2 are kept); for an open surface
        the normals of each piece are flipped to face it (area-weighted majority).  Without it
        the file's own orientation is kept: its vertex normals if it has them, else the
        area-weighted majority of its windings; a part that then faces down, away from a tool
        coming from +z, is logged as a warning naming the fix
        (:func:`swath.io.facing.facing_warning`).
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
    ext = check_file(path, MESH_EXTENSIONS, "mesh", others=" (or a STEP/IGES part: .step, .stp, .iges, .igs)")
    side_vec = None if side is None else parse_side(side)
    units = canonical_length_unit(units)
    factor = length_unit_factor(units)
    label = path.name

    v, f, face_file_normals = read_mesh_file(path, ext)
    bad = int((~np.isfinite(v)).any(axis=1).sum())
    if bad:
        raise InputError(f"{label}: {bad} of {len(v)} vertices have NaN or infinite coordinates; "
                         "repair or re-export the mesh")
    if len(v) == 0:
        raise InputError(f"{label} holds no vertices; check the file or re-export it")
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

    check_extent(np.ptp(v, axis=0).max() / factor, units, force_units, label)

    # --- non-manifold edges ---------------------------------------------------------------
    areas = face_areas(v, f)
    total = float(areas.sum())
    n_edges_tolerated = max(NONMANIFOLD_EDGES_TOLERATED, int(MAX_NONMANIFOLD_EDGE_FRACTION * 1.5 * len(f)))
    drop, n_bad_edges, n_edges = nonmanifold_faces(v, f, areas, max_edges=n_edges_tolerated)
    if n_bad_edges:
        frac_e = n_bad_edges / n_edges
        frac_a = float(areas[drop].sum()) / total
        if n_bad_edges > max(NONMANIFOLD_EDGES_TOLERATED, MAX_NONMANIFOLD_EDGE_FRACTION * n_edges):
            raise InputError(
                f"{label} is badly broken: {n_bad_edges} edges ({100 * frac_e:.1f}%) are shared by more than "
                f"two faces; repair the mesh (e.g. MeshLab 'Repair non manifold edges') and load it again")
        if frac_a > MAX_DROPPED_AREA_FRACTION:
            raise InputError(
                f"{label}: {n_bad_edges} edges are shared by more than two faces, and the faces branching off "
                f"the surface there carry {100 * frac_a:.1f}% of the area (more than "
                f"{100 * MAX_DROPPED_AREA_FRACTION:g}% would be dropped); repair the mesh (e.g. MeshLab "
                "'Repair non manifold edges') and load it again")
        log.warning("%s: %d edges are shared by more than two faces; kept on each the two faces that continue "
                    "the surface (least bend across the edge) and dropped %d faces branching off it, with the "
                    "sheets attached only through them (%.4g m², %.3g%% of the area)", label, n_bad_edges,
                    int(drop.sum()), float(areas[drop].sum()), 100 * frac_a)
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
        f, orig, areas, comp = cut_closed(v, f, orig, areas, comp, closed, side_vec, all_pieces, label)

    # --- orientation toward the tool --------------------------------------------------------
    fn = face_normals(v, f)
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
    facing = facing_warning(surface, side=side_vec)
    if facing is not None:
        log.warning("%s", facing)
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
