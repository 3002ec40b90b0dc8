"""Raster baseline on every built-in part and shared mesh: time, memory, coverage, length, uniformity.

    python benchmarks/bench_plan.py [--quick]

Columns: faces; plan, trajectory and simulate wall time (s); peak traced memory of the simulation (MB);
coverage (% of area touched); removal CoV; contact path L (m); coverage lower bound L* (m); η = L*/L;
cycle time (s).
"""

from __future__ import annotations

import argparse

from common import Measure, max_rss_mb, parts, print_table


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="built-in parts only")
    args = ap.parse_args()

    from swath.contact import Tool
    from swath.order import order_toolpath
    from swath.plan.raster import raster
    from swath.simulate import simulate_removal
    from swath.trajectory import FeedLimit, time_path

    tool = Tool()
    rows = []
    for name, surface in parts(include_shared=not args.quick):
        with Measure() as mp:
            tp = order_toolpath(raster(surface, tool))
        with Measure() as mt:
            tr = time_path(tp, [FeedLimit(0.05)])
        with Measure() as ms:
            rm = simulate_removal(tr, surface, tool)
        m = rm.metrics
        rows.append(dict(part=name, faces=len(surface.faces), spacing_mm=1e3 * tp.metadata.get("spacing_m", float("nan")),
                         passes=len(tp.passes), plan_s=mp.seconds, traj_s=mt.seconds, sim_s=ms.seconds,
                         sim_MB=ms.peak_mb, coverage_pct=100 * m["coverage_fraction"], cov=m["removal_cov"],
                         L_m=m["contact_length_m"], Lstar_m=m["coverage_lower_bound_m"], eta=m["efficiency"],
                         cycle_s=m["cycle_time_s"]))
        print(f"  done {name}", flush=True)
    print()
    print("raster (baseline), default spacing, 3-inch pad, 20 N, 1 mm depression, 50 mm/s")
    print_table(rows, [("part", "s"), ("faces", "d"), ("spacing_mm", ".1f"), ("passes", "d"), ("plan_s", ".2f"),
                       ("traj_s", ".2f"), ("sim_s", ".2f"), ("sim_MB", ".0f"), ("coverage_pct", ".2f"),
                       ("cov", ".3f"), ("L_m", ".2f"), ("Lstar_m", ".2f"), ("eta", ".3f"), ("cycle_s", ".0f")])
    print(f"\npeak RSS {max_rss_mb():.0f} MB")


if __name__ == "__main__":
    main()
