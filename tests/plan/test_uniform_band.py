"""The uniform planner's narrow-band distances (``distance_method="band"``): a generation reads
only distances within the stop distance (:meth:`swath.plan.uniform_model._Context.band_stop`), so
the plan is the one made with the whole-mesh solve of the same method; it covers the parts the
heat method covers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from swath.contact import Tool
from swath.errors import InputError
from swath.examples import blade, doubly_curved_panel
from swath.plan import uniform_model
from swath.plan.uniform import uniform

TOOL = Tool()


def _same_passes(a, b):
    assert len(a.passes) == len(b.passes)
    for p, q in zip(a.passes, b.passes):
        np.testing.assert_array_equal(p.points, q.points)


@pytest.mark.parametrize("make, overlap", [(lambda: doubly_curved_panel(spacing=8e-3), 0.1),
                                           (lambda: blade(span=0.15), 0.3)])
def test_the_band_gives_the_plan_of_the_whole_mesh_solve(monkeypatch, make, overlap):
    calls = []
    band = uniform_model._Context.distance

    def counted(self, sources, stop=math.inf):
        d = band(self, sources, stop)
        calls.append(np.isfinite(d).mean())
        return d

    monkeypatch.setattr(uniform_model._Context, "distance", counted)
    narrow = uniform(make(), TOOL, direction=0.0, overlap=overlap, workers=1, distance_method="band")
    share = np.array(calls)
    monkeypatch.setattr(uniform_model._Context, "band_stop", lambda self, reach: math.inf)
    whole = uniform(make(), TOOL, direction=0.0, overlap=overlap, workers=1, distance_method="band")
    _same_passes(narrow, whole)
    # and the solves visited a part of the mesh only
    assert len(share) >= 4 and np.median(share) < 0.7 and share.min() < 0.5


def test_the_band_and_the_heat_method_lay_nearly_the_same_passes_on_a_panel():
    part = doubly_curved_panel(spacing=8e-3)
    band = uniform(part, TOOL, direction=0.0, workers=1, distance_method="band")
    heat = uniform(part, TOOL, direction=0.0, workers=1, distance_method="heat")
    assert uniform_model.DEFAULT_DISTANCE_METHOD == "heat"
    default = uniform(part, TOOL, direction=0.0, workers=1)
    _same_passes(default, heat)
    assert len(band.passes) == len(heat.passes)
    # the two distances differ by a fraction of a millimetre: so do the contact lengths
    assert band.contact_length == pytest.approx(heat.contact_length, rel=0.02)
    with pytest.raises(InputError, match="distance_method"):
        uniform(part, TOOL, direction=0.0, workers=1, distance_method="exact")


def test_the_band_covers_the_square_bowl_to_its_far_edge():
    """The last generation's level set on the bowl's far edge leaves only pieces too short to keep
    (with exact geodesic distances too): the last pass is pulled in to that edge instead of the
    planner stopping with 6 % of the bowl bare (93.7 % predicted coverage without that rule)."""
    from shapes import bowl

    part = bowl(size=0.3, radius=0.35, n=41)
    lengths = []
    for angle in (0.0, 30.0, 60.0):
        tp = uniform(part, TOOL, direction=math.radians(angle), overlap=0.231, workers=1, distance_method="band")
        assert tp.metadata["predicted_coverage_fraction"] > 0.999
        lengths.append(tp.contact_length)
    # a square bowl: each direction seeds from one of its sides, so the passes are the same ones turned
    assert max(lengths) / min(lengths) < 1.01
