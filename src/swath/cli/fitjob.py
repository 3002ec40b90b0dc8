"""The ``swath fit`` and ``swath register`` jobs: scans in, smooth patches and transforms out.

* :func:`run_fit` — fit a B-spline patch to a scan (point cloud or mesh) and write
  ``patch.json`` (reloadable with :func:`swath.io.patch.load_patch_json`; it also carries the patch's
  :class:`Footprint`, the scanned part of its domain), ``surface.ply`` (the patch triangulated
  and trimmed to the footprint, per-vertex normals), ``fit.json`` (the figures, units in the key
  names) and ``fit.html`` / ``fit.png`` (residual map and histogram), atomically.
* :func:`run_register` — register a CAD mesh onto a scan and write ``transform.json`` (the 4x4
  ``cad2scan`` matrix and its quality) and ``residuals.csv`` (per-point residuals), atomically.
* :func:`load_scan`, :func:`fit_scan` and :func:`patch_surface` are the pieces that
  ``swath plan --fit`` and ``swath plan patch.json`` use (see :func:`swath.cli.job.load_part`).

A scan file is a point cloud (``.xyz .txt .csv .pts .pcd``, or a ``.ply`` without faces) or a
mesh (``.stl .obj``, or a ``.ply`` with faces).  A mesh's triangles make the LSCM
parameterisation available for patches that wrap.  With ``parameterization="rows"`` the scan
rows are read off the point order (:func:`infer_scan_rows`).
"""

from __future__ import annotations

import datetime as _dt
import html as _html
import json
import logging
import re
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError

log = logging.getLogger(__name__)

#: Point-cloud extensions (a ``.ply`` is a cloud when it has no faces).
CLOUD_EXTENSIONS = (".xyz", ".txt", ".csv", ".pts", ".pcd")
#: Default triangulation spacing of a fitted patch: its longest extent / SPACING_DIVISOR,
#: clipped to [SPACING_MIN, SPACING_MAX] m (2 mm on a 0.3 m patch, 3.3 mm on 0.5 m, 5 mm from
#: 0.75 m up) -- fine against a 38 mm pad, coarse enough to plan on quickly.
SPACING_DIVISOR = 150.0
SPACING_MIN = 2e-3
SPACING_MAX = 5e-3
#: Row inference: a new scan row starts where the step to the next point is longer than this
#: many median steps, or where the scan direction turns back (cosine below ROW_TURN_COS).
ROW_JUMP = 3.0
ROW_TURN_COS = -0.7
#: Points drawn at most in the residual map.
MAX_MAP_POINTS = 60_000
#: Format version of fit.json and transform.json.
FORMAT_VERSION = 1


def dumps(doc: dict) -> str:
    """JSON text of ``doc``, indented, with every list of plain numbers on one line (a matrix
    row, a knot vector)."""
    text = json.dumps(doc, indent=2, allow_nan=False)
    number_list = re.compile(r"\[\s+([-+0-9.eE]+(?:,\s+[-+0-9.eE]+)*)\s+\]")
    return number_list.sub(lambda m: "[" + ", ".join(x.strip() for x in m.group(1).split(",")) + "]", text) + "\n"


# --------------------------------------------------------------------------------------------
# scans
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Scan:
    """A loaded scan.

    Attributes
    ----------
    points : (n, 3) float
        Points (a cloud) or vertices (a mesh), m.
    normals : (n, 3) float or None
        Unit normals from the file (clouds) or the mesh's vertex normals; only their side is used.
    faces : (m, 3) int or None
        Triangles of a mesh scan; None for a point cloud.
    name : str
        File stem (or example name).
    """

    points: np.ndarray
    normals: np.ndarray | None
    faces: np.ndarray | None
    name: str

    @property
    def kind(self) -> str:
        """``"mesh"`` or ``"points"``."""
        return "points" if self.faces is None else "mesh"


def ply_face_count(path) -> int:
    """Number of faces declared in a PLY header (0 for a point cloud); -1 if the header is unreadable."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(65536)
    except OSError:
        return -1
    end = head.find(b"end_header")
    if not head.lstrip().startswith(b"ply") or end < 0:
        return -1
    for line in head[:end].decode("ascii", errors="replace").splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[0] == "element" and parts[1] == "face":
            try:
                return int(parts[2])
            except ValueError:
                return -1
    return 0


def is_point_cloud_file(path) -> bool:
    """Whether ``path`` names a point cloud (by extension; a PLY by its header having no faces)."""
    path = Path(path)
    ext = path.suffix.lower()
    if ext in CLOUD_EXTENSIONS:
        return True
    return ext == ".ply" and path.is_file() and ply_face_count(path) == 0


def load_scan(path, *, units: str = "m", side=None, all_pieces: bool = False, force_units: bool = False) -> Scan:
    """Load a scan: a point cloud (:func:`swath.io.points.load_points`) or a mesh (:func:`swath.io.mesh.load_mesh`).

    Parameters
    ----------
    path : str or Path
        ``.xyz .txt .csv .pts .pcd .ply`` (cloud) or ``.stl .obj .ply`` (mesh; a PLY with faces).
    units : str
        The file's length unit (m, mm, cm, in).
    side : str or (3,) float, optional
        For a mesh: the direction the tool comes from (orients the mesh; needed for a closed solid).
    all_pieces : bool
        For a mesh: keep every piece (default the largest).
    force_units : bool
        Accept a size outside 5 mm .. 20 m.

    Returns
    -------
    Scan
    """
    if is_point_cloud_file(path):
        from ..io.points import load_points

        pts, nrm = load_points(path, units=units, force_units=force_units)
        return Scan(pts, nrm, None, Path(path).stem)
    from ..io.mesh import load_mesh

    surface = load_mesh(path, units=units, side=side, all_pieces=all_pieces, force_units=force_units)
    return scan_from_surface(surface)


def scan_from_surface(surface) -> Scan:
    """A :class:`Scan` of a surface's vertices and triangles (``(n, 3)`` m, ``(m, 3)`` int)."""
    return Scan(np.asarray(surface.vertices), np.asarray(surface.normals), np.asarray(surface.faces),
                str(surface.name))


def infer_scan_rows(points) -> np.ndarray:
    """Scan-row ids ``(n,)`` of points stored in scan order, as a point laser records them.

    A new row starts where the step to the next point is longer than ``ROW_JUMP`` median steps
    (the return to the start of the next row) or where the scan turns back (the directions of
    the steps before and after a step have a cosine below ``ROW_TURN_COS``, and neither of them is
    such a jump: a zig-zag scan).

    Parameters
    ----------
    points : (n, 3) float
        Points in scan order, m.

    Returns
    -------
    (n,) int
        Row id of each point, 0, 1, ... in order.
    """
    X = np.asarray(points, float)
    if len(X) < 4:
        return np.zeros(len(X), dtype=np.int64)
    d = np.diff(X, axis=0)                                     # (n-1, 3) steps
    length = np.linalg.norm(d, axis=1)
    h = float(np.median(length))
    if not h > 0:
        raise InputError("consecutive points coincide; the rows of a scan cannot be read off the point order "
                         "(use --parameterization auto)")
    jump = length > ROW_JUMP * h
    unit = d / np.maximum(length, 1e-300)[:, None]
    cos = np.einsum("ij,ij->i", unit[:-2], unit[2:])           # steps j-1 and j+1 around step j
    # a turn next to a jump is the jump's own (a return stroke reverses the steps beside it)
    turn = (cos < ROW_TURN_COS) & ~jump[:-2] & ~jump[2:]
    brk = jump.copy()
    brk[1:-1] |= turn
    return np.concatenate([[0], np.cumsum(brk)]).astype(np.int64)


def default_surface_spacing(patch, footprint=None) -> float:
    """Triangulation spacing (m) for planning on ``patch``: the longest extent of the patch
    (of its footprint, when given) / 150, clipped to 2..5 mm."""
    (u0, u1), (v0, v1) = patch.domain
    if footprint is not None and footprint.mask.any():
        I, J = np.nonzero(footprint.mask)
        pick = _even_sample(len(I), 4000)
        U = np.clip(footprint.origin[0] + (I[pick] + 0.5) * footprint.cell, u0, u1)
        V = np.clip(footprint.origin[1] + (J[pick] + 0.5) * footprint.cell, v0, v1)
    else:
        g = np.linspace(0.0, 1.0, 33)
        U, V = (a.ravel() for a in np.meshgrid(u0 + (u1 - u0) * g, v0 + (v1 - v0) * g, indexing="ij"))
    extent = float(np.ptp(patch.evaluate(U, V), axis=0).max())
    return float(np.clip(extent / SPACING_DIVISOR, SPACING_MIN, SPACING_MAX))


def fit_scan(scan: Scan, *, parameterization: str = "auto", side=None, tolerance=None, progress=None):
    """Fit a B-spline patch to a scan (:func:`swath.surface.fit.fit_patch`).

    Parameters
    ----------
    scan : Scan
        Points (m) with optional normals, and triangles for a mesh.
    parameterization : {"auto", "projection", "lscm", "rows"}
        As for ``fit_patch``; ``"rows"`` reads the rows off the point order
        (:func:`infer_scan_rows`) and needs a point cloud; ``"lscm"`` needs a mesh.
    side : str or (3,) float, optional
        The direction the tool comes from: the patch normal is turned to face it.  Default: the
        side the scan's normals (or a mesh's winding) give, else the convex side.
    tolerance : float, optional
        Fit tolerance, m (see ``fit_patch``; default its default).
    progress : callable, optional
        ``progress(stage, done, total)`` at every stage of the fit (see ``fit_patch``).

    Returns
    -------
    patch : BSplinePatch
    report : FitReport

    Raises
    ------
    InputError, InfeasibleError
        As ``fit_patch`` (too few points, not one patch, a parameterisation that folds over).
    """
    from ..surface.fit import PARAMETERIZATIONS, fit_patch

    if parameterization not in PARAMETERIZATIONS:
        raise InputError(f"unknown parameterization {parameterization!r}; choose one of "
                         f"{', '.join(PARAMETERIZATIONS)}")
    rows = None
    if parameterization == "rows":
        if scan.faces is not None:
            raise InputError("parameterization 'rows' reads the scan rows off the order of a point cloud's "
                             "points; a mesh has no scan rows: use auto, projection or lscm")
        rows = infer_scan_rows(scan.points)
        log.info("%s: %d scan rows read off the point order", scan.name, int(rows.max()) + 1)
    if parameterization == "lscm" and scan.faces is None:
        raise InputError("parameterization 'lscm' needs a mesh (triangles); this scan is a point cloud: "
                         "use auto, projection or rows")
    patch, report = fit_patch(scan.points, normals=scan.normals, mesh_faces=scan.faces, rows=rows,
                              parameterization=parameterization, progress=progress,
                              **({} if tolerance is None else {"tolerance": tolerance}))
    if side is not None:
        from ..io.mesh import parse_side

        s = parse_side(side)
        (u0, u1), (v0, v1) = patch.domain
        g = np.linspace(0.05, 0.95, 7)
        U, V = np.meshgrid(u0 + (u1 - u0) * g, v0 + (v1 - v0) * g, indexing="ij")
        if float(np.mean(patch.normals(U.ravel(), V.ravel()) @ s)) < 0:
            patch = patch.flipped()
    return patch, report


def patch_surface(patch, *, spacing: float | None = None, name: str | None = None, footprint=None):
    """The patch triangulated for planning: ``(Surface, spacing_m)``.

    Parameters
    ----------
    patch : BSplinePatch
    spacing : float, optional
        Vertex spacing, m; default :func:`default_surface_spacing`.
    name : str, optional
        Surface name.
    footprint : Footprint, optional
        Keep only the triangles whose three vertices lie in the footprint (the scanned area).
    """
    from ..io.mesh import remove_unreferenced
    from ..surface import Surface
    from ..surface.grid import grid_faces

    if spacing is None:
        spacing = default_surface_spacing(patch, footprint)
    if not (np.isfinite(spacing) and spacing > 0):
        raise InputError(f"the surface spacing must be a positive length, got {spacing!r} m")
    if footprint is None:
        gu, gv = patch.grid_parameters(spacing=float(spacing))
    else:
        gu, gv = _footprint_grid(patch, footprint, float(spacing))
    U, V = np.meshgrid(gu, gv, indexing="ij")
    faces = grid_faces(gu.size, gv.size)
    if footprint is not None:
        keep = footprint.contains(U.ravel(), V.ravel())
        faces = faces[keep[faces].all(axis=1)]
        if len(faces) < 2:
            raise InputError("the scanned area covers less than one triangle of the fitted patch at "
                             f"{spacing * 1e3:.3g} mm; choose a smaller spacing")
    verts = patch.evaluate(U.ravel(), V.ravel())
    verts, faces = remove_unreferenced(verts, faces)
    return Surface(verts, faces, name=patch.name if name is None else name), float(spacing)


def _even_sample(n: int, size: int) -> np.ndarray:
    """Indices ``(min(n, size),)`` spread evenly over ``range(n)``.

    The footprint's occupied cells are sampled this way rather than at random: a random choice
    from a population of ``n`` reshuffles completely when ``n`` changes by one, so two fits that
    differ by nanometres (the same scan read in m and in mm) could get footprints that differ by a
    cell, speed estimates that differ by a percent, a triangulation grid one row longer, and a
    trimmed surface whose boundary triangles (a spacing wide all round) come out differently.  An
    even stride moves a sample by at most one cell instead."""
    if n <= size:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, size).round().astype(np.int64))


def _footprint_grid(patch, footprint: Footprint, spacing: float):
    """Parameter grids ``(nu,)``, ``(nv,)`` over the footprint's occupied box, uniform in the
    parameters, with steps that make about ``spacing`` metres where the scan is (measured from
    the patch's first derivatives there; the arc length of the whole patch would count the parts
    that shoot off beyond the data).

    The grid lines are those of one lattice laid over the patch's whole domain (which the fit
    fixes), kept where they cross the occupied box; so a cell at the edge of the footprint that
    comes or goes (the footprint's thresholds meet some cell in every scan) adds or removes only
    the grid nodes in that cell.  A grid stretched over the occupied box instead would shift every
    node when the box grows by one cell, and with it whole rows of boundary triangles."""
    (u0, u1), (v0, v1) = patch.domain
    I, J = np.nonzero(footprint.mask)
    if len(I) == 0:
        raise InputError("the patch's footprint is empty: no part of the patch lies near the scan")
    lo = np.maximum(footprint.origin + footprint.cell * np.array([I.min(), J.min()]), [u0, v0])
    hi = np.minimum(footprint.origin + footprint.cell * np.array([I.max() + 1, J.max() + 1]), [u1, v1])
    # Speeds |S_u|, |S_v| at a fixed lattice of the domain, where the footprint is occupied.
    g = (np.arange(64) + 0.5) / 64
    cu, cv = (a.ravel() for a in np.meshgrid(u0 + (u1 - u0) * g, v0 + (v1 - v0) * g, indexing="ij"))
    inside = footprint.contains(cu, cv)
    if inside.sum() >= 16:
        cu, cv = cu[inside], cv[inside]
    D = patch.derivatives(cu, cv, 1)
    speed = np.array([np.median(np.linalg.norm(D[:, 1, 0], axis=1)), np.median(np.linalg.norm(D[:, 0, 1], axis=1))])
    span = np.array([u1 - u0, v1 - v0])
    n_dom = np.maximum(np.ceil(span * speed / spacing).astype(np.int64), 1) + 1
    step = span / (n_dom - 1)
    first = np.clip(np.ceil((lo - [u0, v0]) / step - 1e-9).astype(np.int64), 0, n_dom - 1)
    last = np.clip(np.floor((hi - [u0, v0]) / step + 1e-9).astype(np.int64), first, n_dom - 1)
    n = last - first + 1
    if n[0] * n[1] > 5_000_000:
        raise InputError(f"spacing {spacing:g} m gives {n[0]}x{n[1]} samples; choose a larger spacing")
    return (u0 + step[0] * np.arange(first[0], last[0] + 1), v0 + step[1] * np.arange(first[1], last[1] + 1))


def signed_residuals(patch, points):
    """Signed distances ``(n,)`` (m, positive on the patch's normal side) of ``points`` ``(n, 3)``
    to the patch, and their parameters ``u, v`` ``(n,)``."""
    u, v, dist = patch.project(points)
    side = np.einsum("ij,ij->i", np.asarray(points, float) - patch.evaluate(u, v), patch.normals(u, v))
    return np.where(side < 0, -dist, dist), u, v


# --------------------------------------------------------------------------------------------
# footprint: where a fitted patch has data
# --------------------------------------------------------------------------------------------
#: Points this close to a footprint cell edge (in cells) count as in the cells on both sides.
EDGE_TOLERANCE = 1e-7


@dataclass(frozen=True)
class Footprint:
    """Where a fitted patch is backed by scan points: an occupancy mask over its parameter domain.

    A patch fitted to a scan that is not a rectangle in its parameters (a round dome, a ragged
    scan edge) is extrapolated freely beyond the points; the footprint trims it back to them.

    Attributes
    ----------
    origin : (2,) float
        Parameters ``(u, v)`` of the mask's first cell corner.
    cell : float
        Cell size in parameter units (the fits' parameters are about metres of arc length).
    mask : (nu, nv) bool
        Cells that hold scan points, closed over one-cell gaps and grown by one cell.
    """

    origin: np.ndarray
    cell: float
    mask: np.ndarray

    def contains(self, u, v) -> np.ndarray:
        """Whether parameters ``u, v`` ``(k,)`` lie in an occupied cell, ``(k,)`` bool.

        Cells are closed: a point on the edge between two cells (within ``1e-7`` of a cell in
        relative terms) is in both.  The patch's domain ends fall on cell edges by construction
        (:func:`scan_footprint`), so without this a grid line along a domain end would be kept
        or dropped whole by rounding."""
        x = (np.asarray(u, float) - self.origin[0]) / self.cell
        y = (np.asarray(v, float) - self.origin[1]) / self.cell
        out = np.zeros(np.broadcast(x, y).shape, dtype=bool)
        for dx in (-EDGE_TOLERANCE, EDGE_TOLERANCE):
            for dy in (-EDGE_TOLERANCE, EDGE_TOLERANCE):
                i = np.floor(x + dx).astype(np.int64)
                j = np.floor(y + dy).astype(np.int64)
                inside = (i >= 0) & (i < self.mask.shape[0]) & (j >= 0) & (j < self.mask.shape[1])
                out[inside] |= self.mask[i[inside], j[inside]]
        return out

    @property
    def fraction(self) -> float:
        """Occupied fraction of the mask's cells."""
        return float(self.mask.mean())

    def to_dict(self) -> dict:
        """JSON-ready: rows of the mask as hex of packed bits."""
        return {"type": "uv_occupancy", "origin": [float(x) for x in self.origin], "cell": float(self.cell),
                "shape": list(self.mask.shape), "rows_hex": [np.packbits(r).tobytes().hex() for r in self.mask]}

    @classmethod
    def from_dict(cls, data: dict) -> Footprint:
        """Rebuild from :meth:`to_dict` output; raises InputError when malformed."""
        try:
            nu, nv = (int(x) for x in data["shape"])
            rows = [np.unpackbits(np.frombuffer(bytes.fromhex(h), np.uint8))[:nv] for h in data["rows_hex"]]
            mask = np.array(rows, dtype=bool).reshape(nu, nv)
            origin = np.array(data["origin"], dtype=float).reshape(2)
            cell = float(data["cell"])
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"the patch's footprint is malformed ({exc}); re-run swath fit") from None
        if not (np.isfinite(cell) and cell > 0 and np.isfinite(origin).all()):
            raise InputError("the patch's footprint is malformed (cell or origin); re-run swath fit")
        return cls(origin, cell, mask)


def scan_footprint(patch, points, u, v, *, faces=None, rms: float = 0.0, max_cells: int = 512) -> Footprint:
    """The part of ``patch``'s parameter domain that the scan backs.

    In the parameter plane, the scan points' projections are closed by a disc of radius ``r``
    (gaps narrower than ``2 r`` are filled; the edge stays at the outermost points); of those
    cells, the ones where the patch lies farther than ``r + 3 rms`` from every scan point in space
    are dropped (where the patch shoots off beyond the data, as a free fit does at the rim of a
    steep part), and so are stray specks and pinholes (:func:`_tidy_mask`).  ``r`` is 1.5 times the median distance from a scan point
    to its 4th-nearest neighbour (in the parameter plane, whose units the fits make about
    metres); the cell is ``r / 2``, at most ``max_cells`` per direction.

    Parameters
    ----------
    patch : BSplinePatch
        The fitted patch.
    points : (n, 3) float
        Scan points, m.
    u, v : (n,) float
        Their parameters on the patch (from ``patch.project``).
    faces : (m, 3) int, optional
        Triangles of a mesh scan: their centroids and edge midpoints densify the points.
    rms : float
        RMS distance of the points to the patch, m.
    max_cells : int
        Cells per direction at most.

    Returns
    -------
    Footprint
    """
    from scipy import ndimage
    from scipy.spatial import cKDTree

    X = np.asarray(points, float)
    uv = np.column_stack([np.asarray(u, float), np.asarray(v, float)])
    if faces is not None:            # a mesh: its triangles are data too, not only its vertices
        F = np.asarray(faces)
        def midpoints(A):
            return np.concatenate([A[F].mean(axis=1), 0.5 * (A[F[:, 0]] + A[F[:, 1]]),
                                   0.5 * (A[F[:, 1]] + A[F[:, 2]]), 0.5 * (A[F[:, 2]] + A[F[:, 0]])])

        # their parameters are the same means of their corners' parameters (to second order in
        # the triangle size, far below a cell), not four projections per triangle
        X = np.concatenate([X, midpoints(X)])
        uv = np.concatenate([uv, midpoints(uv)])
    tree_uv = cKDTree(uv)
    sample = uv[np.random.default_rng(0).choice(len(uv), size=min(len(uv), 5000), replace=False)]
    d, _ = tree_uv.query(sample, k=min(5, len(uv)))
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    r = max(1.5 * float(np.median(d[:, -1])), 1e-12)
    cell = max(0.5 * r, float((hi - lo).max() + 2 * r) / max_cells)
    origin = lo - r
    shape = np.ceil((hi - lo + 2 * r) / cell).astype(np.int64) + 1
    I, J = np.meshgrid(np.arange(shape[0]), np.arange(shape[1]), indexing="ij")
    cu, cv = origin[0] + (I.ravel() + 0.5) * cell, origin[1] + (J.ravel() + 0.5) * cell
    near, _ = tree_uv.query(np.column_stack([cu, cv]), distance_upper_bound=r)
    # closing of the points by a disc of radius r: gaps narrower than 2r are filled, the edge
    # stays at the outermost points (give or take a cell)
    k = int(np.ceil(r / cell))
    di, dj = np.meshgrid(np.arange(-k, k + 1), np.arange(-k, k + 1), indexing="ij")
    disc = np.hypot(di, dj) * cell <= r
    keep = ndimage.binary_erosion(np.isfinite(near).reshape(shape), structure=disc, border_value=0)
    idx = np.floor((uv - origin) / cell).astype(np.int64)
    keep[idx[:, 0], idx[:, 1]] = True
    keep = keep.ravel()
    (u0, u1), (v0, v1) = patch.domain
    S = patch.evaluate(np.clip(cu[keep], u0, u1), np.clip(cv[keep], v0, v1))
    gap, _ = cKDTree(X).query(S)
    keep[np.flatnonzero(keep)] = gap <= r + 3.0 * rms
    return Footprint(origin, cell, _tidy_mask(keep.reshape(shape)))


def _tidy_mask(mask: np.ndarray, *, speck: float = 0.01, pinhole: int = 16) -> np.ndarray:
    """Drop occupied pieces smaller than ``speck`` of the occupied cells (stray points) and fill
    holes of at most ``pinhole`` cells (sparse data, not openings in the part)."""
    from scipy import ndimage

    lab, n = ndimage.label(mask)
    if n > 1:
        size = np.bincount(lab.ravel(), minlength=n + 1)
        size[0] = 0
        mask = (size >= speck * size.sum())[lab] & mask
    holes, n = ndimage.label(~mask)
    if n:
        size = np.bincount(holes.ravel(), minlength=n + 1)
        border = np.unique(np.concatenate([holes[0], holes[-1], holes[:, 0], holes[:, -1]]))
        small = size <= pinhole
        small[border] = False
        small[0] = False
        mask = mask | small[holes]
    return mask


def save_patch(patch, path, footprint: Footprint | None = None) -> None:
    """Write ``patch`` as JSON (:func:`swath.io.patch.save_patch_json`) with its footprint, atomically."""
    from ..io.patch import save_patch_json

    save_patch_json(patch, path, extra=None if footprint is None else {"footprint": footprint.to_dict()})


def load_patch(path):
    """Read a patch written by :func:`save_patch` (or :func:`swath.io.patch.save_patch_json`):
    ``(BSplinePatch, Footprint or None)``."""
    from ..io.patch import read_patch_document

    patch, data = read_patch_document(path)
    fp = data.get("footprint")
    return patch, (None if fp is None else Footprint.from_dict(fp))


# --------------------------------------------------------------------------------------------
# swath fit
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class FitSettings:
    """Settings of ``swath fit`` (SI units).

    Attributes
    ----------
    scan, out : str
        Scan file and output directory.
    units : str
        Length unit of the scan file.
    parameterization : str
        ``auto``, ``projection``, ``lscm`` (mesh scans) or ``rows`` (clouds in scan order).
    spacing : float or None
        Triangulation spacing of ``surface.ply``, m (default :func:`default_surface_spacing`).
    side : str or None
        Direction the tool comes from (orients the patch normal).
    force_units : bool
        Accept a scan size outside 5 mm .. 20 m.
    tolerance : float or None
        Fit tolerance, m: points farther from the patch make a warning (default
        :data:`swath.surface.fit.FIT_TOLERANCE`, 1 mm).
    """

    scan: str
    out: str
    units: str = "m"
    parameterization: str = "auto"
    spacing: float | None = None
    side: str | None = None
    force_units: bool = False
    tolerance: float | None = None
    overwrite: bool = False


def run_fit(settings: FitSettings, *, progress=None) -> dict:
    """Fit a patch to a scan and write ``patch.json``, ``surface.ply``, ``fit.json``, ``fit.png``
    and ``fit.html`` into ``settings.out`` atomically.

    Parameters
    ----------
    settings : FitSettings
    progress : callable, optional
        ``progress(stage, done, total)``.

    Returns
    -------
    dict
        The document written as ``fit.json``.
    """
    from ..io.atomic import atomic_directory, check_output_dir, write_text_atomic
    from ..io.mesh import save_surface_ply

    check_output_dir(settings.out, overwrite=settings.overwrite)          # before the fitting, not after

    say = progress or (lambda stage, done, total: None)
    say("loading scan", 0, 1)
    scan = load_scan(settings.scan, units=settings.units, side=settings.side, force_units=settings.force_units)
    say(f"fitting a B-spline patch to {len(scan.points)} {'vertices' if scan.faces is not None else 'points'}"
        f" ({settings.parameterization} parameterisation)", 0, 1)
    patch, report = fit_scan(scan, parameterization=settings.parameterization, side=settings.side,
                             tolerance=settings.tolerance, progress=say)
    say("measuring residuals", 0, 1)
    r, u, v = signed_residuals(patch, scan.points)
    say("finding the scanned area (footprint)", 0, 1)
    footprint = scan_footprint(patch, scan.points, u, v, faces=scan.faces, rms=report.rms)
    spacing = settings.spacing if settings.spacing is not None else default_surface_spacing(patch, footprint)
    how = "given" if settings.spacing is not None else "default: extent / 150 in 2..5 mm"
    say(f"triangulating the patch at {spacing * 1e3:.3g} mm ({how}), trimmed to the scanned area", 0, 1)
    surface, spacing = patch_surface(patch, spacing=spacing, name=scan.name, footprint=footprint)
    doc = fit_document(settings, scan, patch, report, r, surface, spacing)
    doc["surface"]["footprint_fraction"] = footprint.fraction
    say("writing fit report", 0, 1)
    png = residual_figure_png(r, u, v, title=f"Fit of {scan.name}: residuals (point − patch, along the normal)")
    with atomic_directory(settings.out, overwrite=settings.overwrite) as tmp:
        save_patch(patch, tmp / "patch.json", footprint)
        save_surface_ply(surface, tmp / "surface.ply")
        write_text_atomic(tmp / "fit.json", dumps(doc))
        with open(tmp / "fit.png", "wb") as fh:
            fh.write(png)
        write_text_atomic(tmp / "fit.html", fit_html(doc, png))
    say("done", 1, 1)
    return doc


def fit_document(settings: FitSettings, scan: Scan, patch, report, residuals, surface, spacing) -> dict:
    """The content of ``fit.json`` (lengths in m, times in s; units in the key names)."""
    from .. import __version__
    from ..report.metrics import to_jsonable

    a = np.abs(residuals)
    fit = report.to_dict()
    figures = {
        "rms_m": report.rms, "max_error_m": report.max_error,
        "residual_rms_all_points_m": float(np.sqrt(np.mean(residuals ** 2))),
        "residual_mean_m": float(residuals.mean()),
        "residual_p50_m": float(np.percentile(a, 50)), "residual_p95_m": float(np.percentile(a, 95)),
        "residual_max_m": float(a.max()),
        "n_points": report.n_points, "n_dropped": report.n_dropped,
        "n_ctrl_u": report.n_ctrl[0], "n_ctrl_v": report.n_ctrl[1],
        "n_degree_u": report.degree[0], "n_degree_v": report.degree[1],
        "smoothing_u_m": report.smoothing[0], "smoothing_v_m": report.smoothing[1],
        "fit_time_s": report.time, "fit_tolerance_m": report.tolerance,
    }
    return to_jsonable({
        "format_version": FORMAT_VERSION,
        "warnings": list(report.warnings),
        "swath_version": __version__,
        "created_utc": _dt.datetime.now(_dt.UTC).replace(microsecond=0).isoformat(),
        "input": {"scan": str(settings.scan), "units": settings.units, "kind": scan.kind,
                  "n_points": len(scan.points), "has_normals": scan.normals is not None},
        "parameterization": report.parameterization,
        "figures": figures,
        "fit": fit,
        "surface": {"file": "surface.ply", "spacing_m": spacing, "trimmed_to_scan": True, "n_vertices": len(surface.vertices),
                    "n_faces": len(surface.faces), "area_m2": float(surface.area),
                    "extent_m": np.ptp(surface.vertices, axis=0)},
        "files": {"patch": "patch.json", "surface": "surface.ply", "report": "fit.html", "figure": "fit.png"},
        "notes": {"residuals": "signed distance of each scan point to the patch along the patch normal, m; "
                               "residual_* figures cover every point loaded, rms_m and max_error_m only the "
                               "points fitted (stray specks dropped)"},
    })


def residual_figure_png(residuals, u, v, *, title: str = "") -> bytes:
    """PNG bytes: the signed residual (mm) over the patch parameters (≈ m of arc length), and
    its histogram."""
    import matplotlib as mpl
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from ..report.plots import png_bytes

    r_mm = np.asarray(residuals, float) * 1e3
    fig = Figure(figsize=(12.0, 4.8), layout="constrained")
    FigureCanvasAgg(fig)
    ax_map, ax_hist = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.4, 1.0]})
    lim = float(np.percentile(np.abs(r_mm), 99)) or 1e-3
    idx = np.arange(len(r_mm))
    if len(idx) > MAX_MAP_POINTS:
        idx = np.random.default_rng(0).choice(len(idx), MAX_MAP_POINTS, replace=False)
    sc = ax_map.scatter(u[idx], v[idx], c=r_mm[idx], s=2.0, cmap="coolwarm",
                        norm=mpl.colors.Normalize(-lim, lim), linewidths=0)
    ax_map.set_aspect("equal", adjustable="box")
    ax_map.set_xlabel("patch parameter u (≈ m along the surface)")
    ax_map.set_ylabel("patch parameter v (≈ m)")
    ax_map.set_title("residual map")
    fig.colorbar(sc, ax=ax_map, label="residual (mm), clipped at the 99th percentile of |r|", extend="both")
    rms = float(np.sqrt(np.mean(r_mm ** 2)))
    p95 = float(np.percentile(np.abs(r_mm), 95))
    ax_hist.hist(np.clip(r_mm, -3 * lim, 3 * lim), bins=60, color="tab:blue", alpha=0.85)
    ax_hist.axvline(0.0, color="black", lw=0.8)
    for x in (-p95, p95):
        ax_hist.axvline(x, color="tab:red", ls="--", lw=1.0)
    ax_hist.plot([], [], color="tab:red", ls="--", label=f"|r| 95th percentile {p95:.3g} mm")
    ax_hist.plot([], [], " ", label=f"RMS {rms:.3g} mm over {len(r_mm)} points")
    ax_hist.legend(fontsize=8)
    ax_hist.set_xlabel("residual (mm)")
    ax_hist.set_ylabel("points")
    ax_hist.set_title("residual histogram")
    if title:
        fig.suptitle(title)
    return png_bytes(fig)


def fit_html(doc: dict, png: bytes) -> str:
    """A small self-contained HTML page: the fit figures and the residual PNG (embedded)."""
    import base64

    esc = _html.escape
    f = doc["figures"]
    rows = [
        ("scan", f"{doc['input']['scan']} ({doc['input']['kind']}, {doc['input']['n_points']} points, "
                 f"units {doc['input']['units']})"),
        ("parameterisation", doc["parameterization"]),
        ("points fitted / dropped as stray", f"{f['n_points']} / {f['n_dropped']}"),
        ("control net", f"{f['n_ctrl_u']} × {f['n_ctrl_v']}, degree ({f['n_degree_u']}, {f['n_degree_v']})"),
        ("smoothing length u, v", f"{f['smoothing_u_m'] * 1e3:.3g} mm, {f['smoothing_v_m'] * 1e3:.3g} mm"),
        ("RMS distance to the patch", f"{f['rms_m'] * 1e3:.4g} mm"),
        ("largest distance", f"{f['max_error_m'] * 1e3:.4g} mm"),
        ("|residual| median / 95th percentile", f"{f['residual_p50_m'] * 1e3:.4g} mm / "
                                                f"{f['residual_p95_m'] * 1e3:.4g} mm"),
        ("mean signed residual", f"{f['residual_mean_m'] * 1e3:.4g} mm"),
        ("surface.ply", f"{doc['surface']['n_vertices']} vertices, {doc['surface']['n_faces']} triangles at "
                        f"{doc['surface']['spacing_m'] * 1e3:.3g} mm, area {doc['surface']['area_m2']:.4g} m²"),
        ("fit tolerance (a warning beyond it)", f"{f['fit_tolerance_m'] * 1e3:.3g} mm"),
        ("fit time", f"{f['fit_time_s']:.2f} s"),
    ]
    table = "".join(f"<tr><td>{esc(k)}</td><td>{esc(str(v))}</td></tr>" for k, v in rows)
    uri = "data:image/png;base64," + base64.b64encode(png).decode("ascii")
    return (
        "<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
        f"<title>swath fit — {esc(str(doc['input']['scan']))}</title>"
        "<style>body{font-family:system-ui,sans-serif;margin:24px;color:#222}"
        "table{border-collapse:collapse}td{border-bottom:1px solid #eee;padding:4px 14px 4px 0}"
        "img{max-width:100%;border:1px solid #eee}</style></head><body>"
        f"<h1>swath fit — {esc(Path(str(doc['input']['scan'])).name)}</h1>"
        + ("" if not doc.get("warnings") else
           "<div style='border:1px solid #d9a400;background:#fff8e1;padding:8px 14px;margin:0 0 16px 0'>"
           "<b>Warnings</b><ul>" + "".join(f"<li>{esc(w)}</li>" for w in doc["warnings"]) + "</ul></div>")
        + f"<table>{table}</table>"
        "<p>Residual: signed distance of each scan point to the fitted patch along its normal. "
        "Figures with units in their names are in <code>fit.json</code>; the patch is "
        "<code>patch.json</code>.</p>"
        f"<img alt='residual map and histogram' src='{uri}'>"
        f"<p style='color:#777;font-size:.85em'>swath {esc(doc['swath_version'])}, {esc(doc['created_utc'])}</p>"
        "</body></html>\n"
    )


# --------------------------------------------------------------------------------------------
# swath register
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RegisterSettings:
    """Settings of ``swath register`` (SI units).

    Attributes
    ----------
    cad, scan, out : str
        The nominal CAD mesh (or ``patch.json``), the scan (mesh or cloud), the output directory.
    units, scan_units : str
        Length units of the CAD file and of the scan file (default: the CAD's).
    table : bool
        The part rests on a table whose normal is ``table_normal`` in both frames: solve only the
        turn about that normal and the shift along the table (plus the height unless
        ``keep_height``), perimeter points weighted (:func:`register_on_table`).
    keep_height : bool
        With ``table``: both frames put the table at the same height (3 DOF, the thesis's case).
    table_normal : str
        Table normal, e.g. ``+z`` or ``0,0,1``.
    all_pieces : bool
        Keep every piece of a multi-piece CAD mesh (the scan always keeps all of its pieces).
    side : str or None
        Direction the tool comes from, for a closed CAD solid (keeps the faces facing it).
    trim : float
        Fraction of correspondences ICP keeps each step (``1 - trim`` ≥ the outlier fraction).
    max_iterations : int
        ICP steps per stage.
    force_units : bool
        Accept sizes outside 5 mm .. 20 m.
    """

    cad: str
    scan: str
    out: str
    units: str = "m"
    scan_units: str | None = None
    table: bool = False
    keep_height: bool = False
    table_normal: str = "+z"
    all_pieces: bool = False
    side: str | None = None
    trim: float = 0.9
    max_iterations: int = 100
    force_units: bool = False
    overwrite: bool = False


def load_registration_inputs(settings: RegisterSettings):
    """``(cad Surface, scan target)``: the scan target is a Surface for a mesh and
    ``(points, normals)`` for a cloud."""
    from ..io.mesh import load_mesh

    if settings.cad.lower().endswith(".json"):
        patch, footprint = load_patch(settings.cad)
        cad, _ = patch_surface(patch, name=Path(settings.cad).stem, footprint=footprint)
    elif is_point_cloud_file(settings.cad):
        raise InputError(f"{Path(settings.cad).name} is a point cloud; the CAD must be a mesh (STL, PLY with "
                         "faces, OBJ) or a patch.json — register the cloud as the SCAN argument")
    else:
        cad = load_mesh(settings.cad, units=settings.units, side=settings.side, all_pieces=settings.all_pieces,
                        force_units=settings.force_units)
    scan_units = settings.scan_units or settings.units
    if is_point_cloud_file(settings.scan):
        from ..io.points import load_points

        pts, nrm = load_points(settings.scan, units=scan_units, force_units=settings.force_units)
        target = (pts, nrm)
    else:
        target = load_mesh(settings.scan, units=scan_units, side=settings.side, all_pieces=True,
                           force_units=settings.force_units)
    return cad, target


def run_register(settings: RegisterSettings, *, progress=None) -> dict:
    """Register the CAD onto the scan and write ``transform.json`` and ``residuals.csv``
    into ``settings.out`` atomically.

    Parameters
    ----------
    settings : RegisterSettings
    progress : callable, optional
        ``progress(stage, done, total)``.

    Returns
    -------
    dict
        The document written as ``transform.json``: ``cad2scan`` (4x4, m), ``rms_m``,
        ``inlier_fraction``, ``iterations``, ``converged``, ``method`` and the registration's
        quality figures.

    Raises
    ------
    InputError
        Unreadable files, bad settings.
    InfeasibleError
        No overlap, unconstrained geometry, or ICP that does not converge.
    """
    from ..io.atomic import atomic_directory, check_output_dir, write_text_atomic

    check_output_dir(settings.out, overwrite=settings.overwrite)
    from ..io.mesh import parse_side
    from ..surface.register import register_on_table, register_rigid

    say = progress or (lambda stage, done, total: None)
    if not (0.2 <= settings.trim <= 1.0):
        raise InputError(f"--trim must lie in 0.2..1 (the fraction of correspondences kept), got {settings.trim}")
    if settings.max_iterations < 1:
        raise InputError(f"--max-iterations must be at least 1, got {settings.max_iterations}")
    say("loading CAD and scan", 0, 1)
    t0 = time.perf_counter()
    cad, target = load_registration_inputs(settings)
    opts = dict(trim=settings.trim, max_iterations=settings.max_iterations, rng=0)
    if settings.table:
        k = parse_side(settings.table_normal)
        dof = "3 DOF: turn about the table normal, shift along the table" if settings.keep_height else \
            "4 DOF: turn about the table normal, shift along the table and in height"
        method = f"table ({dof}; perimeter weighted)"
        say("registering on the table", 0, 1)
        reg = register_on_table(cad, target, table_normal=k, fit_height=not settings.keep_height, **opts)
    else:
        method = "rigid (6 DOF: global search, trimmed point-to-plane ICP)"
        say("registering (global search, then ICP)", 0, 1)
        reg = register_rigid(cad, target, **opts)
    elapsed = time.perf_counter() - t0
    doc = transform_document(settings, reg, method, elapsed)
    say("writing transform", 0, 1)
    with atomic_directory(settings.out, overwrite=settings.overwrite) as tmp:
        write_text_atomic(tmp / "transform.json", dumps(doc))
        write_text_atomic(tmp / "residuals.csv", residuals_csv(cad.vertices, reg))
    say("done", 1, 1)
    return doc


def transform_document(settings: RegisterSettings, reg, method: str, elapsed: float) -> dict:
    """The content of ``transform.json``."""
    from .. import __version__
    from ..report.metrics import to_jsonable

    quality = reg.to_dict()
    quality.pop("matrix", None)
    return to_jsonable({
        "format_version": FORMAT_VERSION,
        "swath_version": __version__,
        "created_utc": _dt.datetime.now(_dt.UTC).replace(microsecond=0).isoformat(),
        "cad": str(settings.cad), "scan": str(settings.scan),
        "units": settings.units, "scan_units": settings.scan_units or settings.units,
        "cad2scan": np.asarray(reg.matrix),
        "frames": "cad2scan maps points of the CAD's part frame to the scan frame: p_scan = R p_cad + t (m)",
        "method": "table" if settings.table else "rigid",
        "method_description": method,
        "rms_m": reg.rms, "inlier_fraction": reg.inlier_fraction, "iterations": reg.iterations,
        "converged": reg.converged, "time_s": elapsed,
        "quality": quality,
    })


def residuals_csv(cad_points, reg) -> str:
    """``residuals.csv`` text: one row per CAD point used, its position in both frames (m), its
    signed point-to-plane residual (m; ``nan`` where the scan is too far to match) and whether it
    is an inlier (1/0)."""
    import io

    idx = np.asarray(reg.point_indices)
    p = np.asarray(cad_points, float)[idx]
    table = np.column_stack([idx, p, reg.transform(p), np.asarray(reg.residuals, float),
                             np.asarray(reg.inliers, bool)])
    buf = io.StringIO()
    np.savetxt(buf, table, delimiter=",", fmt=["%d"] + ["%.9g"] * 6 + ["%.6e", "%d"], comments="",
               header="point_index,cad_x_m,cad_y_m,cad_z_m,scan_x_m,scan_y_m,scan_z_m,residual_m,inlier")
    return buf.getvalue()
