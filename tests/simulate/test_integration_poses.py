"""The simulator groups trajectory samples by the distance travelled, so a varying feed is
integrated as finely as a constant one (the trajectory is sampled in time)."""

import numpy as np

from swath.contact import Tool
from swath.examples import flat_plate
from swath.simulate import simulate_removal
from swath.trajectory import Trajectory


def two_speed_pass(slow: float, fast: float, dt: float = 0.02) -> Trajectory:
    """A straight pass along x at y = 0.15 m on the plate: ``slow`` m/s up to x = 0.2 m, then
    ``fast`` m/s to x = 0.4 m, sampled every ``dt`` s (as timing samples: in time, not in distance)."""
    x = [0.0]
    while x[-1] < 0.4:
        x.append(x[-1] + (slow if x[-1] < 0.2 else fast) * dt)
    x = np.asarray(x)
    n = len(x)
    position = np.column_stack([x, np.full(n, 0.15), np.zeros(n)])
    quaternion = np.tile([0.0, 1.0, 0.0, 0.0], (n, 1))     # w, x, y, z: tool z along -z of the part
    feed = np.where(x < 0.2, slow, fast)
    return Trajectory(t=np.arange(n) * dt, position=position, quaternion=quaternion, contact=np.ones(n, bool),
                      feed=feed, pass_index=np.zeros(n, int))


def test_fast_stretch_of_a_varying_feed_gets_the_preston_depth():
    tool, plate = Tool(), flat_plate()
    slow, fast = 0.02, 0.1               # 0.4 mm and 2 mm per sample
    removal = simulate_removal(two_speed_pass(slow, fast), plate, tool, sample_spacing=2e-3)
    v = removal.surface.vertices
    y = np.abs(v[:, 1] - 0.15)
    inside = y < 0.9 * tool.pad_radius
    rate = tool.preston * tool.k * tool.flat_depression * tool.relative_speed(0.0)
    for x_mid, feed in ((0.1, slow), (0.3, fast)):
        near = inside & (np.abs(v[:, 0] - x_mid) < 0.04)
        expected = rate * 2 * np.sqrt(tool.pad_radius**2 - y[near] ** 2) / feed
        assert np.max(np.abs(removal.depth[near] / expected - 1)) < 0.05, feed


def test_slow_stretch_gets_the_preston_depth_at_the_edge_of_the_contact_patch():
    """Samples near the side edge of the pad's track are touched along a short chord.  At a tenth of
    the feed a 2 mm group of poses holds ten times the dwell of one at the feed, and a sample that
    only part of the group touches got all of its dwell or none (20 % off here, 0.7 % now);
    the simulator bounds each group's time as well as its travel."""
    tool, plate = Tool(), flat_plate()
    slow, fast = 0.004, 0.05
    removal = simulate_removal(two_speed_pass(slow, fast), plate, tool, sample_spacing=2e-3)
    v = removal.surface.vertices
    y = np.abs(v[:, 1] - 0.15)
    chord = 2 * np.sqrt(np.maximum(tool.pad_radius**2 - y**2, 0.0))
    rate = tool.preston * tool.k * tool.flat_depression * tool.relative_speed(0.0)
    rim = (chord > 5e-3) & (y > 0.9 * tool.pad_radius) & (np.abs(v[:, 0] - 0.1) < 0.04)
    assert rim.sum() > 20
    expected = rate * chord[rim] / slow
    assert np.max(np.abs(removal.depth[rim] / expected - 1)) < 0.03


def test_constant_feed_groups_equal_travel_and_a_slow_stretch_equal_time():
    """1 mm steps at 50 mm/s: groups of three samples (3 mm, 60 ms).  At 5 mm/s (0.1 mm steps) a
    3 mm group would hold 0.6 s; bounded in time at the fast feed it holds the same 60 ms."""
    from swath.simulate.removal import _integration_poses

    dt = 0.02
    trajectory = two_speed_pass(0.005, 0.05, dt=dt)
    idx, dwell = _integration_poses(trajectory, 3e-3)
    x = trajectory.position[idx, 0]
    inner = dwell[1:-1]
    assert np.allclose(inner, 3 * dt)                          # every group but the ends: 3 samples
    fast, slow = np.diff(x)[x[1:] > 0.21], np.diff(x)[x[:-1] < 0.19]
    assert np.allclose(fast, 3e-3, atol=1e-9) and np.allclose(slow, 0.3e-3, atol=1e-9)
    assert np.isclose(dwell.sum(), trajectory.t[-1])
