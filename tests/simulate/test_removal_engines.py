"""simulate_removal: the compiled engine gives the numpy (pair-list, float32) engine's depth and metrics."""

import numpy as np
import pytest

from shapes import sphere_cap
from swath.contact import Tool, kernels
from swath.errors import InputError
from swath.examples import flat_plate
from swath.plan import Pass, ToolPath
from swath.simulate import simulate_removal
from swath.trajectory import FeedLimit, time_path

pytestmark = pytest.mark.skipif(not kernels.AVAILABLE, reason="numba not installed")


def plate_raster():
    s = flat_plate()
    passes = [Pass(np.array([[0.0, y, 0.0], [0.4, y, 0.0]]), np.array([[0, 0, 1.0]] * 2))
              for y in np.linspace(0.04, 0.26, 5)]
    return s, time_path(ToolPath(s, passes, "test"), [FeedLimit(0.05)])


def sphere_passes():
    s = sphere_cap(0.2, 0.5, n=90)
    passes = []
    for y in (-0.03, 0.0, 0.03):
        x = np.linspace(-0.07, 0.07, 60)
        d = np.stack([x, np.full_like(x, y), np.sqrt(0.2**2 - x**2 - y**2)], 1)
        n = d / np.linalg.norm(d, axis=1, keepdims=True)
        passes.append(Pass(d, n))
    return s, time_path(ToolPath(s, passes, "test"), [FeedLimit(0.05)])


def check_same(compiled, numpy_):
    # float32 rounding in the numpy engine: depths to 1e-4 of the peak, metrics to 4 digits
    assert np.array_equal(compiled.depth > 0, numpy_.depth > 0)
    assert np.abs(compiled.depth - numpy_.depth).max() <= 1e-4 * numpy_.depth.max()
    assert compiled.metrics.keys() == numpy_.metrics.keys()
    for key, value in numpy_.metrics.items():
        assert compiled.metrics[key] == pytest.approx(value, rel=5e-5), key


@pytest.mark.parametrize("motion", ["orbital", "rotary"])
@pytest.mark.parametrize("case", [plate_raster, sphere_passes], ids=["plate", "sphere"])
def test_compiled_engine_matches_numpy_engine(case, motion):
    s, tr = case()
    tool = Tool(motion=motion)
    check_same(simulate_removal(tr, s, tool, engine="compiled"), simulate_removal(tr, s, tool, engine="numpy"))


def test_compiled_engine_with_per_sample_force():
    s, tr = plate_raster()
    tool = Tool()
    force = 20.0 + 8.0 * np.sin(np.linspace(0.0, 30.0, len(tr)))
    compiled = simulate_removal(tr, s, tool, force=force, engine="compiled")
    check_same(compiled, simulate_removal(tr, s, tool, force=force, engine="numpy"))
    # and the force does act: the depth differs from the constant-force run
    assert np.abs(compiled.depth - simulate_removal(tr, s, tool).depth).max() > 0.01 * compiled.depth.max()


def test_auto_engine_is_the_compiled_one_and_progress_is_reported():
    s, tr = plate_raster()
    seen = []
    auto = simulate_removal(tr, s, Tool(), chunk=200, progress=lambda done, total: seen.append((done, total)))
    compiled = simulate_removal(tr, s, Tool(), engine="compiled")
    # other batches sum in another order: equal to round-off
    assert np.allclose(auto.depth, compiled.depth, rtol=1e-12, atol=0.0)
    total = seen[-1][1]
    assert seen[-1][0] == total and [d for d, _ in seen] == sorted(d for d, _ in seen) and len(seen) == -(-total // 200)


def test_unknown_engine_is_refused():
    s, tr = plate_raster()
    with pytest.raises(InputError, match="engine must be one of"):
        simulate_removal(tr, s, Tool(), engine="gpu")


def test_without_numba_auto_falls_back_to_numpy_and_compiled_is_refused(monkeypatch):
    s, tr = plate_raster()
    numpy_ = simulate_removal(tr, s, Tool(), engine="numpy")
    monkeypatch.setattr(kernels, "AVAILABLE", False)
    assert np.array_equal(simulate_removal(tr, s, Tool()).depth, numpy_.depth)
    with pytest.raises(InputError, match="needs numba"):
        simulate_removal(tr, s, Tool(), engine="compiled")


def test_depth_is_the_same_on_any_cpu_share(monkeypatch):
    # A batch job on one CPU (Ray sets OMP_NUM_THREADS=1) must give the figures of the same job on two.
    s, tr = plate_raster()
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    one = simulate_removal(tr, s, Tool(), engine="compiled")
    monkeypatch.setenv("OMP_NUM_THREADS", "2")
    two = simulate_removal(tr, s, Tool(), engine="compiled")
    assert np.array_equal(one.depth, two.depth) and one.metrics == two.metrics
