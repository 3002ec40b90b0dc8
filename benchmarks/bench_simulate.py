"""Removal simulation speed and memory: the compiled engine against the numpy (pair-list) engine.

    python benchmarks/bench_simulate.py [--parts crs_part_5.stl panel500k ...] [--spacings 0 0.002]
                                        [--engines compiled numpy] [--methods lattice long_edges halving]
                                        [--timeout 1200]

Table 1, JIT: the first call of the compiled kernels in a fresh process with an empty numba cache
(``NUMBA_CACHE_DIR`` set to a new folder: compile and write the cache), then again in a fresh
process (load from the cache); both include importing swath and numba.

Table 2, one child process per part and removal-sample layout (``method``: ``lattice``,
``simulate_removal(sampling="lattice")``, :func:`swath.simulate.samples.removal_samples`; or
``sampling="mesh"`` with the subdivision method ``long_edges``, the default of
:meth:`swath.surface.Surface.subdivided`, or ``halving``, the earlier 1-to-4 split);
``samples_s`` is the time spent making the removal samples within the call (lattice, or
subdivision and the subdivided surface's normals and areas), ``estimate`` the sample count
predicted before sampling (lattice: :func:`~swath.simulate.samples.count_removal_samples`, exact;
mesh: :func:`swath.simulate.removal.samples_for_area`, an upper estimate); so
``peak_rss_MB`` is that part's and method's; the compiled engine runs
first, so its RSS is the compiled run's and the numpy row's is the larger of the two): for each
removal-sample spacing (``0`` = the default, :func:`swath.contact.tool.sample_spacing_for`, 3 mm
for the 3-inch pad) and engine, ``simulate_removal`` wall time (s), seconds per 100 m of contact
path and CPU time of all threads (s; less sensitive to a loaded machine than the wall time),
the wall and CPU time of the integration alone (``integrate_s``, per 100 m, ``integrate_cpu_s``:
without subdividing the part, its vertex normals and the metrics), the spacing actually used (mm; larger when the part would need more than
``MAX_REMOVAL_SAMPLES``), removal samples, integration poses, the peak traced Python memory (MB;
numpy allocations, not numba's small per-thread buffers) and the largest relative difference of
any metric between the engines.  ``metrics_s`` and ``pad_scale_s`` time :func:`plan_metrics` and
:func:`swath.contact.widths.pad_scale_samples` (which ``plan_metrics`` calls) on a fresh copy of
the surface: the part of ``sim_s`` that is not the removal integration.

Parts: ``panel100k`` is :func:`swath.examples.doubly_curved_panel` at ~91k faces under a raster
of 2.2 mm spacing (~100 m of contact path); the shared meshes and ``panel500k``
(:func:`swath.examples.large_panel`, 500k faces) under the default raster (spacing from the tool);
``panel500k_long`` is the same part under a raster of 8 mm spacing (124 m of path), so its figure per
100 m is the simulation's own and not the fixed cost of a short path.

Last run (defaults: every shared mesh, panel100k, panel500k, 2 mm, compiled engine; 2 cores shared
with other jobs; ``s/100 m`` = the whole simulate_removal call over the contact path, so short paths
show mostly the fixed cost of the metrics; ``RSS before`` = the child after loading and planning;
``picture`` = the report's two depth meshes, :func:`picture_seconds`):

=============== ====== ========== ======= ========= ======= ======== ========== ======= =======
part            path   layout     spacing samples   s/100 m integr.  RSS before RSS MB  picture
                                                            s/100 m  MB                 s
=============== ====== ========== ======= ========= ======= ======== ========== ======= =======
snp_part_scan   5.6 m  lattice    2.00 mm 89,968    10.0    3.33     270        294     1.12
snp_part_scan   5.6 m  long_edges 2.00 mm 174,412   24.4    7.10     269        361     2.46
noether_raw     21.6 m lattice    2.00 mm 271,188   11.7    6.38     325        391     1.21
noether_raw     21.6 m long_edges 2.00 mm 387,970   31.1    9.08     325        508     5.84
bezier_dac_cad  4.3 m  lattice    2.00 mm 56,621    3.83    1.43     268        283     0.65
bezier_dac_cad  4.3 m  long_edges 2.00 mm 152,432   30.4    7.52     267        354     0.66
bezier_dac_scan 18.1 m lattice    2.00 mm 247,579   7.21    3.63     360        433     1.45
bezier_dac_scan 18.1 m long_edges 2.00 mm 288,883   16.8    5.77     360        510     3.23
noether_wavy    1.2 m  lattice    2.00 mm 24,761    12.3    2.79     258        265     0.99
noether_wavy    1.2 m  long_edges 2.00 mm 54,427    34.9    7.24     258        289     0.03
bezier_complex  13.9 m lattice    2.00 mm 145,650   6.41    2.04     288        322     0.89
bezier_complex  13.9 m long_edges 2.00 mm 356,718   18.2    5.23     282        470     1.83
crs_part_5      72.5 m lattice    2.00 mm 777,446   3.30    1.88     824        824     1.04
crs_part_5      72.5 m long_edges 2.34 mm 2,156,847 17.9    3.99     834        1578    9.22
panel100k       101 m  lattice    2.00 mm 162,552   2.48    2.15     328        382     1.06
panel100k       101 m  long_edges 2.00 mm 183,457   3.40    2.90     328        438     1.31
panel500k       13.6 m lattice    2.00 mm 251,126   6.54    1.54     447        566     2.60
panel500k       13.6 m long_edges 2.00 mm 630,238   14.6    2.39     448        882     3.41
=============== ====== ========== ======= ========= ======= ======== ========== ======= =======

The lattice (the job default) is faster on every part, with up to 2.8 times fewer samples; on the two
long paths 3.30 s per 100 m (crs_part_5, 2.39 s for 72.5 m; 2.17 s per 100 m on a quiet machine earlier)
and 2.48 s (panel100k, 101 m), under the issue's 5 s; the short paths' figures per 100 m are the fixed
cost of the metrics (0.1-1 s per call).  Peak RSS stays under 0.9 GB everywhere (crs_part_5: planning's 824 MB is
the peak, the lattice simulation adds nothing visible; the subdivided mesh 1.58 GB).  The lattice's exact
count (``estimate``) equals its samples; the area estimate of the mesh over-counts by 1.2-1.7x (and is
capped on crs_part_5).  The depth pictures cost 0.7-2.6 s on the lattice (subdividing the part for
display and reading the depth off the samples) against 0.03-9.2 s on the subdivided mesh.

Earlier run (before the lattice was the default), on a quiet machine (load 0.1): crs_part_5 at 2 mm
lattice 1.57 s (2.17 s per 100 m, 823 MB RSS) against long_edges at 2.34 mm 7.38 s (10.2 s per 100 m,
1541 MB); panel100k at 2 mm lattice 1.56 s (1.54 s per 100 m) against long_edges 1.78 s; panel100k at
3 mm lattice 0.29 s per 100 m, numpy engine 2.44 s, metrics within 2.4e-6 relative.

Earlier run, engines: panel100k at 2 mm, 101 m: compiled 4.9 s per 100 m in all (integration 3.7 s
wall, 1.75 s CPU), numpy 72.6 s; at 3 mm 1.9 s against 17.5 s.  Metrics agree to 1.2e-6 relative,
peak traced memory 163 MB against 1357 MB.  JIT: 5 s on an empty cache, 0.9 s from the cache.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

from common import REPO, SHARED_MESH_UNITS, SHARED_MESHES, Measure, max_rss_mb, print_table

JIT_SNIPPET = """
import time
t0 = time.perf_counter()
import numpy as np
from swath.contact import Tool, kernels
from swath.examples import flat_plate
s = flat_plate(spacing=4e-3)
g = kernels.sample_grid(s.vertices, s.normals, s.vertex_areas, cell=kernels.default_cell(Tool()))
kernels.accumulate_removal(g, np.array([[0.2, 0.15, 0.0]]), np.array([[0.0, 0.0, -1.0]]), np.ones(1), Tool())
print(time.perf_counter() - t0)
"""


def jit_table() -> list[dict]:
    rows = []
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache, PYTHONPATH=str(REPO / "src"))
        for label in ("empty cache (compile)", "warm cache (load)"):
            done = subprocess.run([sys.executable, "-c", JIT_SNIPPET], capture_output=True, text=True, env=env,
                                  check=True)
            rows.append({"first_call": label, "seconds": float(done.stdout.split()[-1])})
    return rows


def load(name: str):
    """(surface, trajectory) of a benchmark part."""
    from swath.contact import Tool
    from swath.order import order_toolpath
    from swath.plan.raster import raster
    from swath.trajectory import FeedLimit, time_path

    tool = Tool()
    if name == "panel100k":
        from swath.examples import doubly_curved_panel

        part, spacing = doubly_curved_panel(spacing=2.1e-3), 0.0022
    elif name in ("panel500k", "panel500k_long"):
        from swath.examples import large_panel

        # the default raster gives 13.6 m of path; at 8 mm spacing (a dense polishing raster) 124 m,
        # so the per-100 m figure is the integration's, not the fixed cost of one short path
        part, spacing = large_panel(n_faces=500_000), (0.008 if name == "panel500k_long" else None)
    else:
        from swath.io.mesh import load_mesh

        part, spacing = load_mesh(SHARED_MESHES / name, units=SHARED_MESH_UNITS[name]), None
    tp = order_toolpath(raster(part, tool, spacing=spacing, direction=0.0, point_spacing=1e-3))
    return part, time_path(tp, [FeedLimit(0.05)])


def warm_up() -> None:
    """Load the compiled kernels (from numba's cache) before anything is timed."""
    import numpy as np

    from swath.contact import Tool, kernels
    from swath.examples import flat_plate

    s = flat_plate(spacing=0.01)
    grid = kernels.sample_grid(s.vertices, s.normals, s.vertex_areas, cell=kernels.default_cell(Tool()))
    kernels.accumulate_removal(grid, np.array([[0.2, 0.15, 0.0]]), np.array([[0.0, 0.0, -1.0]]), np.ones(1), Tool())


def one_part(name: str, spacings: list[float], engines: list[str], method: str = "lattice") -> list[dict]:
    import swath.simulate.removal as removal
    from swath.contact import Tool
    from swath.contact.widths import pad_scale_samples
    from swath.simulate import plan_metrics, simulate_removal
    from swath.simulate.removal import _integration_poses
    from swath.simulate.samples import count_removal_samples
    from swath.surface import Surface

    timed = {}

    def timing(fn):
        def wrapped(*args, **kwargs):
            t0, c0 = time.perf_counter(), time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                timed["integrate_s"] = time.perf_counter() - t0
                timed["integrate_cpu_s"] = time.process_time() - c0
        return wrapped

    # time the integration itself (the rest of sim_s: subdividing the part, its normals, the metrics)
    removal._depth_compiled = timing(removal._depth_compiled)
    removal._depth_numpy = timing(removal._depth_numpy)
    # the removal samples (lattice, or the subdivision method of sampling="mesh"), timed
    subdivided = Surface.subdivided

    def subdivided_by(self, max_edge, *, method=method):
        return subdivided(self, max_edge, method=method)

    if method != "lattice":
        Surface.subdivided = subdivided_by
    for name_ in ("_lattice_samples", "_mesh_samples"):
        build = getattr(removal, name_)

        def timed_build(*args, _build=build, **kwargs):
            t0 = time.perf_counter()
            try:
                return _build(*args, **kwargs)
            finally:
                timed["samples_s"] = timed.get("samples_s", 0.0) + time.perf_counter() - t0

        setattr(removal, name_, timed_build)
    sampling = "lattice" if method == "lattice" else "mesh"
    tool = Tool()
    warm_up()
    part, tr = load(name)
    path = tr.contact_length
    rss_before = max_rss_mb()                 # the process after loading and planning, before any simulation
    rows = []
    for spacing in spacings:
        results = {}
        for engine in engines:
            c0 = time.process_time()
            timed["samples_s"] = 0.0
            with Measure() as m:
                rm = simulate_removal(tr, part, tool, sample_spacing=spacing or None, engine=engine,
                                      sampling=sampling)
            cpu = time.process_time() - c0
            used = rm.metrics["removal_sample_spacing_m"]
            row = dict(part=name, faces=len(part.faces), path_m=path, spacing_mm=1e3 * used, engine=engine,
                       method=method, samples_s=timed["samples_s"],
                       estimate=(count_removal_samples(part, used) if method == "lattice"
                                 else removal.samples_for_area(part.area, used)), samples=len(rm.depth), poses=len(_integration_poses(tr, used)[0]), sim_s=m.seconds,
                       s_per_100m=100.0 * m.seconds / path, cpu_s=cpu, peak_MB=m.peak_mb, peak_rss_MB=max_rss_mb(),
                       cov=rm.metrics["removal_cov"], integrate_s=timed["integrate_s"],
                       integrate_s_per_100m=100.0 * timed["integrate_s"] / path,
                       integrate_cpu_s=timed["integrate_cpu_s"], rss_before_MB=rss_before)
            results[engine] = rm
            if engine == engines[0]:
                row["picture_s"] = picture_seconds(part, rm)
                fresh = Surface(part.vertices, part.faces)
                t0 = time.perf_counter()
                pad_scale_samples(fresh, tool)
                row["pad_scale_s"] = time.perf_counter() - t0
                fresh = Surface(part.vertices, part.faces)
                t0 = time.perf_counter()
                plan_metrics(tr, fresh, tool, rm)
                row["metrics_s"] = time.perf_counter() - t0
            rows.append(row)
        if len(results) > 1:
            ref = results[engines[-1]].metrics
            worst = 0.0
            for engine in engines[:-1]:
                for key, value in ref.items():
                    other = results[engine].metrics[key]
                    if isinstance(value, float) and value != 0 and value == value:
                        worst = max(worst, abs(other - value) / abs(value))
            rows[-1]["metric_rel_diff"] = worst
    return rows


def picture_seconds(part, removal) -> float:
    """Wall time (s) of the report's two depth pictures' meshes: the PNG map's
    (:func:`swath.report.plots.depth_mesh` at ``MAX_PLOT_FACES``) and the 3D view's
    (:func:`swath.report.html.display_mesh` at ``MAX_VIEW_FACES``)."""
    from swath.report.html import MAX_VIEW_FACES, display_mesh
    from swath.report.plots import MAX_PLOT_FACES, depth_mesh

    t0 = time.perf_counter()
    depth_mesh(removal, max_faces=MAX_PLOT_FACES)
    display_mesh(part, removal, max_faces=MAX_VIEW_FACES)
    return time.perf_counter() - t0


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", nargs="*", default=[*SHARED_MESH_UNITS, "panel100k", "panel500k", "panel500k_long"])
    parser.add_argument("--spacings", nargs="*", type=float, default=[0.002])
    parser.add_argument("--engines", nargs="*", default=["compiled"], help="compiled, numpy (numpy: 10-20x slower)")
    parser.add_argument("--methods", nargs="*", default=["lattice", "long_edges"],
                        help="removal samples: lattice (sampling='lattice') or a subdivision method of "
                             "sampling='mesh' (long_edges, halving)")
    parser.add_argument("--method", default="lattice", help=argparse.SUPPRESS)
    parser.add_argument("--timeout", type=float, default=1800.0)
    parser.add_argument("--one", help=argparse.SUPPRESS)
    parser.add_argument("--skip-jit", action="store_true")
    args = parser.parse_args()
    if args.one:
        print(json.dumps(one_part(args.one, args.spacings, args.engines, args.method)))
        return
    if not args.skip_jit:
        print_table(jit_table(), [("first_call", "s"), ("seconds", ".1f")])
        print()
    rows = []
    for name in args.parts:
        if name not in ("panel100k", "panel500k", "panel500k_long") and not (SHARED_MESHES / name).exists():
            print(f"  {name}: not found in {SHARED_MESHES}", file=sys.stderr)
            continue
        for method in args.methods:
            cmd = [sys.executable, __file__, "--one", name, "--spacings", *map(str, args.spacings),
                   "--engines", *args.engines, "--method", method]
            try:
                done = subprocess.run(cmd, capture_output=True, text=True, timeout=args.timeout, check=True)
                rows += json.loads(done.stdout.strip().splitlines()[-1])
            except subprocess.TimeoutExpired:
                rows.append({"part": name, "method": method, "engine": f"timed out after {args.timeout:.0f} s"})
            except subprocess.CalledProcessError as exc:
                rows.append({"part": name, "method": method,
                             "engine": (exc.stderr.strip().splitlines() or ["failed"])[-1][:80]})
            print(f"  {name} {method} done", file=sys.stderr, flush=True)
    print_table(rows, [("part", "s"), ("faces", "d"), ("path_m", ".1f"), ("method", "s"), ("spacing_mm", ".2f"),
                       ("estimate", "d"), ("samples", "d"), ("samples_s", ".2f"),
                       ("poses", "d"), ("engine", "s"), ("sim_s", ".2f"), ("s_per_100m", ".2f"), ("cpu_s", ".2f"), ("integrate_s", ".2f"),
                       ("integrate_s_per_100m", ".2f"), ("integrate_cpu_s", ".2f"), ("peak_MB", ".0f"),
                       ("rss_before_MB", ".0f"), ("peak_rss_MB", ".0f"), ("metrics_s", ".2f"), ("pad_scale_s", ".2f"),
                       ("picture_s", ".2f"),
                       ("metric_rel_diff", ".1e")])


if __name__ == "__main__":
    main()
