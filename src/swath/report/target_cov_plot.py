"""The ``--target-cov`` trade-off: predicted interior removal CoV against cycle time for every
candidate plan simulated (matplotlib on an Agg canvas)."""

from __future__ import annotations

from pathlib import Path

from .plots import save_png

PNG_NAME = "target_cov_candidates.png"


def target_cov_figure(candidates: list, target: float):
    """Interior removal CoV (%) against cycle time (s) of the simulated ``candidates`` (rows of
    ``metrics.json``'s ``target_cov_candidates``), the ``target`` (fraction) as a line and the
    chosen plan (the first that reached it) ringed."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.5, 4.8), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    rows = [c for c in candidates if c.get("simulated")]
    for c in rows:
        colour = "#1b7837" if c["reached"] else "#762a83"
        ax.scatter(c["cycle_time_s"], c["interior_removal_cov"] * 100, color=colour, s=28, zorder=3)
        ratio = c.get("length_ratio")
        ax.annotate(f"{ratio:.2f} L*" if ratio is not None else "", (c["cycle_time_s"], c["interior_removal_cov"] * 100),
                    textcoords="offset points", xytext=(4, 3), fontsize=7)
    reached = [c for c in rows if c["reached"]]
    if reached:
        best = min(reached, key=lambda c: c["cycle_time_s"])
        ax.scatter(best["cycle_time_s"], best["interior_removal_cov"] * 100, s=160, facecolors="none",
                   edgecolors="black", zorder=4, label=f"chosen: {best['label']}")
    ax.axhline(target * 100, color="#b2182b", ls="--", lw=1, label=f"target {target * 100:.3g} %")
    ax.set_xlabel("predicted cycle time (s)")
    ax.set_ylabel("predicted interior removal CoV (%)")
    ax.set_title("Candidates tried for --target-cov (green: reached, purple: not)")
    ax.grid(alpha=0.3)
    ax.margins(x=0.1, y=0.1)
    ax.legend(fontsize=7, loc="upper right")
    return fig


def write_target_cov_plot(out_dir, candidates: list, target: float) -> dict[str, Path]:
    """Write :func:`target_cov_figure` as ``target_cov_candidates.png`` into ``out_dir``; returns
    ``{"target_cov_candidates": path}``."""
    return {"target_cov_candidates": save_png(target_cov_figure(candidates, target), Path(out_dir) / PNG_NAME)}
