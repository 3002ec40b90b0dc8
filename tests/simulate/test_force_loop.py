"""Stability analysis of the discrete loops against closed forms, and the step response of the
simulated force loop against the predicted time constant."""

import math

import numpy as np
import pytest

from swath.contact import Tool
from swath.errors import InfeasibleError
from swath.examples import flat_plate
from swath.plan import Pass, ToolPath
from swath.simulate import ForceController, simulate_force
from swath.simulate.force import contact_stiffness, force_gains
from swath.simulate.force_loop import check_stability, loop_stability
from swath.trajectory import FeedLimit, time_path


@pytest.mark.parametrize("g", [0.05, 0.3, 0.9, 1.5])
def test_integral_loop_without_lag_matches_closed_form(g):
    # L(z) = g / (z − 1): pole 1 − g, gain margin 2/g, phase margin 90° − asin(g/2)
    rate, K = 1000.0, 2e4
    st = loop_stability(K, rate=rate, kp=g * rate / K)
    assert st.poles[0].real == pytest.approx(1 - g, abs=1e-12)
    assert st.gain_margin == pytest.approx(2 / g, rel=1e-4)
    assert math.degrees(st.phase_margin) == pytest.approx(90 - math.degrees(math.asin(g / 2)), abs=0.01)
    assert st.time_constant == pytest.approx(-1e-3 / math.log(abs(1 - g)), rel=1e-9)


def test_unstable_and_low_margin_gains_are_refused():
    rate, K = 500.0, 2e4
    with pytest.raises(InfeasibleError, match="spectral radius"):
        check_stability(K, rate=rate, kp=2.2 * rate / K)              # pole at −1.2
    with pytest.raises(InfeasibleError, match="gain margin"):
        check_stability(K, rate=rate, kp=1.2 * rate / K)              # stable, but margin 1.67 < 2
    assert check_stability(K, rate=rate, kp=0.8 * rate / K).stable   # margin 2.5
    assert not loop_stability(K, rate=rate, kp=2.2 * rate / K).stable


def test_servo_lag_and_latency_cost_phase_margin():
    K, kp = 2e4, 1 / (2e4 * 0.03)
    free = loop_stability(K, rate=500, kp=kp)
    lag = loop_stability(K, rate=500, kp=kp, servo_lag=0.01)
    late = loop_stability(K, rate=500, kp=kp, servo_lag=0.01, latency=0.008)
    assert free.phase_margin > lag.phase_margin > late.phase_margin > math.radians(30)
    # crossover near K·kp = 33 rad/s; a 10 ms lag costs about atan(0.33) there
    assert free.phase_margin - lag.phase_margin == pytest.approx(math.atan(0.0333 * 10), abs=math.radians(3))


def test_simulation_refuses_a_too_high_force_gain():
    tool = Tool()
    s = flat_plate()
    tr = time_path(ToolPath(s, [Pass(np.array([[0.1, 0.15, 0], [0.2, 0.15, 0]]), np.array([[0, 0, 1.0]] * 2))], "t"),
                   [FeedLimit(0.05)])
    K = contact_stiffness(tool)
    with pytest.raises(InfeasibleError, match="force loop"):
        simulate_force(tr, s, tool, controller=ForceController(force_gain=20.0 / K * 500))
    # a compliant part lowers the loop gain: the same gain passes against a part 30x softer than the pad
    kp, ki, st = force_gains(tool, ForceController(force_gain=1.5 / K * 500, integral_gain=0.0, servo_lag=0.0),
                         part_stiffness=K / 30)
    assert st.stable and st.gain_margin > 2


def test_step_response_reaches_the_set_point_with_the_predicted_time_constant():
    tool = Tool()                                   # 20 N, 1 mm depression: K = 20 N/mm
    s = flat_plate()
    tr = time_path(ToolPath(s, [Pass(np.array([[0.1, 0.15, 0], [0.2, 0.15, 0]]), np.array([[0, 0, 1.0]] * 2))], "t"),
                   [FeedLimit(0.05)])
    c = ForceController(servo_lag=0.0, ramp_time=0.0, rate=1000.0, time_constant=0.02, integral_gain=0.0)
    trace = simulate_force(tr, s, tool, controller=c)
    K = contact_stiffness(tool)
    assert K == pytest.approx(20.0 / 1e-3, rel=1e-9)
    st = trace.stability["force"]
    tau_pred = -1e-3 / math.log(1 - K * (1 / (K * 0.02)) * 1e-3)
    assert st.time_constant == pytest.approx(tau_pred, rel=1e-9)
    # after contact is detected the error decays as exp(−t/τ): find the 1/e time
    F = trace.contact_force
    k0 = int(np.argmax(trace.measured_force >= c.contact_threshold * tool.force))
    e = tool.force - F[k0:]
    k1 = int(np.argmax(e <= e[0] / math.e))
    assert k1 * 1e-3 == pytest.approx(tau_pred, abs=1.5e-3)
    # the pass starts once the force is within 2 % of the set point, and it stays there
    moving = F[trace.moving]
    assert abs(moving[0] - tool.force) <= 0.02 * tool.force
    assert np.max(np.abs(moving[100:] - tool.force)) < 1e-3 * tool.force


def test_default_pi_gains_pass_with_a_jaeger_latency_and_remove_the_ramp_error():
    tool = Tool()
    kp, ki, st = force_gains(tool, ForceController(latency=0.008))
    assert ki == pytest.approx(kp / (5 * 0.03))
    assert st.gain_margin > 2 and st.phase_margin > math.radians(40)
    # a part tilted 0.01 rad under a straight pass: the surface recedes at feed·0.01; proportional
    # control lags it by v_n / K_p, the default PI does not
    from swath.simulate import Disturbance
    s = flat_plate()
    tr = time_path(ToolPath(s, [Pass(np.array([[0.1, 0.15, 0], [0.3, 0.15, 0]]), np.array([[0, 0, 1.0]] * 2))], "t"),
                   [FeedLimit(0.05)])
    dist = Disturbance(part_offset=(0, 0, 0, 0, 0.01, 0))
    p_only = simulate_force(tr, s, tool, controller=ForceController(integral_gain=0.0), disturbance=dist)
    pi = simulate_force(tr, s, tool, disturbance=dist)
    K = contact_stiffness(tool)
    lag = 0.05 * math.tan(0.01) / (1 / (K * 0.03))
    assert abs(p_only.metrics["mean_force_n"] - tool.force) == pytest.approx(lag, rel=0.1)
    assert abs(pi.metrics["mean_force_n"] - tool.force) < 0.2 * lag
