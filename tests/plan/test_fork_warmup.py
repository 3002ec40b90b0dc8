"""What the uniform planner loads before it forks its workers: the compiled kernels of the working
mesh and the cost function's imports, so each worker does not load them again."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from swath.contact import Tool
from swath.examples import doubly_curved_panel
from swath.plan.uniform_model import _Context

SRC = Path(__file__).resolve().parents[2] / "src"

# Run in a fresh interpreter: in this one other tests may have loaded the kernels and toppra already.
FRESH = """
import sys
from swath.cli.job import cycle_time_cost
from swath.contact import Tool
from swath.contact.kernels import _touched
from swath.contact.widths import _widths_across_near
from swath.examples import doubly_curved_panel
from swath.plan.uniform import _warm_before_fork
from swath.plan.uniform_model import _Context, _gradient_vertex_sums
from swath.trajectory import FeedLimit, LinkSettings

kernels = (_touched, _widths_across_near, _gradient_vertex_sums)
ctx = _Context(doubly_curved_panel(size_x=0.2, size_y=0.15, spacing=8e-3), Tool(), Tool().pad_radius / 4)
before = [len(k.signatures) for k in kernels], "toppra" in sys.modules
_warm_before_fork(ctx, cycle_time_cost([FeedLimit(0.05)], LinkSettings()))
after = [len(k.signatures) for k in kernels], "toppra" in sys.modules
print(before, after)
"""


def test_the_kernels_and_the_cost_imports_are_loaded_before_the_fork():
    env = dict(os.environ, PYTHONPATH=str(SRC) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    done = subprocess.run([sys.executable, "-c", FRESH], capture_output=True, text=True, env=env, timeout=120,
                          check=True)
    assert done.stdout.strip().splitlines()[-1] == "([0, 0, 0], False) ([1, 1, 1], True)"


# While the forked child builds the width model, the parent loads the pad-touch kernel and the cost's
# imports (``while_building``), before it reads the child's answer.
WHILE_BUILDING = """
import sys
from swath.cli.job import cycle_time_cost
from swath.contact import Tool
from swath.contact.kernels import _touched
from swath.examples import doubly_curved_panel
from swath.plan import uniform_model
from swath.plan.uniform import _prepare_candidates
from swath.trajectory import FeedLimit, LinkSettings

seen = []
read = uniform_model.Beside.result
uniform_model.Beside.result = lambda self: (seen.append(("answer", len(_touched.signatures), "toppra" in sys.modules)),
                                            read(self))[1]
cost = cycle_time_cost([FeedLimit(0.05)], LinkSettings())
hook = lambda: (seen.append("hook"), _prepare_candidates(Tool(), cost))
ctx = uniform_model._Context(doubly_curved_panel(size_x=0.2, size_y=0.15, spacing=8e-3), Tool(), Tool().pad_radius / 4,
                             while_building=hook)
print(seen)
"""


def test_the_candidates_needs_are_loaded_while_the_child_builds():
    env = dict(os.environ, PYTHONPATH=str(SRC) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    done = subprocess.run([sys.executable, "-c", WHILE_BUILDING], capture_output=True, text=True, env=env, timeout=120,
                          check=True)
    assert done.stdout.strip().splitlines()[-1] == "['hook', ('answer', 1, True)]"


def test_warming_builds_the_parts_closest_point_tree():
    ctx = _Context(doubly_curved_panel(size_x=0.2, size_y=0.15, spacing=8e-3), Tool(), Tool().pad_radius / 4)
    assert "_closest_point_tree" not in vars(ctx.surface)
    ctx.warm()
    assert "_closest_point_tree" in vars(ctx.surface)


def test_warming_the_context_changes_none_of_its_state():
    ctx = _Context(doubly_curved_panel(size_x=0.2, size_y=0.15, spacing=8e-3), Tool(), Tool().pad_radius / 4)
    vertices, widths = ctx.work.vertices.copy(), ctx.widths.max_width.copy()
    d = ctx.distance(np.arange(10))
    ctx.warm()
    np.testing.assert_array_equal(ctx.work.vertices, vertices)
    np.testing.assert_array_equal(ctx.widths.max_width, widths)
    np.testing.assert_array_equal(ctx.distance(np.arange(10)), d)
