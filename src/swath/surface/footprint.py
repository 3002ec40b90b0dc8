"""A fitted patch's footprint — the part of its parameter domain the scan really covers — and the patch triangulated inside it for planning."""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ..errors import InputError

log = logging.getLogger(__name__)


#: Default triangulation spacing of a fitted patch: its longest extent / SPACING_DIVISOR,
#: clipped to [SPACING_MIN, SPACING_MAX] m (2 mm on a 0.3 m patch, 3.3 mm on 0.5 m, 5 mm from
#: 0.75 m up) -- fine against a 38 mm pad, coarse enough to plan on quickly.
SPACING_DIVISOR = 150.0


SPACING_MIN = 2e-3


SPACING_MAX = 5e-3


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
    from .grid import grid_faces
    from .surface import Surface

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
    full = Surface(verts, faces, name=patch.name if name is None else name)
    return full.sub_surface(np.arange(len(faces))), float(spacing)


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
