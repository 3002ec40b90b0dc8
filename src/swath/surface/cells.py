"""Surface samples in a uniform grid of cells, and compiled (numba) kernels on it.

:class:`SampleGrid` sorts samples by cell so that each cell's samples are one contiguous run; a
ball query then visits only the cells the ball reaches.  The pad contact kernels
(:mod:`swath.contact.kernels`) and the normal smoothing of :func:`smooth_normals` use it.

Kernels are compiled on first use and cached on disk (``cache=True``); where no cache directory is
writable they are compiled in memory.  :data:`AVAILABLE` is False when numba is not installed; the
callers then take their numpy paths.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ..errors import InputError

log = logging.getLogger(__name__)

try:
    import numba
except ImportError:                                            # pragma: no cover - numba is a dependency
    numba = None  # type: ignore[assignment]

#: True when numba is importable and the compiled kernels can be used.
AVAILABLE = numba is not None

#: Every kernel :func:`jit` has made in this process (those of the modules imported so far).
_KERNELS: list = []


def jit():
    """``numba.njit(cache=True, nogil=True)``, without the disk cache where no cache directory is
    writable (numba refuses ``cache=True`` at decoration time then)."""
    def wrap(fn):
        if numba is None:                                      # pragma: no cover
            return fn
        try:
            kernel = numba.njit(cache=True, nogil=True)(fn)
        except RuntimeError as exc:                            # no writable cache locator
            log.info("numba cache unavailable (%s); compiling %s in memory", exc, fn.__name__)
            kernel = numba.njit(cache=False, nogil=True)(fn)
        _KERNELS.append(kernel)
        return kernel
    return wrap


def kernels_of(module: str) -> list:
    """The kernels :func:`jit` has made for ``module`` (a module name), once it is imported."""
    return [k for k in _KERNELS if getattr(k, "py_func", k).__module__ == module]


def disk_cached(kernel) -> bool:
    """Whether numba keeps ``kernel`` in its disk cache (False: compiled in memory at every run,
    where no cache directory was writable when :func:`jit` made it)."""
    return hasattr(getattr(kernel, "_cache", None), "_cache_file")


def kernels_to_compile(module: str | None = None) -> list[str]:
    """Names of the kernels made so far (:func:`jit`, in the modules imported; only those of
    ``module`` if given) that numba's disk cache holds nothing for, for their source as it is now:
    numba compiles them on first use, a fraction of a second to a few seconds each (a fresh
    install, or after an upgrade).  A kernel without a disk cache counts; where numba's cache
    cannot be read the answer is empty (nothing is claimed)."""
    names = []
    for kernel in _KERNELS if module is None else kernels_of(module):
        try:
            held = disk_cached(kernel) and bool(kernel._cache._cache_file._load_index())
        except Exception:                                      # numba's private layout changed: no claim
            return []
        if not held:
            names.append(kernel.__name__)
    return names


@dataclass(frozen=True, eq=False)
class SampleGrid:
    """Surface samples sorted into a uniform grid of cubic cells.

    Attributes
    ----------
    points, normals : (S, 3) float
        Samples (m) and unit normals toward the tool, float64, in cell order.
    areas : (S,) float
        Area each sample stands for, m², in cell order.
    order : (S,) int
        Original index of each sorted sample (``points == original_points[order]``).
    origin : (3,) float
        Lower corner of the grid, m.
    cell : float
        Cell edge, m.
    dims : (3,) int
        Cells along x, y, z.
    start : (C + 1,) int
        Samples of cell ``c`` (``c = (ix·ny + iy)·nz + iz``) are ``start[c]:start[c+1]``.
    """

    points: np.ndarray
    normals: np.ndarray
    areas: np.ndarray
    order: np.ndarray
    origin: np.ndarray
    cell: float
    dims: np.ndarray
    start: np.ndarray

    def __len__(self) -> int:
        return len(self.points)


def sample_grid(points: np.ndarray, normals: np.ndarray, areas: np.ndarray, *, cell: float,
                max_cells_per_sample: float = 8.0) -> SampleGrid:
    """Sort surface samples into a :class:`SampleGrid` of cells of edge ``cell``.

    Parameters
    ----------
    points, normals : (S, 3) float
        Samples (m) and unit normals toward the tool.
    areas : (S,) float
        Sample areas, m².
    cell : float
        Wanted cell edge, m (half the query-ball radius is a good choice).  Grown where the grid
        would have more than ``max_cells_per_sample`` cells per sample (a large, sparse part), so
        the grid's memory stays a small multiple of the samples'.
    """
    points = np.ascontiguousarray(points, dtype=np.float64)
    S = len(points)
    if points.ndim != 2 or points.shape[1] != 3 or np.shape(normals) != points.shape or np.shape(areas) != (S,):
        raise InputError(f"samples must be (S, 3) points and normals and (S,) areas, got {points.shape}, "
                         f"{np.shape(normals)} and {np.shape(areas)}")
    if not (np.isfinite(cell) and cell > 0):
        raise InputError(f"grid cell must be a positive length in m, got {cell!r}")
    if S and not np.all(np.isfinite(points)):
        raise InputError("sample points must be finite")
    lo = points.min(axis=0) if S else np.zeros(3)
    extent = (points.max(axis=0) - lo) if S else np.zeros(3)
    cell = float(cell)
    while True:
        dims = (extent // cell).astype(np.int64) + 1
        if np.prod(dims.astype(float)) <= max(max_cells_per_sample * S, 1000.0):
            break
        cell *= 1.25
    ijk = np.minimum(((points - lo) // cell).astype(np.int64), dims - 1)
    cid = (ijk[:, 0] * dims[1] + ijk[:, 1]) * dims[2] + ijk[:, 2]
    order = np.argsort(cid, kind="stable")
    counts = np.bincount(cid, minlength=int(np.prod(dims)))
    start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    return SampleGrid(points[order], np.ascontiguousarray(np.asarray(normals, np.float64)[order]),
                      np.ascontiguousarray(np.asarray(areas, np.float64)[order]), order, lo.astype(np.float64),
                      cell, dims, start)




# ----------------------------------------------------------------------------------------------
# Normal smoothing over a ball
# ----------------------------------------------------------------------------------------------
@jit()
def _smooth(pts, nrm, areas, lo, cell, dims, start, radius, out):
    r2 = radius * radius
    for q in range(len(pts)):
        cx, cy, cz = pts[q, 0], pts[q, 1], pts[q, 2]
        i0 = max(int(np.floor((cx - radius - lo[0]) / cell)), 0)
        i1 = min(int(np.floor((cx + radius - lo[0]) / cell)), dims[0] - 1)
        j0 = max(int(np.floor((cy - radius - lo[1]) / cell)), 0)
        j1 = min(int(np.floor((cy + radius - lo[1]) / cell)), dims[1] - 1)
        k0 = max(int(np.floor((cz - radius - lo[2]) / cell)), 0)
        k1 = min(int(np.floor((cz + radius - lo[2]) / cell)), dims[2] - 1)
        ax = ay = az = 0.0
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                base = (i * dims[1] + j) * dims[2]
                for p in range(start[base + k0], start[base + k1 + 1]):
                    dx = pts[p, 0] - cx
                    dy = pts[p, 1] - cy
                    dz = pts[p, 2] - cz
                    if dx * dx + dy * dy + dz * dz > r2:
                        continue
                    if nrm[p, 0] * nrm[q, 0] + nrm[p, 1] * nrm[q, 1] + nrm[p, 2] * nrm[q, 2] <= 0.0:
                        continue
                    ax += nrm[p, 0] * areas[p]
                    ay += nrm[p, 1] * areas[p]
                    az += nrm[p, 2] * areas[p]
        out[q, 0] = ax
        out[q, 1] = ay
        out[q, 2] = az


def smooth_normals(points: np.ndarray, normals: np.ndarray, areas: np.ndarray, radius: float) -> np.ndarray:
    """Area-weighted sum of the unit ``normals`` ``(n, 3)`` over the ball of ``radius`` (m) about
    each point ``(n, 3)``, neighbours whose normal points away (dot product ≤ 0) left out; ``(n, 3)``,
    not normalised.  The compiled form of the pair sum in
    :func:`swath.surface.geometry.smooth_vertex_normals` (the same pairs: distance ≤ ``radius``)."""
    grid = sample_grid(points, normals, areas, cell=float(radius))
    acc = np.empty((len(grid), 3))
    # Cells along z of one (x, y) column are contiguous, so each column is one run of samples.
    _smooth(grid.points, grid.normals, grid.areas, grid.origin, grid.cell, grid.dims, grid.start, float(radius), acc)
    out = np.empty_like(acc)
    out[grid.order] = acc
    return out
