"""Benchmark: a 20 m, 5 M-face blade-like part planned by regions on 1 and 2 local Ray workers.

Rows (one run each, printed as a Markdown table):

1. ``big, 1 worker`` / ``big, 2 workers`` — :func:`swath.examples.large.large_blade` at ``--faces``
   (default 5 M) and ``--length`` (20 m), saved as ``.npz``, planned by ``swath big``'s
   :func:`swath.cli.bigpart.run_big_part` in ``--regions`` regions on a local Ray with 1 and 2
   workers (both on Ray, so both pay its start, which overlaps the reading and splitting): wall
   time (the whole call: Ray's start, read, split, plan, simulate, stitch, write), the span of the
   region tasks (first start to last end) and the workers' idle time at its end, the CPU time of
   the region tasks (all of it, and the busiest worker's: their ratio is the speed-up the split
   allows, whatever else the machine runs), the peak resident memory of every worker
   (``ru_maxrss`` returned by each task) and the stitched interior removal CoV.  The speed-up is
   the 1-worker wall over the 2-worker wall.
2. ``small`` — the same shape at ``--small-faces`` over ``--small-length`` (a part small enough to
   run whole): whole in this process (one region) against ``--small-regions`` regions on 1 and 2
   workers; the CoV difference is the stitching's, the wall ratio the smaller part's speed-up.
3. ``feed`` (``--feed``) — a 1.5 m blade with the feed optimised to 5 um, whole against 2 regions.

The machine's CPU count and load average before and after are printed: on a machine shared with
other work, the 2-worker figure measures that work too.

    PYTHONPATH=src nice -n 10 python benchmarks/bench_bigpart.py            # the full table
    PYTHONPATH=src python benchmarks/bench_bigpart.py --faces 200000 --small-faces 50000   # quick
"""

from __future__ import annotations

import argparse
import logging
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from swath.cli.bigpart import run_big_part
from swath.cli.settings import JobSettings
from swath.examples.large import large_blade


def save_npz(surface, path: Path) -> None:
    np.savez(path, vertices=surface.vertices, faces=surface.faces.astype(np.int32), name=surface.name)


def run(part: Path, out: Path, *, regions, workers: int, ray: bool = True, **settings) -> dict:
    """run_big_part on a local Ray of ``workers`` (both counts on Ray, so both pay its start), or with
    ``ray=False`` in this process; ``call_s`` is the wall time of the whole call."""
    s = JobSettings(part=str(part), out=str(out), overwrite=True, **settings)
    t0 = time.perf_counter()
    m = run_big_part(s, regions=regions, workers=workers, use_ray=ray)
    m["call_s"] = time.perf_counter() - t0
    return m


def row(label: str, m: dict) -> str:
    gib = [b / 2**30 for b in m["worker_peak_rss_bytes"]]
    return (f"| {label} | {m['n_part_faces']:,} | {m['n_regions']} | {m['workers']} | {m['call_s']:.1f} | "
            f"{m['regions_s']:.1f} | {m['tail_idle_s']:.1f} | "
            f"{m['regions_cpu_s']:.1f} / {m['busiest_worker_cpu_s']:.1f} | {max(gib):.2f} ({len(gib)} workers) | "
            f"{m['n_passes']} | {100 * m['coverage_fraction']:.2f} | {100 * m['interior_removal_cov']:.2f} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--faces", type=int, default=5_000_000)
    ap.add_argument("--length", type=float, default=20.0)
    ap.add_argument("--regions", type=int, default=16)
    ap.add_argument("--small-faces", type=int, default=200_000)
    ap.add_argument("--small-length", type=float, default=5.0)
    ap.add_argument("--small-regions", type=int, default=4)
    ap.add_argument("--feed", action="store_true", help="also the feed-optimised 1.5 m blade, whole and 2 regions")
    ap.add_argument("--skip-big", action="store_true")
    ap.add_argument("--skip-small", action="store_true")
    args = ap.parse_args()
    logging.basicConfig(level=logging.ERROR)
    lines = [f"CPUs {os.cpu_count()}, load average before {os.getloadavg()[0]:.2f}", "",
             "| run | faces | regions | workers | wall s | region tasks s | idle at the end s "
             "| task CPU s: all / busiest worker | peak RSS per worker GiB | passes | coverage % | interior CoV % |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    notes: list[str] = []
    print("\n".join(lines), flush=True)

    def add(line: str) -> None:                 # each row as it is measured (the big runs take minutes)
        lines.append(line)
        print(line, flush=True)
    with tempfile.TemporaryDirectory(prefix="h-bigpart-") as tmp_name:
        tmp = Path(tmp_name)
        small = tmp / "small.npz"
        save_npz(large_blade(n_faces=args.small_faces, length=args.small_length), small)
        whole = run(small, tmp / "o", regions=1, workers=1, ray=False) if not args.skip_small else None
        split = {}
        for w in (1, 2) if whole is not None else ():
            split[w] = run(small, tmp / "o", regions=args.small_regions, workers=w)
        if whole is not None:
            add(row("small, whole in one process", whole))
            for w in (1, 2):
                add(row(f"small, {args.small_regions} regions", split[w]))
            notes.append(f"small part: stitched interior CoV {100 * split[2]['interior_removal_cov']:.3f} % against "
                         f"{100 * whole['interior_removal_cov']:.3f} % whole (difference "
                         f"{100 * abs(split[2]['interior_removal_cov'] - whole['interior_removal_cov']):.3f} points); "
                         f"speed-up 2 workers over 1: {split[1]['call_s'] / split[2]['call_s']:.2f}x")
        if args.feed:
            tiny = tmp / "tiny.npz"
            save_npz(large_blade(n_faces=6000, length=1.5, root_chord=0.35, max_chord=0.45, tip_chord=0.25,
                                 twist=0.15), tiny)
            feed = {"optimise_feed": True, "target_depth": 5e-6, "spacing": 0.06}
            fw = run(tiny, tmp / "o", regions=1, workers=1, ray=False, **feed)
            fs = run(tiny, tmp / "o", regions=2, workers=1, ray=False, **feed)
            add(row("1.5 m blade, feed optimised, whole", fw))
            add(row("1.5 m blade, feed optimised, 2 regions", fs))
            notes.append(f"feed optimised: stitched interior CoV {100 * fs['interior_removal_cov']:.2f} % against "
                         f"{100 * fw['interior_removal_cov']:.2f} % whole")
        if not args.skip_big:
            big = tmp / "big.npz"
            t0 = time.perf_counter()
            surface = large_blade(n_faces=args.faces, length=args.length)
            save_npz(surface, big)
            notes.append(f"big part: {surface.name}, {len(surface.faces):,} faces, {surface.area:.1f} m², made and "
                         f"saved in {time.perf_counter() - t0:.1f} s")
            del surface
            runs = {}
            for w in (1, 2):
                runs[w] = run(big, tmp / "o", regions=args.regions, workers=w)
                add(row(f"big, {args.regions} regions", runs[w]))
            for w in (1, 2):
                m = runs[w]
                first = min(r["start_s"] for r in m["tasks"])
                notes.append(f"big part, {w} worker(s): driver (serial part) load {m['load_s']:.1f} s, spacing "
                             f"{m.get('spacing_s', 0.0):.1f} s, split {m['split_s']:.1f} s, then waiting for Ray "
                             f"{m['ray_wait_s']:.1f} s; first task started {first:.1f} s into the call; after the last "
                             f"task: results {m['results_s']:.1f} s, stitch {m['stitch_s']:.1f} s, write "
                             f"{m['write_s']:.1f} s; driver CPU {m['driver_cpu_s']:.1f} s, region tasks CPU "
                             f"{m['regions_cpu_s']:.1f} s (busiest worker {m['busiest_worker_cpu_s']:.1f} s)")
            two = runs[2]
            notes.append("big part, the CPU-time bound of the speed-up on two free cores, (driver CPU + all task CPU) / "
                         "(driver CPU + busiest worker's task CPU): "
                         f"{(two['driver_cpu_s'] + two['regions_cpu_s']) / (two['driver_cpu_s'] + two['busiest_worker_cpu_s']):.2f}x")
            notes.append(f"big part: speed-up 2 workers over 1: {runs[1]['call_s'] / runs[2]['call_s']:.2f}x wall, "
                         f"{runs[1]['regions_s'] / runs[2]['regions_s']:.2f}x "
                         f"over the region tasks' span; task CPU over the busiest worker's "
                         f"{runs[2]['regions_cpu_s'] / runs[2]['busiest_worker_cpu_s']:.2f}x; the largest worker peak "
                         f"{max(runs[2]['worker_peak_rss_bytes']) / 2**30:.2f} GiB")
    print("\n".join(["", *notes, f"load average after {os.getloadavg()[0]:.2f}"]), flush=True)


if __name__ == "__main__":
    main()
