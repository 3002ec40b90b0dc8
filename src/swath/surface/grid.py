"""Triangles of a structured vertex grid (the triangulation of a patch sampled on a parameter grid)."""

from __future__ import annotations

import numpy as np


def grid_faces(n_u: int, n_v: int) -> np.ndarray:
    """Triangles ``(2 (n_u−1)(n_v−1), 3)`` int of a structured ``n_u × n_v`` vertex grid (row-major in
    u: vertex ``i * n_v + j`` is at grid position ``(i, j)``)."""
    i, j = np.meshgrid(np.arange(n_u - 1), np.arange(n_v - 1), indexing="ij")
    a = (i * n_v + j).ravel()
    b, c, d = a + n_v, a + n_v + 1, a + 1
    return np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
