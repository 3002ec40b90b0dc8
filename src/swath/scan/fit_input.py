"""Input checks and parameterisation of :func:`swath.scan.fit.fit_patch`: one patch (no
separate pieces, no closed mesh), projection onto the best-fit plane, or LSCM of a mesh."""

from __future__ import annotations

import logging

import numpy as np

from ..errors import InfeasibleError, InputError

log = logging.getLogger("swath.scan.fit")
# ----------------------------------------------------------------------------------------------
# Input checks
# ----------------------------------------------------------------------------------------------
def _pair(value, name: str) -> tuple[int, int]:
    arr = np.broadcast_to(np.asarray(value), (2,)) if np.ndim(value) <= 1 else None
    if arr is None or arr.shape != (2,):
        raise InputError(f"{name} must be an int or a pair of ints, got {value!r}")
    try:
        a, b = (int(x) for x in arr)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be an int or a pair of ints, got {value!r}") from None
    if a != arr[0] or b != arr[1]:
        raise InputError(f"{name} must be integers, got {value!r}")
    return a, b


def _optional_array(a, shape, name, dtype):
    if a is None:
        return None
    arr = np.asarray(a)
    if arr.ndim != len(shape) or any(s is not None and s != d for s, d in zip(shape, arr.shape)):
        want = "(" + ", ".join("k" if s is None else str(s) for s in shape) + ")"
        raise InputError(f"expected {name} of shape {want}, got {arr.shape}")
    if dtype is int:
        if not np.issubdtype(arr.dtype, np.integer):
            if not (np.isfinite(arr).all() and np.all(np.mod(arr, 1) == 0)):
                raise InputError(f"{name} must be integers")
        return arr.astype(np.int64)
    arr = arr.astype(float)
    if not np.isfinite(arr).all():
        raise InputError(f"{name} contain NaN or infinite values")
    return arr


def _check_spread(X: np.ndarray) -> None:
    c = X.mean(axis=0)
    ev = np.linalg.eigvalsh(np.cov((X - c).T))
    if not ev[2] > 0:
        raise InputError("all points coincide; a surface cannot be fitted")
    if ev[1] <= 1e-8 * ev[2]:
        raise InputError("the points are (nearly) collinear; a surface patch needs points spread in two directions")


def _nn_scale(X: np.ndarray, tree=None, k: int = 8, sample: int = 5000, nearest_pct: float = 50.0):
    """A percentile (default the median) of the nearest-neighbour distance and the 95th
    percentile of the k-th neighbour distance, m (estimated on a sample of the points)."""
    from scipy.spatial import cKDTree

    tree = tree if tree is not None else cKDTree(X)
    rng = np.random.default_rng(0)
    idx = rng.choice(len(X), size=min(sample, len(X)), replace=False)
    d, _ = tree.query(X[idx], k=min(k + 1, len(X)))
    return float(np.percentile(d[:, 1], nearest_pct)), float(np.percentile(d[:, -1], 95))


def _main_piece(X: np.ndarray) -> np.ndarray:
    """Mask of the points in the largest connected piece; refuses several sizeable pieces.

    Connectivity: points are voxelised at three times the 95th-percentile 8th-neighbour distance
    and voxels touching (26-neighbourhood) are joined.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    _, d8 = _nn_scale(X)
    cell = 3.0 * max(d8, 1e-12)
    ijk = np.floor((X - X.min(axis=0)) / cell).astype(np.int64)
    dims = ijk.max(axis=0) + 3
    keys = ((ijk[:, 0] + 1) * dims[1] + (ijk[:, 1] + 1)) * dims[2] + (ijk[:, 2] + 1)
    vox, inv = np.unique(keys, return_inverse=True)
    inv = inv.ravel()
    src, dst = [], []
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            for dz in (-1, 0, 1):
                if (dx, dy, dz) <= (0, 0, 0):
                    continue
                nb = vox + (dx * dims[1] + dy) * dims[2] + dz
                pos = np.clip(np.searchsorted(vox, nb), 0, len(vox) - 1)
                hit = vox[pos] == nb
                src.append(np.nonzero(hit)[0])
                dst.append(pos[hit])
    rows, cols = np.concatenate(src), np.concatenate(dst)
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(vox), len(vox)))
    n_comp, label = connected_components(graph, directed=False)
    if n_comp == 1:
        return np.ones(len(X), dtype=bool)
    sizes = np.bincount(label[inv], minlength=n_comp)
    order = np.argsort(-sizes)
    big = sizes >= max(0.01 * len(X), 10)
    if big.sum() > 1:
        shown = ", ".join(str(s) for s in sizes[order][:5])
        raise InfeasibleError(f"the points form {int(big.sum())} separate pieces (sizes {shown} points; gaps wider "
                              f"than {cell * 1e3:.3g} mm), not one patch; fit each piece separately")
    return label[inv] == order[0]


def _check_mesh_patch(n_vertices: int, F: np.ndarray) -> None:
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    from ..surface.topology import boundary_edges

    used = np.unique(F)
    if len(used) < n_vertices:
        raise InputError(f"{n_vertices - len(used)} points are not used by any face; pass only the mesh's "
                         "vertices with mesh_faces (or fit the points without faces)")
    e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    graph = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n_vertices, n_vertices))
    n_comp, label = connected_components(graph, directed=False)
    if n_comp > 1:
        sizes = np.sort(np.bincount(label))[::-1]
        raise InfeasibleError(f"the mesh has {n_comp} separate pieces (sizes {', '.join(map(str, sizes[:5]))} "
                              "vertices), not one patch; fit each piece separately")
    if len(boundary_edges(F)) == 0:
        raise InfeasibleError("the mesh is closed (no boundary), so one patch cannot cover it; cut it into "
                              "open patches first")


# ----------------------------------------------------------------------------------------------
# Parameterisations
# ----------------------------------------------------------------------------------------------
def _signed_areas(uv: np.ndarray, F: np.ndarray) -> np.ndarray:
    a, b, c = uv[F[:, 0]], uv[F[:, 1]], uv[F[:, 2]]
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))


def _flipped_triangles(uv: np.ndarray, F: np.ndarray) -> tuple[int, int]:
    """Count of triangles with negative and positive signed area in the parameter plane (area
    below 1e-9 of the mean is ignored)."""
    area = _signed_areas(uv, F)
    eps = 1e-9 * np.abs(area).mean()
    return int((area < -eps).sum()), int((area > eps).sum())


def _projection_parameters(X: np.ndarray, F):
    """Coordinates ``(n, 2)`` in the best-fit plane, and whether (and why) the projection folds."""
    from scipy.spatial import cKDTree

    c = X.mean(axis=0)
    _, vecs = np.linalg.eigh(np.cov((X - c).T))
    e1, e2 = vecs[:, 2], vecs[:, 1]
    uv = np.stack([(X - c) @ e1, (X - c) @ e2], axis=1)
    if F is not None:
        neg, pos = _flipped_triangles(uv, F)
        if pos < neg:                       # winding says the normal side is -e3: mirror v
            e2 = -e2
            uv[:, 1] *= -1
            neg, pos = pos, neg
        if neg > 0:
            return uv, True, f"{neg} of {len(F)} triangles flip over in the plane"
        return uv, False, ""
    # Without faces: points that are neighbours in the plane but far apart in space lie on
    # different layers of a fold.
    h, _ = _nn_scale(X)
    k = min(9, len(X))
    d2, idx = cKDTree(uv).query(uv, k=k)
    d3 = np.linalg.norm(X[idx] - X[:, None, :], axis=2)
    layered = np.any(d3 > 3.0 * d2 + 10.0 * h, axis=1)
    frac = layered.mean()
    if frac > 0.005:
        return uv, True, f"{100 * frac:.1f} % of the points lie over other points"
    return uv, False, ""


def _lscm_parameters(X: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Least-squares conformal map of the mesh, rotated to its principal axes and scaled so the
    parameter area equals the surface area (parameters in metres, roughly arc length)."""
    try:
        import igl
    except ImportError:  # pragma: no cover - libigl is a dependency
        raise InputError("the 'lscm' parameterisation needs libigl (pip install libigl)") from None
    from ..surface.geometry import face_normals_and_areas

    Fi = np.ascontiguousarray(F, dtype=np.int64)
    bnd = np.asarray(igl.boundary_loop(Fi), dtype=np.int64)
    a = bnd[np.argmax(np.linalg.norm(X[bnd] - X[bnd[0]], axis=1))]
    b = bnd[np.argmax(np.linalg.norm(X[bnd] - X[a], axis=1))]
    d = float(np.linalg.norm(X[a] - X[b]))
    res = igl.lscm(np.ascontiguousarray(X), Fi, np.array([a, b], dtype=np.int64),
                   np.array([[0.0, 0.0], [d, 0.0]]))
    uv = np.asarray(res[0] if isinstance(res, tuple) else res, dtype=float)
    if not np.isfinite(uv).all():
        raise InfeasibleError("the LSCM parameterisation failed (non-finite result); check the mesh for "
                              "degenerate or non-manifold triangles")
    uv = uv - uv.mean(axis=0)
    _, vecs = np.linalg.eigh(np.cov(uv.T))
    uv = uv @ vecs[:, ::-1]
    neg, pos = _flipped_triangles(uv, F)
    if pos < neg:
        uv[:, 1] *= -1
        neg, pos = pos, neg
    if neg > 0:
        raise InfeasibleError(f"the LSCM parameterisation folds over: {neg} of {len(F)} triangles are flipped in "
                              "the parameter plane; repair the mesh (fold-overs, spikes) or cut it into simpler "
                              "patches")
    _, area3 = face_normals_and_areas(X, F)
    area2 = np.abs(_signed_areas(uv, F)).sum()
    return uv * np.sqrt(area3.sum() / area2)
