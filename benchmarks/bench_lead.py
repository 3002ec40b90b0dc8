"""Benchmark: the pad pressed flat against the pad led at ``Tool.half_pad_lead``, same part, same run.

For every part (built-in plate, panel, blade and the shared meshes named), four rows, each the
raster in its default direction at the least-ripple spacing of its own pad attitude
(:func:`swath.feed.ripple_spacing`, contact length within 1.5 L* on a plane):

* ``flat``       — the pad pressed flat (z = −normal), constant feed;
* ``flat+feed``  — the same passes with the feed optimised (simulator in the loop, as jobs do);
* ``lead``       — the pad led at the half-pad angle (7.0° for the default pad), constant feed;
* ``lead+feed``  — those passes with the feed optimised.

Both optimised rows aim at one uniform depth ``D``: ``DEPTH_FACTOR`` (3) times the least depth both
plans reach without over-grinding at the feed limit as the simulator measures it (as
``bench_feed._least_depth_simulated``, for each attitude), with a tolerance of 10 % of ``D``: at the
least depth itself every node runs at the fastest feed and the feed has no room to even anything.  Every figure is the simulator's on the timed
trajectory: interior removal CoV (samples a pad radius in from the open boundary, untouched ones
included), L / L*, the largest over-removal against ``D``, cycle time and optimisation time.

Run: ``PYTHONPATH=src python benchmarks/bench_lead.py [plate panel blade noether_raw_mesh.ply ...]``
(default: the three built-in parts).
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np

from bench_feed import CAP_MARGIN, FEED, MODEL_ERROR, TOL_FRACTION, _load
from common import max_rss_mb, rows_per_part

DEPTH_FACTOR = 3.0   # the target over the least depth both attitudes reach at the feed limit

COLUMNS = [("part", ""), ("run", ""), ("lead_deg", ".2f"), ("passes", "d"), ("spacing_R", ".2f"), ("ripple", ".3f"),
           ("cov_interior", ".3f"), ("D_um", ".2f"), ("over_um", ".2f"), ("tol_um", ".2f"), ("L_over_Lstar", ".2f"),
           ("cycle_s", ".1f"), ("opt_s", ".1f"), ("rss_mb", ".0f")]


def run_one(name: str) -> list[dict]:
    from swath.contact import Tool
    from swath.feed import interior_mask, optimise_feed, removal_stats, ripple_cov, ripple_spacing
    from swath.plan import raster
    from swath.simulate.removal import simulate_removal
    from swath.trajectory import AngularSpeedLimit, CentripetalLimit, FeedLimit, TangentialAccelLimit, time_path

    surface = _load(name)
    tool = Tool()
    cons = [FeedLimit(FEED), CentripetalLimit(2.0), AngularSpeedLimit(1.0), TangentialAccelLimit(1.0)]
    angle = raster(surface, tool).metadata["angle_rad"]
    held = 1 + TOL_FRACTION - max(CAP_MARGIN * TOL_FRACTION, MODEL_ERROR)
    plans = {}
    for label, lead in (("flat", 0.0), ("lead", tool.half_pad_lead)):
        d, ripple = ripple_spacing(tool, lead_angle=lead)
        tp = raster(surface, tool, spacing=d, direction=angle)
        rm = simulate_removal(time_path(tp, cons, lead_angle=lead), surface, tool)
        inner = interior_mask(rm.surface, tool.pad_radius)
        plans[label] = (lead, d, ripple, tp, float(rm.depth[inner].max(initial=0.0)) / held)
    D = DEPTH_FACTOR * max(p[4] for p in plans.values())
    tol = TOL_FRACTION * D
    rows = []

    def measure(label, lead, d, ripple, tp, extra, opt_s):
        traj = time_path(tp, cons + extra, lead_angle=lead)
        rm = simulate_removal(traj, surface, tool)
        st = removal_stats(rm.depth, np.full(len(rm.depth), D), rm.surface.vertex_areas,
                           interior_mask(rm.surface, tool.pad_radius))
        m = rm.metrics
        rows.append({"part": name, "run": label, "lead_deg": float(np.degrees(lead)), "passes": len(tp.passes),
                     "spacing_R": d / tool.pad_radius, "ripple": ripple, "cov_interior": st["removal_cov"],
                     "D_um": 1e6 * D, "over_um": 1e6 * st["max_over_removal_m"], "tol_um": 1e6 * tol,
                     "L_over_Lstar": m["contact_length_m"] / m["coverage_lower_bound_m"], "cycle_s": traj.duration,
                     "opt_s": opt_s, "rss_mb": max_rss_mb()})

    for label, (lead, d, ripple, tp, _) in plans.items():
        assert abs(ripple - ripple_cov(tool, d, lead_angle=lead)) < 1e-12
        measure(label, lead, d, ripple, tp, [], 0.0)
        t0 = time.perf_counter()
        fr = optimise_feed(tp, tool, cons, target=D, tolerance=tol, lead_angle=lead,
                           simulate=lambda traj: simulate_removal(traj, surface, tool))
        measure(label + "+feed", lead, d, ripple, tp, [fr.profile], time.perf_counter() - t0)
    return rows


def main(argv):
    if "-h" in argv or "--help" in argv:
        print(__doc__)
        return
    if len(argv) >= 2 and argv[0] == "--one":
        print("ROWS " + json.dumps(run_one(argv[1])))
        return
    rows_per_part(__file__, argv or ["plate", "panel", "blade"], COLUMNS)

if __name__ == "__main__":
    main(sys.argv[1:])
