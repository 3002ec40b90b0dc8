"""Benchmark: interior removal CoV on curved parts, the plane's spacing rule against the curved choice.

For each part the uniform planner runs twice, zig-zag ordered and timed under the same limits:

* ``plane rule``: the overlap :func:`swath.feed.ripple_overlap` gives for the half-pad lead (as
  ``--optimise-spacing ripple --lead-angle auto`` does), that lead;
* ``curved``: :func:`swath.feed.curved_ripple.curved_ripple_choice` over leads 7 / 11 / 15° and the
  first plan's direction or the one across it (the representative curvatures of each), re-planned
  at the chosen overlap, direction and lead.

Each plan is simulated at constant feed and, with ``--feed``, with the feed optimised to 20 µm
(the simulator in the loop).  Columns: interior CoV, the slow part of it (depth averaged over a
disc one spacing across), L / L* and the plane's floor at that L / L* (the least ripple over leads
0-20°).  The bowl (0.35 m) and saddle (0.4 m) are ``tests/shapes.py``'s.

Run: ``PYTHONPATH=src:tests python benchmarks/bench_curved_evenness.py [--feed] [panel bowl saddle blade ...]``
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np

LEADS_DEG = (7.0, 11.0, 15.0)
LIMITS = dict(feed=0.05, centripetal=2.0, angular=1.0, tangential=1.0)


def load(name: str):
    from shapes import bowl, saddle
    from swath.examples import example_part
    from swath.io.mesh import load_mesh

    if name == "bowl":
        return bowl()
    if name == "saddle":
        return saddle()
    if name in ("panel", "blade", "plate"):
        return example_part(name)
    return load_mesh(f"../shared/meshes/{name}", units="in" if "wavy" in name else "m")


def slow_cov(removal, tool, spacing: float) -> float:
    """CoV over the interior of the depth averaged over discs ``spacing`` across."""
    s, z, a = removal.surface, removal.depth, removal.surface.vertex_areas
    idx = np.flatnonzero(s.farther_from_boundary(tool.pad_radius))
    mean = np.average(z[idx], weights=a[idx])
    smooth = np.array([np.average(z[n], weights=a[n]) for n in s.kdtree.query_ball_point(s.vertices[idx], spacing / 2)])
    return float(np.sqrt(np.average((smooth - mean) ** 2, weights=a[idx])) / mean)


def plane_floor(tool, ratio: float) -> float:
    from swath.feed import ripple_spacing

    return min(ripple_spacing(tool, lead_angle=math.radians(a), max_length_ratio=ratio, steps=31)[1]
               for a in range(0, 21))


def measure(name, surface, tool, label, toolpath, lead, spacing, feed: bool) -> list[dict]:
    from swath.feed import optimise_feed
    from swath.order import order_toolpath
    from swath.simulate.removal import simulate_removal
    from swath.trajectory import AngularSpeedLimit, CentripetalLimit, FeedLimit, TangentialAccelLimit, time_path

    cons = [FeedLimit(LIMITS["feed"]), CentripetalLimit(LIMITS["centripetal"]), AngularSpeedLimit(LIMITS["angular"]),
            TangentialAccelLimit(LIMITS["tangential"])]
    tp = order_toolpath(toolpath)
    runs = [("constant", time_path(tp, cons, lead_angle=lead))]
    if feed:
        depth = 20e-6
        result = optimise_feed(tp, tool, cons, target=depth, tolerance=0.1 * depth, trajectory=runs[0][1],
                               simulate=lambda t: simulate_removal(t, surface, tool), lead_angle=lead)
        runs.append(("feed 20um", time_path(tp, cons + [result.profile], lead_angle=lead)))
    rows = []
    for how, trajectory in runs:
        rm = simulate_removal(trajectory, surface, tool)
        m = rm.metrics
        ratio = m["contact_length_m"] / m["coverage_lower_bound_m"]
        rows.append({"part": name, "setting": label, "feed": how, "lead_deg": math.degrees(lead),
                     "cov": m["interior_removal_cov"], "slow_cov": slow_cov(rm, tool, spacing), "L_over_Lstar": ratio,
                     "plane_floor": plane_floor(tool, ratio), "cycle_s": trajectory.duration})
        print(" ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in rows[-1].items()), flush=True)
    return rows


def run_part(name: str, feed: bool) -> list[dict]:
    from swath.contact import Tool
    from swath.feed import ripple_overlap, ripple_spacing
    from swath.feed.curved_ripple import curved_ripple_choice
    from swath.plan import uniform

    tool = Tool()
    surface = load(name)
    lead = tool.half_pad_lead
    first = uniform(surface, tool, overlap=ripple_overlap(tool, lead_angle=lead), workers=1)
    d, _ = ripple_spacing(tool, lead_angle=lead)
    rows = measure(name, surface, tool, "plane rule", first, lead, d, feed)
    angle = first.metadata["direction_rad"]
    options = []
    for a in (angle, angle + math.pi / 2):
        tp = first if a == angle else uniform(surface, tool, overlap=0.3, direction=a, workers=1)
        chosen_lead, choice = curved_ripple_choice(tp, surface, tool, leads=np.radians(LEADS_DEG))
        options.append((choice.robust_cov, a, chosen_lead, choice))
    _, a, chosen_lead, choice = min(options, key=lambda o: o[0])
    tp = uniform(surface, tool, overlap=float(np.clip(choice.overlap, 0.0, 0.85)), direction=a, workers=1)
    label = f"curved: {math.degrees(a):.0f} deg, overlap {choice.overlap:.3f}"
    rows += measure(name, surface, tool, label, tp, chosen_lead, choice.spacing, feed)
    return rows


if __name__ == "__main__":
    args = sys.argv[1:]
    feed = "--feed" in args
    names = [a for a in args if a != "--feed"] or ["panel", "bowl", "saddle"]
    t0 = time.perf_counter()
    rows = [r for n in names for r in run_part(n, feed)]
    keys = list(rows[0])
    print("| " + " | ".join(keys) + " |")
    print("|" + "---|" * len(keys))
    for r in rows:
        print("| " + " | ".join(f"{r[k]:.3f}" if isinstance(r[k], float) else str(r[k]) for k in keys) + " |")
    print(f"{time.perf_counter() - t0:.0f} s")
