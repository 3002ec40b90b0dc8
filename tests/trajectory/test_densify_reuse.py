"""The passes densified on the surface are kept per pass, surface and step: timing the same passes
with another lead (the default job compares three) gives the trajectory of a fresh timing bit for bit."""

import numpy as np

import swath.trajectory.timing as timing_module
from swath.contact import Tool
from swath.examples import doubly_curved_panel
from swath.plan import raster
from swath.trajectory import AngularSpeedLimit, FeedLimit, time_path

CONS = [FeedLimit(0.05), AngularSpeedLimit(1.0)]


def _same(a, b):
    for name in ("t", "position", "quaternion", "contact", "feed", "pass_index"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_another_lead_reuses_the_densified_passes_and_times_alike():
    plan = raster(doubly_curved_panel(), Tool(), point_spacing=8e-3)      # 8 mm points: densified to the grid
    time_path(plan, CONS, lead_angle=0.0)
    kept = [timing_module._DENSE.get(p) for p in plan.passes]
    assert all(k is not None and len(k) == 1 for k in kept)                 # one surface and step per pass
    dense_before = [next(iter(k.values()))[1][0] for k in kept]
    again = time_path(plan, CONS, lead_angle=0.12)                          # another lead: new frames, same points
    assert [next(iter(timing_module._DENSE[p].values()))[1][0] for p in plan.passes] == dense_before
    timing_module._DENSE.clear()
    timing_module._PASS_GEOMETRY.clear()
    fresh = time_path(plan, CONS, lead_angle=0.12)
    _same(again, fresh)
    ((_, (_, u)),) = timing_module._DENSE[plan.passes[0]].values()
    assert not u.flags.writeable                                            # shared: read-only
