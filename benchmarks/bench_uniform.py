"""Uniform coverage against the raster baseline, measured in the same run.

    python benchmarks/bench_uniform.py [--quick] [--skip-large]

1. Jaeger's setting: the built-in blade with passes along the span — raster at its full-coverage
   spacing against uniform, same direction (the thesis: 12.28 m against 3.98 m, 3.1x).
2. Direction: uniform on the blade and the panel for each candidate direction (length, predicted
   cycle time at 50 mm/s with 1 rad/s and 2 m/s² limits) and with ``direction="auto"``.
3. Every built-in part and shared mesh: raster (default, auto angle) against uniform (auto):
   coverage, removal CoV, contact length L, L*, η = L*/L, cycle time, plan time.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from common import parts, print_table


def evaluate(tp, surface, tool, limits):
    from swath.simulate import simulate_removal
    from swath.trajectory import time_path

    tr = time_path(tp, limits)
    m = simulate_removal(tr, surface, tool).metrics
    return dict(passes=len(tp.passes), L_m=m["contact_length_m"], coverage_pct=100 * m["coverage_fraction"],
                cov=m["removal_cov"], Lstar_m=m["coverage_lower_bound_m"], eta=m["efficiency"],
                cycle_s=m["cycle_time_s"])


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="sections 1 and 2 only")
    ap.add_argument("--skip-large", action="store_true", help="skip meshes over 2 m² (crs_part_5)")
    ap.add_argument("--only", help="comma-separated part names for section 3 (e.g. example:blade,snp_part_scan.ply)")
    ap.add_argument("--table-only", action="store_true", help="section 3 only")
    args = ap.parse_args()

    from swath.contact import Tool
    from swath.examples import blade, doubly_curved_panel
    from swath.plan.raster import raster
    from swath.plan.uniform import uniform
    from swath.trajectory import AngularSpeedLimit, CentripetalLimit, FeedLimit

    tool = Tool()
    limits = [FeedLimit(0.05), AngularSpeedLimit(1.0), CentripetalLimit(2.0)]
    cols = [("part", "s"), ("planner", "s"), ("passes", "d"), ("L_m", ".2f"), ("coverage_pct", ".2f"), ("cov", ".3f"),
            ("Lstar_m", ".2f"), ("eta", ".3f"), ("cycle_s", ".0f"), ("plan_s", ".1f")]

    b = blade()
    if args.table_only:
        return table(args, tool, limits, cols)

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
        tp = uniform(part, tool)
        plan_s = time.perf_counter() - t0
        cand = tp.metadata["candidates"]
        print(f"2. {part.name}: uniform candidates (predicted at 50 mm/s, <= 1 rad/s, <= 2 m/s2)")
        print_table([dict(direction_deg=c["direction_deg"], length_m=c["length_m"], cycle_s=c["cycle_time_s"],
                          coverage_pct=100 * c["predicted_coverage_fraction"]) for c in cand],
                    [("direction_deg", ".0f"), ("length_m", ".2f"), ("cycle_s", ".1f"), ("coverage_pct", ".2f")])
        r = evaluate(tp, part, tool, limits)
        best_fixed = min(c["cycle_time_s"] for c in cand)
        print(f"   auto chose {np.degrees(tp.metadata['direction_rad']):.0f} deg: L {r['L_m']:.2f} m, coverage "
              f"{r['coverage_pct']:.2f} %, eta {r['eta']:.3f}, CoV {r['cov']:.3f}, cycle {r['cycle_s']:.1f} s "
              f"(best candidate {best_fixed:.1f} s), plan {plan_s:.0f} s\n", flush=True)
    if args.quick:
        return

    table(args, tool, limits, cols)


def table(args, tool, limits, cols):
    """3. every part: raster against uniform, rows printed as they finish."""
    from swath.plan.raster import raster
    from swath.plan.uniform import uniform

    only = set(args.only.split(",")) if args.only else None
    print("3. raster (baseline) against uniform (auto direction), 3-inch pad, 20 N, 1 mm depression")
    rows = []
    for name, surface in parts():
        if (args.skip_large and surface.area > 2.0) or (only and name not in only):
            continue
        for planner, make in (("raster", lambda: raster(surface, tool)), ("uniform", lambda: uniform(surface, tool))):
            t0 = time.perf_counter()
            tp = make()
            plan_s = time.perf_counter() - t0
            rows.append(dict(part=name, planner=planner, plan_s=plan_s, **evaluate(tp, surface, tool, limits)))
            print_table(rows[-1:], cols)
            print(flush=True)
    print_table(rows, cols)


if __name__ == "__main__":
    main()
