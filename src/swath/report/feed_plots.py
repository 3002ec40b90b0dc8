"""Figures of an optimised feed (:class:`swath.feed.FeedResult`), matplotlib on an Agg canvas.

* :func:`feed_along_passes_figure` — the planned feed coloured along the passes, seen along the
  part's principal normal axis;
* :func:`depth_vs_target_figure` — predicted removal depth beside the target depth (same scale);
* :func:`residual_histogram_figure` — area-weighted histogram of removal minus target over the
  optimised region, with the tolerance marked.

:func:`write_feed_plots` writes all three as PNG files (atomically, through :func:`save_png`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .plots import MAX_PLOT_FACES, cluster_decimate, save_png, view_frame

PNG_NAMES = {"feed_along_passes": "feed_along_passes.png", "depth_vs_target": "depth_vs_target.png",
             "residual_histogram": "residual_histogram.png"}


def _figure(width_in: float, height_in: float):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def feed_along_passes_figure(result):
    """Planned feed (mm/s) coloured along every pass, over the part's outline.

    Parameters
    ----------
    result : FeedResult
        ``result.profile`` holds one speed per pass point (m/s); the passes are ``result.kernel.toolpath``.
    """
    import matplotlib as mpl
    from matplotlib.collections import LineCollection
    from matplotlib.tri import Triangulation

    toolpath = result.kernel.toolpath
    surf = toolpath.surface
    frame = view_frame(surf)
    fig = _figure(9.0, 6.5)
    ax = fig.add_subplot()
    uvw = frame.project(surf.vertices)
    ax.triplot(Triangulation(uvw[:, 0], uvw[:, 1], surf.faces), color="#e0e0e0", lw=0.2, rasterized=True)
    segs, vals = [], []
    for p, v in zip(toolpath.passes, result.profile.speeds):
        q = frame.project(p.points)[:, :2]
        segs.append(np.stack([q[:-1], q[1:]], axis=1))
        vals.append(0.5 * (v[:-1] + v[1:]) * 1e3)
    vals = np.concatenate(vals)
    lc = LineCollection(np.concatenate(segs), cmap="plasma", norm=mpl.colors.Normalize(vals.min(), vals.max()),
                        linewidths=2.0)
    lc.set_array(vals)
    ax.add_collection(lc)
    fig.colorbar(lc, ax=ax, shrink=0.85, pad=0.01).set_label("planned feed (mm/s)")
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_xlabel("along 1st principal axis (m)")
    ax.set_ylabel("along 2nd principal axis (m)")
    ax.set_title(f"Planned feed along {len(toolpath.passes)} passes ({vals.min():.1f}-{vals.max():.1f} mm/s)")
    return fig


def depth_vs_target_figure(result, *, max_faces: int = MAX_PLOT_FACES // 2):
    """Predicted removal depth (µm) and target depth side by side, on one colour scale; samples
    outside the optimised region are drawn grey.  Each panel has about half the area of the
    removal map (:func:`swath.report.plots.removal_map_figure`), so half its faces (``max_faces``)
    draw it as finely: on crs_part_5 twice 177k shaded triangles took 1.6 s to render."""
    import matplotlib as mpl
    from matplotlib.tri import Triangulation

    samples = result.kernel.samples
    frame = view_frame(samples)
    shown = np.stack([np.where(result.region, result.predicted, -1.0), np.where(result.region, result.target, -1.0)], 1)
    top = max(float(np.max(result.predicted[result.region], initial=0.0)),
              float(np.max(result.target[result.region], initial=0.0))) * 1e6 or 1.0
    fig = _figure(12.0, 5.5)
    axes = fig.subplots(1, 2, sharex=True, sharey=True)
    cmap = mpl.colormaps["viridis"].with_extremes(under="#d9d9d9")
    # one coarsening for both panels (the same cells), each carrying its own values
    v, f, both = cluster_decimate(samples.vertices, samples.faces, shown, samples.vertex_areas, max_faces=max_faces)
    uvw = frame.project(v)
    for ax, d, title in zip(axes, both.T, ("predicted removal", "target")):
        d_um = np.where(d < 0, -1.0, d * 1e6)
        tpc = ax.tripcolor(Triangulation(uvw[:, 0], uvw[:, 1], f), d_um, shading="gouraud", cmap=cmap, vmin=0.0,
                           vmax=top, rasterized=True)
        ax.set_aspect("equal")
        ax.set_title(title)
        ax.set_xlabel("along 1st principal axis (m)")
    axes[0].set_ylabel("along 2nd principal axis (m)")
    fig.colorbar(tpc, ax=axes, shrink=0.85, pad=0.01, extend="min").set_label("depth (µm); grey = not optimised")
    m = result.metrics
    fig.suptitle(f"Removal vs target: CoV {m.get('removal_cov', float('nan')):.3f}, "
                 f"RMS residual {1e6 * m.get('residual_rms_m', float('nan')):.2f} µm")
    return fig


def residual_histogram_figure(result, *, bins: int = 60):
    """Area-weighted histogram of ``removal − target`` (µm) over the optimised region, with the
    over-removal tolerance marked."""
    r = (result.predicted - result.target)[result.region] * 1e6
    w = result.kernel.samples.vertex_areas[result.region]
    fig = _figure(8.0, 4.5)
    ax = fig.add_subplot()
    if len(r):
        ax.hist(r, bins=bins, weights=w / w.sum() * 100, color="tab:blue", alpha=0.8)
    tol = result.metrics.get("tolerance_m", float("nan")) * 1e6
    ax.axvline(0.0, color="black", lw=1)
    if np.isfinite(tol):
        ax.axvline(tol, color="tab:red", ls="--", lw=1.2, label=f"tolerance +{tol:.2f} µm")
        ax.legend(fontsize=8)
    ax.set_xlabel("removal − target (µm); positive = over-removal")
    ax.set_ylabel("share of the optimised area (%)")
    ax.set_title("Residual depth over the optimised region")
    ax.grid(alpha=0.3)
    return fig


def write_feed_plots(out_dir, result, *, dpi: int = 110) -> dict[str, Path]:
    """Write the three feed figures as PNG files into ``out_dir``; returns their paths by name."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    makers = {"feed_along_passes": feed_along_passes_figure, "depth_vs_target": depth_vs_target_figure,
              "residual_histogram": residual_histogram_figure}
    return {name: save_png(make(result), out / PNG_NAMES[name], dpi=dpi) for name, make in makers.items()}
