"""Benchmark: the plane's evenness floor, straight passes led by 0 / 7 / 11 / 15°, simulated.

For each lead and length budget (1.5 L* and 2 L*) the passes run at the least-ripple spacing of
:func:`swath.feed.ripple_spacing` for that lead and budget; a 0.5 m × 0.5 m plate is rastered and
simulated (:func:`swath.simulate.simulate_removal`, both the default integration over each pose's
stretch and the pose-only sum).  The CoV is read in the middle of the plate, 0.2 m along the passes
by a whole number of periods across (the interior with no edge effect); ``ripple`` is the
analytic figure of :func:`swath.feed.ripple_cov` at that spacing.

Run: ``PYTHONPATH=src python benchmarks/bench_plane_floor.py``
"""

from __future__ import annotations

import math
import time

import numpy as np

COLUMNS = [("lead_deg", ".0f"), ("budget", ".1f"), ("L_over_Lstar", ".3f"), ("spacing_R", ".3f"), ("ripple", ".4f"),
           ("cov_swept", ".4f"), ("cov_point", ".4f"), ("sim_s", ".2f")]


def centre_cov(removal, centre, across, d: float) -> float:
    """Area-weighted CoV of the depth within 0.1 m along the passes and two periods either side
    of ``across`` (m) across them."""
    p = removal.surface.vertices
    win = (np.abs(p[:, 0] - centre) < 0.1) & (p[:, 1] >= across - 2 * d) & (p[:, 1] < across + 2 * d)
    z, a = removal.depth[win], removal.surface.vertex_areas[win]
    mean = np.average(z, weights=a)
    return float(math.sqrt(np.average((z - mean) ** 2, weights=a)) / mean)


def main() -> list[dict]:
    from swath.contact import Tool
    from swath.examples import flat_plate
    from swath.feed import ripple_spacing
    from swath.plan import raster
    from swath.simulate.removal import simulate_removal
    from swath.trajectory import FeedLimit, time_path

    tool = Tool()
    R = tool.pad_radius
    plate = flat_plate(size_x=0.5, size_y=0.5, spacing=4e-3)
    rows = []
    for deg in (0, 7, 11, 15):
        lead = math.radians(deg)
        for budget in (1.5, 2.0):
            d, ripple = ripple_spacing(tool, lead_angle=lead, max_length_ratio=budget)
            tp = raster(plate, tool, spacing=d, direction=0.0)
            tr = time_path(tp, [FeedLimit(0.05)], lead_angle=lead)
            ys = sorted(p.points[0, 1] for p in tp.passes)
            mid = ys[len(ys) // 2]
            t0 = time.perf_counter()
            swept = simulate_removal(tr, plate, tool)
            sim_s = time.perf_counter() - t0
            point = simulate_removal(tr, plate, tool, swept=False)
            rows.append({"lead_deg": deg, "budget": budget, "L_over_Lstar": 2 * R / d, "spacing_R": d / R,
                         "ripple": ripple, "cov_swept": centre_cov(swept, 0.25, mid, d),
                         "cov_point": centre_cov(point, 0.25, mid, d), "sim_s": sim_s})
            print(" ".join(f"{k}={format(rows[-1][k], f)}" for k, f in COLUMNS), flush=True)
    return rows


if __name__ == "__main__":
    rows = main()
    print("| " + " | ".join(k for k, _ in COLUMNS) + " |")
    print("|" + "---|" * len(COLUMNS))
    for r in rows:
        print("| " + " | ".join(format(r[k], f) for k, f in COLUMNS) + " |")
