"""The discrete control loops of the force simulation and their stability check.

Both loops of the hybrid controller (Jaeger ch. 5) have the same structure at the controller rate
``1/dt``: the controller turns an error into a velocity command (proportional gain, optional
integral gain), the command is integrated into a commanded position, the robot follows that
position through a first-order servo lag ``τ_s`` and a transport delay of ``d`` ticks, and the
plant turns position into the controlled quantity with a gain ``K``:

* force loop (along the tool axis): error in N, gains in m/s per N (and m/s per N·s), plant gain
  the contact stiffness ``K`` in N/m (pad in series with the part);
* tangential position loop (in the tangent plane): error in s of plan progress, gain in 1/s,
  plant gain 1.

With ``β = exp(−dt/τ_s)`` (0 without lag) the open loop is

``L(z) = K · dt/(z−1) · (K_p + K_i·dt·z/(z−1)) · (1−β)·z/(z−β) · z^(−d)``

:func:`loop_stability` gives the closed-loop poles (roots of ``den + num``), the gain and phase
margins from ``L(e^{jωdt})`` (frequency response by :func:`scipy.signal.dfreqresp`) and the time
constant of the slowest pole; :func:`check_stability` refuses a loop with a pole on or outside the
unit circle or with margins below the required ones.  :class:`Servo` is the same loop as code:
the simulator steps it once per tick, so the analysis and the simulation share one model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InfeasibleError, InputError


@dataclass(frozen=True)
class LoopStability:
    """Stability figures of one discrete loop.

    Attributes
    ----------
    poles : (q,) complex
        Closed-loop poles in the z-plane.
    spectral_radius : float
        Largest pole magnitude (< 1 for a stable loop).
    gain_margin : float
        Factor by which the loop gain may grow before instability (``inf`` if the phase never
        reaches −180° below the Nyquist frequency).
    phase_margin : float
        Phase margin, rad (``inf`` if ``|L|`` never reaches 1).
    crossover : float
        Gain-crossover angular frequency, rad/s (NaN if none).
    time_constant : float
        ``−dt / ln|z|`` of the slowest pole, s (the closed-loop settling time constant).
    """

    poles: np.ndarray
    spectral_radius: float
    gain_margin: float
    phase_margin: float
    crossover: float
    time_constant: float

    @property
    def stable(self) -> bool:
        """True when every closed-loop pole lies strictly inside the unit circle."""
        return bool(self.spectral_radius < 1.0 - 1e-12)


def _open_loop(plant_gain: float, *, dt: float, kp: float, ki: float, servo_lag: float, delay: int):
    """Numerator and denominator polynomials (descending powers of z) of ``L(z)``."""
    beta = math.exp(-dt / servo_lag) if servo_lag > 0 else 0.0
    # controller: dt/(z-1) * (kp + ki dt z/(z-1)) = dt*(kp (z-1) + ki dt z) / (z-1)^2
    c_num = dt * np.array([kp + ki * dt, -kp])
    c_den = np.polymul([1.0, -1.0], [1.0, -1.0]) if ki != 0 else np.array([1.0, -1.0])
    if ki == 0:
        c_num = np.array([dt * kp])
    # servo: (1-beta) z / (z - beta), then z^-d
    s_num = np.array([1.0 - beta, 0.0])
    s_den = np.polymul([1.0, -beta], np.concatenate([[1.0], np.zeros(delay)]))
    num = plant_gain * np.polymul(c_num, s_num)
    den = np.polymul(c_den, s_den)
    return num, den


def loop_stability(plant_gain: float, *, rate: float, kp: float, ki: float = 0.0, servo_lag: float = 0.0,
                   latency: float = 0.0) -> LoopStability:
    """Closed-loop poles and margins of the loop in the module docstring.

    Parameters
    ----------
    plant_gain : float
        ``K``: contact stiffness, N/m, for the force loop; 1 for the position loop.
    rate : float
        Controller rate, Hz.
    kp : float
        Proportional gain: m/s per N (force loop) or 1/s (position loop).
    ki : float
        Integral gain: m/s per N·s (force loop) or 1/s² (position loop).
    servo_lag : float
        First-order time constant of the robot's response to a position command, s (0 = none).
    latency : float
        Transport delay of a command, s (rounded to whole ticks).

    Returns
    -------
    LoopStability
    """
    from scipy import signal

    for name, value in (("plant_gain", plant_gain), ("rate", rate)):
        if not (math.isfinite(value) and value > 0):
            raise InputError(f"{name} must be positive and finite, got {value!r}")
    for name, value in (("kp", kp), ("ki", ki), ("servo_lag", servo_lag), ("latency", latency)):
        if not (math.isfinite(value) and value >= 0):
            raise InputError(f"{name} must be a non-negative finite number, got {value!r}")
    if kp == 0 and ki == 0:
        raise InputError("a loop needs a positive proportional or integral gain, got both 0")
    dt = 1.0 / rate
    delay = int(round(latency * rate))
    num, den = _open_loop(plant_gain, dt=dt, kp=kp, ki=ki, servo_lag=servo_lag, delay=delay)
    char = np.polyadd(den, num)
    poles = np.roots(char)
    radius = float(np.max(np.abs(poles))) if len(poles) else 0.0
    # Frequency response on a dense grid up to Nyquist (log-spaced, plus a linear tail).
    w = np.unique(np.concatenate([np.geomspace(1e-4 * math.pi, math.pi, 6000), np.linspace(0.5, math.pi, 2000)]))
    _, resp = signal.dfreqresp(signal.dlti(num, den, dt=dt), w=w)
    mag = np.abs(resp)
    phase = np.unwrap(np.angle(resp))
    # Integrators put the low-frequency phase at −90° (P) or −180° (PI); keep it in (−2π, 0].
    if phase[0] > 0:
        phase -= 2 * math.pi
    gm = _crossing(phase + math.pi, 1.0 / mag, w)
    pm_at = _crossing(mag - 1.0, phase, w)
    crossover_w = _crossing(mag - 1.0, w, w)
    phase_margin = math.pi + pm_at if math.isfinite(pm_at) else math.inf
    tau = -dt / math.log(radius) if 0 < radius < 1 else (0.0 if radius == 0 else math.inf)
    return LoopStability(poles, radius, gm, phase_margin,
                         crossover_w * rate if math.isfinite(crossover_w) else math.nan, tau)


def _crossing(f: np.ndarray, value: np.ndarray, w: np.ndarray) -> float:
    """``value`` (linearly interpolated) where ``f`` first changes sign from + to − or − to +;
    ``inf`` when it never does."""
    s = np.sign(f)
    idx = np.flatnonzero(s[:-1] * s[1:] <= 0)
    idx = idx[(s[idx] != 0) | (s[idx + 1] != 0)]
    if len(idx) == 0:
        return math.inf
    i = int(idx[0])
    f0, f1 = f[i], f[i + 1]
    lam = 0.0 if f1 == f0 else f0 / (f0 - f1)
    return float(value[i] + lam * (value[i + 1] - value[i]))


def check_stability(plant_gain: float, *, rate: float, kp: float, ki: float = 0.0, servo_lag: float = 0.0,
                    latency: float = 0.0, min_gain_margin: float = 2.0,
                    min_phase_margin: float = math.radians(30.0), what: str = "force loop") -> LoopStability:
    """:func:`loop_stability`, refusing an unstable loop or one with too little margin.

    Raises
    ------
    InfeasibleError
        When a closed-loop pole lies on or outside the unit circle, or the gain margin is below
        ``min_gain_margin`` (a factor, default 2 = 6 dB), or the phase margin below
        ``min_phase_margin`` (rad, default 30°).  The message names the largest gain that would
        pass, so the user can lower the gain (or raise the rate).
    """
    st = loop_stability(plant_gain, rate=rate, kp=kp, ki=ki, servo_lag=servo_lag, latency=latency)
    ok = st.stable and st.gain_margin >= min_gain_margin and st.phase_margin >= min_phase_margin
    if not ok:
        hint = _largest_passing_scale(plant_gain, rate=rate, kp=kp, ki=ki, servo_lag=servo_lag, latency=latency,
                                      min_gain_margin=min_gain_margin, min_phase_margin=min_phase_margin)
        raise InfeasibleError(
            f"{what} gains kp={kp:.4g}, ki={ki:.4g} with plant gain {plant_gain:.4g} at {rate:g} Hz "
            f"(servo lag {servo_lag * 1e3:g} ms, latency {latency * 1e3:g} ms): expected every closed-loop pole "
            f"inside the unit circle with gain margin >= {min_gain_margin:g} and phase margin >= "
            f"{math.degrees(min_phase_margin):.0f} deg, got spectral radius {st.spectral_radius:.4f}, gain margin "
            f"{st.gain_margin:.3g}, phase margin {math.degrees(st.phase_margin):.1f} deg; "
            f"scale both gains by at most {hint:.3g} (or raise the controller rate)")
    return st


def _largest_passing_scale(plant_gain, *, min_gain_margin, min_phase_margin, **kw) -> float:
    """Largest factor (bisection, 1e-6..1) on both gains that passes the margins."""
    kp, ki = kw.pop("kp"), kw.pop("ki")
    lo, hi = 0.0, 1.0
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        if mid <= 0:
            break
        st = loop_stability(plant_gain, kp=kp * mid, ki=ki * mid, **kw)
        if st.stable and st.gain_margin >= min_gain_margin and st.phase_margin >= min_phase_margin:
            lo = mid
        else:
            hi = mid
    return lo


class Servo:
    """One controlled axis as the simulator steps it: command integrator, servo lag and delay.

    Each :meth:`step` takes the velocity command (m/s or s/s) computed at this tick, integrates it
    into the commanded position, pushes that through the transport delay and moves the actual
    position toward the delayed command by the first-order lag.  Matches :func:`_open_loop`.
    """

    def __init__(self, position: float, *, dt: float, servo_lag: float, delay: int):
        self.dt = dt
        self.beta = math.exp(-dt / servo_lag) if servo_lag > 0 else 0.0
        self.command = position
        self.actual = position
        self._queue = [position] * delay

    def step(self, velocity: float) -> None:
        self.command += self.dt * velocity
        self._queue.append(self.command)
        delayed = self._queue.pop(0)
        self.actual = self.beta * self.actual + (1.0 - self.beta) * delayed
