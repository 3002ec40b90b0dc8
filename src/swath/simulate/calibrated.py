"""A calibration applied to a job: the job's tool with the calibrated Preston coefficient and wear,
checked against the tool the trials were run with, and the depths a calibrated tool predicts.

:func:`tool_with_calibration` sets the coefficient (the tangent one when exponents were fitted);
:func:`calibrated_tool` builds a job's tool once from its settings and the calibration's tool record
(:mod:`swath.simulate.calibrate` writes it); :func:`predict_depth` and :func:`predict_job_depth`
turn a calibration into depths with their intervals.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, replace

import numpy as np

from ..contact import Tool
from ..errors import InputError
from .calibrate import Calibration, load_calibration, make_trials

log = logging.getLogger(__name__)


def tool_with_calibration(tool: Tool, calibration, *, grit: str | None = None) -> Tool:
    """``tool`` with its Preston coefficient from ``calibration`` (a :class:`Calibration` or a path).

    With fitted exponents the removal model of swath stays linear, so the coefficient is the
    tangent one at the tool's own operating point: ``k_p · p₀^(a−1) · v₀^(b−1)`` with ``p₀ = F/(πR²)``
    and ``v₀`` the pad's mean relative speed (``ω e`` orbital, ``2ωR/3`` rotary); a warning says so.
    """
    cal = calibration if isinstance(calibration, Calibration) else load_calibration(calibration)
    f = cal.fit_for(grit)
    k = f.preston
    if not f.linear:
        p0 = tool.force / tool.pad_area
        v0 = tool.spindle_speed * (tool.orbit_radius if tool.motion == "orbital" else 2 * tool.pad_radius / 3)
        k = f.preston * p0 ** (f.pressure_exponent - 1) * v0 ** (f.speed_exponent - 1)
        log.warning("calibration exponents a=%.3g, b=%.3g: removal uses k_p = %.4g 1/Pa, exact at %.4g Pa and %.4g m/s "
                    "only", f.pressure_exponent, f.speed_exponent, k, p0, v0)
    return replace(tool, preston=float(k), wear_rate=float(f.wear_rate) if f.wear_rate > 0 else tool.wear_rate)


def calibrated_tool(tool: Tool, calibration, *, grit: str | None = None, motion: str | None = None,
                    spindle_speed: float | None = None, orbit_radius: float | None = None,
                    wear_rate: float | None = None) -> Tool:
    """A job's tool built once from its settings and the calibration's tool record.

    ``tool`` carries the job's pad and force; ``motion``, ``spindle_speed`` (rad/s),
    ``orbit_radius`` (m) and ``wear_rate`` (1/s) are what the user gave (None: not given).  What
    the user did not give comes from the calibration's tool (when its trials share one value), else
    from ``tool``.  A job that runs the pad in another motion than the trials is refused (the
    Preston coefficient of a rotary pad is not that of an orbital one in practice); a spindle speed
    or orbit outside the trials' is accepted, converted by the model (removal ∝ relative speed),
    with a warning that it extrapolates.
    """
    cal = calibration if isinstance(calibration, Calibration) else load_calibration(calibration)
    rec = cal.metadata.get("tool")
    kw: dict = {}
    if not isinstance(rec, dict):
        log.warning("the calibration file does not state the tool its trials were run with (written before swath "
                    "recorded it): the job's own tool is used as is; recalibrate to have it checked")
    else:
        cal_motion = rec.get("motion")
        if cal_motion == "mixed":
            raise InputError("the calibration mixes orbital and rotary trials in one fit; calibrate each motion from "
                             "its own trials")
        if motion is not None and motion != cal_motion:
            raise InputError(f"the calibration was measured with a {cal_motion} pad and the job runs it {motion}: "
                             f"drop --motion (the job then runs {cal_motion}), or calibrate from {motion} trials")
        kw["motion"] = cal_motion
        speeds = [v * 2 * math.pi / 60.0 for v in rec.get("spindle_speed_rpm", [])]
        orbits = list(rec.get("orbit_radius_m", []))
        if spindle_speed is None and len(speeds) == 1:
            kw["spindle_speed"] = speeds[0]
        elif spindle_speed is not None and speeds and not min(speeds) * 0.999 <= spindle_speed <= max(speeds) * 1.001:
            log.warning("spindle speed %.0f rpm lies outside the calibration's %.0f..%.0f rpm: removal scales with "
                        "the relative speed by the model, untested there", spindle_speed * 60 / (2 * math.pi),
                        min(speeds) * 60 / (2 * math.pi), max(speeds) * 60 / (2 * math.pi))
        if cal_motion == "orbital":
            if orbit_radius is None and len(orbits) == 1:
                kw["orbit_radius"] = orbits[0]
            elif orbit_radius is not None and orbits and not min(orbits) * 0.999 <= orbit_radius <= max(orbits) * 1.001:
                log.warning("orbit radius %.3g mm lies outside the calibration's %.3g..%.3g mm: removal scales with "
                            "the orbit by the model, untested there", orbit_radius * 1e3, min(orbits) * 1e3,
                            max(orbits) * 1e3)
        radii = rec.get("pad_radius_m", [])
        if radii and not min(radii) * 0.999 <= tool.pad_radius <= max(radii) * 1.001:
            log.warning("pad radius %.4g mm differs from the calibration's trials (%s mm)", tool.pad_radius * 1e3,
                        ", ".join(f"{r * 1e3:.4g}" for r in radii))
    out = tool_with_calibration(replace(tool, **kw), cal, grit=grit)
    if wear_rate is not None:
        out = replace(out, wear_rate=float(wear_rate))
    return out


@dataclass(frozen=True)
class DepthPrediction:
    """A predicted depth with its intervals, m (arrays or floats).

    ``low, high``: interval of the mean depth (the uncertainty of ``k_p``); ``pred_low, pred_high``:
    where one new run falls (adds the trials' scatter).  Both at ``confidence``.
    """

    depth: object
    low: object
    high: object
    pred_low: object
    pred_high: object
    confidence: float


def predict_depth(calibration: Calibration, tool: Tool, *, feed: float, passes: int = 1, grit: str | None = None,
                  confidence: float | None = None) -> DepthPrediction:
    """Centre-line depth (m) of ``passes`` straight passes of ``tool`` at ``feed`` (m/s) on a flat part."""
    f = calibration.fit_for(grit)
    t = make_trials(force=tool.force, spindle_speed=tool.spindle_speed, feed=feed, passes=passes, depth=1.0,
                    pad_radius=tool.pad_radius, orbit_radius=tool.orbit_radius if tool.motion == "orbital" else 0.0)
    d, lo, hi, plo, phi = (float(v[0]) for v in f.predict(t, confidence=confidence))
    return DepthPrediction(d, lo, hi, plo, phi, f.confidence if confidence is None else confidence)


def predict_job_depth(depth, *, calibration: Calibration, preston_used: float, grit: str | None = None,
                      confidence: float | None = None) -> DepthPrediction:
    """Scale a simulated removal depth to the calibration, with its interval.

    ``depth`` (m, scalar or array, e.g. ``RemovalMap.depth`` or a metric such as the mean removal)
    was simulated with the Preston coefficient ``preston_used`` (1/Pa).  Removal is linear in
    ``k_p``, so the depth and both intervals scale by the calibrated ``k_p`` and its relative
    uncertainty.  Only plain (linear) fits are accepted.
    """
    from scipy import stats

    f = calibration.fit_for(grit)
    if not f.linear:
        raise InputError("predict_job_depth needs a plain Preston fit (exponents 1); simulate with "
                         "tool_with_calibration(...) and read the depth directly")
    if not (preston_used > 0):
        raise InputError(f"preston_used must be positive (1/Pa), got {preston_used!r}")
    level = f.confidence if confidence is None else confidence
    tq = stats.t.ppf(0.5 + level / 2, f.dof)
    d = np.asarray(depth, float) * (f.preston / preston_used)
    se = math.sqrt(f.covariance[0][0])
    # a wear fit's covariance is of log k_p0: its standard error is already relative
    rel = tq * (se if f.error_model == "wear" else se / f.preston)
    if f.error_model == "wear":
        relp = tq * math.sqrt(se**2 + f.residual_std**2)
    elif f.error_model == "relative":
        relp = tq * math.sqrt((se / f.preston) ** 2 + f.residual_std**2)
    else:
        relp = rel
    out = [d, d * (1 - rel), d * (1 + rel), d * (1 - relp), d * (1 + relp)]
    if np.ndim(d) == 0:
        out = [float(v) for v in out]
    return DepthPrediction(out[0], out[1], out[2], out[3], out[4], level)
