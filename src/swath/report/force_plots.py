"""Figures of the force simulation and of the Preston calibration (matplotlib, Agg canvas).

* :func:`force_trace_figure` — contact force against time with the set point, the contact phases
  shaded, and the normal offset below; other runs (e.g. the position-control baseline) overlaid;
* :func:`calibration_figure` — measured depth against the Preston exposure with the fitted line,
  its confidence band and the prediction band, one colour per grit (measured against predicted
  depth with error bars for an exponent fit);
* :func:`write_force_plots` — both as PNGs (``force_trace.png``, ``calibration.png``).

Figures are ``matplotlib.figure.Figure`` objects on an Agg canvas; no ``pyplot`` state is used.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError
from .plots import save_png

#: File names :func:`write_force_plots` uses.
FORCE_PNG_NAMES = {"force_trace": "force_trace.png", "calibration": "calibration.png"}


def _figure(width_in: float, height_in: float, *, rows: int = 1, sharex: bool = True):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(rows, 1, sharex=sharex, squeeze=False)[:, 0]
    return fig, axes


def _broken(trace, values: np.ndarray, step: int) -> tuple[np.ndarray, np.ndarray]:
    """Time and values decimated by ``step``, with a NaN gap between contact runs (no line across
    the air moves, which are not simulated)."""
    t, v, run = trace.t[::step], np.asarray(values, float)[::step], trace.pass_index[::step]
    cut = np.flatnonzero(np.diff(run) != 0) + 1
    return np.insert(t, cut, np.nan), np.insert(v, cut, np.nan)


def force_trace_figure(trace, *, compare: dict | None = None, label: str = "force control",
                       max_points: int = 20000):
    """Contact force (N) and normal offset (mm) against time (s).

    Parameters
    ----------
    trace : ForceTrace
        The run to draw (from :func:`swath.simulate.simulate_force`).
    compare : dict of str -> ForceTrace, optional
        Other runs of the same trajectory to overlay (e.g. ``{"position control": baseline}``).
    label : str
        Legend label of ``trace``.
    max_points : int
        Ticks drawn at most per curve (evenly decimated).

    Returns
    -------
    matplotlib.figure.Figure
    """
    if len(trace.t) == 0:
        raise InputError("the force trace is empty; simulate a trajectory with contact passes")
    fig, (ax_f, ax_o) = _figure(8.0, 5.2, rows=2)
    step = max(1, len(trace.t) // max_points)
    # shade the contact phases (descent, ramp, settling) where the tool does not move along the pass
    hold = ~trace.moving
    edges = np.flatnonzero(np.diff(np.concatenate([[0], hold.astype(int), [0]])))
    for a, b in zip(edges[::2], edges[1::2]):
        for ax in (ax_f, ax_o):
            ax.axvspan(trace.t[a], trace.t[min(b, len(trace.t) - 1)], color="0.9", lw=0)
    for name, other in (compare or {}).items():
        s2 = max(1, len(other.t) // max_points)
        ax_f.plot(*_broken(other, other.contact_force, s2), lw=0.8, label=name, alpha=0.8)
        ax_o.plot(*_broken(other, other.actual_offset * 1e3, s2), lw=0.8, label=f"{name}: actual", alpha=0.8)
    ax_f.plot(*_broken(trace, trace.contact_force, step), lw=1.0, color="C3", label=f"{label}: contact force")
    ax_f.plot(*_broken(trace, trace.measured_force, step), lw=0.6, color="C7", alpha=0.7,
              label=f"{label}: measured (compensated)")
    ax_f.plot(*_broken(trace, trace.set_force, step), lw=1.0, ls="--", color="k", label="set point")
    ax_f.set_ylabel("force (N)")
    m = trace.metrics
    if m:
        ax_f.set_title(f"RMS force error {100 * m.get('rms_force_error_fraction', np.nan):.2f} % of "
                       f"{m.get('set_force_n', np.nan):.3g} N over the passes (grey: contact phases)", fontsize=9)
    ax_f.legend(fontsize=7, loc="lower right")
    ax_o.plot(*_broken(trace, trace.commanded_offset * 1e3, step), lw=0.8, ls="--", color="C0",
              label=f"{label}: commanded")
    ax_o.plot(*_broken(trace, trace.actual_offset * 1e3, step), lw=1.0, color="C3", label=f"{label}: actual")
    ax_o.set_ylabel("normal offset (mm)")
    ax_o.set_xlabel("time (s)")
    ax_o.legend(fontsize=7, loc="lower right")
    return fig


def calibration_figure(calibration, trials, *, confidence: float | None = None):
    """Measured depth (µm) against the Preston exposure (Pa·m), with fit, confidence and prediction bands.

    Parameters
    ----------
    calibration : Calibration
        From :func:`swath.simulate.calibrate.calibrate`.
    trials : Trials
        The trials it was fitted to (:func:`swath.simulate.calibrate.read_trials`).
    confidence : float, optional
        Level of the bands (default the calibration's).

    Returns
    -------
    matplotlib.figure.Figure
    """
    from ..simulate.calibrate import exposure

    if len(trials) == 0:
        raise InputError("no trials to plot")
    fig, (ax,) = _figure(6.4, 4.6, rows=1)
    X = exposure(trials)
    for c, (grit, fit) in enumerate(calibration.fits.items()):
        sel = trials.grit == grit
        if not sel.any():
            continue
        sub = trials.subset(sel)
        colour = f"C{c % 10}"
        level = fit.confidence if confidence is None else confidence
        if fit.linear:
            # a fit with pad wear: the exposure of each trial at its media's cut, X · exp(−λ a)
            Xs = X[sel] * (np.exp(-fit.wear_rate * np.nan_to_num(sub.pad_age)) if fit.error_model == "wear" else 1.0)
            order = np.argsort(Xs)
            grid = sub.subset(order)
            d, lo, hi, plo, phi = fit.predict(grid, confidence=level)
            xs = Xs[order]
            wear = f", wear {fit.wear_rate:.3g} 1/s" if fit.error_model == "wear" else ""
            ax.plot(xs, d * 1e6, color=colour, lw=1.2,
                    label=f"grit {grit}: k_p = {fit.preston:.3g} 1/Pa [{fit.preston_low:.3g}, {fit.preston_high:.3g}]"
                          + wear)
            ax.fill_between(xs, lo * 1e6, hi * 1e6, color=colour, alpha=0.25, lw=0)
            ax.fill_between(xs, plo * 1e6, phi * 1e6, color=colour, alpha=0.08, lw=0)
            ax.plot(Xs, sub.depth * 1e6, "o", ms=4, color=colour)
        else:
            d, lo, hi, plo, phi = fit.predict(sub, confidence=level)
            ax.errorbar(X[sel], d * 1e6, yerr=[(d - plo) * 1e6, (phi - d) * 1e6], fmt="none", ecolor=colour,
                        alpha=0.5, lw=0.8)
            ax.plot(X[sel], sub.depth * 1e6, "o", ms=4, color=colour,
                    label=f"grit {grit}: k_p = {fit.preston:.3g}, a = {fit.pressure_exponent:.2f}, "
                          f"b = {fit.speed_exponent:.2f}")
            ax.plot(X[sel], d * 1e6, "x", ms=4, color=colour)
    worn = any(f.error_model == "wear" for f in calibration.fits.values())
    ax.set_xlabel("Preston exposure  passes · p · ∫v dt" + ("  · exp(−λ · pad age)" if worn else "") + "  (Pa·m)")
    ax.set_ylabel("centre-line depth (µm)")
    level = next(iter(calibration.fits.values())).confidence if confidence is None else confidence
    ax.set_title(f"Preston fit: line, {100 * level:.0f} % confidence band (dark) and prediction band (light)",
                 fontsize=9)
    ax.set_xlim(left=0)
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=7, loc="upper left")
    return fig


def write_force_plots(out_dir, *, trace=None, compare: dict | None = None, calibration=None,
                      trials=None) -> dict[str, Path]:
    """Write ``force_trace.png`` (when ``trace`` is given) and ``calibration.png`` (when
    ``calibration`` and ``trials`` are) into the existing directory ``out_dir``; returns name -> path."""
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        raise InputError(f"plot directory {out_dir} does not exist; create it first")
    paths = {}
    if trace is not None:
        paths["force_trace"] = save_png(force_trace_figure(trace, compare=compare),
                                        out_dir / FORCE_PNG_NAMES["force_trace"])
    if calibration is not None and trials is not None:
        paths["calibration"] = save_png(calibration_figure(calibration, trials), out_dir / FORCE_PNG_NAMES["calibration"])
    return paths
