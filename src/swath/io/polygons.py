"""Polygon helpers shared by the mesh readers: fan triangulation and unit rows."""

from __future__ import annotations

import numpy as np

#: Larger indices than this are refused as corrupt (they could not be stored as int64 arrays).
MAX_INDEX = 2**62


def fan_triangles(corners: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Fan triangles (t, 3) of polygons given as flattened ``corners`` with ``counts`` corners each."""
    if len(counts) == 0:
        return np.zeros((0, 3), dtype=np.int64)
    start = np.r_[0, np.cumsum(counts)[:-1]]
    n_tri = counts - 2
    first = np.repeat(start, n_tri)
    step = np.arange(int(n_tri.sum())) - np.repeat(np.r_[0, np.cumsum(n_tri)[:-1]], n_tri)
    return np.stack([corners[first], corners[first + step + 1], corners[first + step + 2]], axis=1)


def triangulate(faces) -> np.ndarray:
    """Polygon faces, a (m, k) array or a ragged list, as (t, 3) int64 fan triangles; rows of < 3 dropped."""
    if faces is None:
        return np.zeros((0, 3), dtype=np.int64)
    try:
        rows = np.asarray(faces, dtype=np.int64)
    except (ValueError, TypeError):
        rows = None
    if rows is not None and rows.ndim == 2:
        if rows.shape[1] < 3:
            return np.zeros((0, 3), dtype=np.int64)
        return fan_triangles(rows.ravel(), np.full(len(rows), rows.shape[1], dtype=np.int64))
    polys = [np.asarray(p, dtype=np.int64).ravel() for p in faces]
    polys = [p for p in polys if len(p) >= 3]
    if not polys:
        return np.zeros((0, 3), dtype=np.int64)
    return fan_triangles(np.concatenate(polys), np.array([len(p) for p in polys], dtype=np.int64))


def unit_rows(a: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        unit = a / np.linalg.norm(a, axis=1, keepdims=True)
    return np.nan_to_num(unit, nan=0.0, posinf=0.0, neginf=0.0)
