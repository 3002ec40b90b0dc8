"""What the force loop's ticks come to: the force per trajectory sample, the loop's figures, and the
landings and lifts as removal poses.

The simulation (:func:`swath.simulate.force.simulate_force`) records every control tick of every
contact run in a catalogue (``cat``: run, phase 0 landing / 1 moving / 2 lift, contact force,
progress, reference); these functions reduce it.
"""

from __future__ import annotations

import math

import numpy as np

#: Force levels each landing or lift is split into for the removal simulation.
HOLD_LEVELS = 6


def landing_holds(cat: dict, runs, cidx: np.ndarray, position: np.ndarray, axes: np.ndarray, dt: float) -> dict:
    """The landing and lift ticks in contact as removal poses (:attr:`ForceTrace.holds`): at the
    run's first (landing) or last (lift) sample, the ticks grouped into :data:`HOLD_LEVELS` force
    levels, each with its dwell and mean force."""
    pos, ax, dwell, force, run_of, lift = [], [], [], [], [], []
    for r, run in enumerate(runs):
        for is_lift, phase, sample in ((False, 0, cidx[run[0]]), (True, 2, cidx[run[-1]])):
            f = cat["contact"][(cat["run"] == r) & (cat["phase"] == phase)]
            f = np.sort(f[f > 0])
            if len(f) == 0:
                continue
            for part in np.array_split(f, min(HOLD_LEVELS, len(f))):
                pos.append(position[sample])
                ax.append(axes[sample])
                dwell.append(len(part) * dt)
                force.append(float(part.mean()))
                run_of.append(r)
                lift.append(is_lift)
    return {"position": np.asarray(pos, float).reshape(-1, 3), "axis": np.asarray(ax, float).reshape(-1, 3),
            "dwell": np.asarray(dwell, float), "force": np.asarray(force, float), "run": np.asarray(run_of, int),
            "lift": np.asarray(lift, bool)}


def transient_metrics(cat: dict, F: float, holds: dict) -> dict:
    """Figures of the landings and lifts: time in contact standing still, force overshoot."""
    landing = cat["phase"] == 0
    peak = float(cat["contact"][landing].max()) if landing.any() else 0.0
    return {"landing_hold_time_s": float(holds["dwell"][~holds["lift"]].sum()),
            "lift_hold_time_s": float(holds["dwell"][holds["lift"]].sum()),
            "landing_force_overshoot_fraction": max(0.0, peak / F - 1.0)}


def per_sample_force(runs, t_plan: np.ndarray, cat: dict) -> np.ndarray:
    """Mean contact force of the moving ticks over each sample's half-intervals (interpolated
    where no tick fell), per contact sample."""
    out = np.zeros(len(t_plan))
    for r, run in enumerate(runs):
        sel = (cat["run"] == r) & (cat["moving"] > 0)
        T = t_plan[run]
        if not sel.any():
            continue
        prog, fc = cat["progress"][sel], cat["contact"][sel]
        if len(T) == 1:
            out[run] = fc.mean()
            continue
        edges = 0.5 * (T[1:] + T[:-1])
        which = np.searchsorted(edges, prog, side="right")
        sums = np.bincount(which, weights=fc, minlength=len(T))
        counts = np.bincount(which, minlength=len(T))
        order = np.argsort(prog, kind="stable")
        interp = np.interp(T, prog[order], fc[order])
        out[run] = np.where(counts > 0, sums / np.maximum(counts, 1), interp)
    return out


def trace_metrics(cat: dict, F: float, kp: float, ki: float, stability: dict) -> dict:
    mv = cat["moving"] > 0
    err = cat["contact"][mv] - F
    rms = float(np.sqrt(np.mean(err**2))) if mv.any() else math.nan
    tang = (cat["ref"] - cat["progress"]) * cat["feed"]
    held = sum(float(cat["held"][cat["run"] == r][0]) for r in np.unique(cat["run"]))
    fs = stability.get("force")
    return {
        "set_force_n": float(F),
        "rms_force_error_n": rms,
        "rms_force_error_fraction": rms / F,
        "max_abs_force_error_n": float(np.max(np.abs(err))) if mv.any() else math.nan,
        "mean_force_n": float(np.mean(cat["contact"][mv])) if mv.any() else math.nan,
        "contact_loss_fraction": float(np.mean(cat["contact"][mv] <= 0)) if mv.any() else math.nan,
        "rms_tangential_error_m": float(np.sqrt(np.mean(tang[mv] ** 2))) if mv.any() else math.nan,
        "hold_time_s": held,
        "force_gain_m_per_s_per_n": kp,
        "force_integral_gain_m_per_s2_per_n": ki,
        "force_gain_margin": fs.gain_margin if fs else math.nan,
        "force_phase_margin_deg": math.degrees(fs.phase_margin) if fs else math.nan,
        "force_time_constant_s": fs.time_constant if fs else math.nan,
        "position_phase_margin_deg": math.degrees(stability["position"].phase_margin),
    }
