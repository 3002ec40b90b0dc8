"""The removal kernel built with the compiled contact kernels gives the matrix the numpy pair lists
give (float64 against float32: the same pairs, rates within float32 rounding)."""

import numpy as np
import pytest

from shapes import sphere_cap
from swath.contact import Tool, kernels
from swath.errors import InputError
from swath.feed import build_kernel
from swath.plan import Pass, ToolPath

pytestmark = pytest.mark.skipif(not kernels.AVAILABLE, reason="numba is not installed")


def _toolpath(lead_tool=None):
    s = sphere_cap(0.2, 0.5, n=40)                                   # curved: the pad sinks unevenly
    x = np.linspace(-0.08, 0.08, 81)
    passes = []
    for y in (-0.04, 0.0, 0.035):
        d = np.stack([x, np.full_like(x, y), np.sqrt(0.2**2 - x**2 - y**2)], 1)
        passes.append(Pass(0.2 * d / np.linalg.norm(d, axis=1, keepdims=True), d / np.linalg.norm(d, axis=1,
                                                                                                keepdims=True)))
    return ToolPath(s, passes, "test")


@pytest.mark.parametrize("tool", [Tool(), Tool(motion="rotary")])
def test_compiled_and_numpy_kernels_agree(tool):
    tp = _toolpath()
    fast = build_kernel(tp, tool, sample_spacing=3e-3, engine="compiled")
    slow = build_kernel(tp, tool, sample_spacing=3e-3, engine="numpy", nodes=fast.nodes)
    a, b = fast.matrix.tocsr(), slow.matrix.tocsr()
    assert a.shape == b.shape and a.nnz > 1000
    # the same non-zeros (pairs); the rates to the float32 rounding of the heights the pressure comes
    # from, which is absolute (about 1e-8 m at 0.2 m from the origin): measured 3e-6 of the largest rate
    assert np.array_equal(a.indptr, b.indptr) and np.array_equal(a.indices, b.indices)
    assert np.allclose(a.data, b.data, rtol=0.0, atol=3e-5 * float(np.abs(b.data).max()))
    dwell = np.full(len(fast.nodes), 0.1)
    depth = slow.removal(dwell)                                      # measured: 7e-6 of the deepest
    assert np.allclose(fast.removal(dwell), depth, rtol=0.0, atol=3e-5 * depth.max())


def test_an_unknown_engine_is_refused():
    with pytest.raises(InputError, match="kernel engine"):
        build_kernel(_toolpath(), Tool(), sample_spacing=3e-3, engine="gpu")
