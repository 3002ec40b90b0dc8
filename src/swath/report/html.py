"""One self-contained HTML report of a finishing job: tables, an interactive 3D view, figures.

The file opens offline: plotly.js is inlined (no CDN), the PNG figures are embedded as base64
``data:`` URIs and no other resource is referenced.  Large parts are shown coarsened (at most
:data:`MAX_VIEW_FACES` faces in the 3D mesh, :data:`MAX_LINE_POINTS` points per line trace) so a
100k-face part still gives a file of a few MB.
"""

from __future__ import annotations

import base64
import datetime as _dt
import html as _html
import json
import logging
import math
from pathlib import Path

import numpy as np

from .. import __version__
from ..errors import InputError
from ..io.atomic import write_text_atomic
from . import plots
from .metrics import format_value, key_unit, to_jsonable

log = logging.getLogger(__name__)

#: Faces shown at most in the 3D mesh.
MAX_VIEW_FACES = 60_000
#: Points shown at most in each 3D line trace (passes, links).
MAX_LINE_POINTS = 20_000

# matplotlib's "cool" (cyan -> magenta), the pass-order colours of the PNG removal map.
_PASS_COLORSCALE = [[0.0, "rgb(0,255,255)"], [1.0, "rgb(255,0,255)"]]
_NO_REMOVAL_GREY = "rgb(208,208,208)"

#: The share of the 3D view's depth colour bar drawn red, for depths beyond the scale's end
#: (:func:`swath.report.plots.depth_scale`).
_DEEPER_BAND = 0.03

_EXPLAIN = {
    "view3d": (
        "The part coloured by the predicted depth of material removed (µm), read off the removal "
        "simulation's samples; grey means the pad did not touch that spot (or removed under 1 % of the peak depth). "
        "Where a few spots lie far deeper than the rest, the colour scale ends short of the peak (at the 99.5th "
        "percentile) and those spots are red, so that the rest keeps its colours. Coloured lines are the contact "
        "passes, from cyan (first) to magenta (last), drawn slightly above the surface; thin grey "
        "lines are the moves in the air between passes (retract, travel, approach); the white dot is "
        "where the job starts. Drag to rotate, scroll to zoom, hover for values."
    ),
    "removal_map": (
        "The same depth map flattened: the part seen straight along its main normal direction, so "
        "the whole surface is visible at once. Even colour means even finishing; dark or grey "
        "stripes between passes show where the passes are too far apart, bright stripes where they "
        "overlap too much."
    ),
    "depth_histogram": (
        "How the removed depth is spread over the area the pad touched. A narrow peak means an even "
        "finish; the coefficient of variation (CoV, standard deviation over mean) is the usual "
        "single-number summary, and a long tail to the left points at under-finished strips."
    ),
    "feed_contact": (
        "The commanded feed speed over the cycle; shaded stretches are in contact with the part, "
        "the rest is time in the air. The share of time in contact is what the ordering stage "
        "tries to raise."
    ),
}
_FIGURE_TITLES = {
    "removal_map": "Removal map (plan view)",
    "depth_histogram": "Removal depth distribution",
    "feed_contact": "Feed and contact over time",
}


# --- data for the 3D view ------------------------------------------------------------------------
def display_mesh(surface, removal=None, *, max_faces: int = MAX_VIEW_FACES):
    """A mesh of at most ``max_faces`` faces to show, with removal depth per vertex.

    Parameters
    ----------
    surface : Surface
        The part.
    removal : RemovalMap, optional
        Removal depth (m) on a sampled copy of the part.
    max_faces : int
        Face budget.

    Returns
    -------
    vertices : (n, 3) float
        m.
    faces : (m, 3) int
    depth : (n,) float or None
        Removal depth at each vertex, m (``None`` without ``removal``).

    Notes
    -----
    Removal on lattice samples is shown on the part's own triangulation, subdivided to fit the
    budget, with the depth interpolated from the samples (:func:`plots.depth_mesh`).  Removal on a
    subdivided surface: the sampled surface is shown when it fits the budget; otherwise the part
    itself when it fits, each part vertex carrying the area-weighted mean depth of the samples
    nearest to it (or of its nearest sample when none is); otherwise the sampled surface
    coarsened by vertex clustering (:func:`plots.cluster_decimate`).
    """
    if removal is None:
        v, f, _ = plots.cluster_decimate(surface.vertices, surface.faces, np.zeros(len(surface.vertices)),
                                         surface.vertex_areas, max_faces=max_faces)
        return v, f, None
    samples = removal.surface
    if hasattr(samples, "depth_at"):           # lattice samples: the part's own mesh, depth interpolated
        return plots.depth_mesh(removal, max_faces=max_faces)
    depth = np.nan_to_num(np.asarray(removal.depth, float))
    if len(samples.faces) <= max_faces:
        return np.asarray(samples.vertices), np.asarray(samples.faces), depth
    if len(surface.faces) <= max_faces:
        _, owner = surface.kdtree.query(samples.vertices)
        w = samples.vertex_areas
        wsum = np.bincount(owner, weights=w, minlength=len(surface.vertices))
        dsum = np.bincount(owner, weights=w * depth, minlength=len(surface.vertices))
        d = np.empty(len(surface.vertices))
        has = wsum > 0
        d[has] = dsum[has] / wsum[has]
        if not has.all():
            _, nearest = samples.kdtree.query(surface.vertices[~has])
            d[~has] = depth[nearest]
        return np.asarray(surface.vertices), np.asarray(surface.faces), d
    return plots.cluster_decimate(samples.vertices, samples.faces, depth, samples.vertex_areas, max_faces=max_faces)


def _polylines_with_gaps(lines: list[np.ndarray], max_points: int, values=None):
    """Join polylines ``[(k_i, 3)]`` into one ``(N, 3)`` array with NaN rows between them, keeping
    at most about ``max_points`` points (every s-th point of each line plus its last point).
    ``values`` (one number per line) gives an (N,) array of each point's line value."""
    total = sum(len(p) for p in lines)
    stride = max(int(np.ceil(total / max(max_points, 2))), 1)
    parts, vals = [], []
    for i, p in enumerate(lines):
        keep = np.unique(np.r_[np.arange(0, len(p), stride), len(p) - 1])
        parts.append(np.vstack([p[keep], np.full((1, 3), np.nan)]))
        if values is not None:
            vals.append(np.full(len(keep) + 1, values[i], float))
    if not parts:
        return np.zeros((0, 3)), np.zeros(0)
    return np.vstack(parts)[:-1], (np.concatenate(vals)[:-1] if values is not None else None)


def _pass_lines(toolpath, trajectory, lift: float) -> list[np.ndarray]:
    """Contact passes as polylines lifted ``lift`` metres off the surface along its normal."""
    if toolpath is not None:
        return [p.points + lift * p.normals for p in toolpath.passes]
    if trajectory is None or not len(trajectory):
        return []
    pos = trajectory.position - lift * trajectory.tool_z()
    idx = np.asarray(trajectory.pass_index)
    c = np.asarray(trajectory.contact, bool) & (idx >= 0)
    cut = np.flatnonzero(np.diff(np.where(c, idx, -1)) != 0) + 1
    runs = np.split(np.arange(len(idx)), cut)
    return [pos[r] for r in runs if c[r[0]] and len(r) >= 2]


def _link_lines(trajectory) -> list[np.ndarray]:
    """Air moves (every step not in contact at both ends) as polylines."""
    if trajectory is None or len(trajectory) < 2:
        return []
    c = np.asarray(trajectory.contact, bool)
    air = np.flatnonzero(~(c[:-1] & c[1:]))       # step i goes from sample i to i + 1
    if not len(air):
        return []
    runs = np.split(air, np.flatnonzero(np.diff(air) > 1) + 1)
    return [trajectory.position[np.r_[r, r[-1] + 1]] for r in runs]


def figure_3d(surface, *, toolpath=None, trajectory=None, removal=None, max_faces: int = MAX_VIEW_FACES,
              max_line_points: int = MAX_LINE_POINTS, scene_traces=None):
    """The interactive plotly 3D view: removal-coloured mesh, passes, air moves.

    Parameters
    ----------
    surface : Surface
        The part.
    toolpath : ToolPath, optional
        Passes, coloured by processing order.
    trajectory : Trajectory, optional
        Air moves (thin grey lines); also the passes when ``toolpath`` is not given.
    removal : RemovalMap, optional
        Removal depth (m) on the sampled surface; the mesh is coloured by it in µm.
    max_faces, max_line_points : int
        Display budgets.
    scene_traces : list of plotly traces, optional
        More of the scene in the part frame (the robot cell: table, fixtures, collision marks; the
        robot, its reach, unreached stretches); the view's range grows to take them in.

    Returns
    -------
    plotly.graph_objects.Figure
    """
    import plotly.graph_objects as go
    from plotly.colors import get_colorscale

    verts, faces, depth = display_mesh(surface, removal, max_faces=max_faces)
    frame = plots.view_frame(surface)
    diag = float(np.linalg.norm(np.ptp(surface.vertices, axis=0)))
    traces = []
    mesh = dict(x=verts[:, 0].astype(np.float32), y=verts[:, 1].astype(np.float32),
                z=verts[:, 2].astype(np.float32), i=faces[:, 0].astype(np.int32),
                j=faces[:, 1].astype(np.int32), k=faces[:, 2].astype(np.int32), name=surface.name or "part",
                flatshading=False, lighting=dict(ambient=0.55, diffuse=0.6, specular=0.05, roughness=0.9),
                showlegend=False)
    if depth is not None:
        d_um = depth * 1e6
        ds = plots.depth_scale(d_um)
        # plotly samples a colorscale on a ~256-step texture: a grey band narrower than two steps is
        # lost, so depths under 1 % of the peak are shown grey ("no removal").  Plotly has no
        # colour for values beyond ``cmax``: where the scale ends short of the peak, ``cmax`` lies
        # a little beyond its end and the last stretch of the bar is red, so deeper spots are red
        # (their hover still says their depth).
        red = _DEEPER_BAND if ds.clipped else 0.0
        cmax = ds.top / (1.0 - red)
        eps = min(ds.none_below / cmax, 0.5)
        scale = [[0.0, _NO_REMOVAL_GREY], [eps, _NO_REMOVAL_GREY]] + [
            [eps + (1 - red - eps) * s, c] for s, c in get_colorscale("Viridis")]
        if red:
            scale += [[1 - red, plots.DEEPER_THAN_SCALE], [1.0, plots.DEEPER_THAN_SCALE]]
        traces.append(go.Mesh3d(**mesh, intensity=d_um.astype(np.float32), intensitymode="vertex",
                                colorscale=scale, cmin=0.0, cmax=cmax,
                                colorbar=dict(title=dict(text="removal depth (µm)" + (
                                    f"; red: over {ds.top:.3g}" if ds.clipped else ""), side="right"), x=1.0,
                                              len=0.8),
                                hovertemplate="removal %{intensity:.3g} µm<extra></extra>"))
    else:
        traces.append(go.Mesh3d(**mesh, color="rgb(190,190,200)", hoverinfo="skip"))

    lines = _pass_lines(toolpath, trajectory, lift=2e-3 * diag)
    if lines:
        order = np.arange(1, len(lines) + 1)
        pts, val = _polylines_with_gaps(lines, max_line_points, order)
        traces.append(go.Scatter3d(
            x=pts[:, 0], y=pts[:, 1], z=pts[:, 2], mode="lines", name="passes",
            line=dict(width=4, color=val, colorscale=_PASS_COLORSCALE, cmin=1, cmax=max(len(lines), 2),
                      showscale=True, colorbar=dict(title=dict(text="pass order", side="right"), x=1.12,
                                                    len=0.8, tick0=1, dtick=max(1, int(np.ceil(len(lines) / 10))))),
            customdata=val, hovertemplate="pass %{customdata:.0f}<extra></extra>"))
        # Travel direction: from every pass start a short thick stroke along the pass, ending in a dot.
        strokes = []
        for ln in lines:
            run = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(ln, axis=0), axis=1))])
            k = int(np.searchsorted(run, 0.06 * diag))
            if len(ln) > 1:
                strokes.append(ln[:max(min(k, len(ln) - 1), 1) + 1])
        if strokes:
            pts, _ = _polylines_with_gaps(strokes, max_line_points)
            tips = np.array([st[-1] for st in strokes])
            traces.append(go.Scatter3d(x=pts[:, 0], y=pts[:, 1], z=pts[:, 2], mode="lines", name="travel direction",
                                       line=dict(width=9, color="rgb(210,40,40)"), hoverinfo="skip"))
            traces.append(go.Scatter3d(x=tips[:, 0], y=tips[:, 1], z=tips[:, 2], mode="markers", showlegend=False,
                                       marker=dict(size=4, symbol="diamond", color="rgb(210,40,40)"),
                                       hovertemplate="travel direction<extra></extra>"))
        start = lines[0][0]
        traces.append(go.Scatter3d(x=[start[0]], y=[start[1]], z=[start[2]], mode="markers", name="start",
                                   marker=dict(size=5, color="white", line=dict(color="black", width=2)),
                                   hovertemplate="start<extra></extra>"))
    links = _link_lines(trajectory)
    if links:
        pts, _ = _polylines_with_gaps(links, max_line_points)
        traces.append(go.Scatter3d(x=pts[:, 0], y=pts[:, 1], z=pts[:, 2], mode="lines", name="air moves",
                                   line=dict(width=1.5, color="rgb(120,120,120)"), opacity=0.7,
                                   hoverinfo="skip"))

    traces.extend(scene_traces or [])
    fig = go.Figure(traces)
    # Look at the side the surface faces, tilted a little, with its normal axis pointing up.
    u, v, w = frame.axes
    eye = w - 0.55 * v + 0.2 * u
    eye = 2.2 * eye / np.linalg.norm(eye)
    axis = dict(showbackground=False, gridcolor="rgb(225,225,225)", zerolinecolor="rgb(200,200,200)")
    # The view spans the part and a margin, so far air moves do not shrink the part to a speck.
    lo, hi = surface.vertices.min(axis=0) - 0.08 * diag, surface.vertices.max(axis=0) + 0.08 * diag
    for tr in scene_traces or []:
        if tr.x is None or not len(tr.x):
            continue
        marks = np.c_[np.asarray(tr.x, float), np.asarray(tr.y, float), np.asarray(tr.z, float)]
        marks = marks[np.all(np.isfinite(marks), axis=1)]           # line traces break at None
        if len(marks):
            lo, hi = np.minimum(lo, marks.min(axis=0) - 0.02 * diag), np.maximum(hi, marks.max(axis=0) + 0.02 * diag)
    fig.update_layout(
        scene=dict(aspectmode="data",
                   xaxis=dict(title=dict(text="x (m)"), range=[lo[0], hi[0]], **axis),
                   yaxis=dict(title=dict(text="y (m)"), range=[lo[1], hi[1]], **axis),
                   zaxis=dict(title=dict(text="z (m)"), range=[lo[2], hi[2]], **axis),
                   camera=dict(eye=dict(x=eye[0], y=eye[1], z=eye[2]), up=dict(x=w[0], y=w[1], z=w[2]))),
        margin=dict(l=0, r=0, t=10, b=0), height=680, paper_bgcolor="white",
        legend=dict(x=0.0, y=1.0, bgcolor="rgba(255,255,255,0.7)"),
    )
    return fig


# --- HTML ----------------------------------------------------------------------------------------
def _flatten(d: dict, prefix: str = "") -> list[tuple[str, object]]:
    rows = []
    for k, v in d.items():
        if isinstance(v, dict):
            rows += _flatten(v, f"{prefix}{k}.")
        else:
            rows.append((f"{prefix}{k}", v))
    return rows


def _table(values: dict, caption: str) -> str:
    esc = _html.escape
    if not values:
        return f"<p class='note'>No {esc(caption.lower())} given.</p>"
    rows = []
    for key, value in _flatten(values):
        label = key_unit(key.rsplit(".", 1)[-1]).label
        if "." in key:
            label = key.rsplit(".", 1)[0].replace(".", " / ") + " / " + label
        raw = json.dumps(to_jsonable(value), ensure_ascii=False)
        rows.append(f"<tr><td>{esc(label)}</td><td class='num'>{esc(format_value(key.rsplit('.', 1)[-1], value))}"
                    f"</td><td><code title='{esc(str(raw))}'>{esc(key)}</code></td></tr>")
    return (f"<div class='scroll'><table><caption>{esc(caption)}</caption><thead><tr><th>quantity</th><th>value</th>"
            f"<th>key (unit in the name)</th></tr></thead><tbody>{''.join(rows)}</tbody></table></div>")


#: What a user reads first, in this order: (label, metric key, explanation). The rest of the
#: metrics and the settings are folded below them.
HEADLINE = (
    ("coverage", "coverage_fraction", "share of the part's area the pad touches"),
    ("interior removal CoV", "interior_removal_cov",
     "evenness of removal a pad radius in from the edges (std / mean; lower is more even)"),
    ("removal CoV", "removal_cov", "evenness of removal over the covered area, edges included"),
    ("cycle time", "cycle_time_s", "contact passes and air moves, as timed under the speed limits"),
    ("contact path L", "contact_length_m", "length of the passes in contact"),
    ("air path", "air_length_m", "length of the moves between passes"),
    ("shortest covering path L*", "coverage_lower_bound_m", "area / widest swath: no path can be shorter"),
    ("efficiency L*/L", "efficiency", "how close the path comes to the bound (100 % cannot be beaten)"),
    ("passes", "n_passes", ""),
)


def _split_text(metrics: dict) -> str:
    """The shares of the interior variance by cause (:func:`swath.simulate.evenness.variance_shares`,
    as the CLI's line states them), e.g. ``"across 48 % · along 1 % · between 0 % · band 51 %"``;
    ``""`` where the job has no split.  A part with no core (every interior sample in the band) has
    no band share."""
    from ..simulate.evenness import variance_shares

    share = variance_shares(metrics)
    parts = [("across", share["within_cells"]), ("along", share["along_passes"]),
             ("between", share["between_passes"]), ("band", share["band"])]
    if not all(math.isfinite(v) for _, v in parts[:3]):
        return ""
    return " · ".join(f"{name} {v:.0f} %" for name, v in parts if math.isfinite(v))


def _headline_html(metrics: dict) -> str:
    """The figures a user reads first, one row each, with the warnings count."""
    esc = _html.escape
    rows = []
    for label, key, why in HEADLINE:
        if key not in metrics:
            continue
        rows.append(f"<tr><td>{esc(label)}</td><td class='num'><b>{esc(format_value(key, metrics[key]))}</b></td>"
                    f"<td class='why'>{esc(why)}</td></tr>")
        if key == "interior_removal_cov" and metrics.get("ripple_pv_m") is not None:
            pv, rms = (format_value(k, metrics.get(k)) for k in ("ripple_pv_m", "ripple_rms_m"))
            rows.append(f"<tr><td>ripple across the passes</td><td class='num'><b>{esc(pv)}</b> "
                        f"(rms {esc(rms)})</td><td class='why'>mid-spatial ripple: the removal's rise and fall "
                        "from pass to pass, peak to valley (median over lines across the passes)</td></tr>")
        if key == "interior_removal_cov" and (split := _split_text(metrics)):
            rows.append(f"<tr><td>where it comes from</td><td class='num'>{esc(split)}</td><td class='why'>the "
                        "interior's variance by cause: the spacing and the lead set the ripple across the passes, "
                        "the feed what varies along and between them, the edge passes the band within one "
                        "spacing of the interior's edge</td></tr>")
        if key == "contact_length_m" and metrics.get("coverage_lower_bound_m"):
            ratio = float(metrics[key]) / float(metrics["coverage_lower_bound_m"])
            rows.append(f"<tr><td>L / L*</td><td class='num'><b>{ratio:.3f}</b></td>"
                        "<td class='why'>contact path over the shortest covering path</td></tr>")
    n_warn = len(metrics.get("warnings") or [])
    rows.append(f"<tr><td>warnings</td><td class='num'><b>{n_warn}</b></td>"
                f"<td class='why'>{'listed at the top of the report' if n_warn else 'none'}</td></tr>")
    return f"<table class='headline'><tbody>{''.join(rows)}</tbody></table>"


def _png_data_uri(data: bytes) -> str:
    if not data.startswith(b"\x89PNG\r\n\x1a\n"):
        raise InputError("an embedded figure is not a PNG file; pass the paths write_plots returned")
    return "data:image/png;base64," + base64.b64encode(data).decode("ascii")


_CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:0;color:#222;background:#fafafa}
header{background:#20303f;color:#fff;padding:18px 28px}
header h1{margin:0 0 6px 0;font-size:1.5em}
header .meta{opacity:.85;font-size:.92em}
header .meta span{margin-right:22px}
main{max-width:1400px;margin:0 auto;padding:10px 28px 40px}
section{background:#fff;border:1px solid #e2e2e2;border-radius:6px;margin:18px 0;padding:14px 18px}
h2{font-size:1.15em;margin:4px 0 10px 0}
p.note{color:#555;font-size:.93em;max-width:70em;margin:4px 0 10px 0}
table{border-collapse:collapse;font-size:.92em;max-width:100%}
.scroll{overflow-x:auto;max-width:100%;min-width:0;flex:1 1 34em}
caption{text-align:left;font-weight:600;padding:4px 0}
th,td{border-bottom:1px solid #eee;padding:4px 12px 4px 0;text-align:left}
td.num{font-variant-numeric:tabular-nums;overflow-wrap:anywhere;max-width:28em}
td.why{color:#555;font-size:.93em}
table.headline td{padding:5px 18px 5px 0}
table.headline td.num{white-space:nowrap}
details{margin-top:14px}
details>summary{cursor:pointer;font-weight:600;padding:4px 0}
code{color:#666;font-size:.9em;overflow-wrap:anywhere}
.tables{display:flex;flex-wrap:wrap;gap:30px}
figure{margin:0}
img{max-width:min(100%,1100px);height:auto;border:1px solid #eee}
footer{color:#777;font-size:.85em;text-align:center;padding:10px}
section.warn{border-left:6px solid #c0392b;background:#fdf0ee}
section.ok{border-left:6px solid #2e8b57}
"""


def _plain(markdown: str) -> str:
    return markdown.replace("`", "").replace("\\", "").replace("*", "")


def _advice_html(warning: str) -> str:
    """The docs entry of a warning's code (``[W-...]``), folded under the warning."""
    from .warncodes import CODES, code_for

    c = CODES.get(code_for(warning) or "")
    if c is None:
        return ""
    return (f"<details><summary>{c.code}: what it means, what to do</summary><p>{_html.escape(_plain(c.meaning))} "
            f"<b>What to do:</b> {_html.escape(_plain(c.action))} (docs: Reference, Warnings, {c.code})</p></details>")


def _warnings_html(metrics: dict) -> str:
    """The warnings panel at the top of the report (empty when the plan raised none)."""
    warnings = list(metrics.get("warnings") or [])
    if not warnings:
        return ("<section class='ok'><h2>Warnings</h2><p>None: coverage, efficiency, speed limits and air moves "
                "are all within their checks.</p></section>")
    items = "".join(f"<li>{_html.escape(str(w))}{_advice_html(str(w))}</li>" for w in warnings)
    return f"<section class='warn'><h2>Warnings ({len(warnings)})</h2><ul>{items}</ul></section>"


def report_html_text(*, surface, toolpath=None, trajectory=None, removal=None, metrics=None, settings=None,
                     title=None, images=None, max_faces: int = MAX_VIEW_FACES,
                     max_line_points: int = MAX_LINE_POINTS, scene_traces=None) -> str:
    """The report as HTML text (see :func:`write_report_html`)."""
    if surface is None:
        raise InputError("the report needs the part surface")
    esc = _html.escape
    if metrics is None:
        metrics = dict(removal.metrics) if removal is not None else {}
    settings = dict(settings or {})
    name = surface.name or "part"
    title = title or f"swath report — {name}"
    planner = toolpath.planner if toolpath is not None else settings.get("planner", "–")
    now = _dt.datetime.now(_dt.UTC).replace(microsecond=0)

    fig = figure_3d(surface, toolpath=toolpath, trajectory=trajectory, removal=removal, max_faces=max_faces,
                    max_line_points=max_line_points, scene_traces=scene_traces)
    plot_div = fig.to_html(full_html=False, include_plotlyjs=True, div_id="view3d", default_width="100%",
                           default_height="680px",
                           config=dict(displaylogo=False, responsive=True,
                                       toImageButtonOptions=dict(filename=f"{name}_removal_3d", scale=2)))

    if callable(images):
        images = images()                   # figures drawn elsewhere while the 3D view was made
    if images is None:
        images = {}
        if removal is not None:
            images["removal_map"] = plots.png_bytes(plots.removal_map_figure(removal, toolpath))
            images["depth_histogram"] = plots.png_bytes(plots.depth_histogram_figure(removal))
        if trajectory is not None and len(trajectory):
            images["feed_contact"] = plots.png_bytes(plots.feed_contact_figure(trajectory))
    figures = []
    for key, img in images.items():
        data = img if isinstance(img, (bytes, bytearray)) else Path(img).read_bytes()
        caption = _FIGURE_TITLES.get(key, key.replace("_", " "))
        figures.append(f"<section><h2>{esc(caption)}</h2><p class='note'>{esc(_EXPLAIN.get(key, ''))}</p>"
                       f"<figure><img alt='{esc(caption)}' src='{_png_data_uri(bytes(data))}'></figure></section>")

    n_pass = len(toolpath.passes) if toolpath is not None else None
    meta = [("part", name), ("planner", planner), ("passes", n_pass),
            ("faces", f"{len(surface.faces):,}"), ("date", now.strftime("%Y-%m-%d %H:%M UTC"))]
    meta_html = "".join(f"<span>{esc(k)}: <b>{esc(str(v))}</b></span>" for k, v in meta if v is not None)
    shown = f"{max_faces:,}"
    rest = {k: v for k, v in metrics.items() if k != "warnings"}
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<meta name="generator" content="swath {esc(__version__)}">
<title>{esc(title)}</title><style>{_CSS}</style></head>
<body>
<header><h1>{esc(title)}</h1><div class="meta">{meta_html}</div></header>
<main>
{_warnings_html(metrics)}
<section><h2>Summary</h2>
{_headline_html(metrics)}
<details><summary>All metrics ({len(rest)}) and settings</summary>
<p class="note">Each figure's unit is part of its key name (m, s, fraction, …); values are shown here in
handier units. Fractions are shown in per cent; "CoV" is the standard deviation of the removal depth
divided by its mean over the covered area, "interior removal CoV" the same over the part more than a pad
radius in from its edge (untouched points included; the band where the pad hangs over is left out); the
coverage lower bound is the surface area divided by the
widest swath the pad can make, the shortest contact path that could cover the part, and "efficiency" relates
it to the path actually run (100 % cannot be beaten). Times named after a stage (plan_s, simulate_s, …) are
how long swath took to compute it.</p>
<div class="tables">{_table(rest, "Metrics")}{_table(settings, "Settings")}</div></details></section>
<section><h2>3D view</h2><p class="note">{esc(_EXPLAIN["view3d"])} Large parts are shown coarsened to at
most {shown} faces for display; the figures and metrics use the full sampling.</p>
{plot_div}</section>
{''.join(figures)}
</main>
<footer>Generated by swath {esc(__version__)} on {esc(now.isoformat())}. This file is self-contained and
works offline.</footer>
</body></html>
"""


def write_report_html(path, *, surface, toolpath=None, trajectory=None, removal=None, metrics=None,
                      settings=None, title=None, images=None, max_faces: int = MAX_VIEW_FACES,
                      max_line_points: int = MAX_LINE_POINTS, scene_traces=None) -> Path:
    """Write the self-contained HTML report atomically.

    Parameters
    ----------
    path : str or Path
        The ``.html`` file to write.
    surface : Surface
        The part (name, faces and, for large sampled surfaces, the mesh shown in 3D).
    toolpath : ToolPath, optional
        Passes in processing order (planner name, pass lines).
    trajectory : Trajectory, optional
        Timed samples (air moves, feed/contact figure).
    removal : RemovalMap, optional
        Removal depth per sample of the sampled surface, m.
    metrics : dict, optional
        Figures with units in their key names; default ``removal.metrics``.
    settings : dict, optional
        Job settings with units in their key names (``pad_radius_m``, ``force_n``).
    title : str, optional
        Page title; default ``"swath report — <part name>"``.
    images : dict of str -> (Path or bytes), or a callable returning one, optional
        PNG figures to embed by name (as :func:`plots.write_plots` returns them); rendered here
        when not given.  A callable is called once the 3D view is made (the figures may be drawn
        elsewhere meanwhile).
    max_faces : int
        Faces shown at most in the 3D mesh (default 60,000).
    max_line_points : int
        Points shown at most per 3D line trace (default 20,000).
    scene_traces : list of plotly traces, optional
        The robot cell in the part frame (:func:`swath.report.cell_view.cell_traces`) and the robot
        (:func:`swath.report.robot_plots.robot_traces`).

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    text = report_html_text(surface=surface, toolpath=toolpath, trajectory=trajectory, removal=removal,
                            metrics=metrics, settings=settings, title=title, images=images,
                            max_faces=max_faces, max_line_points=max_line_points, scene_traces=scene_traces)
    write_text_atomic(path, text)
    log.info("wrote report %s (%.1f MB)", path, len(text.encode("utf-8")) / 1e6)
    return path
