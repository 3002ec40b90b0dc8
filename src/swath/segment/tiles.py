"""Span-wise tiles of a big part: regions along one axis that can be planned on separate workers.

A long part (a blade, a beam, a hull strake) is cut by planes normal to its longest axis into
``n`` tiles.  The cutting planes of the plan (the passes lie on planes normal to the same axis,
``spacing`` apart) are laid over the whole part first, and every tile boundary falls halfway between
two of them, so each plane, and each pass on it, belongs to exactly one tile and no pass crosses a
seam.  A tile *owns* the faces whose centroid lies in its span range; its *extended* mesh adds a
band on each side, wide enough that a pad pressed anywhere on the owned area, or on a neighbour's
pass that reaches it, lies wholly on the mesh.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError


@dataclass(frozen=True)
class Tile:
    """One span-wise region of a part.

    Attributes
    ----------
    index : int
        Position along the axis, 0 first.
    lo, hi : float
        The owned span range ``lo <= h < hi`` of heights ``h = p · axis``, m (the first tile's
        ``lo`` is ``-inf`` and the last one's ``hi`` ``+inf``).
    offsets : (p,) float
        Heights of the cutting planes this tile plans on, m, ascending.
    levels : (p,) int
        Their indices among all the part's planes (the passes' ``level``).
    band : float
        Width of the band each side of the owned range in the extended mesh, m.
    """

    index: int
    lo: float
    hi: float
    offsets: np.ndarray
    levels: np.ndarray
    band: float

    def owns(self, heights: np.ndarray) -> np.ndarray:
        """(k,) bool: which of ``heights`` (k,) (m) lie in the owned range."""
        return (heights >= self.lo) & (heights < self.hi)

    def reaches(self, heights: np.ndarray) -> np.ndarray:
        """(k,) bool: which of ``heights`` (k,) (m) lie in the owned range grown by the band."""
        return (heights >= self.lo - self.band) & (heights < self.hi + self.band)


def plane_grid(lo: float, hi: float, spacing: float) -> np.ndarray:
    """Heights ``(p,)`` of cutting planes ``spacing`` apart centred on ``[lo, hi]`` (m), with
    ``p = ceil((hi - lo) / spacing)`` (at least 1): the margin left at each end is the same and at
    most half a spacing (the raster planner's rule, :func:`swath.plan.raster.plane_offsets`)."""
    if not (np.isfinite(spacing) and spacing > 0 and hi >= lo):
        raise InputError(f"plane grid needs a positive spacing and lo <= hi; got spacing {spacing!r} m on "
                         f"[{lo}, {hi}] m")
    n = max(math.ceil((hi - lo) / spacing), 1)
    return 0.5 * (lo + hi) + (np.arange(n) - 0.5 * (n - 1)) * spacing


def span_tiles(heights: np.ndarray, spacing: float, n_tiles: int, *, band: float) -> list[Tile]:
    """``n_tiles`` tiles along the heights ``(k,)`` (m) of a part's vertices, each with about the
    same number of planes ``spacing`` apart (:func:`plane_grid` over the whole part), the
    boundaries halfway between planes.

    Raises
    ------
    InputError
        When there are fewer planes than tiles (ask for fewer regions or a smaller spacing).
    """
    if n_tiles < 1:
        raise InputError(f"the number of regions must be at least 1, got {n_tiles}")
    if not band >= 0:
        raise InputError(f"the band around a region must be a length >= 0, got {band!r} m")
    heights = np.asarray(heights, float)
    offsets = plane_grid(float(heights.min()), float(heights.max()), spacing)
    if len(offsets) < n_tiles:
        raise InputError(f"{n_tiles} regions need at least {n_tiles} passes along the part, but it has "
                         f"{len(offsets)} at {spacing * 1e3:.3g} mm; ask for at most {len(offsets)} regions")
    cuts = np.round(np.linspace(0, len(offsets), n_tiles + 1)).astype(int)
    tiles = []
    for k in range(n_tiles):
        a, b = cuts[k], cuts[k + 1]
        lo = -math.inf if k == 0 else 0.5 * float(offsets[a - 1] + offsets[a])
        hi = math.inf if k == n_tiles - 1 else 0.5 * float(offsets[b - 1] + offsets[b])
        tiles.append(Tile(k, lo, hi, offsets[a:b].copy(), np.arange(a, b), float(band)))
    return tiles


def principal_axes(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The unit axes ``(3,)`` of the largest and second largest spread of ``vertices`` (n, 3) (m),
    each with its largest coordinate positive, from the covariance of at most 200k evenly taken
    vertices: the long axis a big part is cut along, and the direction its passes run."""
    v = np.asarray(vertices, float)
    v = v[:: max(len(v) // 200_000, 1)]
    _, vecs = np.linalg.eigh(np.cov((v - v.mean(axis=0)).T))
    first, second = vecs[:, -1], vecs[:, -2]
    return tuple(a if a[np.argmax(np.abs(a))] > 0 else -a for a in (first, second))  # type: ignore[return-value]


def face_heights(vertices: np.ndarray, faces: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """(m,) height of each face centroid along ``axis`` (3,), m (vertices (n, 3), faces (m, 3))."""
    h = np.asarray(vertices, float) @ np.asarray(axis, float)
    return (h[faces[:, 0]] + h[faces[:, 1]] + h[faces[:, 2]]) / 3.0


def submesh(vertices: np.ndarray, faces: np.ndarray, keep: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices (n', 3), faces (m', 3))`` of the faces where ``keep`` (m,) bool is set, with only
    the vertices they use, renumbered in their old order."""
    kept = faces[keep]
    if not len(kept):
        return np.asarray(vertices)[:0], np.zeros(kept.shape, np.intp)
    # marks and a running count over the span of indices the kept faces use (a region of a mesh
    # laid out along the part uses a small window of its vertices): no sort of m' * 3 indices
    first, last = int(kept.min()), int(kept.max())
    local = kept - first
    used = np.zeros(last - first + 1, bool)
    used[local.ravel()] = True
    new_index = np.cumsum(used) - 1
    return np.asarray(vertices)[first:last + 1][used], new_index[local]
