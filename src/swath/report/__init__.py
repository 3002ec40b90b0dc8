"""The ``report`` stage: ``metrics.json``, PNG figures and one self-contained ``report.html``.

* :func:`write_report` — everything into one output directory;
* :func:`write_metrics_json` — the figures and settings as JSON, units in every key name;
* :func:`plots.write_plots` — removal map, feed/contact and depth-histogram PNGs;
* :func:`write_report_html` — an offline HTML page with tables, a 3D view and the figures.
"""

from __future__ import annotations

import logging
from pathlib import Path

from ..core.beside import Beside
from ..errors import InputError
from .html import write_report_html
from .metrics import format_value, key_unit, to_jsonable, write_metrics_json
from .plots import PNG_NAMES, write_plots
from .warnings import plan_warnings

log = logging.getLogger(__name__)

__all__ = ["write_report", "write_metrics_json", "write_report_html", "write_plots", "format_value",
           "key_unit", "to_jsonable", "plan_warnings"]


def write_report(out_dir, *, surface, toolpath=None, trajectory=None, removal=None, metrics=None,
                 settings=None, title=None, extra_figures=None, scene_traces=None) -> dict[str, Path]:
    """Write ``metrics.json``, the PNG figures and ``report.html`` into ``out_dir``.

    Parameters
    ----------
    out_dir : str or Path
        An existing directory; files in it with the same names are replaced (each atomically).
    surface : Surface
        The part.
    toolpath : ToolPath, optional
        Passes in processing order.
    trajectory : Trajectory, optional
        Timed samples (needed for ``feed_contact.png`` and the air moves in 3D).
    removal : RemovalMap, optional
        Removal depth on the sampled surface, m (needed for the removal figures).
    metrics : dict, optional
        Figures with units in their key names; default ``removal.metrics``.
    settings : dict, optional
        Job settings with units in their key names (``pad_radius_m``, ``force_n``, ...).
    title : str, optional
        Report title; default ``"swath report — <part name>"``.
    extra_figures : dict of str -> Path, or a callable returning one, optional
        PNGs other stages wrote into ``out_dir`` (force trace, joint plots, ...), shown after the
        standard figures.  A callable is called once the standard figures are drawn (figures
        still being drawn elsewhere meanwhile).
    scene_traces : list of plotly traces, optional
        More of the 3D view in the part frame: the robot cell and where collisions happen
        (:func:`swath.report.cell_view.cell_traces`).

    Returns
    -------
    dict of str -> Path
        ``"metrics"``, ``"html"`` and one entry per PNG (``"removal_map"``, ``"feed_contact"``,
        ``"depth_histogram"``), each the written file.
    """
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        raise InputError(f"report directory {out_dir} does not exist; create it first or choose another --out")
    if metrics is None:
        metrics = dict(removal.metrics) if removal is not None else {}
    settings = dict(settings or {})
    paths = {"metrics": write_metrics_json(out_dir / "metrics.json", metrics, settings)}
    # The removal map and histogram are drawn by a forked child while this process draws the feed
    # figure and the 3D view (the same files; drawn here where no child can be forked).
    drawn = Beside(_draw, out_dir, toolpath, trajectory, removal, BESIDE_PLOTS, metrics)
    here = write_plots(out_dir, toolpath=toolpath, trajectory=trajectory, removal=removal,
                       names=[n for n in PNG_NAMES if n not in BESIDE_PLOTS])
    pngs: dict[str, Path] = {}

    def images() -> dict[str, Path]:
        both = {**drawn.result(), **here}
        pngs.update((n, both[n]) for n in PNG_NAMES if n in both)          # in the figures' own order
        pngs.update((extra_figures() if callable(extra_figures) else extra_figures) or {})
        return pngs

    html = write_report_html(out_dir / "report.html", surface=surface, toolpath=toolpath, trajectory=trajectory,
                             removal=removal, metrics=metrics, settings=settings, title=title, images=images,
                             scene_traces=list(scene_traces or []) + _hot_spot_traces(metrics))
    return {**paths, **pngs, "html": html}


def _hot_spot_traces(metrics: dict) -> list:
    """The 3D view's mark of the hot spot in ``metrics`` where the job warns of it
    (:func:`swath.simulate.hot_spots.warned_position`): a ring at its deepest removal, labelled."""
    from ..simulate.hot_spots import warned_position

    spot = warned_position(metrics)
    if spot is None:
        return []
    import plotly.graph_objects as go

    x, y, z = (float(c) for c in spot)
    label = f"hot spot {1e6 * float(metrics['hot_spot_depth_m']):.3g} µm ({float(metrics['hot_spot_depth_ratio']):.0f}x)"
    return [go.Scatter3d(x=[x], y=[y], z=[z], mode="markers+text", name="hot spot", text=[label],
                         textposition="top center", marker=dict(size=10, symbol="circle-open", color="black"),
                         hovertemplate=f"{label}<extra></extra>")]


#: The standard figures drawn beside the rest of the report (the slowest two of three).
BESIDE_PLOTS = ("removal_map", "depth_histogram")


def _draw(out_dir, toolpath, trajectory, removal, names, metrics=None) -> dict[str, Path]:
    return write_plots(out_dir, toolpath=toolpath, trajectory=trajectory, removal=removal, names=names, metrics=metrics)
