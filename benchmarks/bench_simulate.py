"""Removal simulation speed: a ~100k-face part under a ~100 m contact path.

    python benchmarks/bench_simulate.py

Prints faces, path length, removal samples, the time of ``simulate_removal`` (s) and its peak traced
memory (MB).  The issue's target: well inside a minute on this 2-core machine.
"""

from __future__ import annotations

from common import Measure, max_rss_mb, print_table


def main():
    from swath.contact import Tool
    from swath.examples import doubly_curved_panel
    from swath.order import order_toolpath
    from swath.plan.raster import raster
    from swath.simulate import simulate_removal
    from swath.trajectory import FeedLimit, time_path

    tool = Tool()
    part = doubly_curved_panel(spacing=2.1e-3)                  # ~100k faces
    rows = []
    for spacing in (0.02, 0.0022):
        tp = order_toolpath(raster(part, tool, spacing=spacing, direction=0.0, point_spacing=1e-3))
        tr = time_path(tp, [FeedLimit(0.05)])
        with Measure() as m:
            rm = simulate_removal(tr, part, tool)
        rows.append(dict(faces=len(part.faces), path_m=tr.contact_length, poses=int(tr.contact.sum()),
                         samples=len(rm.depth), sim_s=m.seconds, peak_MB=m.peak_mb,
                         s_per_100m=100 * m.seconds / tr.contact_length,
                         coverage_pct=100 * rm.metrics["coverage_fraction"]))
        print(f"  done {tr.contact_length:.1f} m", flush=True)
    print_table(rows, [("faces", "d"), ("path_m", ".1f"), ("poses", "d"), ("samples", "d"), ("sim_s", ".1f"),
                       ("s_per_100m", ".1f"), ("peak_MB", ".0f"), ("coverage_pct", ".2f")])
    print(f"peak RSS {max_rss_mb():.0f} MB")


if __name__ == "__main__":
    main()
