"""Hybrid position/force control of the pad along a planned trajectory, simulated (Jaeger ch. 5).

The planned trajectory puts the TCP on the planned surface; the robot runs it with

* a **force loop** along the tool axis (the planned surface normal): the force error (set force
  minus the measured force) is turned into a normal velocity ``K_p·e + K_i·∫e`` added to the
  feed-forward velocity of the nominal sink (the offset at which the tool model carries the set
  force on the planned surface), integrated into a commanded normal offset;
* a **position loop** in the tangent plane: the plan's own velocity fed forward plus ``K_t`` times
  the progress error, so the tool keeps the planned feed;
* a robot that follows both commands through a first-order **servo lag** and a **latency**;
* **gravity compensation**: the force sensor is tared with the tool hanging along gravity, so a
  tool of mass ``m`` tilted until its axis makes ``g·a`` with gravity reads ``m·(|g| − g·a)`` too much;
  with compensation the controller subtracts the same term computed from the tool's orientation;
* an **initial contact phase** at the start of every pass: the tool starts ``clearance`` above the
  nominal sink and descends at ``approach_speed`` until the measured force passes a small
  threshold, then the set point ramps up to the set force over ``ramp_time``; the tool starts along
  the pass only when the force has settled (Jaeger 5.3.2);
* a **lift** at the end of every pass: the tool stops at the pass's last pose and retracts along
  its axis at ``lift_speed`` until the pad lets go;
* a **damped pad** (``Tool.damping_time`` ``τ_d``): pressed at the rate ``δ̇`` the pad carries
  ``F(δ) + τ_d · F'(δ) · δ̇`` (Kelvin–Voigt over the contact patch, never pulling), which resists
  the landing and lets go late on the lift.

Both transients hold the tool still on one spot while the force builds up and dies away: the
removal they cause (the mark where a pad lands) is in :attr:`ForceTrace.holds`, poses with a
dwell and a force each that :func:`swath.simulate.simulate_removal` adds (``holds=``).

The plant is the tool model on the **real** part (:mod:`.force_contact`): the planned part moved
by a rigid registration error, with the part's own stiffness in series with the pad.  The
controller rate is its own (default 500 Hz); the trajectory is resampled by interpolating the
pose between its samples at the simulated progress.  Both loops are checked for stability before
the run (:mod:`.force_loop`): closed-loop poles inside the unit circle and gain and phase margins
at least the controller's minimums, with the loop gain at the stiffest contact the pad can make
(``k·π·R²`` in series with the part), else :class:`~swath.errors.InfeasibleError`.

The **position-control baseline** (``ForceController(mode="position")``) commands the nominal
sink and never reads the force.

Entry point: :func:`simulate_force`; :func:`trajectory_with_force` adds the ``force`` column.
"""

from __future__ import annotations

import bisect
import logging
import math
from dataclasses import dataclass, field

import numpy as np

from ..contact import Tool
from ..errors import InputError
from .force_contact import ContactCurves, contact_curves, rigid_offset
from .force_figures import landing_holds, per_sample_force, trace_metrics, transient_metrics
from .force_loop import LoopStability, Servo, check_stability

log = logging.getLogger(__name__)

STANDARD_GRAVITY = 9.80665


@dataclass(frozen=True)
class ForceController:
    """Settings of the hybrid position/force controller (or of the position-only baseline).

    Attributes
    ----------
    mode : str
        ``"hybrid"`` (force loop along the tool axis) or ``"position"`` (baseline: command the
        nominal sink, no force feedback).
    rate : float
        Controller rate, Hz (default 500).
    force_gain : float or None
        Proportional force gain ``K_p``, m/s per N.  None: ``1 / (K_c · time_constant)`` with ``K_c``
        the stiffest contact (pad ``k·π·R²`` in series with the part).
    integral_gain : float or None
        Integral force gain ``K_i``, m/s per N·s.  None (default): ``K_p / (5 · time_constant)``,
        which removes the steady force error of a surface that recedes at a constant rate (a tilted
        part under a straight pass) for about 10° of phase margin; 0 gives Jaeger's proportional
        law (no steady error to a constant set force, an error ``v_n / K_p`` to a ramp ``v_n``).
    time_constant : float
        Closed-loop force time constant the default gain aims at, s (default 30 ms).
    position_gain : float
        Tangential position gain ``K_t``, 1/s (default 30).
    servo_lag : float
        First-order time constant of the robot following a command, s (default 10 ms).
    latency : float
        Command transport delay, s (default 0; Jaeger reports 8–16 ms for joint-velocity commands).
    gravity_compensation : bool
        Subtract the tool weight's share of the sensor reading (default True).
    approach_speed : float
        Descent speed before contact, m/s (default 5 mm/s).
    max_normal_speed : float
        Limit of the normal velocity command in contact, m/s (default 50 mm/s).
    clearance : float
        Start of the descent above the nominal sink, m (default 1 mm).
    search_depth : float
        How far beyond the nominal sink the descent goes looking for contact before the pass is
        skipped (logged), m (default 5 mm).
    contact_threshold : float
        Measured force (fraction of the set force) that counts as contact (default 0.1).
    ramp_time : float
        Time the set point takes from the contact threshold to the set force, s (default 0.1).
    start_tolerance : float
        The pass starts when ``|F_measured − F_set| ≤ start_tolerance · F_set`` has held for
        ``settle_time`` after the ramp (default 0.02).
    settle_time : float
        See ``start_tolerance``, s (default 0.05).
    max_hold : float
        Longest wait for that before starting anyway (logged), s (default 2).
    min_gain_margin : float
        Required gain margin of both loops, factor (default 2 = 6 dB).
    min_phase_margin : float
        Required phase margin of both loops, rad (default 30°).
    lift_speed : float
        Retract speed along the tool axis at the end of a pass, m/s (default 5 mm/s).
    """

    mode: str = "hybrid"
    rate: float = 500.0
    force_gain: float | None = None
    integral_gain: float | None = None
    time_constant: float = 0.03
    position_gain: float = 30.0
    servo_lag: float = 0.01
    latency: float = 0.0
    gravity_compensation: bool = True
    approach_speed: float = 5e-3
    max_normal_speed: float = 0.05
    clearance: float = 1e-3
    search_depth: float = 5e-3
    contact_threshold: float = 0.1
    ramp_time: float = 0.1
    start_tolerance: float = 0.02
    settle_time: float = 0.05
    max_hold: float = 2.0
    min_gain_margin: float = 2.0
    min_phase_margin: float = math.radians(30.0)
    lift_speed: float = 5e-3

    def __post_init__(self):
        if self.mode not in ("hybrid", "position"):
            raise InputError(f"controller mode must be 'hybrid' or 'position', got {self.mode!r}")
        positive = ("rate", "search_depth", "time_constant", "position_gain", "approach_speed", "max_normal_speed",
                    "contact_threshold", "start_tolerance", "max_hold", "min_gain_margin", "lift_speed")
        for name in positive:
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise InputError(f"controller {name} must be a positive finite number, got {v!r}")
        for name in ("settle_time", "servo_lag", "latency", "clearance", "ramp_time", "min_phase_margin"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise InputError(f"controller {name} must be a non-negative finite number, got {v!r}")
        if self.integral_gain is not None and not (math.isfinite(self.integral_gain) and self.integral_gain >= 0):
            raise InputError(f"controller integral_gain must be >= 0 (m/s per N·s), got {self.integral_gain!r}")
        if self.force_gain is not None and not (math.isfinite(self.force_gain) and self.force_gain > 0):
            raise InputError(f"controller force_gain must be positive (m/s per N), got {self.force_gain!r}")
        if not self.contact_threshold < 1:
            raise InputError(f"contact_threshold is a fraction of the set force below 1, got {self.contact_threshold!r}")


@dataclass(frozen=True)
class Disturbance:
    """What differs between the plan and the cell.

    Attributes
    ----------
    part_offset : (6,) float
        Registration error: the real part is the planned one rotated by the rotation vector
        ``(rx, ry, rz)`` (rad) about ``offset_centre`` and moved by ``(dx, dy, dz)`` (m).
    offset_centre : (3,) float or None
        Centre of that rotation, m, part frame (default: the surface's area centroid).
    tool_mass : float
        Mass below the force sensor, kg (default 0).
    gravity : (3,) float
        Gravity in the part frame, m/s² (default ``(0, 0, −9.80665)``: part z up).  See
        :func:`gravity_for_tilt`.
    mass_error : float
        Relative error of the mass the compensation uses (default 0: exact).
    force_noise : float
        Standard deviation of the sensor noise, N (default 0).
    seed : int
        Seed of the noise generator.
    """

    part_offset: tuple = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    offset_centre: tuple | None = None
    tool_mass: float = 0.0
    gravity: tuple = (0.0, 0.0, -STANDARD_GRAVITY)
    mass_error: float = 0.0
    force_noise: float = 0.0
    seed: int = 0

    def __post_init__(self):
        if np.shape(self.part_offset) != (6,) or not np.all(np.isfinite(self.part_offset)):
            raise InputError(f"part_offset must be 6 finite numbers (dx,dy,dz m, rx,ry,rz rad), got {self.part_offset!r}")
        if np.shape(self.gravity) != (3,) or not np.all(np.isfinite(self.gravity)):
            raise InputError(f"gravity must be 3 finite numbers (m/s², part frame), got {self.gravity!r}")
        for name in ("tool_mass", "force_noise"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise InputError(f"disturbance {name} must be non-negative, got {v!r}")
        if self.offset_centre is not None and np.shape(self.offset_centre) != (3,):
            raise InputError(f"offset_centre must be 3 numbers (m), got {self.offset_centre!r}")


def gravity_for_tilt(tilt: float, *, magnitude: float = STANDARD_GRAVITY) -> tuple:
    """Gravity (m/s², part frame) for a part mounted so that a tool pointing along part −z is
    tilted ``tilt`` rad from hanging straight down (the part rotated about its y-axis)."""
    return (magnitude * math.sin(tilt), 0.0, -magnitude * math.cos(tilt))


_MASS_UNITS = {"kg": 1.0, "g": 1e-3, "lb": 0.45359237}


def parse_mass(text) -> float:
    """``"2kg"``, ``"500g"``, ``"4.4lb"`` or a bare number of kg -> kg (for ``--tool-mass``)."""
    import re

    m = re.fullmatch(r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([a-z]*)\s*", str(text))
    if not m or m.group(2) not in ("", *_MASS_UNITS):
        raise InputError(f"expected a mass such as '2kg' or '500g', got {text!r}")
    value = float(m.group(1)) * _MASS_UNITS[m.group(2) or "kg"]
    if not (math.isfinite(value) and value >= 0):
        raise InputError(f"a tool mass must be a non-negative finite number, got {text!r}")
    return value


def parse_part_offset(text) -> tuple:
    """``"dx,dy,dz,rx,ry,rz"`` -> 6 SI numbers (for ``--part-offset``).

    Translations are lengths (``0.5mm``; a bare number is metres), rotations angles (``0.2deg``; a
    bare number is radians), the rotation a rotation vector about the part's centroid.
    """
    from ..units import parse_quantity

    parts = [p.strip() for p in str(text).split(",")]
    if len(parts) != 6:
        raise InputError(f"expected a part offset as dx,dy,dz,rx,ry,rz (e.g. 0.5mm,0,0,0.2deg,0,0), got {text!r}")
    return tuple(parse_quantity(p, "length") for p in parts[:3]) + tuple(parse_quantity(p, "angle") for p in parts[3:])


@dataclass(frozen=True, eq=False)
class ForceTrace:
    """The simulated run: controller ticks, and the contact force per trajectory sample.

    Ticks exist only on contact passes (from the start of each descent to the end of the pass);
    air moves are not simulated.

    Attributes
    ----------
    t : (m,) float
        Time of each tick, s: each run's descent starts at the plan time of its first sample plus
        the time earlier runs' contact phases added to the plan.
    progress : (m,) float
        Plan time the tool has actually reached along the trajectory, s.
    set_force : (m,) float
        Force set point, N (the ramp during each contact phase).
    contact_force : (m,) float
        Actual pad force on the real part, N.
    measured_force : (m,) float
        Force the controller sees (sensor reading, after gravity compensation when on), N.
    commanded_offset, actual_offset : (m,) float
        Normal offset of the TCP along tool z beyond the planned pose, commanded and reached, m.
    moving : (m,) bool
        True once the tool travels along the pass (after the contact phase).
    pass_index : (m,) int
        Contact run (0-based, in trajectory order) of each tick.
    force : (n,) float
        Mean contact force while the tool passed each trajectory sample, N; 0 off contact.
    nominal_offset : (n,) float
        Nominal sink (feed-forward offset) of each trajectory sample, m; NaN off contact.
    metrics : dict
        Figures with units in their keys (see :func:`simulate_force`).
    stability : dict of str -> LoopStability
        ``"force"`` (hybrid mode) and ``"position"`` loop figures.
    holds : dict of str -> array
        The tool standing still in contact at the landing and the lift of every pass, as poses
        for the removal simulation: ``position`` (h, 3) m, ``axis`` (h, 3), ``dwell`` (h,) s,
        ``force`` (h,) N (the ticks of one transient grouped by force), ``run`` (h,) int and
        ``lift`` (h,) bool (False: landing).
    """

    t: np.ndarray
    progress: np.ndarray
    set_force: np.ndarray
    contact_force: np.ndarray
    measured_force: np.ndarray
    commanded_offset: np.ndarray
    actual_offset: np.ndarray
    moving: np.ndarray
    pass_index: np.ndarray
    force: np.ndarray
    nominal_offset: np.ndarray
    metrics: dict = field(default_factory=dict)
    stability: dict = field(default_factory=dict)
    holds: dict = field(default_factory=dict)


def contact_stiffness(tool: Tool, *, part_stiffness: float = math.inf) -> float:
    """Stiffest contact the pad can make, N/m: full pad ``k·π·R²`` in series with ``part_stiffness`` (N/m)."""
    pad = tool.k * tool.pad_area
    return pad if math.isinf(part_stiffness) else pad * part_stiffness / (pad + part_stiffness)


def force_gains(tool: Tool, controller: ForceController, *,
                part_stiffness: float = math.inf) -> tuple[float, float, LoopStability]:
    """The force gains ``K_p`` (m/s per N) and ``K_i`` (m/s per N·s) and the checked stability of the
    force loop.

    Raises
    ------
    InfeasibleError
        When the loop at the stiffest contact is unstable or lacks the required margins.
    """
    K = contact_stiffness(tool, part_stiffness=part_stiffness)
    kp = controller.force_gain if controller.force_gain is not None else 1.0 / (K * controller.time_constant)
    ki = controller.integral_gain if controller.integral_gain is not None else kp / (5.0 * controller.time_constant)
    st = check_stability(K, rate=controller.rate, kp=kp, ki=ki, servo_lag=controller.servo_lag,
                         latency=controller.latency, min_gain_margin=controller.min_gain_margin,
                         min_phase_margin=controller.min_phase_margin, what="force loop")
    return kp, ki, st


def simulate_force(trajectory, surface, tool: Tool, *, controller: ForceController = ForceController(),
                   disturbance: Disturbance = Disturbance(), part_stiffness: float = math.inf,
                   sample_spacing: float | None = None) -> ForceTrace:
    """Run the controller along the contact passes of ``trajectory`` on the real part.

    Parameters
    ----------
    trajectory : Trajectory
        The plan (part frame); its contact runs are simulated, its air moves are not.
    surface : Surface
        The planned part surface (part frame, normals toward the tool).
    tool : Tool
        Pad radius, stiffness and set force ``tool.force`` (N).
    controller : ForceController
    disturbance : Disturbance
    part_stiffness : float
        Stiffness of the part (and fixture) at the contact, N/m, in series with the pad (default
        infinite: rigid part).
    sample_spacing : float, optional
        Largest edge of the sampled surface the contact is evaluated on, m (default an eighth of
        the pad radius, at most 3 mm, as the removal simulation).

    Returns
    -------
    ForceTrace
        ``metrics`` holds ``set_force_n``, ``rms_force_error_n`` and ``rms_force_error_fraction``
        (contact force minus set force over the ticks where the tool moves along a pass),
        ``max_abs_force_error_n``, ``mean_force_n``, ``contact_loss_fraction`` (moving ticks with no
        force), ``rms_tangential_error_m``, ``hold_time_s`` (total contact-phase wait),
        ``force_gain_m_per_s_per_n``, ``force_integral_gain_m_per_s2_per_n``, ``force_gain_margin``, ``force_phase_margin_deg``,
        ``force_time_constant_s`` and ``position_phase_margin_deg``; of the transients
        ``landing_hold_time_s`` and ``lift_hold_time_s`` (time in contact standing still at the
        pass starts and ends) and ``landing_force_overshoot_fraction`` (peak landing force over
        the set force, minus 1).

    Raises
    ------
    InputError
        On a trajectory without contact samples or bad settings.
    InfeasibleError
        When a loop's gains fail the stability check.
    """
    from .removal import sample_spacing_for

    if not (part_stiffness > 0):
        raise InputError(f"part stiffness must be positive (N/m), got {part_stiffness!r}")
    contact = np.asarray(trajectory.contact, bool)
    cidx = np.flatnonzero(contact)
    if len(cidx) == 0:
        raise InputError("the trajectory has no in-contact samples to simulate; plan contact passes first")
    c = controller
    stability = {"position": check_stability(1.0, rate=c.rate, kp=c.position_gain, servo_lag=c.servo_lag,
                                             latency=c.latency, min_gain_margin=c.min_gain_margin,
                                             min_phase_margin=c.min_phase_margin, what="tangential position loop")}
    kp = ki = math.nan
    if c.mode == "hybrid":
        kp, ki, stability["force"] = force_gains(tool, c, part_stiffness=part_stiffness)

    spacing = sample_spacing_for(tool) if sample_spacing is None else float(sample_spacing)
    samples = surface.subdivided(spacing)
    t_plan = np.asarray(trajectory.t, float)[cidx]
    feed = np.asarray(trajectory.feed, float)[cidx]

    # Contact runs: consecutive contact samples of one pass.  The plant is evaluated at "key"
    # samples about one removal-sample spacing apart (and at both ends of each run) and
    # interpolated in between: the force curve changes on the scale of the surface sampling.
    pidx = np.asarray(trajectory.pass_index)[cidx]
    breaks = np.flatnonzero((np.diff(cidx) > 1) | (np.diff(pidx) != 0)) + 1
    runs = np.split(np.arange(len(cidx)), breaks)
    steps = np.linalg.norm(np.diff(trajectory.position[cidx], axis=0), axis=1)
    inner = np.ones(len(steps), bool)
    inner[breaks - 1] = False
    typical = float(np.median(steps[inner])) if inner.any() else spacing
    every = max(1, int(spacing / max(typical, 1e-9)))
    keys = [np.unique(np.concatenate([run[::every], run[-1:]])) for run in runs]
    kidx = np.concatenate(keys)
    key_start = np.concatenate([[0], np.cumsum([len(k) for k in keys])])

    axes = trajectory.tool_z()
    pos_k, ax_k = trajectory.position[cidx[kidx]], axes[cidx[kidx]]
    plan_curves = contact_curves(samples, pos_k, ax_k, tool)
    nominal = plan_curves.offsets(tool.force)
    if np.isnan(nominal).any():
        log.warning("%d contact samples have no surface under the pad; using the flat depression as their "
                    "nominal sink", int(np.isnan(nominal).sum()))
        nominal = np.where(np.isnan(nominal), tool.flat_depression, nominal)
    d = disturbance
    if np.any(np.asarray(d.part_offset) != 0):
        R, shift = rigid_offset(d.part_offset)
        centre = np.asarray(d.offset_centre, float) if d.offset_centre is not None else surface.principal_axes[0]
        real_curves = contact_curves(samples, pos_k, ax_k, tool, part2real=(R, shift, centre))
    else:
        real_curves = plan_curves

    g = np.asarray(d.gravity, float)
    gnorm = float(np.linalg.norm(g))
    # Sensor reading (tared hanging along gravity) minus the contact force: m (|g| − g·a); the
    # compensation subtracts the same with the mass it believes.
    weight_share = d.tool_mass * (gnorm - ax_k @ g)
    comp_mass = d.tool_mass * (1.0 + d.mass_error)
    comp_share = comp_mass * (gnorm - ax_k @ g) if c.gravity_compensation else np.zeros(len(kidx))
    reading = weight_share - comp_share

    rng = np.random.default_rng(d.seed)
    sim = _Run(c, kp=kp, ki=ki, tool=tool, curves=real_curves, part_stiffness=part_stiffness, rng=rng,
               noise=d.force_noise)
    records, waited = [], 0.0
    nominal_full = np.full(len(trajectory), np.nan)
    for r, run in enumerate(runs):
        ks = slice(key_start[r], key_start[r + 1])
        Tk = t_plan[kidx[ks]]
        rec = sim.run(int(key_start[r]), Tk, nominal[ks], reading[ks], start_time=waited, index=r)
        waited = rec["t"][-1] - t_plan[run][-1] if len(rec["t"]) else waited
        rec["feed"] = np.interp(rec["progress"], t_plan[run], feed[run]) if len(run) > 1 else np.full(len(rec["t"]), feed[run][0])
        records.append(rec)
        nominal_full[cidx[run]] = np.interp(t_plan[run], Tk, nominal[ks]) if len(Tk) > 1 else nominal[ks][0]
    cat = {k: np.concatenate([rec[k] for rec in records]) for k in records[0]}

    force = np.zeros(len(trajectory))
    force[cidx] = per_sample_force(runs, t_plan, cat)
    metrics = trace_metrics(cat, tool.force, kp, ki, stability)
    holds = landing_holds(cat, runs, cidx, trajectory.position, axes, 1.0 / c.rate)
    metrics.update(transient_metrics(cat, tool.force, holds))
    return ForceTrace(cat["t"], cat["progress"], cat["set"], cat["contact"], cat["measured"], cat["command"],
                      cat["actual"], cat["moving"].astype(bool), cat["run"].astype(int), force, nominal_full,
                      metrics, stability, holds)


class _Run:
    """The tick loop of one contact run (scalar Python: the loop is sequential feedback)."""

    def __init__(self, c: ForceController, *, kp, ki, tool, curves: ContactCurves, part_stiffness, rng, noise):
        self.c, self.kp, self.ki, self.F = c, kp, ki, tool.force
        self.damping = tool.damping_time
        self.curves, self.kpart = curves, part_stiffness
        self.rng, self.noise = rng, noise
        self.dt = 1.0 / c.rate
        self.delay = int(round(c.latency * c.rate))

    def pad_force(self, i0: int, i1: int, lam: float, delta: float, x0: float) -> tuple[float, float, float]:
        """Elastic contact force (N) at robot offset ``delta`` between poses ``i0, i1`` (weight
        ``lam`` on ``i1``), with the part in series; returns (force, pad offset, pad slope dF/dx N/m)."""
        cv = self.curves

        def f(x):
            f0, k0 = cv.force(i0, x)
            if lam == 0.0:
                return f0, k0
            f1, k1 = cv.force(i1, x)
            return (1 - lam) * f0 + lam * f1, (1 - lam) * k0 + lam * k1

        if math.isinf(self.kpart):
            fd, kd = f(delta)
            return fd, delta, kd
        x = min(x0, delta)
        kx = 0.0
        for _ in range(30):                       # Newton on the convex f(x) + k_part x
            fx, kx = f(x)
            r = fx - self.kpart * (delta - x)
            step = r / (kx + self.kpart)
            x -= step
            if abs(step) < 1e-12:
                break
        return self.kpart * (delta - x), x, kx

    def run(self, base: int, T: np.ndarray, nominal: np.ndarray, weight_share: np.ndarray, *,
            start_time: float, index: int) -> dict:
        """Simulate one run whose key poses are curves ``base .. base + len(T) − 1`` at plan times ``T``."""
        c, dt, F = self.c, self.dt, self.F
        Tl = T.tolist()
        n = len(Tl)
        T0, T1 = Tl[0], Tl[-1]
        slope = np.zeros(n)
        if n > 1:
            with np.errstate(divide="ignore", invalid="ignore"):
                slope[:-1] = np.where(np.diff(T) > 0, np.diff(nominal) / np.diff(T), 0.0)
        nom, slo, wsh = nominal.tolist(), slope.tolist(), weight_share.tolist()
        tan = Servo(T0, dt=dt, servo_lag=c.servo_lag, delay=self.delay)
        nrm = Servo(nom[0] - c.clearance, dt=dt, servo_lag=c.servo_lag, delay=self.delay)
        ref, moving, seen, t_seen, integ, held = T0, False, False, 0.0, 0.0, 0.0
        x_pad = nrm.actual
        out: dict[str, list] = {k: [] for k in ("progress", "set", "contact", "measured", "command", "actual", "moving",
                                                "ref", "phase")}
        lift_time = (max(nom) + c.search_depth + c.clearance) / c.lift_speed
        max_ticks = int(((T1 - T0) + c.max_hold + 2.0 + 10 * c.clearance / c.approach_speed + lift_time) * c.rate) + 10
        lifting, free_ticks = False, 0
        noise = self.rng.standard_normal(max_ticks) * self.noise if self.noise > 0 else None
        settled = 0
        for k in range(max_ticks):
            tau = min(max(tan.actual, T0), T1)
            i = max(0, min(bisect.bisect_right(Tl, tau) - 1, n - 2)) if n > 1 else 0
            lam = 0.0 if n == 1 or Tl[i + 1] <= Tl[i] else (tau - Tl[i]) / (Tl[i + 1] - Tl[i])
            i1 = i + 1 if n > 1 else i
            x_before = x_pad
            fc, x_pad, k_pad = self.pad_force(base + i, base + i1, lam, nrm.actual, x_pad)
            if self.damping > 0 and k > 0 and fc > 0:
                # Kelvin–Voigt pad: k·(h + τ_d ḣ) over the patch, i.e. F(x) + τ_d F'(x) ẋ, never pulling
                fc = max(0.0, fc + self.damping * k_pad * (x_pad - x_before) / dt)
            share = (1 - lam) * wsh[i] + lam * wsh[i1]
            fm = fc + share + (noise[k] if noise is not None else 0.0)
            nom_here = (1 - lam) * nom[i] + lam * nom[i1]
            ff_rate = 1.0 if (moving and ref < T1) else 0.0
            if lifting:
                sp, v = 0.0, -c.lift_speed
            elif c.mode == "position":
                sp = F
                target = nom_here
                if not moving:
                    v = c.approach_speed if nrm.command < target else 0.0
                    if nrm.command + dt * v >= target:
                        v = (target - nrm.command) / dt
                        moving = True
                else:
                    v = (target + slo[i] * ff_rate * dt - nrm.command) / dt
            else:
                if not seen and fm >= c.contact_threshold * F:
                    seen, t_seen = True, k * dt
                if not seen:
                    sp, v = F, c.approach_speed
                else:
                    frac = 1.0 if c.ramp_time == 0 else min(1.0, (k * dt - t_seen) / c.ramp_time)
                    sp = c.contact_threshold * F + (F - c.contact_threshold * F) * frac
                    e = sp - fm
                    # the sum includes this tick (as in force_loop); it starts once the ramp is over, so
                    # the ramp's tracking lag does not wind it up into an overshoot
                    integ_next = integ + e * dt if frac >= 1.0 else integ
                    v = slo[i] * ff_rate + self.kp * e + self.ki * integ_next
                    if abs(v) > c.max_normal_speed:        # saturated: hold the integral (anti-windup)
                        v = math.copysign(c.max_normal_speed, v)
                    else:
                        integ = integ_next
                    if not moving and frac >= 1.0:
                        settled = settled + 1 if abs(fm - F) <= c.start_tolerance * F else 0
                        if settled * dt >= c.settle_time:
                            moving = True
                        elif k * dt - t_seen > c.max_hold:
                            log.warning("contact run %d: force %.3g N did not settle within %.3g N of %.3g N in %g s; "
                                        "starting anyway", index, fm, c.start_tolerance * F, F, c.max_hold)
                            moving = True
            out["progress"].append(tau)
            out["set"].append(sp)
            out["contact"].append(fc)
            out["measured"].append(fm)
            out["command"].append(nrm.command)
            out["actual"].append(nrm.actual)
            out["moving"].append(moving and not lifting)
            out["ref"].append(ref)
            out["phase"].append(2 if lifting else 1 if moving else 0)
            if not moving:
                held += dt
            if lifting:
                free_ticks = free_ticks + 1 if fc <= 0.0 else 0
                if free_ticks >= 2:
                    break
                nrm.step(v)
                continue
            # tangential loop: feed-forward of the plan's progress rate plus the position gain
            u = (ff_rate + c.position_gain * (ref - tan.actual)) if moving else 0.0
            if moving:
                ref = min(ref + dt, T1)
            nrm.step(v)
            tan.step(u)
            if moving and ref >= T1 and T1 - tan.actual < 0.5 * dt:
                lifting = True          # the pass is done: stop and retract along the tool axis
            if not seen and c.mode == "hybrid" and nrm.command > nom[0] + c.search_depth:
                log.warning("contact run %d: no contact within %.3g mm beyond the nominal sink; the pass is "
                            "skipped (is the part where the plan expects it?)", index, 1e3 * c.search_depth)
                break
        m = len(out["progress"])
        res = {k: np.asarray(v, float) for k, v in out.items()}
        res["t"] = start_time + T0 + np.arange(m) * dt
        res["run"] = np.full(m, index)
        res["held"] = np.full(m, held)
        return res


def trajectory_with_force(trajectory, trace: ForceTrace):
    """``trajectory`` with the extra column ``force`` (N per sample, 0 off contact) from ``trace``."""
    from dataclasses import replace

    if len(trace.force) != len(trajectory):
        raise InputError(f"force trace has {len(trace.force)} samples, the trajectory {len(trajectory)}; "
                         "simulate the force on this trajectory")
    extra = dict(trajectory.extra)
    extra["force"] = np.asarray(trace.force, float)
    return replace(trajectory, extra=extra)
