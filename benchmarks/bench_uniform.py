"""Uniform coverage against the raster baseline, measured in the same run.

    python benchmarks/bench_uniform.py

1. Jaeger's setting: the built-in blade with passes along the span — raster at its full-coverage
   spacing against uniform, same direction (the thesis: 12.28 m against 3.98 m, 3.1x).
2. Direction: uniform on the blade and the panel for each candidate direction (length, predicted
   cycle time at 50 mm/s with 1 rad/s and 2 m/s² limits) and with ``direction="auto"``.

Every part with raster, uniform and equidistant side by side: ``bench_planners.py``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from bench_planners import COLUMNS, default_limits, evaluate
from common import print_table


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.parse_args()

    from swath.cli.job import cycle_time_cost
    from swath.contact import Tool
    from swath.examples import blade, doubly_curved_panel
    from swath.plan.raster import raster
    from swath.plan.uniform import uniform
    from swath.trajectory import LinkSettings

    tool = Tool()
    limits = default_limits()
    cost = cycle_time_cost(limits, LinkSettings())      # candidates ranked under the limits they are timed with
    cols = COLUMNS[:-1]
    b = blade()

    # 1. the thesis's setting
    span = np.array([0.0, 1.0, 0.0])
    rows = []
    for name, make in (("raster", lambda: raster(b, tool, direction=span)),
                       ("uniform", lambda: uniform(b, tool, direction=span))):
        t0 = time.perf_counter()
        tp = make()
        plan_s = time.perf_counter() - t0
        rows.append(dict(part="blade, along span", planner=name, plan_s=plan_s, **evaluate(tp, b, tool, limits)))
    print("1. blade, passes along the span (full coverage)")
    print_table(rows, cols)
    print(f"   raster / uniform contact length: {rows[0]['L_m'] / rows[1]['L_m']:.2f}x (thesis: 3.1x)\n", flush=True)

    # 2. direction
    for part in (b, doubly_curved_panel()):
        t0 = time.perf_counter()
        tp = uniform(part, tool, cost=cost)
        plan_s = time.perf_counter() - t0
        cand = tp.metadata["candidates"]
        print(f"2. {part.name}: uniform candidates (predicted at 50 mm/s, <= 1 rad/s, <= 2 m/s2)")
        print_table([dict(direction_deg=c["direction_deg"], length_m=c["length_m"], cycle_s=c["cost"],
                          coverage_pct=100 * c["predicted_coverage_fraction"]) for c in cand],
                    [("direction_deg", ".0f"), ("length_m", ".2f"), ("cycle_s", ".1f"), ("coverage_pct", ".2f")])
        r = evaluate(tp, part, tool, limits)
        best_fixed = min(c["cost"] for c in cand)
        print(f"   auto chose {np.degrees(tp.metadata['direction_rad']):.0f} deg: L {r['L_m']:.2f} m, coverage "
              f"{r['coverage_pct']:.2f} %, eta {r['eta']:.3f}, CoV {r['cov']:.3f}, cycle {r['cycle_s']:.1f} s "
              f"(best candidate {best_fixed:.1f} s), plan {plan_s:.0f} s\n", flush=True)


if __name__ == "__main__":
    main()
