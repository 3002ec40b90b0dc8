"""Benchmark: a 20 m, 5 M-face blade-like part planned by regions on 1 and 2 Ray workers.

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
   the 1-worker wall over the 2-worker wall.  With ``--head`` (a Ray head with 2 CPUs started
   for the purpose, on the loopback address, stopped after) or ``--address ADDR`` (a Ray already
   running), the same two runs again on that Ray, joined as ``swath big --address`` joins it: its
   start and shutdown are then not part of the call.  Every big run's ``trajectory.csv`` is
   compared: the same file in every run.
2. ``small`` — the same shape at ``--small-faces`` over ``--small-length`` (a part small enough to
   run whole): whole in this process (one region) against ``--small-regions`` regions on 1 and 2
   workers; the CoV difference is the stitching's, the wall ratio the smaller part's speed-up.
3. ``feed`` (``--feed``) — a 1.5 m blade with the feed optimised to 5 um, whole against 2 regions.

The machine's CPU count and load average before and after are printed: on a machine shared with
other work, the 2-worker figure measures that work too.

    PYTHONPATH=src nice -n 10 python benchmarks/bench_bigpart.py            # the full table
    PYTHONPATH=src python benchmarks/bench_bigpart.py --skip-small --head   # big part: local Ray and a running head
    PYTHONPATH=src python benchmarks/bench_bigpart.py --faces 200000 --small-faces 50000   # quick
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import logging
import os
import secrets
import tempfile
import time
from pathlib import Path

import numpy as np

from swath.cli.bigpart import run_big_part
from swath.cli.bigpart_head import LocalRayHead
from swath.cli.settings import JobSettings
from swath.examples.large import large_blade


def save_npz(surface, path: Path) -> None:
    np.savez(path, vertices=surface.vertices, faces=surface.faces.astype(np.int32), name=surface.name)


def run(part: Path, out: Path, *, regions, workers: int, ray: bool = True, address: str | None = None,
        **settings) -> dict:
    """run_big_part on a local Ray of ``workers`` (both counts on Ray, so both pay its start), on the
    running Ray at ``address``, or with ``ray=False`` in this process; ``call_s`` is the wall time
    of the whole call, ``load_before`` / ``load_after`` the 1-minute load average around it."""
    s = JobSettings(part=str(part), out=str(out), overwrite=True, **settings)
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    m = run_big_part(s, regions=regions, workers=workers, use_ray=ray, address=address)
    m["call_s"] = time.perf_counter() - t0
    m["load_before"], m["load_after"] = load, os.getloadavg()[0]
    return m


def row(label: str, m: dict) -> str:
    gib = [b / 2**30 for b in m["worker_peak_rss_bytes"]]
    return (f"| {label} | {m['n_part_faces']:,} | {m['n_regions']} | {m['workers']} | {m['call_s']:.1f} | "
            f"{m['regions_s']:.1f} | {m['tail_idle_s']:.1f} | "
            f"{m['regions_cpu_s']:.1f} / {m['busiest_worker_cpu_s']:.1f} | {max(gib):.2f} ({len(gib)} workers) | "
            f"{m['n_passes']} | {100 * m['coverage_fraction']:.2f} | {100 * m['interior_removal_cov']:.3f} | "
            f"{m['load_before']:.2f} / {m['load_after']:.2f} |")


def big_notes(label: str, runs: dict) -> list[str]:
    """Where the time of the big part's runs on 1 and 2 workers (``runs``) went, and the speed-up."""
    notes = []
    for w in (1, 2):
        m = runs[w]
        first = min(r["start_s"] for r in m["tasks"])
        last = max(r["end_s"] for r in m["tasks"])
        notes.append(f"big part, {label}, {w} worker(s): Ray up {m.get('ray_start_s', float('nan')):.1f} s into the "
                     f"call; beside it, load {m['load_s']:.1f} s, spacing {m.get('spacing_s', 0.0):.1f} s, split "
                     f"{m['split_s']:.1f} s, then waiting for Ray {m['ray_wait_s']:.1f} s; first task started "
                     f"{first:.1f} s into the call; the plans fetched ({m['results_s']:.2f} s) and joined "
                     f"({m.get('join_s', 0.0):.2f} s) while the last regions were simulated; after the last task "
                     f"({last:.1f} s): stitch {m['stitch_s']:.2f} s, write {m['write_s']:.2f} s, Ray's shutdown or "
                     f"disconnect "
                     f"{m['call_s'] - m['wall_s']:.2f} s; driver CPU {m['driver_cpu_s']:.1f} s, region tasks CPU "
                     f"{m['regions_cpu_s']:.1f} s (busiest worker {m['busiest_worker_cpu_s']:.1f} s)")
    one, two = runs[1], runs[2]
    serial = two["call_s"] - two["regions_s"]
    notes.append(f"big part, {label}: speed-up 2 workers over 1: {one['call_s'] / two['call_s']:.2f}x wall "
                 f"({one['call_s']:.1f} / {two['call_s']:.1f} s), {one['regions_s'] / two['regions_s']:.2f}x over the "
                 f"region tasks' span; outside the tasks' span {serial:.1f} s of the 2-worker call; task CPU over the "
                 f"busiest worker's {two['regions_cpu_s'] / two['busiest_worker_cpu_s']:.2f}x; the largest worker "
                 f"peak {max(two['worker_peak_rss_bytes']) / 2**30:.2f} GiB")
    return notes


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
    ap.add_argument("--address", default=None,
                    help="also the big part on 1 and 2 workers of the running Ray at this address")
    ap.add_argument("--head", action="store_true",
                    help="also the big part on 1 and 2 workers of a Ray head with 2 CPUs started here for it "
                         "(swath.cli.bigpart_head.LocalRayHead, stopped after)")
    args = ap.parse_args()
    if args.head and "RAY_AUTH_TOKEN" not in os.environ:
        # one token for every Ray of this process and for the head: a local Ray takes the token
        # of its first start for the life of the process
        os.environ.setdefault("RAY_AUTH_MODE", "token")
        os.environ["RAY_AUTH_TOKEN"] = secrets.token_hex(16)
    logging.basicConfig(level=logging.ERROR)
    lines = [f"CPUs {os.cpu_count()}, load average before {os.getloadavg()[0]:.2f}", "",
             "| run | faces | regions | workers | wall s | region tasks s | idle at the end s "
             "| task CPU s: all / busiest worker | peak RSS per worker GiB | passes | coverage % | interior CoV % "
             "| load avg before / after |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
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
            feed: dict = {"optimise_feed": True, "target_depth": 5e-6, "spacing": 0.06}
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
            digests: set = set()
            where: dict[str, str | None] = {"a local Ray": None}
            with contextlib.ExitStack() as stack:
                if args.head:
                    head = stack.enter_context(LocalRayHead(2))
                    where["a running head (--head)"] = head.address
                elif args.address:
                    where[f"the Ray at {args.address}"] = args.address
                for label, address in where.items():
                    runs = {}
                    for w in (1, 2):
                        runs[w] = run(big, tmp / "o", regions=args.regions, workers=w, address=address)
                        digests.add(hashlib.sha256((tmp / "o" / "trajectory.csv").read_bytes()).hexdigest())
                        add(row(f"big, {args.regions} regions, {label}", runs[w]))
                    notes.extend(big_notes(label, runs))
            notes.append(f"big part: trajectory.csv the same file in every run: {len(digests) == 1}")
    print("\n".join(["", *notes, f"load average after {os.getloadavg()[0]:.2f}"]), flush=True)


if __name__ == "__main__":
    main()
