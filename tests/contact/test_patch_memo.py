"""unique_patches answers repeated questions from its memo with the same patch and rows as a fresh
solve, and each caller gets rows of its own."""

from __future__ import annotations

import numpy as np

from swath.contact import Tool, widths
from swath.contact.model import local_patch


def test_memo_answers_as_a_fresh_solve(rng):
    tool = Tool()
    k1 = rng.uniform(-5.0, 5.0, 300)
    k2 = rng.uniform(-5.0, 5.0, 300)
    widths._PATCHES.clear()
    patch, rows = widths.unique_patches(k1, k2, tool, 180)
    again, rows_again = widths.unique_patches(k1.copy(), k2.copy(), tool, 180)
    assert again is patch and rows_again is not rows and np.array_equal(rows_again, rows)
    rows_again[:] = -1                                   # a caller's rows are its own
    assert np.array_equal(widths.unique_patches(k1, k2, tool, 180)[1], rows)
    # the same as solving the rounded pairs afresh
    step = widths.CURVATURE_STEP / tool.pad_radius
    key = np.round(np.stack([k1, k2], axis=1) / step)
    uniq, inverse = np.unique(key, axis=0, return_inverse=True)
    fresh = local_patch(uniq[:, 0] * step, uniq[:, 1] * step, tool, n_rays=180)
    assert np.array_equal(inverse.ravel(), rows)
    assert np.array_equal(fresh.min_width(), patch.min_width())
    assert np.array_equal(fresh.max_width(36), patch.max_width(36))


def test_memo_tells_tools_and_curvatures_apart(rng):
    k1, k2 = rng.uniform(-5.0, 5.0, 50), rng.uniform(-5.0, 5.0, 50)
    a = widths.unique_patches(k1, k2, Tool(), 180)[0]
    b = widths.unique_patches(k1, k2, Tool(pad_radius=0.02), 180)[0]
    c = widths.unique_patches(k1 + 1.0, k2, Tool(), 180)[0]
    assert a is not b and a is not c
    assert not np.array_equal(a.min_width(), b.min_width())
    for _ in range(widths.PATCH_MEMO_ENTRIES + 2):      # bounded: the oldest answers go first
        widths.unique_patches(rng.uniform(-5.0, 5.0, 10), k2[:10], Tool(), 180)
    assert len(widths._PATCHES) == widths.PATCH_MEMO_ENTRIES
