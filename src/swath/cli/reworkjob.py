"""The rework job: a part measured after a run, planned again only where material is left.

``swath rework CAD SCAN --out DIR`` places the CAD on the scan (a global registration refined on
the part's nominal areas, :func:`swath.feed.rework.register_excluding_excess`), maps the material
standing proud of the CAD onto its vertices (:func:`swath.feed.rework.excess_on_cad`), plans the
faces within reach of that material with the feed optimised to remove the map (not a uniform
depth), simulates the plan on the whole part and reports the predicted residual.

Output: the plan's own ``plan/`` folder (``trajectory.csv`` in the CAD frame, ``metrics.json``,
``report.html``), ``excess.csv`` (the target map), ``rework.json`` (figures, ``cad2scan``) and
``rework.png`` (the excess before, the predicted residual after), written atomically.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from .settings import JobSettings

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ReworkSettings:
    """Settings of ``swath rework`` (SI units).

    Attributes
    ----------
    cad, scan, out : str
        The nominal part (mesh), the scan after the run (point cloud or mesh), the output folder.
    plan : JobSettings
        The plan's settings (pad, force, feed, planner, limits ...); its ``part``, ``out``,
        ``target_map`` and ``optimise_feed`` are set by the job.
    scan_units : str or None
        Unit of the scan file (default: the CAD's ``plan.units``).
    placement : {"register", "as-measured"} or a path
        How the CAD is placed on the scan: a global registration refined on the nominal areas,
        the scan taken in the CAD frame (identity), or a ``transform.json`` from ``swath register``
        (its ``cad2scan``, then refined).
    radius : float
        Averaging radius of the excess map, m.
    min_excess : float or None
        Excess (m) under which nothing is reworked; default three times the map's noise, at least
        1 µm.
    """

    cad: str
    scan: str
    out: str
    plan: JobSettings
    scan_units: str | None = None
    placement: str = "register"
    radius: float = 1e-2
    min_excess: float | None = None
    overwrite: bool = False


def load_scan_points(path: str, *, units: str, force_units: bool = False) -> np.ndarray:
    """The scan's points ``(m, 3)`` in metres: a point cloud's points or a mesh's vertices."""
    from ..io.scan import is_point_cloud_file

    if is_point_cloud_file(path):
        from ..io.points import load_points

        return load_points(path, units=units, force_units=force_units)[0]
    from ..io.mesh import load_mesh

    return np.asarray(load_mesh(path, units=units, all_pieces=True, force_units=force_units).vertices)


def _initial_placement(placement: str) -> np.ndarray | None:
    if placement in ("register", "as-measured"):
        return None if placement == "register" else np.eye(4)
    import json

    path = Path(placement)
    if not path.exists():
        raise InputError(f"--placement {placement!r}: expected 'register', 'as-measured' or a transform.json from "
                         "swath register, and no such file exists")
    try:
        matrix = np.asarray(json.loads(path.read_text())["cad2scan"], float)
    except (ValueError, KeyError, TypeError) as exc:
        raise InputError(f"{path.name}: expected a transform.json with a 'cad2scan' 4x4 matrix ({exc})") from None
    if matrix.shape != (4, 4) or not np.allclose(matrix[:3, :3] @ matrix[:3, :3].T, np.eye(3), atol=1e-6):
        raise InputError(f"{path.name}: cad2scan: expected a (4, 4) rigid transform, got shape {matrix.shape}")
    return matrix


def run_rework(settings: ReworkSettings, *, progress=None) -> dict:
    """Run the rework job; returns the figures written to ``rework.json``.

    Raises
    ------
    InputError
        Unreadable files, a scan that does not lie on the part, bad settings.
    InfeasibleError
        A registration that does not converge, a feed programme that cannot remove the map.
    """
    from ..feed import ripple_spacing
    from ..feed.rework import excess_on_cad, register_excluding_excess, removal_floor, residual_figures, rework_area
    from ..feed.targets import write_target_map
    from ..io.atomic import atomic_directory, check_output_dir, write_text_atomic
    from ..io.mesh import load_mesh, save_surface_ply
    from ..simulate import simulate_removal
    from ..trajectory import read_csv
    from .fitjob import dumps
    from .job import run_job
    from .stages import job_tool

    say = progress or (lambda stage, done, total: None)
    check_output_dir(settings.out, overwrite=settings.overwrite)
    plan = settings.plan
    initial = _initial_placement(settings.placement)
    if not (settings.radius > 0):
        raise InputError(f"--excess-radius must be > 0, got {settings.radius}")
    t0 = time.perf_counter()
    say("loading CAD and scan", 0, 1)
    cad = load_mesh(settings.cad, units=plan.units, side=plan.side, force_units=plan.force_units)
    points = load_scan_points(settings.scan, units=settings.scan_units or plan.units, force_units=plan.force_units)
    if settings.placement == "as-measured":
        cad2scan = np.eye(4)
    else:
        say("placing the CAD on the scan (registration, then refined on the nominal areas)", 0, 1)
        cad2scan = register_excluding_excess(cad, points, cad2scan=initial, radius=settings.radius)
    say("mapping the excess", 0, 1)
    excess = excess_on_cad(cad, points, scan2cad=np.linalg.inv(cad2scan), radius=settings.radius)
    tool = job_tool(plan)
    floor = removal_floor(tool, feed=plan.feed, spacing=ripple_spacing(tool, lead_angle=plan.lead())[0],
                          lead_angle=plan.lead())
    min_excess = settings.min_excess if settings.min_excess is not None else max(1e-6, 3.0 * excess.noise, floor)
    depth = np.asarray(excess.target.depth)
    faces = rework_area(cad, depth, min_excess=min_excess, grow=1.2 * plan.pad_radius)
    figures: dict = {"cad2scan": cad2scan.tolist(), "excess_map_noise_m": excess.noise,
                     "excess_radius_m": settings.radius, "min_excess_m": min_excess,
                     "removal_floor_m": floor,
                     "measured_fraction": float(excess.measured.mean()),
                     "excess_max_m": float(depth.max()), "rework_faces": int(len(faces)),
                     "rework_area_m2": float(cad.face_areas[faces].sum()) if len(faces) else 0.0,
                     "part_area_m2": float(cad.area)}
    if excess.measured.mean() < 0.5:
        log.warning("the scan measured only %.0f %% of the CAD's vertices (within %.3g mm): the rest is taken as "
                    "nominal; check the placement or scan the whole area", 100 * excess.measured.mean(),
                    settings.radius * 1e3)
    with atomic_directory(settings.out, overwrite=settings.overwrite) as tmp:
        write_target_map(tmp / "excess.csv", excess.target)
        if len(faces) == 0:
            figures["message"] = (f"no material left above {min_excess * 1e6:.3g} um: nothing to rework")
            write_text_atomic(tmp / "rework.json", dumps(figures))
            say("done", 1, 1)
            return figures
        area = cad.sub_surface(faces, name=f"{cad.name} rework area")
        part_file = tmp / "rework_area.ply"
        save_surface_ply(area, part_file)
        # Wherever the passes run they remove at least what the fastest feed removes: where the
        # excess tapers off below that (and on the nominal band the pad crosses to reach it) the
        # target is raised to it (target_floor), so the programme matches what the pad must remove
        # instead of refusing; the residual figures say how far below nominal that goes.
        tolerance = plan.depth_tolerance if plan.depth_tolerance is not None else \
            max(0.1 * float(np.percentile(depth[depth > min_excess], 95)), 0.5 * floor) + 3.0 * excess.noise
        job = dataclasses.replace(plan, part=str(part_file), units="m", side=None, all_pieces=True,
                                  out=str(tmp / "plan"),
                                  optimise_feed=True, target_map=str(tmp / "excess.csv"), target_depth=None,
                                  target_floor="fastest",
                                  depth_tolerance=tolerance, overwrite=False)
        say(f"planning the rework area ({len(faces)} faces, {figures['rework_area_m2']:.3g} m²)", 0, 1)
        metrics = run_job(job, progress=say)
        say("simulating the rework on the whole part", 0, 1)
        trajectory = read_csv(tmp / "plan" / "trajectory.csv")
        removal = simulate_removal(trajectory, cad, tool, sampling=plan.removal_sampling)
        figures.update(residual_figures(excess, removal.surface.vertices, removal.depth, min_excess=min_excess))
        figures.update({"depth_tolerance_m": tolerance, "cycle_time_s": metrics.get("cycle_time_s"),
                        "n_passes": metrics.get("n_passes"), "warnings": metrics.get("warnings", []),
                        "time_s": time.perf_counter() - t0})
        _plot(tmp / "rework.png", cad, depth, removal, excess)
        write_text_atomic(tmp / "rework.json", dumps(figures))
    say("done", 1, 1)
    return figures


def _plot(path, cad, depth, removal, excess) -> None:
    """Two maps over the part's plan view: the excess before, the predicted residual after (µm)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    left = excess.target.depth_on(removal.surface) - removal.depth
    centre, axes = cad.principal_axes          # plan view: the two axes of largest spread
    uv_cad = (cad.vertices - centre) @ np.asarray(axes)[:2].T
    uv_rem = (removal.surface.vertices - centre) @ np.asarray(axes)[:2].T
    hi = max(float(depth.max()), 1e-9) * 1e6
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.5), constrained_layout=True)
    a = ax[0].tripcolor(uv_cad[:, 0] * 1e3, uv_cad[:, 1] * 1e3, cad.faces, depth * 1e6, shading="gouraud",
                        vmin=0, vmax=hi, cmap="viridis")
    ax[0].set_title("excess before rework (µm)")
    b = ax[1].scatter(uv_rem[:, 0] * 1e3, uv_rem[:, 1] * 1e3, c=left * 1e6, s=1, cmap="coolwarm",
                      vmin=-0.25 * hi, vmax=0.25 * hi)
    ax[1].set_title("predicted residual after rework (µm; < 0: below nominal)")
    for x, m in zip(ax, (a, b)):
        x.set_aspect("equal")
        x.set_xlabel("mm")
        fig.colorbar(m, ax=x)
    fig.savefig(path, dpi=110)
    plt.close(fig)
