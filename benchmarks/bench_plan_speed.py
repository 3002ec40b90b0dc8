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

Last run (commit b435a7f, 2 CPUs, load average 1.55 before, 2.82 after, from
other jobs; default workers = 2).  CPU times inflate under load, so compare ratios, and speed-ups
only between runs minutes apart (the A/B figures below).

| part | raster CPU s | x noether | ratio_cpu to trimesh | slice / trimesh | uniform/raster e2e CPU (wall) |
|---|---|---|---|---|---|
| panel_18k | 0.43 | 1.9 (0.23 s) | 96 | 4.2 | 10.8 (12.6) |
| panel_80k | 0.44 | 0.65 (0.67 s) | 30 | 4.7 | 16.2 (16.5) |
| panel_500k | 2.25 | 0.50 (4.5 s) | 17 | 5.3 | 7.0 (6.8) |
| snp_part_scan | 0.33 | | 108 | 2.7 | 6.71 (6.33) |
| noether_raw_mesh | 0.91 | | 41 | 2.8 | 11.5 (17.4) |
| bezier_dac_cad | 0.16 | | 128 | 3.4 | 4.63 (5.20) |
| bezier_dac_scan | 1.20 | | 23 | 3.0 | 8.66 (6.32) |
| noether_wavy_mesh_with_hole | 0.11 | | 107 | 3.3 | 3.38 (3.16) |
| bezier_complex_shape | 0.61 | | 195 | 1.8 | 8.26 (8.30) |
| crs_part_5 | 3.45 | | 465 | 1.8 | 6.65 (6.45) |

* ``Surface.subdivided(method="halving")`` no longer calls trimesh: :func:`swath.surface.subdivide.
  halve_long_edges` gives trimesh 5.2's ``subdivide_to_size`` mesh (vertices and faces, same order,
  same bits; pinned in tests/surface/test_halving.py) at 0.6x its time (18k panel at R/8: 50 against
  73 ms; at 2.5 mm 0.22 against 0.35 s, best of 5).  The 18k panel's raster plan, three fresh panels
  per process, three processes each: before 0.38-0.50 s CPU (first plan) and 0.34-0.35 s (third), after
  0.34-0.44 s and 0.31-0.32 s, i.e. 1.35-1.9x noether's 0.23 s (11 passes, same spacing).
* ``AirGuard._clear`` (order/routing.py) settles a route's samples by their nearest vertex first: a
  vertex nearer than the limit means not clear, a nearest vertex farther than the limit plus the
  longest edge means clear, and only the samples in between go to the closest-point search (far
  from the part that search is the slow one, ~10 us per point on bezier_dac_scan, with no per-call
  overhead to save by batching).  bezier_dac_scan uniform plan, serial cProfile: the routes 1.64 ->
  0.53 s, the whole ``make_plan`` 22.2 -> 20.8 s CPU, 87 passes both.

Not changed (no exact form found in the time): the contact model's ``local_patch`` (3.4 s of the
width model's set-up on bezier_dac_scan): its Newton loop's ``ρ⁴`` is numpy's SIMD ``pow`` on this
CPU (AVX-512), which neither ``r*r*r*r`` nor numba's or libm's ``pow`` reproduces bit for bit, and
the row sums are numpy's pairwise sums; sharing the squares and the contact mask between volume and
area gave no measurable gain.  The pad-scale curvature fit (einsum normal equations + batched
solve) likewise has no faster form with the same bits; toppra link timing lives in trajectory/.

Earlier findings (still valid): uniform, serial (workers=1, the job's cycle-time cost, toppra
imported beforehand), 9e5d4f4 -> f5104cc: snp_part_scan 5.93 -> 5.50 s CPU, noether_raw_mesh
21.59 -> 19.71 s CPU, noether_wavy 2.01 -> 1.88 s.  Where uniform's time goes (serial cProfile):
snp_part_scan 79 heat-method solves 2.9 s and the solver's set-up 0.6 s of 8.4 s wall; the
cycle-time cost 2.5 s (toppra link timing 1.6 s); noether_raw_mesh 142 solves and a 3.8 s set-up;
bezier_dac_scan 106 solves 7.2 s, the width model's contact patches (local_patch) 3.5 s, toppra
link timing 1.7 s.  The heat solver is built once per working mesh, in the parent before the
workers fork; potpourri3d holds the GIL while it factorises and solves one source set per call,
and each generation's sources are the previous generation's coverage frontier, so the solves of a
candidate cannot be batched; a different solver would change the distances and the plans.
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
