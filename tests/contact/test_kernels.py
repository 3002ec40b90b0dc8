"""The compiled contact kernels against the numpy pair-list model (same model, float64 samples)."""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from shapes import cylinder_patch, sphere_cap
from swath.contact import Tool, kernels, mesh_contact
from swath.errors import InputError
from swath.examples import flat_plate

pytestmark = pytest.mark.skipif(not kernels.AVAILABLE, reason="numba not installed")

SRC = Path(kernels.__file__).resolve().parents[2]


def plate():
    return flat_plate(spacing=3e-3)


def sphere():
    return sphere_cap(0.1, 0.6, n=140)


def cylinder():
    return cylinder_patch(0.06, 1.2, 0.2, n_theta=160, n_len=70)


def poses_on(surface, n, rng, *, lift=-5e-4, tilt=0.15):
    """``n`` TCPs near random vertices (``lift`` m along the normal), axes against the normal with
    a random tilt (rad)."""
    sel = rng.choice(len(surface.vertices), n, replace=False)
    axes = -surface.normals[sel] + tilt * rng.normal(size=(n, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    return surface.vertices[sel] + lift * surface.normals[sel], axes


def numpy_depth(surface, positions, axes, weight, tool, force=None):
    """The reference: float64 mesh_contact pairs, Preston rate summed per sample with bincount."""
    mc = mesh_contact(surface.vertices, surface.normals, surface.vertex_areas, surface.kdtree, positions, axes,
                      tool, force=force)
    rate = tool.preston * mc.pressure * tool.relative_speed(mc.radius)
    return np.bincount(mc.sample, weights=rate * weight[mc.pose], minlength=len(surface.vertices)), mc.sink


@pytest.mark.parametrize("make", [plate, sphere, cylinder], ids=["plate", "sphere", "cylinder"])
@pytest.mark.parametrize("motion", ["orbital", "rotary"])
@pytest.mark.parametrize("per_pose_force", [False, True], ids=["tool-force", "pose-force"])
def test_removal_kernel_equals_numpy_model(make, motion, per_pose_force):
    rng = np.random.default_rng(7)
    s = make()
    tool = Tool(motion=motion)
    positions, axes = poses_on(s, 40, rng)
    weight = rng.uniform(0.01, 0.05, len(positions))
    force = rng.uniform(5.0, 40.0, len(positions)) if per_pose_force else None
    expected, sink_expected = numpy_depth(s, positions, axes, weight, tool, force)
    grid = kernels.sample_grid(s.vertices, s.normals, s.vertex_areas, cell=kernels.default_cell(tool))
    out, sink = kernels.accumulate_removal(grid, positions, axes, weight, tool, force=force, threads=2)
    depth = kernels.depth_in_input_order(grid, out)
    assert (expected > 0).sum() > 1000                           # the poses do press into the part
    assert np.array_equal(depth > 0, expected > 0)
    assert np.abs(depth - expected).max() <= 1e-9 * expected.max()
    assert np.allclose(sink, sink_expected, rtol=1e-12, atol=1e-15)


def test_thread_count_does_not_change_the_depth_beyond_round_off():
    rng = np.random.default_rng(3)
    s = sphere()
    tool = Tool()
    positions, axes = poses_on(s, 30, rng)
    grid = kernels.sample_grid(s.vertices, s.normals, s.vertex_areas, cell=kernels.default_cell(tool))
    one = kernels.depth_in_input_order(grid, kernels.accumulate_removal(grid, positions, axes, np.ones(30), tool,
                                                                        threads=1)[0])
    three = kernels.depth_in_input_order(grid, kernels.accumulate_removal(grid, positions, axes, np.ones(30), tool,
                                                                          threads=3)[0])
    assert np.allclose(one, three, rtol=1e-13, atol=0.0)


def test_flat_plate_depth_is_preston_times_dwell():
    # One pose on a plate: every sample under the pad gets k_p · k·e · v · dwell (orbital pad).
    tool = Tool()
    s = flat_plate(spacing=2e-3)
    grid = kernels.sample_grid(s.vertices, s.normals, s.vertex_areas, cell=kernels.default_cell(tool))
    out, sink = kernels.accumulate_removal(grid, np.array([[0.2, 0.15, 0.0]]), np.array([[0.0, 0.0, -1.0]]),
                                           np.array([2.0]), tool)
    depth = kernels.depth_in_input_order(grid, out)
    inside = np.hypot(s.vertices[:, 0] - 0.2, s.vertices[:, 1] - 0.15) < tool.pad_radius - 3e-3
    # sample areas within R add up to πR² only to the sampling resolution: the sink to 0.3 %
    assert sink[0] == pytest.approx(tool.flat_depression, rel=3e-3)
    expected = tool.preston * tool.k * sink[0] * tool.spindle_speed * tool.orbit_radius * 2.0
    assert np.allclose(depth[inside], expected, rtol=1e-12)
    assert np.all(depth[np.hypot(s.vertices[:, 0] - 0.2, s.vertices[:, 1] - 0.15) > tool.pad_radius + 1e-9] == 0)


def test_contact_pairs_equal_mesh_contact():
    rng = np.random.default_rng(11)
    s = cylinder()
    tool = Tool(motion="rotary")
    positions, axes = poses_on(s, 25, rng)
    ref = mesh_contact(s.vertices, s.normals, s.vertex_areas, s.kdtree, positions, axes, tool)
    got = mesh_contact(s.vertices, s.normals, s.vertex_areas, None, positions, axes, tool, engine="compiled")
    assert np.all(np.diff(got.pose) >= 0)
    a, b = np.lexsort((ref.sample, ref.pose)), np.lexsort((got.sample, got.pose))
    assert np.array_equal(ref.pose[a], got.pose[b]) and np.array_equal(ref.sample[a], got.sample[b])
    assert np.allclose(got.pressure[b], ref.pressure[a], rtol=1e-9, atol=1e-9 * ref.pressure.max())
    assert np.allclose(got.radius[b], ref.radius[a], rtol=0, atol=1e-9)
    assert np.allclose(got.sink, ref.sink, rtol=1e-12)


def test_far_poses_and_sparse_grid():
    # Two plates 70 m apart (diagonally): the grid grows its cells to stay small, and still finds every sample;
    # a pose in the empty space between them touches nothing (NaN sink, no depth).
    tool = Tool()
    a = flat_plate(spacing=4e-3)
    pts = np.concatenate([a.vertices, a.vertices + [50.0, 0.0, 50.0]])
    nrm = np.concatenate([a.normals, a.normals])
    area = np.concatenate([a.vertex_areas, a.vertex_areas])
    grid = kernels.sample_grid(pts, nrm, area, cell=kernels.default_cell(tool))
    assert np.prod(grid.dims) <= 8 * len(pts) and grid.cell > kernels.default_cell(tool)
    positions = np.array([[0.2, 0.15, 0.0], [50.2, 0.15, 50.0], [25.0, 0.15, 25.0]])
    axes = np.tile([0.0, 0.0, -1.0], (3, 1))
    out, sink = kernels.accumulate_removal(grid, positions, axes, np.ones(3), tool)
    depth = kernels.depth_in_input_order(grid, out)
    n = len(a.vertices)
    assert np.isnan(sink[2]) and sink[0] == pytest.approx(sink[1], rel=1e-12)
    assert np.allclose(depth[:n], depth[n:], rtol=1e-12) and depth[:n].max() > 0


def test_pad_facing_away_touches_nothing():
    tool = Tool()
    s = plate()
    grid = kernels.sample_grid(s.vertices, s.normals, s.vertex_areas, cell=kernels.default_cell(tool))
    out, sink = kernels.accumulate_removal(grid, np.array([[0.2, 0.15, 0.0]]), np.array([[0.0, 0.0, 1.0]]),
                                           np.ones(1), tool)
    assert np.isnan(sink[0]) and not out.any()


def test_refuses_bad_input():
    tool = Tool()
    s = plate()
    with pytest.raises(InputError, match="positive length"):
        kernels.sample_grid(s.vertices, s.normals, s.vertex_areas, cell=0.0)
    with pytest.raises(InputError, match=r"\(S, 3\)"):
        kernels.sample_grid(s.vertices[:, :2], s.normals, s.vertex_areas, cell=0.01)
    grid = kernels.sample_grid(s.vertices, s.normals, s.vertex_areas, cell=0.01)
    with pytest.raises(InputError, match="one dwell"):
        kernels.accumulate_removal(grid, np.zeros((2, 3)), np.zeros((2, 3)), np.ones(3), tool)
    with pytest.raises(InputError, match="one value"):
        kernels.accumulate_removal(grid, np.zeros((2, 3)), np.zeros((2, 3)), np.ones(2), tool, force=np.ones(3))
    with pytest.raises(InputError, match="'numpy' or 'compiled'"):
        mesh_contact(s.vertices, s.normals, s.vertex_areas, s.kdtree, np.zeros((1, 3)), np.zeros((1, 3)), tool,
                     engine="fast")


def test_kernels_work_without_a_writable_cache():
    # With no cache locator numba refuses cache=True at decoration; the module must still import
    # and compile in memory.
    code = textwrap.dedent("""
        import numba.core.caching as caching
        caching.CacheImpl._locator_classes = []
        import numpy as np
        from swath.contact import kernels
        s = kernels._sink(np.array([0.0, 1.0, 2.0]), np.ones(3), 3, 4.0)
        print(type(kernels._sink._cache).__name__, repr(s))
    """)
    env = dict(os.environ, PYTHONPATH=str(SRC))
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert done.returncode == 0, done.stderr
    cache, s = done.stdout.split()
    assert cache == "NullCache" and float(s) == pytest.approx(7.0 / 3.0, rel=1e-15)
