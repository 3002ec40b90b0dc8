"""STEP parts: loading and tessellation time, each planner on a tube's exact faces, keep-outs, and
closed parts all round in setups.  Every part is built with Open CASCADE here (no download).

    python benchmarks/bench_step.py [--grid 29] [--planners raster equidistant uniform] [--skip-setups]

1. Load time: an assembly of ``grid²`` boxes (6 faces each; ``--grid 29`` gives 5,046 faces) written
   as STEP, read and tessellated at 0.1 mm chordal tolerance (first read in a fresh process pays
   Open CASCADE's own start-up; the figure is the second read, wall and CPU time: on a shared machine
   the CPU time is the steadier one).
2. The 300 mm tube with a flange, its outer cylinder selected, planned by each planner: the largest
   angle between the pass normals and the cylinder's radial direction, coverage of the selected
   face's tessellation (simulation on the selected face), and the same judged on the whole part
   (every face present: the flange holds a flat pad off the tube near it).
3. A keep-out: the tube's outer face finished with the flange top kept out: removal on the keep-out
   and coverage of the tube beyond the pad's clearance band.
4. ``--side all`` on a capped cylinder and a box with rounded edges: setups, faces per setup and the
   coverage of the whole outer surface.

Measured (2 shared vCPUs, load average 13-16 while it ran; pad 25 mm, chordal tolerance 0.3 mm for
the planning runs, 3 mm removal samples):

| figure | value |
|---|---|
| 5,046-face assembly (10,092 triangles): read + tessellate at 0.1 mm | 41.3 s wall; Open CASCADE's ReadFile + Transfer were 34 s of 49 s in a profile; swath's own tessellation loop about 9 s |
| raster / equidistant / uniform on tube_outer: largest pass-normal error | 0.0018° / 0.0019° / 0.0019° |
| coverage of the selected face's tessellation | 100 % / 99.996 % / 99.94 % |
| the same with every face present (the flange holds the pad off) | 100 % / 99.59 % / 99.51 % |
| keep-out flange_top: removal, touched area | 0 m, 0 m² |
| tube_outer covered beyond the clearance band | 99.98 % |
| capped cylinder all round | 3 setups (faces [1, 2], [1, 3], [1]), 99.86 % of the outer surface |
| rounded box all round | 4 setups (tetrahedral corner directions), 100 % of the outer surface |
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np


def _load_time(tmp: Path, grid: int) -> dict:
    from swath.examples import cad
    from swath.io.step import load_step

    path = cad.write_step(cad.plate_grid(grid), tmp / "grid.step")
    load_step(path, max_edge=None)                      # warm: Open CASCADE's first translator call
    t0, c0 = time.perf_counter(), time.process_time()
    part = load_step(path, max_edge=None)
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {"faces": len(part.faces), "triangles": len(part.surface.faces), "load_and_tessellate_s": seconds,
            "load_and_tessellate_cpu_s": cpu}


def _tube_planner(step: Path, planner: str) -> dict:
    from swath.cli.job import load_part_info, make_plan
    from swath.cli.settings import settings_from_mapping
    from swath.segment.select import area_metrics
    from swath.simulate import simulate_removal
    from swath.trajectory import time_path

    settings = settings_from_mapping({"part": str(step), "out": "unused", "faces": "tube_outer", "planner": planner,
                                      "pad_radius": 0.025, "chordal_tol": 3e-4, "direction": "0deg"})
    t0 = time.perf_counter()
    surface, info = load_part_info(settings)
    part = info["part"]
    toolpath = make_plan(surface, settings, part=part)
    plan_s = time.perf_counter() - t0
    pts = np.vstack([p.points for p in toolpath.passes])
    nrm = np.vstack([p.normals for p in toolpath.passes])
    radial = pts.copy()
    radial[:, 2] = 0
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    away = (pts[:, 2] > 0.011) & (pts[:, 2] < 0.299)
    angle = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", nrm[away], radial[away]), -1, 1)))
    trajectory = time_path(toolpath, settings.constraints(), links=settings.links())
    on_face = simulate_removal(trajectory, surface, settings.tool(), sample_spacing=3e-3)
    whole = simulate_removal(trajectory, part.surface, settings.tool(), sample_spacing=3e-3)
    judged = area_metrics(part, whole.surface.vertices, whole.surface.vertex_areas, whole.depth)
    return {"planner": planner, "passes": len(toolpath.passes), "plan_s": plan_s,
            "max_normal_error_deg": float(angle.max()),
            "coverage_selected_face": on_face.metrics["coverage_fraction"],
            "coverage_selected_face_whole_part": judged["selected_coverage_fraction"]}


def _keep_out(step: Path) -> dict:
    from swath.cli.job import load_part_info, make_plan
    from swath.cli.settings import settings_from_mapping
    from swath.segment.select import area_metrics
    from swath.simulate import simulate_removal
    from swath.trajectory import time_path

    pad = 0.02
    settings = settings_from_mapping({"part": str(step), "out": "unused", "faces": "tube_outer",
                                      "keep_out": "flange_top", "pad_radius": pad, "chordal_tol": 3e-4})
    surface, info = load_part_info(settings)
    part = info["part"]
    trajectory = time_path(make_plan(surface, settings, part=part), settings.constraints(), links=settings.links())
    removal = simulate_removal(trajectory, part.surface, settings.tool(), sample_spacing=3e-3)
    m = area_metrics(part, removal.surface.vertices, removal.surface.vertex_areas, removal.depth)
    v = removal.surface.vertices
    _, _, tri = part.surface.closest_points(v)
    beyond = (part.face_ids[tri] == 1) & (v[:, 2] > 0.01 + pad + settings.keep_out_margin + 0.003)
    a = removal.surface.vertex_areas
    return {"keep_out_max_removal_m": m["keep_out_max_removal_m"],
            "keep_out_touched_area_m2": m["keep_out_touched_area_m2"],
            "tube_coverage_beyond_clearance": float(a[beyond & (removal.depth > 0)].sum() / a[beyond].sum())}


def _all_round(step: Path, out: Path) -> dict:
    from swath.cli.job import run_job
    from swath.cli.settings import settings_from_mapping

    t0 = time.perf_counter()
    m = run_job(settings_from_mapping({"part": str(step), "out": str(out), "side": "all", "pad_radius": 0.025,
                                       "chordal_tol": 3e-4, "sample_spacing": 3e-3}))
    return {"part": step.stem, "setups": m["n_setups"], "faces_per_setup": [s["faces"] for s in m["setups"]],
            "coverage_whole_surface": m["coverage_fraction"], "cycle_time_s": m["cycle_time_s"],
            "wall_s": time.perf_counter() - t0}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grid", type=int, default=29, help="boxes per side of the load-time assembly (6 faces each)")
    ap.add_argument("--planners", nargs="+", default=["raster", "equidistant", "uniform"])
    ap.add_argument("--skip-setups", action="store_true")
    args = ap.parse_args()
    from swath.examples import cad

    results: dict = {}
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        results["load"] = _load_time(tmp, args.grid)
        print(json.dumps(results["load"]), flush=True)
        shape = cad.tube_with_flange()
        tube = cad.write_step(shape, tmp / "tube.step", names=cad.tube_face_names(shape))
        results["planners"] = []
        for planner in args.planners:
            results["planners"].append(_tube_planner(tube, planner))
            print(json.dumps(results["planners"][-1]), flush=True)
        results["keep_out"] = _keep_out(tube)
        print(json.dumps(results["keep_out"]), flush=True)
        if not args.skip_setups:
            results["all_round"] = []
            for name, shape in (("capped_cylinder", cad.capped_cylinder()), ("rounded_box", cad.rounded_box())):
                step = cad.write_step(shape, tmp / f"{name}.step")
                results["all_round"].append(_all_round(step, tmp / f"{name}_out"))
                print(json.dumps(results["all_round"][-1]), flush=True)


if __name__ == "__main__":
    main()
