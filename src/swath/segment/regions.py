"""Regions drawn on the part: a polygon projected along a direction, and a mask mesh.

Both are terms of a selection text (:func:`swath.segment.select.parse_selection`), so they work for
``--faces`` and ``--keep-out`` alike and become the same per-triangle masks as face ids and boxes:

- ``polygon:PATH`` or ``polygon:x,y x,y x,y ...`` -- a closed polyline in the part frame, projected
  along a direction (default ``+z``, the part frame's up axis).  The triangles whose centroid
  projects inside it are taken, on every layer of the part the prism crosses.  Points have two
  coordinates (the two axes other than the projection axis, in x, y, z order: ``(x, y)`` along z,
  ``(x, z)`` along y, ``(y, z)`` along x) or three (projected along the direction, any direction).
  A file (``.csv`` / ``.txt``) holds one point a line, coordinates separated by commas or blanks;
  ``#`` starts a comment, and a first line that is no point (a header) is skipped.
- ``mask:PATH`` -- a mesh file (STL, PLY, OBJ) in the part frame: the part's triangles whose
  centroid lies within a distance of the mask's surface (``within``, default 1 mm), or inside the
  mask when it is closed.

Options go in brackets before the colon: ``polygon[along=-y,units=mm]:window.csv``,
``mask[within=3mm,units=mm]:area.stl``.  ``units`` is the unit of bare numbers in a polygon and of
a mask mesh's coordinates (default: the job's ``units`` for a mask, metres for a polygon); a
polygon's numbers may also carry their own unit (``120mm``).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.part import Part
from ..units import length_unit_factor, parse_quantity

#: A region term: ``kind[options]:body``.
REGION_TERM = re.compile(r"^\s*(polygon|mask)\s*(?:\[([^\]]*)\])?\s*:(.*)$", re.IGNORECASE | re.DOTALL)

#: Default distance (m) of a part triangle's centroid from an open mask's surface to be taken.
DEFAULT_MASK_WITHIN = 1e-3

#: Polygon files are read from these extensions.
POLYGON_EXTENSIONS = (".csv", ".txt")

_OPTIONS = {"polygon": ("along", "units"), "mask": ("within", "units")}


def is_region_term(term: str) -> bool:
    """Whether a selection term is a ``polygon:`` or ``mask:`` region."""
    return REGION_TERM.match(term) is not None


def region_mask(part: Part, term: str, *, what: str = "--faces", units: str = "m",
                base_dir: Path | None = None) -> np.ndarray:
    """The ``(m,) bool`` triangles of ``part`` a ``polygon:`` or ``mask:`` term takes.

    Parameters
    ----------
    part : Part
    term : str
        The term, e.g. ``"polygon[along=+z]:regions/window.csv"``.
    what : str
        The option's name, for messages.
    units : str
        The unit of a mask mesh's coordinates when the term states none (the job's ``units``).
    base_dir : Path, optional
        Relative paths are taken from here (a job file's folder; default the working directory).

    Raises
    ------
    InputError
        For an unreadable file, a polygon with fewer than three points, crossing itself or of no
        area, an unknown option, or a region that takes no triangle of the part.
    """
    m = REGION_TERM.match(term)
    if m is None:
        raise InputError(f"{what}: {term!r} is no region; write polygon:FILE, polygon:x,y x,y x,y or mask:FILE")
    kind, body = m.group(1).lower(), m.group(3).strip()
    options = _options(kind, m.group(2) or "", what)
    if kind == "polygon":
        along = _direction(options.get("along", "+z"), what)
        points = polygon_points(body, what=what, units=options.get("units", "m"), base_dir=base_dir)
        mask = polygon_mask(part, points, along, what=what)
        described = f"polygon {body!r}"
    else:
        within = _length(options.get("within"), what, "within") if "within" in options else DEFAULT_MASK_WITHIN
        vertices, faces = read_mask_mesh(_path(body, base_dir), what=what, units=options.get("units", units))
        mask = mesh_mask(part, vertices, faces, within=within)
        described = f"mask {body!r}"
    if not mask.any():
        raise InputError(f"{what}: the {described} takes no triangle of the part (none has its centre inside); "
                         "check that it is drawn in the part frame, in the part's units, over the part")
    return mask


def _options(kind: str, text: str, what: str) -> dict[str, str]:
    options: dict[str, str] = {}
    for item in (i.strip() for i in re.split(r",\s*(?=[A-Za-z_]+\s*=)", text)):
        if not item:
            continue
        key, eq, value = item.partition("=")
        key = key.strip().lower()
        if not eq or key not in _OPTIONS[kind]:
            raise InputError(f"{what}: unknown {kind} option {item!r}; a {kind} takes "
                             f"{', '.join(k + '=...' for k in _OPTIONS[kind])}")
        options[key] = value.strip()
    if "units" in options:
        try:
            length_unit_factor(options["units"])
        except InputError as exc:
            raise InputError(f"{what}: {exc}") from None
    return options


def _direction(text: str, what: str) -> np.ndarray:
    from ..io.mesh import parse_side

    try:
        return parse_side(text)
    except InputError as exc:
        raise InputError(f"{what}: a polygon's 'along' is a direction such as +z or 0,0,1: {exc}") from None


def _length(text, what: str, name: str, units: str = "m") -> float:
    text = str(text).strip()
    try:
        value = float(text) * length_unit_factor(units)
    except ValueError:
        try:
            value = parse_quantity(text, "length")
        except InputError as exc:
            raise InputError(f"{what}: {name} {text!r} is no length: {exc}") from None
    if not np.isfinite(value):
        raise InputError(f"{what}: {name} must be a finite length, got {text!r}")
    if name == "within" and value <= 0:
        raise InputError(f"{what}: a mask's within must be a length > 0, got {text!r}")
    return value


def _path(text: str, base_dir: Path | None) -> Path:
    path = Path(text).expanduser()
    if base_dir is not None and not path.is_absolute():
        path = Path(base_dir) / path
    return path


def polygon_points(body: str, *, what: str = "--faces", units: str = "m", base_dir: Path | None = None) -> np.ndarray:
    """The points ``(k, 2)`` or ``(k, 3)`` float (m) of a polygon given inline or as a file.

    ``body`` is a file name ending in ``.csv`` / ``.txt`` or inline points ``"x,y x,y ..."``
    (points separated by blanks, coordinates by commas).  Bare numbers are in ``units``.
    """
    body = body.strip()
    if Path(body).suffix.lower() in POLYGON_EXTENSIONS:
        path = _path(body, base_dir)
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise InputError(f"{what}: cannot read the polygon file {path}: {exc.__class__.__name__}: "
                             f"{getattr(exc, 'strerror', None) or exc}; give a .csv of x,y points") from None
        lines = [line.split("#", 1)[0].strip() for line in text.splitlines()]
        rows = [re.split(r"[,\s;]+", line) for line in lines if line]
        if rows and not _is_point(rows[0]):
            rows = rows[1:]                      # a header
        source = f"polygon file {path.name}"
    else:
        rows = [t.split(",") for t in body.split()]
        source = "polygon"
    if not rows:
        raise InputError(f"{what}: the {source} has no points; give at least three x,y points")
    widths = {len(r) for r in rows}
    if len(widths) != 1 or widths.pop() not in (2, 3):
        raise InputError(f"{what}: every point of the {source} needs 2 (x,y) or 3 (x,y,z) coordinates, "
                         f"got rows of {sorted({len(r) for r in rows})}")
    return np.array([[_length(c, what, f"{source} coordinate", units) for c in r] for r in rows])


def _is_point(row: list[str]) -> bool:
    try:
        [parse_quantity(c, "length") for c in row]
    except (InputError, ValueError):
        return False
    return True


def _plane_axes(along: np.ndarray) -> np.ndarray:
    """(2, 3) unit axes of the projection plane: the two other coordinate axes for an axis
    direction, else an orthonormal pair."""
    axis = int(np.argmax(np.abs(along)))
    if np.isclose(abs(along[axis]), 1.0):
        return np.eye(3)[[i for i in range(3) if i != axis]]
    a = np.cross(along, np.eye(3)[int(np.argmin(np.abs(along)))])
    a /= np.linalg.norm(a)
    return np.array([a, np.cross(along, a)])


def polygon_mask(part: Part, points, along=(0.0, 0.0, 1.0), *, what: str = "--faces") -> np.ndarray:
    """(m,) bool: the triangles of ``part`` whose centroid projects, along ``along``, inside the polygon.

    Parameters
    ----------
    part : Part
    points : (k, 2) or (k, 3) float
        The closed polyline in the part frame, m (the last point may repeat the first).  Two
        coordinates are the axes other than ``along`` (which must then be a coordinate axis).
    along : (3,) float
        Projection direction in the part frame.

    Raises
    ------
    InputError
        Fewer than three distinct points, a polygon crossing itself or of no area, or two
        coordinates with a slanted direction.
    """
    import shapely

    along = np.asarray(along, float) / np.linalg.norm(along)
    axes = _plane_axes(along)
    pts = np.asarray(points, float)
    if pts.ndim != 2 or pts.shape[1] not in (2, 3) or not np.isfinite(pts).all():
        raise InputError(f"{what}: a polygon is (k, 2) or (k, 3) finite points, got shape {pts.shape}")
    if pts.shape[1] == 3:
        pts = pts @ axes.T
    elif not np.isclose(np.abs(along).max(), 1.0):
        raise InputError(f"{what}: a polygon projected along a slanted direction needs x,y,z points")
    if len(pts) > 1 and np.allclose(pts[0], pts[-1]):
        pts = pts[:-1]
    distinct = np.unique(pts, axis=0)
    if len(distinct) < 3:
        raise InputError(f"{what}: a polygon needs at least 3 distinct points, got {len(distinct)}")
    spread = np.linalg.svd(pts - pts.mean(axis=0), compute_uv=False)
    if spread[1] <= 1e-9 * spread[0]:
        raise InputError(f"{what}: the polygon has no area (its points lie on a line)")
    ring = shapely.LinearRing(pts)
    if not ring.is_simple:
        raise InputError(f"{what}: the polygon crosses itself ({shapely.is_valid_reason(shapely.Polygon(pts))}); "
                         "list its corners in order around it, once each")
    polygon = shapely.Polygon(ring)
    centroid = part.surface.vertices[part.surface.faces].mean(axis=1) @ axes.T
    return np.asarray(shapely.contains_xy(polygon, centroid[:, 0], centroid[:, 1]) |
                      shapely.intersects_xy(polygon.boundary, centroid[:, 0], centroid[:, 1]), bool)


def read_mask_mesh(path: Path, *, what: str = "--faces", units: str = "m") -> tuple[np.ndarray, np.ndarray]:
    """A mask mesh's ``(n, 3)`` vertices (m) and ``(k, 3)`` triangles, refusing an unreadable file."""
    from ..io.checks import check_file
    from ..io.mesh import MESH_EXTENSIONS
    from ..io.mesh_read import read_mesh_file

    path = Path(path)
    try:
        ext = check_file(path, MESH_EXTENSIONS, f"{what} mask mesh")
        vertices, faces, _ = read_mesh_file(path, ext)
    except InputError as exc:
        raise InputError(f"{what}: {exc}") from None
    except (OSError, ValueError) as exc:
        raise InputError(f"{what}: cannot read the mask mesh {path.name}: {exc}; give an STL, PLY or OBJ") from None
    vertices = np.asarray(vertices, float) * length_unit_factor(units)
    faces = np.asarray(faces, np.int64)
    if len(faces) == 0 or not np.isfinite(vertices).all():
        raise InputError(f"{what}: the mask mesh {path.name} has no triangles (or non-finite points)")
    return vertices, faces


def mesh_mask(part: Part, vertices, faces, *, within: float = DEFAULT_MASK_WITHIN) -> np.ndarray:
    """(m,) bool: triangles of ``part`` whose centroid lies within ``within`` (m) of the mask mesh's
    surface, or inside the mask when it is closed (generalised winding number > 1/2; libigl's fast
    approximation when the mask's triangles times the part's exceed 2e8).

    Parameters
    ----------
    part : Part
    vertices : (n, 3) float
        The mask's vertices in the part frame, m.
    faces : (k, 3) int
        The mask's triangles.
    within : float
        Largest distance (m) from the mask's surface.
    """
    from ..io.mesh_repair import merge_vertices
    from ..surface import Surface

    vertices = np.asarray(vertices, float)
    extent = float(np.ptp(vertices, axis=0).max()) or 1.0
    vertices, faces = merge_vertices(vertices, np.asarray(faces, np.int64), tolerance=1e-9 * extent)
    centroid = part.surface.vertices[part.surface.faces].mean(axis=1)
    mask_surface = Surface(vertices, faces, name="mask")
    _, distance, _ = mask_surface.closest_points(centroid)
    taken = distance <= within
    if not mask_surface.boundary_loops:
        import igl

        V, F, Q = (np.ascontiguousarray(vertices), np.ascontiguousarray(faces, dtype=np.int64),
                   np.ascontiguousarray(centroid))
        # exact for small masks; the hierarchical approximation (errors only very near the mask's
        # surface, where the distance rule decides anyway) for large ones
        winding = igl.winding_number(V, F, Q) if len(F) * len(Q) <= 2e8 else igl.fast_winding_number(V, F, Q)
        taken |= np.abs(np.asarray(winding)) > 0.5
    return taken


def selection_text_from_table(value, key: str) -> str:
    """A job file's region given as a table (or a list of terms and tables) as a selection text.

    ``{polygon = [[0, 0], ["100mm", 0], ["100mm", "50mm"]], along = "+z", units = "mm"}`` becomes
    ``"polygon[along=+z,units=mm]:0,0 100mm,0 100mm,50mm"``; a string is kept as it is; a list joins its
    items with ``;``.
    """
    if isinstance(value, str):
        return value
    if isinstance(value, list) and all(isinstance(v, (str, dict)) for v in value):
        return "; ".join(selection_text_from_table(v, key) for v in value)
    if not isinstance(value, dict):
        raise InputError(f"{key} is a selection text, a table {{polygon = [[x, y], ...]}} or a list of them, "
                         f"got {type(value).__name__}")
    unknown = set(value) - {"polygon", "along", "units", "mask", "within"}
    if unknown or ("polygon" in value) == ("mask" in value):
        raise InputError(f"{key}: a region table has polygon = [[x, y], ...] (with along, units) or "
                         f"mask = 'file.stl' (with within, units); got keys {sorted(value)}")
    kind = "polygon" if "polygon" in value else "mask"
    options = ",".join(f"{k}={value[k]}" for k in _OPTIONS[kind] if k in value)
    head = f"{kind}[{options}]" if options else kind
    if kind == "mask":
        return f"{head}:{value['mask']}"
    points = value["polygon"]
    if isinstance(points, str):
        return f"{head}:{points}"
    if not isinstance(points, list) or not all(isinstance(p, list) and p for p in points):
        raise InputError(f"{key}: polygon is a list of points [[x, y], ...] or a file name")
    return f"{head}:" + " ".join(",".join(str(c).replace(" ", "") for c in p) for p in points)


def resolve_region_paths(text: str, base_dir: Path) -> str:
    """``text`` with the relative file names of its ``polygon:`` / ``mask:`` terms taken from
    ``base_dir`` (a job file's folder); other terms are kept as they are."""
    terms = []
    for term in str(text).split(";"):
        m = REGION_TERM.match(term)
        if m is not None:
            body = m.group(3).strip()
            is_file = m.group(1).lower() == "mask" or Path(body).suffix.lower() in POLYGON_EXTENSIONS
            if is_file and not Path(body).expanduser().is_absolute():
                options = f"[{m.group(2)}]" if m.group(2) is not None else ""
                lead = term[:len(term) - len(term.lstrip())]
                term = f"{lead}{m.group(1)}{options}:{Path(base_dir) / body}"
        terms.append(term)
    return ";".join(terms)
