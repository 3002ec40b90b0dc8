"""The register job: a CAD mesh (or patch) registered onto a scan, written as transform.json and residuals.csv."""

from __future__ import annotations

import datetime as _dt
import logging
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.patch_files import load_patch
from ..io.scan import is_point_cloud_file
from ..surface.footprint import patch_surface
from .fitjob import FORMAT_VERSION, dumps

log = logging.getLogger(__name__)


# --------------------------------------------------------------------------------------------
# swath register
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RegisterSettings:
    """Settings of ``swath register`` (SI units).

    Attributes
    ----------
    cad, scan, out : str
        The nominal CAD mesh (or ``patch.json``), the scan (mesh or cloud), the output directory.
    units, scan_units : str
        Length units of the CAD file and of the scan file (default: the CAD's).
    table : bool
        The part rests on a table whose normal is ``table_normal`` in both frames: solve only the
        turn about that normal and the shift along the table (plus the height unless
        ``keep_height``), perimeter points weighted (:func:`register_on_table`).
    keep_height : bool
        With ``table``: both frames put the table at the same height (3 DOF, the thesis's case).
    table_normal : str
        Table normal, e.g. ``+z`` or ``0,0,1``; without ``table`` the direction the perimeters are
        compared along (the CAD's and the scan's outlines seen from above).
    all_pieces : bool
        Keep every piece of a multi-piece CAD mesh (the scan always keeps all of its pieces).
    side : str or None
        Direction the tool comes from, for a closed CAD solid (keeps the faces facing it).
    trim : float
        Fraction of correspondences ICP keeps each step (``1 - trim`` ≥ the outlier fraction).
    max_iterations : int
        ICP steps per stage.
    force_units : bool
        Accept sizes outside 5 mm .. 20 m.
    """

    cad: str
    scan: str
    out: str
    units: str = "m"
    scan_units: str | None = None
    table: bool = False
    keep_height: bool = False
    table_normal: str = "+z"
    all_pieces: bool = False
    side: str | None = None
    trim: float = 0.9
    max_iterations: int = 100
    force_units: bool = False
    overwrite: bool = False


def load_registration_inputs(settings: RegisterSettings):
    """``(cad Surface, scan target)``: the scan target is a Surface for a mesh and
    ``(points, normals)`` for a cloud."""
    from ..io.mesh import load_mesh

    if settings.cad.lower().endswith(".json"):
        patch, footprint = load_patch(settings.cad)
        cad, _ = patch_surface(patch, name=Path(settings.cad).stem, footprint=footprint)
    elif is_point_cloud_file(settings.cad):
        raise InputError(f"{Path(settings.cad).name} is a point cloud; the CAD must be a mesh (STL, PLY with "
                         "faces, OBJ) or a patch.json — register the cloud as the SCAN argument")
    else:
        cad = load_mesh(settings.cad, units=settings.units, side=settings.side, all_pieces=settings.all_pieces,
                        force_units=settings.force_units)
    scan_units = settings.scan_units or settings.units
    if is_point_cloud_file(settings.scan):
        from ..io.points import load_points

        pts, nrm = load_points(settings.scan, units=scan_units, force_units=settings.force_units)
        target = (pts, nrm)
    else:
        target = load_mesh(settings.scan, units=scan_units, side=settings.side, all_pieces=True,
                           force_units=settings.force_units)
    return cad, target


def run_register(settings: RegisterSettings, *, progress=None) -> dict:
    """Register the CAD onto the scan and write ``transform.json`` and ``residuals.csv``
    into ``settings.out`` atomically.

    Parameters
    ----------
    settings : RegisterSettings
    progress : callable, optional
        ``progress(stage, done, total)``.

    Returns
    -------
    dict
        The document written as ``transform.json``: ``cad2scan`` (4x4, m), ``rms_m``,
        ``inlier_fraction``, ``iterations``, ``converged``, ``method`` and the registration's
        quality figures.

    Raises
    ------
    InputError
        Unreadable files, bad settings.
    InfeasibleError
        No overlap, unconstrained geometry, or ICP that does not converge.
    """
    from ..io.atomic import atomic_directory, check_output_dir, write_text_atomic

    check_output_dir(settings.out, overwrite=settings.overwrite)
    from ..io.mesh import parse_side
    from ..scan.register import register_on_table, register_rigid

    say = progress or (lambda stage, done, total: None)
    if not (0.2 <= settings.trim <= 1.0):
        raise InputError(f"--trim must lie in 0.2..1 (the fraction of correspondences kept), got {settings.trim}")
    if settings.max_iterations < 1:
        raise InputError(f"--max-iterations must be at least 1, got {settings.max_iterations}")
    say("loading CAD and scan", 0, 1)
    t0 = time.perf_counter()
    cad, target = load_registration_inputs(settings)
    opts: dict = dict(trim=settings.trim, max_iterations=settings.max_iterations, rng=0)
    k = parse_side(settings.table_normal)
    if settings.table:
        dof = "3 DOF: turn about the table normal, shift along the table" if settings.keep_height else \
            "4 DOF: turn about the table normal, shift along the table and in height"
        method = f"table ({dof}; perimeter weighted)"
        say("registering on the table", 0, 1)
        reg = register_on_table(cad, target, table_normal=k, fit_height=not settings.keep_height, **opts)
    else:
        method = "rigid (6 DOF: global search, trimmed point-to-plane ICP, perimeter seen along the table normal)"
        say("registering (global search, then ICP)", 0, 1)
        reg = register_rigid(cad, target, perimeter_view=k, **opts)
    elapsed = time.perf_counter() - t0
    doc = transform_document(settings, reg, method, elapsed)
    say("writing transform", 0, 1)
    with atomic_directory(settings.out, overwrite=settings.overwrite) as tmp:
        write_text_atomic(tmp / "transform.json", dumps(doc))
        write_text_atomic(tmp / "residuals.csv", residuals_csv(cad.vertices, reg))
    say("done", 1, 1)
    return doc


def transform_document(settings: RegisterSettings, reg, method: str, elapsed: float) -> dict:
    """The content of ``transform.json``."""
    from .. import __version__
    from ..report.metrics import to_jsonable

    quality = reg.to_dict()
    quality.pop("matrix", None)
    return to_jsonable({
        "format_version": FORMAT_VERSION,
        "swath_version": __version__,
        "created_utc": _dt.datetime.now(_dt.UTC).replace(microsecond=0).isoformat(),
        "cad": str(settings.cad), "scan": str(settings.scan),
        "units": settings.units, "scan_units": settings.scan_units or settings.units,
        "cad2scan": np.asarray(reg.matrix),
        "frames": "cad2scan maps points of the CAD's part frame to the scan frame: p_scan = R p_cad + t (m)",
        "method": "table" if settings.table else "rigid",
        "method_description": method,
        "rms_m": reg.rms, "inlier_fraction": reg.inlier_fraction, "iterations": reg.iterations,
        "converged": reg.converged, "time_s": elapsed,
        "warnings": list(reg.warnings),
        "quality": quality,
    })


def residuals_csv(cad_points, reg) -> str:
    """``residuals.csv`` text: one row per CAD point used, its position in both frames (m), its
    signed point-to-plane residual (m; ``nan`` where the scan is too far to match) and whether it
    is an inlier (1/0)."""
    import io

    idx = np.asarray(reg.point_indices)
    p = np.asarray(cad_points, float)[idx]
    table = np.column_stack([idx, p, reg.transform(p), np.asarray(reg.residuals, float),
                             np.asarray(reg.inliers, bool)])
    buf = io.StringIO()
    np.savetxt(buf, table, delimiter=",", fmt=["%d"] + ["%.9g"] * 6 + ["%.6e", "%d"], comments="",
               header="point_index,cad_x_m,cad_y_m,cad_z_m,scan_x_m,scan_y_m,scan_z_m,residual_m,inlier")
    return buf.getvalue()
