"""The ``swath fit`` and ``swath register`` jobs: scans in, smooth patches and transforms out.

* :func:`run_fit` — fit a B-spline patch to a scan (point cloud or mesh) and write
  ``patch.json`` (reloadable with :func:`swath.io.patch.load_patch_json`; it also carries the patch's
  :class:`Footprint`, the scanned part of its domain), ``surface.ply`` (the patch triangulated
  and trimmed to the footprint, per-vertex normals), ``fit.json`` (the figures, units in the key
  names) and ``fit.html`` / ``fit.png`` (residual map and histogram), atomically.
* :func:`run_register` — register a CAD mesh onto a scan and write ``transform.json`` (the 4x4
  ``cad2scan`` matrix and its quality) and ``residuals.csv`` (per-point residuals), atomically.
* :func:`load_scan`, :func:`fit_scan` and :func:`patch_surface` are the pieces that
  ``swath plan --fit`` and ``swath plan patch.json`` use (see :func:`swath.cli.job.load_part`).

A scan file is a point cloud (``.xyz .txt .csv .pts .pcd``, or a ``.ply`` without faces) or a
mesh (``.stl .obj``, or a ``.ply`` with faces).  A mesh's triangles make the LSCM
parameterisation available for patches that wrap.  With ``parameterization="rows"`` the scan
rows are read off the point order (:func:`infer_scan_rows`).
"""

from __future__ import annotations

import datetime as _dt
import html as _html
import json
import logging
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.patch_files import save_patch
from ..io.scan import Scan, infer_scan_rows, load_scan
from ..surface.footprint import default_surface_spacing, patch_surface, scan_footprint, signed_residuals

log = logging.getLogger(__name__)

#: Points drawn at most in the residual map.
MAX_MAP_POINTS = 60_000
#: Format version of fit.json and transform.json.
FORMAT_VERSION = 1


def dumps(doc: dict) -> str:
    """JSON text of ``doc``, indented, with every list of plain numbers on one line (a matrix
    row, a knot vector)."""
    text = json.dumps(doc, indent=2, allow_nan=False)
    number_list = re.compile(r"\[\s+([-+0-9.eE]+(?:,\s+[-+0-9.eE]+)*)\s+\]")
    return number_list.sub(lambda m: "[" + ", ".join(x.strip() for x in m.group(1).split(",")) + "]", text) + "\n"


def fit_scan(scan: Scan, *, parameterization: str = "auto", side=None, tolerance=None, progress=None):
    """Fit a B-spline patch to a scan (:func:`swath.scan.fit.fit_patch`).

    Parameters
    ----------
    scan : Scan
        Points (m) with optional normals, and triangles for a mesh.
    parameterization : {"auto", "projection", "lscm", "rows"}
        As for ``fit_patch``; ``"rows"`` reads the rows off the point order
        (:func:`infer_scan_rows`) and needs a point cloud; ``"lscm"`` needs a mesh.
    side : str or (3,) float, optional
        The direction the tool comes from: the patch normal is turned to face it.  Default: the
        side the scan's normals (or a mesh's winding) give, else the convex side.
    tolerance : float, optional
        Fit tolerance, m (see ``fit_patch``; default its default).
    progress : callable, optional
        ``progress(stage, done, total)`` at every stage of the fit (see ``fit_patch``).

    Returns
    -------
    patch : BSplinePatch
    report : FitReport

    Raises
    ------
    InputError, InfeasibleError
        As ``fit_patch`` (too few points, not one patch, a parameterisation that folds over).
    """
    from ..scan.fit import PARAMETERIZATIONS, fit_patch

    if parameterization not in PARAMETERIZATIONS:
        raise InputError(f"unknown parameterization {parameterization!r}; choose one of "
                         f"{', '.join(PARAMETERIZATIONS)}")
    rows = None
    if parameterization == "rows":
        if scan.faces is not None:
            raise InputError("parameterization 'rows' reads the scan rows off the order of a point cloud's "
                             "points; a mesh has no scan rows: use auto, projection or lscm")
        rows = infer_scan_rows(scan.points)
        log.info("%s: %d scan rows read off the point order", scan.name, int(rows.max()) + 1)
    if parameterization == "lscm" and scan.faces is None:
        raise InputError("parameterization 'lscm' needs a mesh (triangles); this scan is a point cloud: "
                         "use auto, projection or rows")
    patch, report = fit_patch(scan.points, normals=scan.normals, mesh_faces=scan.faces, rows=rows,
                              parameterization=parameterization, progress=progress,
                              **({} if tolerance is None else {"tolerance": tolerance}))
    if side is not None:
        from ..io.mesh import parse_side

        s = parse_side(side)
        (u0, u1), (v0, v1) = patch.domain
        g = np.linspace(0.05, 0.95, 7)
        U, V = np.meshgrid(u0 + (u1 - u0) * g, v0 + (v1 - v0) * g, indexing="ij")
        if float(np.mean(patch.normals(U.ravel(), V.ravel()) @ s)) < 0:
            patch = patch.flipped()
    return patch, report


# --------------------------------------------------------------------------------------------
# swath fit
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class FitSettings:
    """Settings of ``swath fit`` (SI units).

    Attributes
    ----------
    scan, out : str
        Scan file and output directory.
    units : str
        Length unit of the scan file.
    parameterization : str
        ``auto``, ``projection``, ``lscm`` (mesh scans) or ``rows`` (clouds in scan order).
    spacing : float or None
        Triangulation spacing of ``surface.ply``, m (default :func:`default_surface_spacing`).
    side : str or None
        Direction the tool comes from (orients the patch normal).
    force_units : bool
        Accept a scan size outside 5 mm .. 20 m.
    tolerance : float or None
        Fit tolerance, m: points farther from the patch make a warning (default
        :data:`swath.scan.fit.FIT_TOLERANCE`, 1 mm).
    """

    scan: str
    out: str
    units: str = "m"
    parameterization: str = "auto"
    spacing: float | None = None
    side: str | None = None
    force_units: bool = False
    tolerance: float | None = None
    overwrite: bool = False


def run_fit(settings: FitSettings, *, progress=None) -> dict:
    """Fit a patch to a scan and write ``patch.json``, ``surface.ply``, ``fit.json``, ``fit.png``
    and ``fit.html`` into ``settings.out`` atomically.

    Parameters
    ----------
    settings : FitSettings
    progress : callable, optional
        ``progress(stage, done, total)``.

    Returns
    -------
    dict
        The document written as ``fit.json``.
    """
    from ..io.atomic import atomic_directory, check_output_dir, write_text_atomic
    from ..io.mesh import save_surface_ply

    check_output_dir(settings.out, overwrite=settings.overwrite)          # before the fitting, not after

    say = progress or (lambda stage, done, total: None)
    say("loading scan", 0, 1)
    scan = load_scan(settings.scan, units=settings.units, side=settings.side, force_units=settings.force_units)
    say(f"fitting a B-spline patch to {len(scan.points)} {'vertices' if scan.faces is not None else 'points'}"
        f" ({settings.parameterization} parameterisation)", 0, 1)
    patch, report = fit_scan(scan, parameterization=settings.parameterization, side=settings.side,
                             tolerance=settings.tolerance, progress=say)
    say("measuring residuals", 0, 1)
    r, u, v = signed_residuals(patch, scan.points)
    say("finding the scanned area (footprint)", 0, 1)
    footprint = scan_footprint(patch, scan.points, u, v, faces=scan.faces, rms=report.rms)
    spacing = settings.spacing if settings.spacing is not None else default_surface_spacing(patch, footprint)
    how = "given" if settings.spacing is not None else "default: extent / 150 in 2..5 mm"
    say(f"triangulating the patch at {spacing * 1e3:.3g} mm ({how}), trimmed to the scanned area", 0, 1)
    surface, spacing = patch_surface(patch, spacing=spacing, name=scan.name, footprint=footprint)
    doc = fit_document(settings, scan, patch, report, r, surface, spacing)
    doc["surface"]["footprint_fraction"] = footprint.fraction
    say("writing fit report", 0, 1)
    png = residual_figure_png(r, u, v, title=f"Fit of {scan.name}: residuals (point − patch, along the normal)")
    with atomic_directory(settings.out, overwrite=settings.overwrite) as tmp:
        save_patch(patch, tmp / "patch.json", footprint)
        save_surface_ply(surface, tmp / "surface.ply")
        write_text_atomic(tmp / "fit.json", dumps(doc))
        with open(tmp / "fit.png", "wb") as fh:
            fh.write(png)
        write_text_atomic(tmp / "fit.html", fit_html(doc, png))
    say("done", 1, 1)
    return doc


def fit_document(settings: FitSettings, scan: Scan, patch, report, residuals, surface, spacing) -> dict:
    """The content of ``fit.json`` (lengths in m, times in s; units in the key names)."""
    from .. import __version__
    from ..report.metrics import to_jsonable
    from ..report.warncodes import tagged

    a = np.abs(residuals)
    fit = report.to_dict()
    figures = {
        "rms_m": report.rms, "max_error_m": report.max_error,
        "residual_rms_all_points_m": float(np.sqrt(np.mean(residuals ** 2))),
        "residual_mean_m": float(residuals.mean()),
        "residual_p50_m": float(np.percentile(a, 50)), "residual_p95_m": float(np.percentile(a, 95)),
        "residual_max_m": float(a.max()),
        "n_points": report.n_points, "n_dropped": report.n_dropped,
        "n_ctrl_u": report.n_ctrl[0], "n_ctrl_v": report.n_ctrl[1],
        "n_degree_u": report.degree[0], "n_degree_v": report.degree[1],
        "smoothing_u_m": report.smoothing[0], "smoothing_v_m": report.smoothing[1],
        "fit_time_s": report.time, "fit_tolerance_m": report.tolerance,
    }
    return to_jsonable({
        "format_version": FORMAT_VERSION,
        "warnings": [tagged(w) for w in report.warnings],          # "... [W-FIT-RESIDUAL]"
        "swath_version": __version__,
        "created_utc": _dt.datetime.now(_dt.UTC).replace(microsecond=0).isoformat(),
        "input": {"scan": str(settings.scan), "units": settings.units, "kind": scan.kind,
                  "n_points": len(scan.points), "has_normals": scan.normals is not None},
        "parameterization": report.parameterization,
        "figures": figures,
        "fit": fit,
        "surface": {"file": "surface.ply", "spacing_m": spacing, "trimmed_to_scan": True, "n_vertices": len(surface.vertices),
                    "n_faces": len(surface.faces), "area_m2": float(surface.area),
                    "extent_m": np.ptp(surface.vertices, axis=0)},
        "files": {"patch": "patch.json", "surface": "surface.ply", "report": "fit.html", "figure": "fit.png"},
        "notes": {"residuals": "signed distance of each scan point to the patch along the patch normal, m; "
                               "residual_* figures cover every point loaded, rms_m and max_error_m only the "
                               "points fitted (stray specks dropped)"},
    })


def residual_figure_png(residuals, u, v, *, title: str = "") -> bytes:
    """PNG bytes: the signed residual (mm) over the patch parameters (≈ m of arc length), and
    its histogram."""
    import matplotlib as mpl
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from ..report.plots import png_bytes

    r_mm = np.asarray(residuals, float) * 1e3
    fig = Figure(figsize=(12.0, 4.8), layout="constrained")
    FigureCanvasAgg(fig)
    ax_map, ax_hist = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.4, 1.0]})
    lim = float(np.percentile(np.abs(r_mm), 99)) or 1e-3
    idx = np.arange(len(r_mm))
    if len(idx) > MAX_MAP_POINTS:
        idx = np.random.default_rng(0).choice(len(idx), MAX_MAP_POINTS, replace=False)
    sc = ax_map.scatter(u[idx], v[idx], c=r_mm[idx], s=2.0, cmap="coolwarm",
                        norm=mpl.colors.Normalize(-lim, lim), linewidths=0)
    ax_map.set_aspect("equal", adjustable="box")
    ax_map.set_xlabel("patch parameter u (≈ m along the surface)")
    ax_map.set_ylabel("patch parameter v (≈ m)")
    ax_map.set_title("residual map")
    fig.colorbar(sc, ax=ax_map, label="residual (mm), clipped at the 99th percentile of |r|", extend="both")
    rms = float(np.sqrt(np.mean(r_mm ** 2)))
    p95 = float(np.percentile(np.abs(r_mm), 95))
    ax_hist.hist(np.clip(r_mm, -3 * lim, 3 * lim), bins=60, color="tab:blue", alpha=0.85)
    ax_hist.axvline(0.0, color="black", lw=0.8)
    for x in (-p95, p95):
        ax_hist.axvline(x, color="tab:red", ls="--", lw=1.0)
    ax_hist.plot([], [], color="tab:red", ls="--", label=f"|r| 95th percentile {p95:.3g} mm")
    ax_hist.plot([], [], " ", label=f"RMS {rms:.3g} mm over {len(r_mm)} points")
    ax_hist.legend(fontsize=8)
    ax_hist.set_xlabel("residual (mm)")
    ax_hist.set_ylabel("points")
    ax_hist.set_title("residual histogram")
    if title:
        fig.suptitle(title)
    return png_bytes(fig)


def fit_html(doc: dict, png: bytes) -> str:
    """A small self-contained HTML page: the fit figures and the residual PNG (embedded)."""
    import base64

    esc = _html.escape
    f = doc["figures"]
    rows = [
        ("scan", f"{doc['input']['scan']} ({doc['input']['kind']}, {doc['input']['n_points']} points, "
                 f"units {doc['input']['units']})"),
        ("parameterisation", doc["parameterization"]),
        ("points fitted / dropped as stray", f"{f['n_points']} / {f['n_dropped']}"),
        ("control net", f"{f['n_ctrl_u']} × {f['n_ctrl_v']}, degree ({f['n_degree_u']}, {f['n_degree_v']})"),
        ("smoothing length u, v", f"{f['smoothing_u_m'] * 1e3:.3g} mm, {f['smoothing_v_m'] * 1e3:.3g} mm"),
        ("RMS distance to the patch", f"{f['rms_m'] * 1e3:.4g} mm"),
        ("largest distance", f"{f['max_error_m'] * 1e3:.4g} mm"),
        ("|residual| median / 95th percentile", f"{f['residual_p50_m'] * 1e3:.4g} mm / "
                                                f"{f['residual_p95_m'] * 1e3:.4g} mm"),
        ("mean signed residual", f"{f['residual_mean_m'] * 1e3:.4g} mm"),
        ("surface.ply", f"{doc['surface']['n_vertices']} vertices, {doc['surface']['n_faces']} triangles at "
                        f"{doc['surface']['spacing_m'] * 1e3:.3g} mm, area {doc['surface']['area_m2']:.4g} m²"),
        ("fit tolerance (a warning beyond it)", f"{f['fit_tolerance_m'] * 1e3:.3g} mm"),
        ("fit time", f"{f['fit_time_s']:.2f} s"),
    ]
    table = "".join(f"<tr><td>{esc(k)}</td><td>{esc(str(v))}</td></tr>" for k, v in rows)
    uri = "data:image/png;base64," + base64.b64encode(png).decode("ascii")
    return (
        "<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
        f"<title>swath fit — {esc(str(doc['input']['scan']))}</title>"
        "<style>body{font-family:system-ui,sans-serif;margin:24px;color:#222}"
        "table{border-collapse:collapse}td{border-bottom:1px solid #eee;padding:4px 14px 4px 0}"
        "img{max-width:100%;border:1px solid #eee}</style></head><body>"
        f"<h1>swath fit — {esc(Path(str(doc['input']['scan'])).name)}</h1>"
        + ("" if not doc.get("warnings") else
           "<div style='border:1px solid #d9a400;background:#fff8e1;padding:8px 14px;margin:0 0 16px 0'>"
           "<b>Warnings</b><ul>" + "".join(f"<li>{esc(w)}</li>" for w in doc["warnings"]) + "</ul></div>")
        + f"<table>{table}</table>"
        "<p>Residual: signed distance of each scan point to the fitted patch along its normal. "
        "Figures with units in their names are in <code>fit.json</code>; the patch is "
        "<code>patch.json</code>.</p>"
        f"<img alt='residual map and histogram' src='{uri}'>"
        f"<p style='color:#777;font-size:.85em'>swath {esc(doc['swath_version'])}, {esc(doc['created_utc'])}</p>"
        "</body></html>\n"
    )


