"""``--side all``: a closed part finished all round, in setups (orientations on the table).

:func:`run_setups` reads the closed part (STEP/IGES or a closed mesh), picks the setups
(:func:`swath.segment.setups.plan_setups`), plans, times and simulates each on its own faces
(widened by a pad radius so that neighbouring setups overlap), and judges the removal of all setups
together on the whole outer surface.  It writes ``setup_1/trajectory.csv``, ``setup_1/metrics.json``,
``setup_1/report.html`` ... and a top-level ``metrics.json`` with every setup's faces, up direction and ``part2table``
transform, and the coverage of the whole surface.  The output directory appears complete or not at
all.  A rotary positioner (one program with coordinated motion) is not planned here.
"""

from __future__ import annotations

import json
import logging
import time
from pathlib import PurePath
from typing import Any

import numpy as np

from ..errors import InputError
from .settings import JobSettings

log = logging.getLogger(__name__)


def load_closed_part(settings: JobSettings):
    """The job's part as a closed :class:`~swath.io.part.Part` with outward normals."""
    from ..io.part import Part

    name = settings.part
    suffix = PurePath(name).suffix.lower()
    if suffix in (".step", ".stp", ".iges", ".igs"):
        from ..io.step import load_step

        part = load_step(name, chordal_tolerance=settings.chordal_tol, force_units=settings.force_units)
    elif name.startswith("example:"):
        raise InputError("--side all plans a closed part; the built-in examples are open surfaces: give a STEP file "
                         "or a closed mesh")
    else:
        part = Part.from_surface(_closed_mesh(name, settings), source=PurePath(name).name)
    if not part.closed:
        raise InputError(f"{PurePath(name).name} is an open surface; --side all is for closed parts (plan an open "
                         "surface without --side, or with --side +z)")
    return part


def _closed_mesh(path, settings: JobSettings):
    """A closed mesh with its triangles wound outward (positive enclosed volume)."""
    from pathlib import Path

    from ..io.checks import check_file
    from ..io.mesh import MESH_EXTENSIONS, check_extent
    from ..io.mesh_pieces import orient_faces
    from ..io.mesh_read import read_mesh_file
    from ..io.mesh_repair import degenerate_faces, face_areas, merge_vertices, remove_unreferenced
    from ..surface import Surface
    from ..units import length_unit_factor

    path = Path(path)
    ext = check_file(path, MESH_EXTENSIONS, "mesh")
    v, f, _ = read_mesh_file(path, ext)
    if len(f) == 0:
        raise InputError(f"{path.name} has no faces; --side all needs a closed mesh")
    v = np.asarray(v, float) * length_unit_factor(settings.units)
    extent = float(np.ptp(v, axis=0).max())
    check_extent(extent / length_unit_factor(settings.units), settings.units, settings.force_units, path.name)
    v, f = merge_vertices(v, f, tolerance=1e-9 * extent)
    f = f[~degenerate_faces(v, f, scale=extent)]
    v, f = remove_unreferenced(v, f)
    flip, _, _ = orient_faces(f, face_areas(v, f))
    f = np.where(flip[:, None], f[:, ::-1], f)
    volume = np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]])).sum() / 6
    if volume < 0:
        f = f[:, ::-1]
    return Surface(v, f, name=path.stem)


def part2table(part, up: np.ndarray) -> np.ndarray:
    """(4, 4) transform placing the part on the table: ``up`` (part frame) to +z, lowest point at z = 0."""
    up = np.asarray(up, float) / np.linalg.norm(up)
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(up, z)
    s, c = np.linalg.norm(axis), float(up @ z)
    if s < 1e-12:
        rotation = np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    else:
        k = axis / s
        kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        rotation = np.eye(3) + s * kx + (1 - c) * kx @ kx
    out = np.eye(4)
    out[:3, :3] = rotation
    out[2, 3] = -float((part.surface.vertices @ rotation.T)[:, 2].min())
    return out


def run_setups(settings: JobSettings, *, progress=None) -> dict:
    """Plan a closed part all round in setups; write one trajectory per setup.

    Returns
    -------
    dict
        Whole-surface figures (``coverage_fraction`` of the selected outer surface with all setups'
        removal summed, ``removal_cov``, lengths and cycle time summed over the setups) and
        ``setups``: per setup its ``up`` direction, ``part2table``, ``faces`` (ids), areas, passes and
        coverage; plus ``warnings``.
    """
    from ..io.atomic import atomic_directory, check_output_dir
    from ..report import write_report
    from ..segment.select import area_metrics, clear_triangles, select
    from ..segment.setups import plan_setups
    from ..simulate import simulate_removal
    from ..trajectory import time_path
    from . import stages
    from .job import _jsonable, make_plan

    say = progress or (lambda stage, done, total: None)
    check_output_dir(settings.out, overwrite=settings.overwrite)
    tool = stages.job_tool(settings)
    t0 = time.perf_counter()
    say("loading part", 0, 1)
    part = select(load_closed_part(settings), faces=settings.faces, keep_out=settings.keep_out,
                  keep_out_margin=settings.keep_out_margin, edge_margin=settings.edge_margin,
                  units=settings.units)
    setups = plan_setups(part, overlap=settings.pad_radius)
    clear = clear_triangles(part, settings.pad_radius)
    say(f"{len(setups)} setups expose the part", 0, 1)
    total_depth: Any = None
    samples: Any = None
    per_setup, outputs = [], []
    totals = {"n_passes": 0, "contact_length_m": 0.0, "air_length_m": 0.0, "cycle_time_s": 0.0,
              "coverage_lower_bound_m": 0.0}
    warnings: list[str] = []
    for setup in setups:
        say(f"setup {setup.index}: planning ({settings.planner}) on faces "
            f"{', '.join(str(i) for i in setup.faces)}", 0, 1)
        surface = part.surface.sub_surface(np.flatnonzero(setup.planned & clear), name=f"{part.surface.name} setup "
                                                                               f"{setup.index}")
        toolpath = make_plan(surface, settings, progress=say, part=part)
        trajectory = time_path(toolpath, settings.constraints(), links=settings.links(), lead_angle=settings.lead())
        say(f"setup {setup.index}: simulating removal on the whole part", 0, 1)
        removal = simulate_removal(trajectory, part.surface, tool, sample_spacing=settings.sample_spacing,
                                   sampling=settings.removal_sampling)
        if total_depth is None:
            samples = removal.surface
            total_depth = np.zeros(len(removal.depth))
        total_depth += removal.depth
        own = area_metrics(part.with_selection(selected=setup.assigned), samples.vertices, samples.vertex_areas,
                           removal.depth)
        m = removal.metrics
        record = {"setup": setup.index, "up": setup.up.tolist(), "part2table": part2table(part, setup.up).tolist(),
                  "faces": list(setup.faces), "assigned_area_m2": setup.area,
                  "planned_area_m2": float(part.surface.face_areas[setup.planned].sum()),
                  "n_passes": len(toolpath.passes), "contact_length_m": m["contact_length_m"],
                  "air_length_m": m["air_length_m"], "cycle_time_s": m["cycle_time_s"],
                  "assigned_coverage_fraction": own["selected_coverage_fraction"],
                  "hidden_by_part_area_m2": setup.hidden}
        for key in ("contact_length_m", "air_length_m", "cycle_time_s"):
            totals[key] += m[key]
        totals["n_passes"] += len(toolpath.passes)
        totals["coverage_lower_bound_m"] += m.get("coverage_lower_bound_m", 0.0)
        per_setup.append(record)
        outputs.append((setup.index, trajectory, record, toolpath, removal))
    judged = area_metrics(part, samples.vertices, samples.vertex_areas, total_depth)
    touched = total_depth > 0
    a = samples.vertex_areas
    mean = float((total_depth[touched] * a[touched]).sum() / a[touched].sum()) if touched.any() else float("nan")
    std = float(np.sqrt(((total_depth[touched] - mean) ** 2 * a[touched]).sum() / a[touched].sum())) \
        if touched.any() else float("nan")
    metrics = {**totals, **judged, "coverage_fraction": judged["selected_coverage_fraction"],
               "removal_cov": std / mean if mean > 0 else float("nan"),
               "efficiency": totals["coverage_lower_bound_m"] / max(totals["contact_length_m"], 1e-300),
               "n_setups": len(setups), "setups": per_setup, "load_and_plan_s": time.perf_counter() - t0,
               "part_faces": part.faces_table()}
    if judged["selected_coverage_fraction"] < 0.99:
        warnings.append(f"the setups together cover {100 * judged['selected_coverage_fraction']:.2f} % of the outer "
                        "surface (below 99 %); lower the spacing or add a setup")
    if judged["keep_out_max_removal_m"] > 0:
        warnings.append(f"the pad removes material on the keep-outs (up to {judged['keep_out_max_removal_m'] * 1e6:.3g}"
                        " um); raise --keep-out-margin")
    metrics["warnings"] = warnings
    for w in warnings:
        log.warning("%s", w)
    doc = {"metrics": metrics, "settings": settings.as_record()}
    say("writing setups", 0, 1)
    with atomic_directory(settings.out, overwrite=settings.overwrite) as tmp:
        for index, trajectory, record, toolpath, removal in outputs:
            folder = tmp / f"setup_{index}"
            folder.mkdir()
            trajectory.write_csv(folder / "trajectory.csv")
            say(f"setup {index}: writing its report", 0, 1)
            write_report(folder, surface=part.surface, toolpath=toolpath, trajectory=trajectory, removal=removal,
                         metrics={**removal.metrics, **record}, settings=_jsonable(settings.as_record()),
                         title=f"swath plan — {part.surface.name}, setup {index} of {len(outputs)}")
        (tmp / "metrics.json").write_text(json.dumps(_jsonable(doc), indent=2), encoding="utf-8")
    return metrics
