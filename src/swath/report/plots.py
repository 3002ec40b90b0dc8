"""Static PNG figures of a finishing job (matplotlib, Agg canvas, no display needed).

* :func:`removal_map_figure` — the removal depth over the part seen along its principal normal
  axis, with the passes drawn on top in processing order;
* :func:`feed_contact_figure` — commanded feed and contact state against time;
* :func:`depth_histogram_figure` — how removal depth is spread over the covered area.

:func:`write_plots` writes all three; each figure can also be written alone with :func:`save_png`
or rendered to bytes with :func:`png_bytes` (for embedding).  Figures are built on
``matplotlib.figure.Figure`` with an Agg canvas, never through ``pyplot``, so no GUI backend or
global figure state is touched.
"""

from __future__ import annotations

import io
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..io.atomic import atomic_file

log = logging.getLogger(__name__)

#: File names :func:`write_plots` uses, by figure.
PNG_NAMES = {
    "removal_map": "removal_map.png",
    "feed_contact": "feed_contact.png",
    "depth_histogram": "depth_histogram.png",
}

#: Faces drawn at most in the removal map (larger sampled surfaces are decimated for drawing).
MAX_PLOT_FACES = 200_000

#: Depths under this fraction of the peak are drawn grey ("no removal") in maps.
NO_REMOVAL_FRACTION = 0.01

#: The depth colour scale ends at this percentile of the drawn depths where the peak lies more than
#: :data:`DEEP_OUTLIER_RATIO` times beyond it; deeper spots are drawn in :data:`DEEPER_THAN_SCALE`.
#: On crs_part_5 the default job removes 2.08 µm at the median and 2.56 µm at the 95th percentile,
#: but 8.75 µm at a few facet corners: a scale to the peak drew the whole part in the bottom third.
DEPTH_SCALE_PERCENTILE = 99.5

#: How far (a ratio) the peak must lie beyond :data:`DEPTH_SCALE_PERCENTILE` before the scale ends there.
DEEP_OUTLIER_RATIO = 1.25

#: The colour of depths beyond the end of the scale (maps and the 3D view).
DEEPER_THAN_SCALE = "#d62728"

_DEPTH_CMAP = "viridis"
_PASS_CMAP = "cool"


@dataclass(frozen=True)
class DepthScale:
    """The colour scale of a removal-depth picture (:func:`depth_scale`), µm.

    Attributes
    ----------
    top : float
        The depth at the end of the scale, µm.
    peak : float
        The deepest drawn depth, µm (``top`` where the scale runs to the peak).
    none_below : float
        Depths under this are drawn grey ("no removal"): :data:`NO_REMOVAL_FRACTION` of the peak, µm.
    """

    top: float
    peak: float
    none_below: float

    @property
    def clipped(self) -> bool:
        """Whether deeper spots than the scale's end are drawn in :data:`DEEPER_THAN_SCALE`."""
        return self.peak > self.top

    def label(self) -> str:
        """The colour bar's caption."""
        if self.clipped:          # as short as the plain caption, which fills the figure's height
            return f"removal depth (µm); grey = none, red = over {self.top:.2g} (peak {self.peak:.2g})"
        return f"removal depth (µm); grey = none (under {NO_REMOVAL_FRACTION:.0%} of the peak)"


def depth_scale(depth_um) -> DepthScale:
    """The colour scale for drawn depths ``depth_um`` ((n,) µm): from zero to the peak, or to the
    :data:`DEPTH_SCALE_PERCENTILE` of the depths where the peak lies more than
    :data:`DEEP_OUTLIER_RATIO` times beyond it (a few deep spots would otherwise squeeze every
    other depth into a few colours)."""
    d = np.asarray(depth_um, float)
    d = d[np.isfinite(d)]
    peak = float(d.max()) if len(d) and d.max() > 0 else 1.0
    high = float(np.percentile(d, DEPTH_SCALE_PERCENTILE)) if len(d) else peak
    top = high if high > 0 and peak > DEEP_OUTLIER_RATIO * high else peak
    return DepthScale(top=top, peak=peak, none_below=NO_REMOVAL_FRACTION * peak)


# --- geometry helpers shared with the HTML report ------------------------------------------------
@dataclass(frozen=True)
class ViewFrame:
    """A right-handed frame for looking at a surface along its principal normal axis.

    Attributes
    ----------
    origin : (3,) float
        Area-weighted centroid of the surface, m.
    axes : (3, 3) float
        Rows u, v, w: u and v span the plane of largest spread (u the longest), w is the normal
        axis, oriented so that most of the surface faces a viewer on the +w side.
    """

    origin: np.ndarray
    axes: np.ndarray

    def project(self, points: np.ndarray) -> np.ndarray:
        """(k, 3) coordinates of ``points`` (k, 3) in the frame (u, v, w), m."""
        return (np.asarray(points, float) - self.origin) @ self.axes.T


def view_frame(surface) -> ViewFrame:
    """The :class:`ViewFrame` of ``surface`` (from :attr:`Surface.principal_axes`)."""
    origin, axes = surface.principal_axes
    # Eigenvectors have arbitrary signs: make each in-plane axis point along + its largest component,
    # so a part aligned with the x-y plane is drawn unmirrored (u = +x, v = +y).
    u, v = (a * (1.0 if a[np.argmax(np.abs(a))] > 0 else -1.0) for a in axes[:2])
    w = np.cross(u, v)
    facing = float(np.sum(surface.face_areas * (surface.face_normals @ w)))
    if facing < 0:                      # look at the side the normals point to; keep right-handed
        v, w = -v, -w
    return ViewFrame(np.asarray(origin, float), np.stack([u, v, w]))


def cluster_decimate(vertices: np.ndarray, faces: np.ndarray, values: np.ndarray, weights: np.ndarray,
                     *, max_faces: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Coarsen a triangle mesh for display by vertex clustering on a cubic grid.

    Vertices in the same grid cell merge into one, placed at their weighted mean and carrying
    the weighted mean of ``values``; faces that collapse are dropped.  The cell size grows until
    at most ``max_faces`` faces remain.

    Parameters
    ----------
    vertices : (n, 3) float
        Mesh vertices, m.
    faces : (m, 3) int
        Triangles.
    values : (n,) or (n, k) float
        A per-vertex quantity, or ``k`` of them, to carry over (e.g. removal depth, m).
    weights : (n,) float
        Vertex weights for the averages (e.g. vertex areas, m²); all positive.
    max_faces : int
        Face budget.

    Returns
    -------
    vertices : (n', 3) float
    faces : (m', 3) int
    values : (n',) or (n', k) float
    """
    vertices = np.asarray(vertices, float)
    faces = np.asarray(faces)
    if len(faces) <= max_faces:
        return vertices, faces, np.asarray(values, float)
    if max_faces < 1:
        raise InputError(f"max_faces must be at least 1, got {max_faces}")
    w = np.maximum(np.asarray(weights, float), 1e-300)
    tri = vertices[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
    lo = vertices.min(axis=0)
    cell = np.sqrt(2.0 * area / max_faces)         # a grid of this pitch holds ~max_faces triangles
    for _ in range(40):
        key = np.floor((vertices - lo) / cell).astype(np.int64)
        _, label = np.unique(_row_codes(key), return_inverse=True)
        label = label.ravel()
        f = label[faces]
        f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]
        first = np.unique(_row_codes(np.sort(f, axis=1)), return_index=True)[1]
        f = f[np.sort(first)]                     # unique triangles, original winding and order
        if len(f) <= max_faces:
            break
        cell *= 1.15
    k = label.max() + 1
    wsum = np.bincount(label, weights=w, minlength=k)
    v_new = np.stack([np.bincount(label, weights=w * vertices[:, i], minlength=k) for i in range(3)], 1) / wsum[:, None]
    values = np.asarray(values, float)
    columns = values.reshape(len(values), -1)
    val_new = np.stack([np.bincount(label, weights=w * c, minlength=k) for c in columns.T], 1) / wsum[:, None]
    val_new = val_new.reshape((k,) + values.shape[1:])
    used = np.zeros(k, bool)
    used[f.ravel()] = True
    remap = np.cumsum(used) - 1
    return v_new[used], remap[f], val_new[used]


def _row_codes(rows: np.ndarray):
    """One integer per row of the non-negative ``(n, 3)`` int array ``rows``, ordered as the rows
    are lexicographically, so that ``np.unique`` of the codes labels the rows as ``np.unique(rows,
    axis=0)`` would, ten times faster (it sorts integers, not rows); the rows themselves where
    the codes would overflow int64."""
    span = rows.max(axis=0) + 1 if len(rows) else np.ones(3, np.int64)
    if float(span[0]) * float(span[1]) * float(span[2]) >= 2.0 ** 62:
        fields = np.dtype([("a", rows.dtype), ("b", rows.dtype), ("c", rows.dtype)])   # compared field by field
        return np.ascontiguousarray(rows).view(fields).ravel()
    return (rows[:, 0] * span[1] + rows[:, 1]) * span[2] + rows[:, 2]


#: Faces of a part display mesh per ``area / edge²`` (longest-edge bisection of a regular mesh gives
#: triangles of about a quarter of the squared edge limit): the first display edge tried for a budget.
_FACES_PER_EDGE2 = 4.0


def part_display_mesh(part, *, max_faces: int, min_edge: float = 0.0) -> tuple[np.ndarray, np.ndarray, float]:
    """The part's own connected triangulation at about the finest resolution ``max_faces`` allows.

    The part's faces are split (:func:`swath.surface.subdivide.split_long_edges`, conforming, so
    neighbouring faces keep sharing their edges) until no edge is longer than an edge limit of at
    least ``min_edge`` chosen for the budget; when the part alone, or its subdivision after a few
    coarser tries, has more than ``max_faces`` faces, it is coarsened by :func:`cluster_decimate`.

    Parameters
    ----------
    part : Surface
        The part.
    max_faces : int
        Face budget (>= 1).
    min_edge : float
        Finest edge limit worth drawing, m (e.g. the removal-sample spacing).

    Returns
    -------
    vertices : (n, 3) float
        m, part frame.
    faces : (m, 3) int
        Triangles, wound as the part's.
    edge : float
        The display resolution, m: the edge limit used, or the clustering's typical edge.
    """
    from ..surface.geometry import face_normals_and_areas, vertex_areas
    from ..surface.subdivide import split_long_edges

    if max_faces < 1:
        raise InputError(f"max_faces must be at least 1, got {max_faces}")
    vertices, faces = np.asarray(part.vertices, float), np.asarray(part.faces, np.int64)
    area = float(np.sum(face_normals_and_areas(vertices, faces)[1]))
    budget_edge = float(np.sqrt(_FACES_PER_EDGE2 * area / max_faces))
    if len(faces) <= max_faces:
        edge = max(float(min_edge), budget_edge)
        for _ in range(4):
            v, f = split_long_edges(vertices, faces, edge)
            if len(f) <= max_faces:
                return v, f, edge
            # meshes of slivers gain faces about as 1 / edge, regular ones as 1 / edge²
            edge *= 1.05 * (len(f) / max_faces) ** 0.75
        vertices, faces = v, f
    weights = vertex_areas(len(vertices), faces, face_normals_and_areas(vertices, faces)[1])
    v, f, _ = cluster_decimate(vertices, faces, np.zeros(len(vertices)), weights, max_faces=max_faces)
    return v, f, max(float(np.sqrt(_FACES_PER_EDGE2 * area / max(len(f), 1))), budget_edge)


def depth_mesh(removal, *, max_faces: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A connected mesh of at most ``max_faces`` faces to draw the removal depth on, with the depth
    at each vertex.

    Removal on lattice samples (:class:`swath.simulate.samples.RemovalSamples`) is drawn on the
    part's own triangulation (:func:`part_display_mesh`, no finer than the sample spacing), each
    vertex carrying the area- and distance-weighted mean depth of the samples around it
    (:meth:`~swath.simulate.samples.RemovalSamples.depth_at`, over a quarter of a display edge and at least
    1.5 sample spacings): every face of the part is drawn and neighbouring faces join.  Removal on a
    subdivided surface is drawn on that surface, coarsened by :func:`cluster_decimate` over the budget.

    Parameters
    ----------
    removal : RemovalMap
        Samples and removal depth per sample, m.
    max_faces : int
        Face budget.

    Returns
    -------
    vertices : (n, 3) float
        m, part frame.
    faces : (m, 3) int
    depth : (n,) float
        Removal depth at each vertex, m.
    """
    from ..surface.geometry import face_normals_and_areas, vertex_normals

    samples = removal.surface
    depth = np.nan_to_num(_check_removal(removal))
    if not hasattr(samples, "depth_at"):
        return cluster_decimate(samples.vertices, samples.faces, depth, samples.vertex_areas, max_faces=max_faces)
    vertices, faces, edge = part_display_mesh(samples.part, max_faces=max_faces, min_edge=samples.spacing)
    normals = vertex_normals(len(vertices), faces, *face_normals_and_areas(vertices, faces))
    return vertices, faces, samples.depth_at(vertices, depth, normals=normals, radius=0.25 * edge)


def covered_mask(removal, *, min_depth: float | None = None) -> np.ndarray:
    """(n,) bool: samples of ``removal.surface`` with removal depth above ``min_depth`` (m).

    ``min_depth`` defaults to ``removal.metrics['coverage_threshold_m']`` when the simulator
    reports one, else 0 (any removal counts).
    """
    if min_depth is None:
        min_depth = float((removal.metrics or {}).get("coverage_threshold_m", 0.0) or 0.0)
    depth = np.asarray(removal.depth, float)
    return np.isfinite(depth) & (depth > min_depth)


def _check_removal(removal) -> np.ndarray:
    depth = np.asarray(removal.depth, float)
    n = len(removal.surface.vertices)
    if depth.shape != (n,):
        raise InputError(f"removal depth must have one value per sampled vertex, shape ({n},), got {depth.shape}")
    return depth


# --- figures -------------------------------------------------------------------------------------
def _new_figure(width_in: float, height_in: float):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def removal_map_figure(removal, toolpath=None, *, max_faces: int = MAX_PLOT_FACES, metrics: dict | None = None):
    """The removal depth map seen along the surface's principal normal axis.

    Parameters
    ----------
    removal : RemovalMap
        Sampled surface and removal depth per vertex, m.
    toolpath : ToolPath, optional
        Passes to draw on top, coloured by processing order.
    max_faces : int
        Faces drawn at most (see :func:`depth_mesh`).
    metrics : dict, optional
        The job's metrics: where the job warns of their hot spot
        (:func:`swath.simulate.hot_spots.warned_position`), its deepest spot is circled and labelled.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib as mpl
    from matplotlib.collections import LineCollection
    from matplotlib.tri import Triangulation

    surf = removal.surface
    frame = view_frame(getattr(surf, "part", surf))
    verts, faces, d = depth_mesh(removal, max_faces=max_faces)
    uvw = frame.project(verts)
    # Painter's order: faces nearer the viewer (+w) drawn last, so overlapping sheets look right.
    faces = faces[np.argsort(uvw[faces, 2].mean(axis=1), kind="stable")]
    d_um = d * 1e6

    fig = _new_figure(9.0, 6.5)
    ax = fig.add_subplot()
    cmap = mpl.colormaps[_DEPTH_CMAP].with_extremes(under="#d9d9d9", over=DEEPER_THAN_SCALE)
    scale = depth_scale(d_um)
    # The scale starts at zero; depths under 1 % of the peak are grey ("no removal"), as in the
    # HTML 3D view, and those beyond its end red.
    shown = np.where(d_um < scale.none_below, -1.0, d_um)      # -1: the colormap's grey "under"
    tpc = ax.tripcolor(Triangulation(uvw[:, 0], uvw[:, 1], faces), shown, shading="gouraud", cmap=cmap,
                       vmin=0.0, vmax=scale.top, rasterized=True)
    # Left out of the layout: it lies inside the axes anyway, and measuring it would turn every
    # triangle into a matplotlib Path (0.6 s for 40k triangles, most of a small job's report).
    tpc.set_in_layout(False)
    cb = fig.colorbar(tpc, ax=ax, shrink=0.85, pad=0.01, extend="both" if scale.clipped else "min")
    cb.set_label(scale.label())

    if toolpath is not None and len(toolpath.passes):
        n_pass = len(toolpath.passes)
        segs, order = [], []
        for i, p in enumerate(toolpath.passes):
            q = frame.project(p.points)[:, :2]
            segs.append(np.stack([q[:-1], q[1:]], axis=1))
            order.append(np.full(len(q) - 1, i + 1))
        norm = mpl.colors.Normalize(1, max(n_pass, 2))
        segments: Any = np.concatenate(segs)
        lc = LineCollection(segments, cmap=_PASS_CMAP, norm=norm, linewidths=1.1, alpha=0.9)
        lc.set_array(np.concatenate(order))
        ax.add_collection(lc)
        start = frame.project(toolpath.passes[0].points[:1])[0]
        ax.plot(start[0], start[1], "o", ms=6, mfc="white", mec="black", zorder=5)
        ax.annotate("start", (start[0], start[1]), xytext=(4, 4), textcoords="offset points", fontsize=8)
        cb2 = fig.colorbar(lc, ax=ax, shrink=0.85, pad=0.01)
        cb2.set_label("pass order (1 = first)")
        if n_pass <= 12:
            cb2.set_ticks(np.arange(1, n_pass + 1))

    _mark_hot_spot(ax, frame, metrics or {})
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_xlabel("along 1st principal axis (m)")
    ax.set_ylabel("along 2nd principal axis (m)")
    name = getattr(surf, "name", "") or "part"
    ax.set_title(f"Removal depth on {name}, seen along the surface normal axis")
    return fig


def _mark_hot_spot(ax, frame, metrics: dict) -> None:
    """Circle the hot spot's deepest removal in ``metrics`` on the map ``ax`` (view ``frame``), with
    its depth, where the job warns of it."""
    from ..simulate.hot_spots import warned_position

    spot = warned_position(metrics)
    if spot is None:
        return
    at = frame.project(spot[None, :])[0]
    ax.plot(at[0], at[1], "o", ms=14, mfc="none", mec="black", mew=1.6, zorder=6)
    ax.annotate(f"hot spot {1e6 * float(metrics['hot_spot_depth_m']):.3g} µm "
                f"({float(metrics['hot_spot_depth_ratio']):.0f}x the interior)", (at[0], at[1]),
                xytext=(9, -12), textcoords="offset points", fontsize=8, zorder=6,
                bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": "none", "alpha": 0.8})


def feed_contact_figure(trajectory):
    """Commanded feed (mm/s) and contact state against time.

    Parameters
    ----------
    trajectory : Trajectory
        Timed samples with ``t`` (s), ``feed`` (m/s) and ``contact``.

    Returns
    -------
    matplotlib.figure.Figure
    """
    t = np.asarray(trajectory.t, float)
    feed = np.asarray(trajectory.feed, float) * 1e3
    contact = np.asarray(trajectory.contact, bool)
    fig = _new_figure(9.0, 5.0)
    ax_f, ax_c = fig.subplots(2, 1, sharex=True, height_ratios=[3, 1])
    if len(t):
        ax_f.fill_between(t, 0, 1, where=contact, step="post", transform=ax_f.get_xaxis_transform(),
                          color="tab:orange", alpha=0.15, linewidth=0, label="in contact")
        ax_f.step(t, feed, where="post", color="tab:blue", lw=1.0, label="commanded feed")
        ax_c.fill_between(t, 0, contact.astype(float), step="post", color="tab:orange", alpha=0.8, linewidth=0)
        duration = t[-1] - t[0]
        in_contact = float(np.sum(np.diff(t)[contact[:-1] & contact[1:]])) if len(t) > 1 else 0.0
        share = in_contact / duration * 100 if duration > 0 else 0.0
        ax_f.set_title(f"Feed and contact over the cycle ({duration:.1f} s, {share:.0f} % of the time in contact)")
    ax_f.set_ylabel("feed (mm/s)")
    ax_f.set_ylim(bottom=0)
    ax_f.legend(loc="upper right", fontsize=8)
    ax_f.grid(alpha=0.3)
    ax_c.set_yticks([0, 1], ["air", "contact"])
    ax_c.set_ylim(-0.05, 1.05)
    ax_c.set_xlabel("time (s)")
    return fig


def depth_histogram_figure(removal, *, min_depth: float | None = None, bins: int = 50):
    """Histogram of removal depth (µm) over the covered samples, weighted by surface area.

    Parameters
    ----------
    removal : RemovalMap
        Sampled surface and removal depth per vertex, m.
    min_depth : float, optional
        Depth above which a sample counts as covered, m (see :func:`covered_mask`).
    bins : int
        Number of histogram bins.

    Returns
    -------
    matplotlib.figure.Figure
    """
    depth = _check_removal(removal)
    mask = covered_mask(removal, min_depth=min_depth)
    area = np.asarray(removal.surface.vertex_areas, float)
    fig = _new_figure(8.0, 4.8)
    ax = fig.add_subplot()
    if mask.any():
        d_um = depth[mask] * 1e6
        w = area[mask] / area.sum() * 100.0          # % of the whole surface area
        ax.hist(d_um, bins=bins, weights=w, color="tab:green", alpha=0.8, edgecolor="white", linewidth=0.4)
        mean = float(np.average(d_um, weights=area[mask]))
        std = float(np.sqrt(np.average((d_um - mean) ** 2, weights=area[mask])))
        ax.axvline(mean, color="black", lw=1.4, label=f"mean {mean:.3g} µm")
        for x in (mean - std, mean + std):
            ax.axvline(x, color="black", lw=1.0, ls="--")
        ax.plot([], [], color="black", ls="--", label=f"±1 std ({std:.3g} µm, CoV {std / mean * 100:.1f} %)")
        ax.legend(fontsize=8)
        covered = area[mask].sum() / area.sum() * 100
        ax.set_title(f"Removal depth over the covered area ({covered:.1f} % of the surface)")
    else:
        ax.text(0.5, 0.5, "no sample received any removal", ha="center", va="center", transform=ax.transAxes)
        ax.set_title("Removal depth over the covered area")
    ax.set_xlim(left=0)                              # spread is read against the full depth scale
    ax.set_xlabel("removal depth (µm)")
    ax.set_ylabel("share of surface area (%)")
    ax.grid(alpha=0.3)
    return fig


# --- output --------------------------------------------------------------------------------------
def png_bytes(fig, *, dpi: int = 110) -> bytes:
    """The figure rendered as PNG bytes."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def save_png(fig, path, *, dpi: int = 110) -> Path:
    """Write the figure as a PNG atomically; returns ``path``."""
    path = Path(path)
    data = png_bytes(fig, dpi=dpi)
    with atomic_file(path, "wb") as fh:
        fh.write(data)
    return path


def write_plots(out_dir, *, toolpath=None, trajectory=None, removal=None, dpi: int = 110,
                names=None, metrics: dict | None = None) -> dict[str, Path]:
    """Write the PNG figures whose inputs are given into ``out_dir``.

    Parameters
    ----------
    out_dir : str or Path
        Existing (or creatable) directory.
    toolpath : ToolPath, optional
        Drawn on the removal map.
    trajectory : Trajectory, optional
        Needed for ``feed_contact.png``.
    removal : RemovalMap, optional
        Needed for ``removal_map.png`` and ``depth_histogram.png``.
    dpi : int
        Resolution, dots per inch.
    names : collection of str, optional
        Draw only these figures (keys of :data:`PNG_NAMES`); default all whose inputs are given.
    metrics : dict, optional
        The job's metrics: the removal map marks their hot spot (:func:`removal_map_figure`).

    Returns
    -------
    dict of str -> Path
        Written files by figure name (keys of :data:`PNG_NAMES`).
    """
    out_dir = Path(out_dir)
    figs = {}
    if removal is not None:
        figs["removal_map"] = lambda: removal_map_figure(removal, toolpath, metrics=metrics)
        figs["depth_histogram"] = lambda: depth_histogram_figure(removal)
    if trajectory is not None and len(trajectory):
        figs["feed_contact"] = lambda: feed_contact_figure(trajectory)
    written = {}
    for name in PNG_NAMES:
        if name in figs and (names is None or name in names):
            written[name] = save_png(figs[name](), out_dir / PNG_NAMES[name], dpi=dpi)
            log.debug("wrote %s", written[name])
    return written
