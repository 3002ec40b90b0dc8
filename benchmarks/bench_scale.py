"""Scale: stage times and peak memory of a raster job on every shared mesh and on a 500k-face part,
and raster plan time against trimesh's own plane slicing at 18k, 80k and 500k faces.

    python benchmarks/bench_scale.py [--skip-shared] [--timeout 900]

Table 1 runs each part in its own process (so the peak RSS is that part's): raster with the
default job settings (3-inch pad, 20 N, 50 mm/s, auto angle, 1 mm point spacing), then timing,
the removal simulation (the job's sampling: a lattice at the tool's sample spacing, 3 mm for the
3-inch pad; ``bench_simulate.py`` times it at 2 mm) and the report (metrics.json, PNGs, report.html).
Columns: load / plan / trajectory / simulate / report wall times (s), the simulation per 100 m of
contact path, and the child's peak RSS (MB).

Table 2 slices the generated panel (:func:`swath.examples.large_panel`) at 18k, 80k and
500k faces, in one process: the raster plan (fixed angle 0, so no direction search; and auto)
and with the spacing given (``slice``: no contact-width analysis, so slicing, chaining and
resampling only), against ``trimesh.intersections.mesh_multiplane`` cutting the same mesh with
the same number of planes, same normal and spacing (segments only: no chaining, ordering or
resampling).  Best of 3 (``--repeats``), wall and CPU time (CPU time suffers less from a loaded
machine).
The ratio raster / trimesh is the machine-independent figure to compare with noether's published
0.23 s / 0.67 s / 4.5 s (their C++ slicer against VTK on their machine).

The shared meshes are looked for in ``SWATH_SHARED_MESHES``, ``../shared/meshes`` beside the
repository, then ``../../shared/meshes`` (a worktree).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import REPO, SHARED_MESH_UNITS, SHARED_MESHES, max_rss_mb, print_table

LARGE = "generated:panel_500k"


def shared_folder() -> Path | None:
    for folder in (os.environ.get("SWATH_SHARED_MESHES"), SHARED_MESHES, REPO.parents[1] / "shared" / "meshes"):
        if folder and Path(folder).is_dir():
            return Path(folder)
    return None


def load(name: str):
    if name == LARGE:
        from swath.examples import large_panel

        return large_panel(n_faces=500_000)
    from swath.io.mesh import load_mesh

    return load_mesh(shared_folder() / name, units=SHARED_MESH_UNITS[name])


def one_part(name: str) -> dict:
    """Run the stages on one part in this process; the figures as a dict."""
    from swath.cli.job import make_plan, settings_from_mapping
    from swath.report import write_report
    from swath.simulate import simulate_removal
    from swath.trajectory import time_path

    settings = settings_from_mapping({"part": name, "out": "unused"})
    row = {"part": name}
    t0 = time.perf_counter()
    surface = load(name)
    row["faces"] = len(surface.faces)
    row["load_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    toolpath = make_plan(surface, settings)
    row["plan_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    trajectory = time_path(toolpath, settings.constraints(), links=settings.links())
    row["trajectory_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    # as the job simulates: its removal sampling (lattice) at its sample spacing
    removal = simulate_removal(trajectory, surface, settings.tool(), sample_spacing=settings.sample_spacing,
                               sampling=settings.removal_sampling)
    row["simulate_s"] = time.perf_counter() - t0
    row["contact_m"] = trajectory.contact_length
    row["sim_s_per_100m"] = 100.0 * row["simulate_s"] / max(trajectory.contact_length, 1e-9)
    row["samples"] = int(removal.metrics.get("n_removal_samples", 0))
    row["spacing_mm"] = 1e3 * removal.metrics["removal_sample_spacing_m"]
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        write_report(Path(tmp), surface=surface, toolpath=toolpath, trajectory=trajectory, removal=removal,
                     metrics=dict(removal.metrics), settings={}, title=name)
    row["report_s"] = time.perf_counter() - t0
    row["coverage_pct"] = 100.0 * removal.metrics["coverage_fraction"]
    row["peak_rss_MB"] = max_rss_mb()
    return row


def stage_table(names: list[str], timeout: float) -> list[dict]:
    rows = []
    for name in names:
        t0 = time.perf_counter()
        try:
            done = subprocess.run([sys.executable, __file__, "--one", name], capture_output=True, text=True,
                                  timeout=timeout, check=True)
            row = json.loads(done.stdout.strip().splitlines()[-1])
        except subprocess.TimeoutExpired:
            row = {"part": name, "note": f"timed out after {timeout:.0f} s"}
        except subprocess.CalledProcessError as exc:
            row = {"part": name, "note": (exc.stderr.strip().splitlines() or ["failed"])[-1][:80]}
        row["total_s"] = time.perf_counter() - t0
        rows.append(row)
        print(f"  {name}: {row.get('note', 'done')} in {row['total_s']:.1f} s", file=sys.stderr, flush=True)
    return rows


def slicing_table(face_counts=(18_000, 80_000, 500_000), repeats: int = 3) -> list[dict]:
    import numpy as np
    import trimesh
    from trimesh.intersections import mesh_multiplane

    from swath.contact import Tool
    from swath.examples import large_panel
    from swath.plan.raster import raster

    tool = Tool()
    raster(large_panel(n_faces=2000), tool, direction=0.0)      # warm-up: imports and caches
    rows = []
    for n in face_counts:
        surface = large_panel(n_faces=n)
        mesh = trimesh.Trimesh(surface.vertices, surface.faces, process=False)
        row = {"faces": len(surface.faces)}
        spacing = None
        for label, angle in (("fixed", 0.0), ("auto", None), ("slice", 0.0)):
            wall, cpu = np.inf, np.inf
            for _ in range(repeats):
                # a fresh surface each time: the planner memoises per surface (pad-scale samples)
                surface = large_panel(n_faces=n)
                t0, c0 = time.perf_counter(), time.process_time()
                toolpath = raster(surface, tool, direction=angle, spacing=spacing if label == "slice" else None)
                wall, cpu = min(wall, time.perf_counter() - t0), min(cpu, time.process_time() - c0)
            row[f"raster_{label}_s"], row[f"raster_{label}_cpu_s"] = wall, cpu
            if label == "fixed":
                fixed, spacing = toolpath, float(toolpath.metadata["spacing_m"])
        # The same planes for trimesh: normal across the first pass, in the mean surface plane.
        first = fixed.passes[0].points
        feed = first[-1] - first[0]
        normal = np.cross(feed, surface.face_normals.mean(axis=0))
        normal /= np.linalg.norm(normal)
        along = surface.vertices @ normal
        heights = np.arange(along.min() + spacing / 2, along.max(), spacing)
        wall, cpu = np.inf, np.inf
        for _ in range(repeats):
            t0, c0 = time.perf_counter(), time.process_time()
            lines, *_ = mesh_multiplane(mesh, np.zeros(3), normal, heights)
            wall, cpu = min(wall, time.perf_counter() - t0), min(cpu, time.process_time() - c0)
        row.update(planes=len(heights), passes=len(fixed.passes), trimesh_s=wall, trimesh_cpu_s=cpu,
                   ratio_fixed=row["raster_fixed_s"] / wall, ratio_auto=row["raster_auto_s"] / wall,
                   ratio_fixed_cpu=row["raster_fixed_cpu_s"] / cpu, ratio_auto_cpu=row["raster_auto_cpu_s"] / cpu,
                   ratio_slice=row["raster_slice_s"] / wall, ratio_slice_cpu=row["raster_slice_cpu_s"] / cpu,
                   segments=int(sum(len(x) for x in lines)))
        rows.append(row)
        print(f"  sliced {len(surface.faces)} faces", file=sys.stderr, flush=True)
    return rows


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--one", help=argparse.SUPPRESS)
    parser.add_argument("--skip-shared", action="store_true", help="only the 500k-face part in table 1")
    parser.add_argument("--skip-slicing", action="store_true", help="no table 2")
    parser.add_argument("--only-slicing", action="store_true", help="only table 2")
    parser.add_argument("--repeats", type=int, default=3, help="table 2: best of this many runs")
    parser.add_argument("--timeout", type=float, default=900.0, help="per part, s")
    args = parser.parse_args()
    if args.one:
        print(json.dumps(one_part(args.one)))
        return
    print(f"load average {os.getloadavg()[0]:.2f} / {os.getloadavg()[1]:.2f} (1 / 5 min) on {os.cpu_count()} CPUs")
    folder = shared_folder()
    names = [] if args.skip_shared or folder is None else [n for n in SHARED_MESH_UNITS if (folder / n).exists()]
    if not args.only_slicing:
        rows = stage_table(names + [LARGE], args.timeout)
        print("\nraster end to end, each part in its own process (times s, peak RSS MB)")
        print_table(rows, [("part", "s"), ("faces", "d"), ("load_s", ".2f"), ("plan_s", ".2f"),
                           ("trajectory_s", ".2f"), ("simulate_s", ".2f"), ("report_s", ".2f"), ("contact_m", ".1f"),
                           ("sim_s_per_100m", ".1f"), ("spacing_mm", ".1f"), ("samples", "d"), ("coverage_pct", ".2f"),
                           ("peak_rss_MB", ".0f"), ("note", "s")])
    if not args.skip_slicing:
        rows = slicing_table(repeats=args.repeats)
        print(f"\nraster plan vs trimesh mesh_multiplane, same planes (best of {args.repeats}; wall and CPU s)")
        print_table(rows, [("faces", "d"), ("planes", "d"), ("passes", "d"), ("segments", "d"), ("trimesh_s", ".3f"),
                           ("trimesh_cpu_s", ".3f"), ("raster_fixed_s", ".3f"), ("raster_fixed_cpu_s", ".3f"),
                           ("ratio_fixed", ".1f"), ("ratio_fixed_cpu", ".1f"), ("raster_auto_s", ".3f"),
                           ("raster_auto_cpu_s", ".3f"), ("ratio_auto", ".1f"), ("ratio_auto_cpu", ".1f"),
                           ("raster_slice_s", ".3f"), ("raster_slice_cpu_s", ".3f"), ("ratio_slice", ".1f"),
                           ("ratio_slice_cpu", ".1f")])
    print(f"\nload average after {os.getloadavg()[0]:.2f} / {os.getloadavg()[1]:.2f}")


if __name__ == "__main__":
    main()
