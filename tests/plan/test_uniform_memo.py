"""The uniform planner's working mesh is built once per part and shared by every plan of it
(the default job's probe, re-plans and plain plan): the same plans as a working mesh built for
each call, bit for bit."""

import pickle

import numpy as np
import pytest

from swath.contact import Tool
from swath.examples import doubly_curved_panel
from swath.plan import uniform_model
from swath.plan.uniform import uniform
from swath.surface import Surface


def _panel():
    return doubly_curved_panel(size_x=0.2, size_y=0.15, spacing=8e-3)


def _same(a, b):
    assert len(a.passes) == len(b.passes)
    for p, q in zip(a.passes, b.passes):
        np.testing.assert_array_equal(p.points, q.points)
        np.testing.assert_array_equal(p.normals, q.normals)
    assert a.metadata["predicted_coverage_fraction"] == b.metadata["predicted_coverage_fraction"]


@pytest.fixture()
def builds(monkeypatch):
    """How many working meshes were built."""
    count = []
    real = uniform_model._Context.__init__

    def counting(self, *args, **kwargs):
        count.append(1)
        real(self, *args, **kwargs)

    monkeypatch.setattr(uniform_model._Context, "__init__", counting)
    return count


def test_plans_of_one_part_share_its_working_mesh_and_equal_fresh_ones(builds):
    tool = Tool()
    part = _panel()
    shared = [uniform(part, tool, overlap=ov, direction=0.3, workers=1) for ov in (0.1, 0.3, 0.1)]
    assert len(builds) == 1                            # one working mesh for the three plans
    fresh = [uniform(_panel(), tool, overlap=ov, direction=0.3, workers=1) for ov in (0.1, 0.3)]
    assert len(builds) == 3                            # a new part object: its own
    _same(shared[0], fresh[0])
    _same(shared[1], fresh[1])
    _same(shared[2], fresh[0])
    # the overlap did change the plan: the passes lie elsewhere
    assert not np.allclose(shared[1].passes[1].points[0], shared[0].passes[1].points[0], atol=1e-3)


def test_another_turn_limit_reads_the_same_mesh_with_its_own_limit(builds):
    tool, part = Tool(), _panel()
    a = uniform_model.shared_context(part, tool, None, max_turn_curvature=40.0, beside=False)
    b = uniform_model.shared_context(part, tool, None, max_turn_curvature=10.0, beside=False)
    assert len(builds) == 1
    assert (a.max_turn_curvature, b.max_turn_curvature) == (40.0, 10.0)
    assert b.work is a.work and b.solver is a.solver and b.widths is a.widths
    # the plan with a lower feed (a looser turn limit) is the one a fresh part gives
    _same(uniform(part, tool, direction=0.0, feed=0.02, workers=1),
          uniform(_panel(), tool, direction=0.0, feed=0.02, workers=1))
    assert len(builds) == 2                            # the fresh part's
    # another tool or working edge: another working mesh
    uniform_model.shared_context(part, Tool(pad_radius=0.03), None, beside=False)
    uniform_model.shared_context(part, tool, 5e-3, beside=False)
    assert len(builds) == 4


def test_the_memo_is_not_pickled_and_forget_releases_it(builds):
    tool, part = Tool(), _panel()
    uniform_model.shared_context(part, tool, None, beside=False)
    copy = pickle.loads(pickle.dumps(part))            # the solver (C++) stays in this process
    assert "_memos" not in copy.__dict__
    uniform_model.shared_context(copy, tool, None, beside=False)
    assert len(builds) == 2
    part.forget("uniform model")
    uniform_model.shared_context(part, tool, None, beside=False)
    assert len(builds) == 3


def test_each_piece_of_a_part_keeps_its_working_mesh(builds):
    one = _panel()
    two = Surface(np.vstack([one.vertices, one.vertices + [0.0, 0.3, 0.0]]),
                  np.vstack([one.faces, one.faces + len(one.vertices)]), name="two panels")
    first = uniform(two, Tool(), direction=0.0, workers=1)
    assert len(builds) == 2
    again = uniform(two, Tool(), direction=0.0, overlap=0.2, workers=1)
    assert len(builds) == 2
    assert first.metadata["n_pieces"] == again.metadata["n_pieces"] == 2
