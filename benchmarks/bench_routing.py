"""Air routes between passes: how many stay clear of the part, how long they are, how long routing takes.

For every built-in part and shared mesh, the job's default raster and uniform plans (``swath plan``
defaults, ``make_plan``) are routed again with :func:`swath.order.route_links` at the job's clearance
(20 mm): ``links``, ``near_part`` (routes that pass closer than half the clearance to the part: the
guard found no clear one), the air route length and the routing time.  Uniform is skipped on
crs_part_5 (its plan alone takes 20 s; raster shows the routing there).

    PYTHONPATH=src python benchmarks/bench_routing.py [part ...]
"""

from __future__ import annotations

import logging
import sys
import time

from common import parts, print_table

COLUMNS = [("part", ""), ("planner", ""), ("links", "d"), ("near_part", "d"), ("air_route_m", ".3f"),
           ("route_s", ".3f")]


def main(argv: list[str]) -> None:
    from swath.cli.job import make_plan
    from swath.cli.settings import settings_from_mapping
    from swath.order import route_links

    logging.disable(logging.WARNING)                   # the per-link warnings; counted below
    rows = []
    for name, surface in parts():
        if argv and name not in argv and name.removeprefix("example:") not in argv:
            continue
        for planner in ("raster", "uniform"):
            if planner == "uniform" and name == "crs_part_5.stl":
                continue
            settings = settings_from_mapping({"part": name, "out": "unused", "planner": planner})
            tp = make_plan(surface, settings)
            t0 = time.perf_counter()
            routed = route_links(tp, clearance=settings.clearance, pad_radius=settings.pad_radius)
            seconds = time.perf_counter() - t0
            rows.append({"part": name, "planner": planner, "links": len(routed.links),
                         "near_part": routed.metadata["air_moves_near_part_count"],
                         "air_route_m": routed.metadata["air_route_length_m"], "route_s": seconds})
            print_table(rows[-1:], COLUMNS)
            sys.stdout.flush()
    print()
    print_table(rows, COLUMNS)


if __name__ == "__main__":
    main(sys.argv[1:])
