"""Equidistant (geodesic-parallel) passes against the plane-slice raster, on every part.

    python benchmarks/bench_equidistant.py [--quick] [--simulate]

Both planners at their full-coverage default spacing (3-inch pad, 20 N, 1 mm depression).
Columns per planner (r_ = raster, e_ = equidistant): spacing (mm), passes, contact length L (m),
spread = (max − min) / mean of the geodesic distance from every pass point to the next level's
passes (%; fast marching on the part refined to 3 mm, or coarser on big parts: its own noise is
about 0.5–1 %), p5_95 = the same between the 5th and 95th percentiles (%; on scans the maximum is a
pass end whose neighbour level stops short at a ragged edge or a hole), and planning time (s).  ``--quick`` runs the built-in parts only; ``--simulate``
adds coverage (%), removal CoV and cycle time (s) from ``time_path`` + ``simulate_removal`` at
50 mm/s for plans with less than 25 m of contact path (the simulator costs 2–3 s per metre).
"""

from __future__ import annotations

import argparse
import math

from common import Measure, max_rss_mb, parts, print_table


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="built-in parts only")
    ap.add_argument("--simulate", action="store_true", help="add coverage, removal CoV and cycle time")
    args = ap.parse_args()

    from swath.contact import Tool
    from swath.plan.equidistant import equidistant
    from swath.plan.raster import raster
    from swath.plan.spacing_check import pass_spacing

    tool = Tool()
    rows = []
    for name, surface in parts(include_shared=not args.quick):
        if name == "example:plate":
            continue
        surface.normals                              # cached outside the timings
        row = dict(part=name.replace("example:", ""), faces=len(surface.faces))
        measure_edge = max(3e-3, math.sqrt(2.3 * surface.area / 150_000))
        for key, planner in (("r", raster), ("e", equidistant)):
            with Measure() as m:
                tp = planner(surface, tool)
            spacing = pass_spacing(tp, max_edge=measure_edge)
            row.update({f"{key}_mm": 1e3 * tp.metadata["spacing_m"], f"{key}_passes": len(tp.passes),
                        f"{key}_L": tp.contact_length, f"{key}_spread": 100 * spacing.spread,
                        f"{key}_p5_95": 100 * spacing.robust_spread, f"{key}_s": m.seconds})
            if args.simulate:
                row.update(_simulate(tp, surface, tool, key))
        rows.append(row)
        print(f"  done {name}", flush=True)
    print()
    print("raster vs equidistant at their default spacings, 3-inch pad, 20 N, 1 mm depression")
    cols = [("part", "s"), ("faces", "d")]
    for key in ("r", "e"):
        cols += [(f"{key}_mm", ".1f"), (f"{key}_passes", "d"), (f"{key}_L", ".2f"), (f"{key}_spread", ".1f"),
                 (f"{key}_p5_95", ".2f"), (f"{key}_s", ".2f")]
        if args.simulate:
            cols += [(f"{key}_cov_pct", ".2f"), (f"{key}_cv", ".3f"), (f"{key}_cycle", ".0f")]
    print_table(rows, cols)
    print(f"\npeak RSS {max_rss_mb():.0f} MB")


def _simulate(tp, surface, tool, key) -> dict:
    if tp.contact_length > 25.0:
        return {}
    from swath.order import order_toolpath
    from swath.simulate import simulate_removal
    from swath.trajectory import FeedLimit, time_path

    tr = time_path(order_toolpath(tp), [FeedLimit(0.05)])
    m = simulate_removal(tr, surface, tool).metrics
    return {f"{key}_cov_pct": 100 * m["coverage_fraction"], f"{key}_cv": m["removal_cov"],
            f"{key}_cycle": m["cycle_time_s"]}


if __name__ == "__main__":
    main()
