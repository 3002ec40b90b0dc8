"""The landing and the lift of every pass under force control, and the removal they cause."""

import json
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

from swath.contact import Tool
from swath.examples import flat_plate
from swath.plan import Pass, ToolPath
from swath.simulate import simulate_removal
from swath.simulate.force import simulate_force
from swath.trajectory import FeedLimit, time_path


def one_pass():
    s = flat_plate()
    p = Pass(np.array([[0.1, 0.15, 0.0], [0.3, 0.15, 0.0]]), np.array([[0, 0, 1.0]] * 2))
    return s, time_path(ToolPath(s, [p], "t"), [FeedLimit(0.05)])


@pytest.mark.parametrize("damping", [0.0, 0.02])
def test_the_landing_removal_on_flat_is_preston_over_the_force_history(damping):
    """On a flat plate the pressure under a still pad is F/(πR²) everywhere, so the landing's mark is
    k_p · v_rel · Σ F_i dt_i / (πR²) at its centre: the simulator's hold poses must give exactly that."""
    s, tr = one_pass()
    tool = Tool(damping_time=damping)
    trace = simulate_force(tr, s, tool)
    h = trace.holds
    assert h["lift"].any() and (~h["lift"]).any()
    landing = {k: np.asarray(v)[~h["lift"]] for k, v in h.items()}
    assert np.allclose(landing["position"], tr.position[np.flatnonzero(tr.contact)[0]])
    assert landing["dwell"].sum() == pytest.approx(trace.metrics["landing_hold_time_s"])
    idle = replace(tr, contact=np.zeros(len(tr), bool))
    rm = simulate_removal(idle, s, tool, sample_spacing=2e-3, holds=landing)
    expected = tool.preston * tool.relative_speed(0.0) * float((landing["force"] * landing["dwell"]).sum()) / tool.pad_area
    assert rm.depth.max() == pytest.approx(expected, rel=0.01)
    # the mark is the pad's footprint at the pass start
    start = tr.position[np.flatnonzero(tr.contact)[0]]
    marked = rm.surface.vertices[rm.depth > 0.5 * rm.depth.max()]
    assert np.linalg.norm(marked[:, :2] - start[:2], axis=1).max() <= tool.pad_radius + 2e-3


def test_pad_damping_lengthens_the_landing_and_shortens_the_lift():
    s, tr = one_pass()
    elastic = simulate_force(tr, s, Tool()).metrics
    damped = simulate_force(tr, s, Tool(damping_time=0.02)).metrics
    assert damped["landing_hold_time_s"] > elastic["landing_hold_time_s"] + 0.03
    assert damped["lift_hold_time_s"] < elastic["lift_hold_time_s"]
    # the lift at 5 mm/s lets go of an elastic pad sunk 1 mm within about 1 mm / 5 mm/s = 0.2 s
    assert elastic["lift_hold_time_s"] == pytest.approx(1e-3 / 5e-3, rel=0.15)


def test_a_force_controlled_job_reports_the_landing_marks(tmp_path):
    out = tmp_path / "job"
    r = subprocess.run([sys.executable, "-m", "swath.cli", "plan", "--constant-feed", "example:plate", "--spacing", "100mm",
                        "--force-control", "--pad-damping", "10ms", "--out", str(out)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "without a unit suffix" not in r.stderr          # every new metric names its unit
    m = json.loads((out / "metrics.json").read_text())["metrics"]
    assert m["landing_hold_time_s"] > 0 and m["lift_hold_time_s"] > 0
    assert 0 < m["landing_depth_excess_m"] < m["removal_max_m"]
    assert m["landing_depth_excess_fraction"] == pytest.approx(m["landing_depth_excess_m"] / m["removal_mean_m"])
