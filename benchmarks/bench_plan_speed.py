"""Planning speed: raster plan time against trimesh's own plane slicing, and uniform against raster
end to end, on generated panels of 18k, 80k and 500k faces and on every shared mesh.

    python benchmarks/bench_plan_speed.py [--parts panel_18k,crs_part_5.stl] [--timeout 1800]
                                          [--workers N] [--skip-uniform]

Each part runs in its own process (so the peak RSS is that part's; the uniform planner's worker
processes are reported separately, as the largest child's peak RSS).  Per part, in one run:

* ``raster_s`` / ``raster_cpu_s``: the raster plan with the job's defaults (auto direction: four
  candidate directions, default spacing from the contact model, fill passes), on a freshly loaded
  surface (nothing memoised from an earlier call);
* ``trimesh_s``: ``trimesh.intersections.mesh_multiplane`` cutting the same mesh with the chosen
  plan's planes (same count, normal and spacing), timed in the same process: the reference that
  makes ``ratio = raster_s / trimesh_s`` comparable across machines.  noether publishes 0.23 s,
  0.67 s and 4.5 s for its plane slicer at 18k, 80k and 500k faces (``noether_s``);
* ``slice_s``: raster with that direction and spacing given and no fill passes (slicing, chaining
  and resampling only: the work of noether's slicer), and ``ratio_slice_cpu`` against trimesh;
* ``raster_e2e_s`` and ``uniform_e2e_s``: plan + order (``make_plan``) + timing (``time_path``) +
  removal simulation (``simulate_removal``), as ``swath plan`` runs them, each on a freshly
  loaded surface, uniform with automatic direction (six candidates, ``--workers`` processes) and
  the job's cycle-time cost; ``uniform/raster`` is their ratio.
* ``peak_MB``: the part's process peak RSS; ``workers_MB``: the largest worker's.

Wall times suffer from other load on the machine; CPU times (``*_cpu_s``: the part's process and
its finished worker processes) less, and the ``*_cpu`` ratios are the ones to compare when the
load average is above the CPU count.

Last run (2 CPUs, quiet machine: load average 0.01 before, 1.3 after; default workers = 2),
raster plan CPU at 18k/80k/500k faces 0.49/0.61/1.79 s = 2.1x/0.9x/0.4x noether's published
0.23/0.67/4.5 s (0.45 s = 1.96x on an earlier, loaded run: 18k sits at the 2x line); ratio to
trimesh's own multiplane slicing 111/47/12 (CPU), slicing alone 4.0/5.2/3.9x trimesh.
Uniform/raster end to end, CPU (wall): noether_wavy_mesh_with_hole 3.95 (2.54), bezier_dac_cad 4.85
(3.15), snp_part_scan 6.09 (4.02), crs_part_5 5.60 (3.76), bezier_complex_shape 7.53 (4.86),
noether_raw_mesh 9.83 (6.55), bezier_dac_scan 7.62 (5.33); panels 12.6/12.8/7.4 (8.3/8.6/6.8).
Uniform end to end, CPU s, the code before this change run right after on the same quiet machine
-> now: wavy 2.57 -> 1.79, bezier_dac_cad 4.66 -> 2.84, snp 8.31 -> 5.70, crs_part_5 72.7 -> 42.6,
bezier_complex_shape 18.0 -> 11.0, noether_raw_mesh 32.7 -> 19.3, bezier_dac_scan 25.2 -> 16.8,
panel_18k 32.9 -> 21.6 (its uniform/raster CPU ratios then: 5.5, 7.4, 5.5, 8.2, 11.4, 15.2, 9.3).
The uniform planner's own serial time (workers=1, the job's cycle-time cost) against the code
before this change, same quiet machine minutes apart: snp 8.0 -> 5.4 s, bezier_complex_shape
17.2 -> 10.6 s, noether_raw_mesh 37.5 -> 18.7 s CPU, with the same plans (pass count, contact
length and all six candidate costs equal to the last digit).  What is left is mostly the heat
method: on snp 2.1 s of solves and 0.7 s of factorisation of the 5.4 s; on the 18k panel 19 s of
24 s (loaded machine); the plans depend on its distances, so a cheaper distance would change them.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time

from common import SHARED_MESH_UNITS, SHARED_MESHES, max_rss_mb, print_table

PANELS = {"panel_18k": 18_000, "panel_80k": 80_000, "panel_500k": 500_000}
NOETHER_S = {"panel_18k": 0.23, "panel_80k": 0.67, "panel_500k": 4.5}


def load(name: str):
    if name in PANELS:
        from swath.examples import large_panel

        return large_panel(n_faces=PANELS[name])
    from swath.io.mesh import load_mesh

    return load_mesh(SHARED_MESHES / name, units=SHARED_MESH_UNITS[name])


def trimesh_reference(surface, toolpath) -> tuple[float, float]:
    """Wall and CPU seconds trimesh takes to cut ``surface`` with the planes of ``toolpath`` (best of 3)."""
    import numpy as np
    import trimesh
    from trimesh.intersections import mesh_multiplane

    meta = toolpath.metadata
    cross = np.asarray(meta["cross_direction"], float)
    spacing, n_planes = float(meta["spacing_m"]), int(meta["n_planes"])
    h = surface.vertices @ cross
    heights = 0.5 * (h.min() + h.max()) + (np.arange(n_planes) - 0.5 * (n_planes - 1)) * spacing
    mesh = trimesh.Trimesh(surface.vertices, surface.faces, process=False)
    best, best_cpu = np.inf, np.inf
    for _ in range(3):
        t0, c0 = time.perf_counter(), time.process_time()
        mesh_multiplane(mesh, cross * 0.0, cross, heights)
        best, best_cpu = min(best, time.perf_counter() - t0), min(best_cpu, time.process_time() - c0)
    return float(best), float(best_cpu)


def cpu_seconds() -> float:
    """CPU seconds of this process and of its finished children (the uniform planner's workers)."""
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def end_to_end(name: str, planner: str, workers: int | None) -> tuple[float, float, object]:
    """Plan + order + time + simulate as ``swath plan`` does, on a freshly loaded part: (wall s,
    CPU s of this process and its workers, the ordered tool path)."""
    from swath.cli.job import make_plan, settings_from_mapping
    from swath.simulate import simulate_removal
    from swath.trajectory import time_path

    values = {"part": name, "out": "unused", "planner": planner}
    if planner == "uniform" and workers is not None:
        values["planner_options"] = {"workers": workers}
    settings = settings_from_mapping(values)
    surface = load(name)
    t0, c0 = time.perf_counter(), cpu_seconds()
    toolpath = make_plan(surface, settings)
    trajectory = time_path(toolpath, settings.constraints(), links=settings.links())
    simulate_removal(trajectory, surface, settings.tool())
    return time.perf_counter() - t0, cpu_seconds() - c0, toolpath


def one_part(name: str, workers: int | None, skip_uniform: bool) -> dict:
    import numpy as np

    from swath.contact import Tool
    from swath.examples import flat_plate
    from swath.plan.raster import raster

    raster(flat_plate(size_x=0.1, size_y=0.1), Tool())            # warm-up: the imports are not timed
    row: dict = {"part": name}
    surface = load(name)
    row["faces"] = len(surface.faces)
    t0, c0 = time.perf_counter(), time.process_time()
    toolpath = raster(surface, Tool())
    row["raster_s"], row["raster_cpu_s"] = time.perf_counter() - t0, time.process_time() - c0
    row["passes"] = len(toolpath.passes)
    row["trimesh_s"], row["trimesh_cpu_s"] = trimesh_reference(surface, toolpath)
    row["ratio"] = row["raster_s"] / row["trimesh_s"]
    row["ratio_cpu"] = row["raster_cpu_s"] / max(row["trimesh_cpu_s"], 1e-9)
    row["noether_s"] = NOETHER_S.get(name, "")
    # The plane slicing alone (the chosen direction and spacing given, no fill passes): slicing,
    # chaining and resampling, the work noether's plane slicer does.
    fresh = load(name)
    t0, c0 = time.perf_counter(), time.process_time()
    raster(fresh, Tool(), spacing=float(toolpath.metadata["spacing_m"]), fill_gaps=False,
           direction=np.asarray(toolpath.metadata["feed_direction"]),
           cross_direction=np.asarray(toolpath.metadata["cross_direction"]))
    row["slice_s"], row["slice_cpu_s"] = time.perf_counter() - t0, time.process_time() - c0
    row["ratio_slice_cpu"] = row["slice_cpu_s"] / max(row["trimesh_cpu_s"], 1e-9)
    del surface, toolpath, fresh
    row["raster_e2e_s"], row["raster_e2e_cpu_s"], _ = end_to_end(name, "raster", None)
    if not skip_uniform:
        row["uniform_e2e_s"], row["uniform_e2e_cpu_s"], uni = end_to_end(name, "uniform", workers)
        row["uniform/raster"] = row["uniform_e2e_s"] / row["raster_e2e_s"]
        row["uniform/raster_cpu"] = row["uniform_e2e_cpu_s"] / row["raster_e2e_cpu_s"]
        row["uniform_passes"] = len(uni.passes)
    row["peak_MB"] = max_rss_mb()
    row["workers_MB"] = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", default=",".join([*PANELS, *SHARED_MESH_UNITS]))
    parser.add_argument("--timeout", type=float, default=1800.0, help="seconds per part")
    parser.add_argument("--workers", type=int, default=None, help="uniform's worker processes (default: auto)")
    parser.add_argument("--skip-uniform", action="store_true")
    parser.add_argument("--one", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        print(json.dumps(one_part(args.one, args.workers, args.skip_uniform)))
        return
    print(f"load average {os.getloadavg()[0]:.2f} (1 min) on {os.cpu_count()} CPUs")
    rows = []
    for name in args.parts.split(","):
        command = [sys.executable, __file__, "--one", name]
        if args.workers is not None:
            command += ["--workers", str(args.workers)]
        if args.skip_uniform:
            command.append("--skip-uniform")
        t0 = time.perf_counter()
        try:
            done = subprocess.run(command, capture_output=True, text=True, timeout=args.timeout, check=True)
            row = json.loads(done.stdout.strip().splitlines()[-1])
        except subprocess.TimeoutExpired:
            row = {"part": name, "note": f"timed out after {args.timeout:.0f} s"}
        except subprocess.CalledProcessError as exc:
            row = {"part": name, "note": (exc.stderr.strip().splitlines() or ["failed"])[-1][:80]}
        print(f"  {name}: {row.get('note', 'done')} in {time.perf_counter() - t0:.1f} s {json.dumps(row)}",
              file=sys.stderr, flush=True)
        rows.append(row)
    print_table(rows, [("part", ""), ("faces", "d"), ("passes", "d"), ("raster_s", ".2f"), ("raster_cpu_s", ".2f"),
                       ("trimesh_s", ".3f"), ("trimesh_cpu_s", ".3f"), ("ratio", ".1f"), ("ratio_cpu", ".1f"),
                       ("slice_s", ".3f"), ("slice_cpu_s", ".3f"), ("ratio_slice_cpu", ".1f"), ("noether_s", ".2f"), ("raster_e2e_s", ".1f"), ("raster_e2e_cpu_s", ".1f"),
                       ("uniform_e2e_s", ".1f"), ("uniform_e2e_cpu_s", ".1f"), ("uniform/raster", ".2f"),
                       ("uniform/raster_cpu", ".2f"), ("uniform_passes", "d"), ("peak_MB", ".0f"),
                       ("workers_MB", ".0f"), ("note", "")])
    print(f"load average after {os.getloadavg()[0]:.2f} (1 min)")


if __name__ == "__main__":
    main()
