"""The force and calibration figures render, with the curves they promise."""


import numpy as np
import pytest

from swath.contact import Tool
from swath.errors import InputError
from swath.examples import flat_plate
from swath.plan import Pass, ToolPath
from swath.report.force_plots import calibration_figure, force_trace_figure, write_force_plots
from swath.simulate import ForceController, simulate_force
from swath.simulate.calibrate import calibrate, exposure, make_trials
from swath.trajectory import FeedLimit, time_path


@pytest.fixture(scope="module")
def traces():
    s = flat_plate()
    tr = time_path(ToolPath(s, [Pass(np.array([[0.1, 0.15, 0], [0.2, 0.15, 0]]), np.array([[0, 0, 1.0]] * 2))], "t"),
                   [FeedLimit(0.05)])
    tool = Tool()
    return simulate_force(tr, s, tool), simulate_force(tr, s, tool, controller=ForceController(mode="position"))


def test_force_trace_figure(traces, tmp_path):
    hyb, pos = traces
    fig = force_trace_figure(hyb, compare={"position control": pos})
    ax_f, ax_o = fig.axes
    labels = [l.get_label() for l in ax_f.get_lines()]
    assert "set point" in labels and "position control" in labels
    setpoint = ax_f.get_lines()[labels.index("set point")]
    assert np.max(setpoint.get_ydata()) == pytest.approx(20.0)
    paths = write_force_plots(tmp_path, trace=hyb, compare={"position control": pos})
    assert paths["force_trace"].read_bytes()[:4] == b"\x89PNG"


def test_calibration_figure(tmp_path):
    rng = np.random.default_rng(1)
    f = np.repeat([15.0, 20.0, 25.0, 30.0], 2)
    w = np.tile([100.0, 300.0], 4)
    t0 = make_trials(force=f, spindle_speed=w, feed=0.02, passes=2, depth=1.0, orbit_radius=2.5e-3,
                     grit=np.repeat(["80", "120"], 4))
    d = 2e-10 * exposure(t0) * (1 + 0.05 * rng.standard_normal(8))
    t = make_trials(force=f, spindle_speed=w, feed=0.02, passes=2, depth=d, orbit_radius=2.5e-3,
                    grit=np.repeat(["80", "120"], 4))
    cal = calibrate(t)
    fig = calibration_figure(cal, t)
    (ax,) = fig.axes
    assert len(ax.collections) == 4          # a confidence and a prediction band per grit
    paths = write_force_plots(tmp_path, calibration=cal, trials=t)
    assert paths["calibration"].exists()
    with pytest.raises(InputError):
        write_force_plots(tmp_path / "missing", calibration=cal, trials=t)
