"""The uniform planner's narrow-band distances: a generation reads only distances within the stop
distance (:meth:`swath.plan.uniform_model._Context.band_stop`), so the plan is the one made with
the whole-mesh solve of the same method; the heat method stays available to compare with."""

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
    narrow = uniform(make(), TOOL, direction=0.0, overlap=overlap, workers=1)
    share = np.array(calls)
    monkeypatch.setattr(uniform_model._Context, "band_stop", lambda self, reach: math.inf)
    whole = uniform(make(), TOOL, direction=0.0, overlap=overlap, workers=1)
    _same_passes(narrow, whole)
    # and the solves visited a part of the mesh only
    assert len(share) >= 4 and np.median(share) < 0.7 and share.min() < 0.5


def test_the_heat_method_is_kept_to_compare_with():
    part = doubly_curved_panel(spacing=8e-3)
    band = uniform(part, TOOL, direction=0.0, workers=1)
    heat = uniform(part, TOOL, direction=0.0, workers=1, distance_method="heat")
    assert len(band.passes) == len(heat.passes)
    # the two distances differ by a fraction of a millimetre: so do the contact lengths
    assert band.contact_length == pytest.approx(heat.contact_length, rel=0.02)
    with pytest.raises(InputError, match="distance_method"):
        uniform(part, TOOL, direction=0.0, workers=1, distance_method="exact")
