"""Re-timing a plan and simulating it again reuse what does not change (links, air routes, the
passes' grids, the removal sample mesh), and the answers are the same bit for bit as when
everything is computed afresh."""

import numpy as np
import pytest

import swath.contact.widths as widths_module
import swath.trajectory.timing as timing_module
from swath.contact import Tool
from swath.examples import doubly_curved_panel
from swath.order.routing import AirGuard
from swath.plan import raster
from swath.simulate import simulate_removal
from swath.trajectory import AngularSpeedLimit, CentripetalLimit, FeedLimit, FeedProfile, LinkSettings, time_path
from swath.trajectory.links import clear_link_cache, time_link

TOOL = Tool()
CONS = [FeedLimit(0.05), CentripetalLimit(2.0), AngularSpeedLimit(1.0)]


def _forget_everything():
    clear_link_cache()
    widths_module._MEMO.clear()          # air routes and removal samples, per surface
    timing_module._PASS_GEOMETRY.clear()


def _same(a, b):
    for name in ("t", "position", "quaternion", "contact", "feed", "pass_index"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    for name in ("wx", "wy", "wz"):
        assert np.array_equal(a.extra[name], b.extra[name]), name


@pytest.fixture(scope="module")
def plan():
    return raster(doubly_curved_panel(), TOOL)


def _slower_in_the_middle(tp):
    """A feed profile: 30 mm/s on the middle third of every pass, 50 mm/s elsewhere."""
    speeds = []
    for p in tp.passes:
        v = np.full(len(p.points), 0.05)
        k = len(v)
        v[k // 3: 2 * k // 3] = 0.03
        speeds.append(v)
    return FeedProfile(speeds)


def test_retiming_with_another_feed_is_the_same_as_timing_afresh(plan):
    profile = _slower_in_the_middle(plan)
    _forget_everything()
    first = time_path(plan, CONS)                        # fills every store
    again = time_path(plan, CONS + [profile])            # links, routes and grids reused
    _forget_everything()
    fresh = time_path(plan, CONS + [profile])
    _same(again, fresh)
    # ... and the profile did change the timing (the reuse is not of the timed speeds)
    assert again.duration > first.duration + 1.0


def test_a_link_is_timed_once_and_handed_out_read_only():
    clear_link_cache()
    route = np.array([[0.0, 0, 0], [0.0, 0, 0.02], [0.1, 0.0, 0.02], [0.1, 0.0, 0.0]])
    q = np.array([1.0, 0, 0, 0])
    a = time_link(route, q, q, LinkSettings())
    b = time_link(route.copy(), q.copy(), q.copy(), LinkSettings())
    assert b is a
    with pytest.raises(ValueError):
        a.t[0] = 1.0
    # any input that differs gives its own link
    c = time_link(route, q, q, LinkSettings(speed=0.1))
    assert c is not a and c.duration > a.duration
    d = time_link(route, q, q, LinkSettings(), include_end=False)
    assert len(d.t) == len(a.t) - 1
    clear_link_cache()
    e = time_link(route, q, q, LinkSettings())
    assert e is not a and np.array_equal(e.t, a.t) and np.array_equal(e.position, a.position)


def test_air_routes_are_remembered_per_shared_memo_and_handed_out_as_copies(plan):
    surface = plan.surface
    a, b = plan.passes[0], plan.passes[1]
    ends = (a.points[-1], a.normals[-1], b.points[0], b.normals[0])
    memo: dict = {}
    first = AirGuard(surface, 0.02, memo=memo).route(*ends)
    assert len(memo) == 1
    first[:] = 0.0                                        # the caller's copy only
    second = AirGuard(surface, 0.02, memo=memo).route(*ends)
    fresh = AirGuard(surface, 0.02).route(*ends)
    assert np.array_equal(second, fresh) and np.abs(fresh).max() > 0


def test_a_second_simulation_of_the_same_surface_reuses_its_samples(plan):
    widths_module._MEMO.clear()
    traj = time_path(plan, CONS)
    one = simulate_removal(traj, plan.surface, TOOL)
    two = simulate_removal(traj, plan.surface, TOOL)
    assert two.surface is one.surface
    assert np.array_equal(one.depth, two.depth)
    # another spacing makes its own samples
    three = simulate_removal(traj, plan.surface, TOOL, sample_spacing=4e-3)
    assert three.surface is not one.surface and len(three.surface.vertices) < len(one.surface.vertices)
