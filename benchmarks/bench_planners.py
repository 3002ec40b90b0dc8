"""The three planners side by side on every part, measured in the same run.

    python benchmarks/bench_planners.py [--planners raster,uniform,equidistant] [--only a,b] [--skip-large]

Each planner at its defaults (full-coverage spacing from the contact model, direction chosen by the
planner; uniform: 10 % overlap, auto direction), 3-inch pad, 20 N, 1 mm depression.  Every plan is
timed at 50 mm/s with angular speed <= 1 rad/s and centripetal acceleration <= 2 m/s2 and its
removal simulated (Preston, FORMATS.md contact model).  Columns: passes, contact length L (m),
coverage (% of area touched), removal CoV over the covered area, the coverage lower bound L* (m),
eta = L*/L, cycle time (s, contact + air), planning time (s) and the planner's peak traced memory (MB).
Rows print as they finish; the full table at the end.
"""

from __future__ import annotations

import argparse

from common import Measure, max_rss_mb, parts, print_table

PLANNERS = ("raster", "uniform", "equidistant")

COLUMNS = [("part", "s"), ("planner", "s"), ("passes", "d"), ("L_m", ".2f"), ("coverage_pct", ".2f"), ("cov", ".3f"),
           ("Lstar_m", ".2f"), ("eta", ".3f"), ("cycle_s", ".0f"), ("plan_s", ".1f"), ("plan_MB", ".0f")]


def evaluate(tp, surface, tool, limits) -> dict:
    """Order ``tp`` (the planner's own order), time it under ``limits``, simulate its removal, and
    return the table's plan columns."""
    from swath.order import order_toolpath
    from swath.simulate import simulate_removal
    from swath.trajectory import time_path

    tr = time_path(order_toolpath(tp), limits)
    m = simulate_removal(tr, surface, tool).metrics
    return dict(passes=len(tp.passes), L_m=m["contact_length_m"], coverage_pct=100 * m["coverage_fraction"],
                cov=m["removal_cov"], Lstar_m=m["coverage_lower_bound_m"], eta=m["efficiency"],
                cycle_s=m["cycle_time_s"])


def default_limits():
    from swath.trajectory import AngularSpeedLimit, CentripetalLimit, FeedLimit

    return [FeedLimit(0.05), AngularSpeedLimit(1.0), CentripetalLimit(2.0)]


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--planners", default=",".join(PLANNERS), help="comma-separated, from " + ", ".join(PLANNERS))
    ap.add_argument("--only", help="comma-separated part names (e.g. example:blade,snp_part_scan.ply)")
    ap.add_argument("--skip-large", action="store_true", help="skip parts over 2 m² (crs_part_5)")
    args = ap.parse_args()

    from swath.cli.job import cycle_time_cost
    from swath.contact import Tool
    from swath.plan import get_planner
    from swath.trajectory import LinkSettings

    planners = args.planners.split(",")
    unknown = set(planners) - set(PLANNERS)
    if unknown:
        ap.error(f"unknown planners {sorted(unknown)}; choose from {PLANNERS}")
    only = set(args.only.split(",")) if args.only else None
    tool = Tool()
    limits = default_limits()
    # uniform ranks its candidate directions by the cycle time under the very limits they are timed with
    options = {"uniform": {"cost": cycle_time_cost(limits, LinkSettings())}}
    print("raster (baseline), uniform and equidistant at their defaults; 3-inch pad, 20 N, 1 mm depression, "
          "50 mm/s, <= 1 rad/s, <= 2 m/s2", flush=True)
    rows = []
    for name, surface in parts():
        if (args.skip_large and surface.area > 2.0) or (only and name not in only):
            continue
        surface.normals, surface.curvature             # cached outside the timings
        for planner in planners:
            with Measure() as m:
                tp = get_planner(planner)(surface, tool, **options.get(planner, {}))
            rows.append(dict(part=name, planner=planner, plan_s=m.seconds, plan_MB=m.peak_mb,
                             **evaluate(tp, surface, tool, limits)))
            print_table(rows[-1:], COLUMNS)
            print(flush=True)
    print_table(rows, COLUMNS)
    print(f"\npeak RSS {max_rss_mb():.0f} MB")


if __name__ == "__main__":
    main()
