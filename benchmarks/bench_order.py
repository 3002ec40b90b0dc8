"""Regions and pass order: air moves, optimality and cycle time (issue 13).

1. Wheel hub (example): segment -> raster per region -> order by index / greedy / gtsp, groups =
   regions (Wang's four path types each) and groups = single passes.  Air = the order stage's
   estimate (retract + straight move at the clearance + approach, links inside groups included);
   "between" = the same without the links inside groups (what ordering can change).
2. Optimality: gtsp against the exact Held-Karp optimum on instances of <= 10 groups, and against
   the best of 100 LKH runs on the larger ones, with solve times.
3. Shared meshes and the hub: trajectory (time_path, FeedLimit(0.05), AngularSpeedLimit(1.0),
   CentripetalLimit(2.0)) air length, cycle time, farthest excursion beyond the part's bounding box,
   and simulated coverage, before (planner's order) and after ordering by air length ("gtsp") and by
   estimated link time ("gtsp(time)": the tool's turn at 1 rad/s counted; coverage not simulated
   again for those rows, the contact passes are the same).

Run: ``PYTHONPATH=src python benchmarks/bench_order.py [--no-removal] [--uniform PICKLE]``.
"""

from __future__ import annotations

import argparse
import pickle
import time

import numpy as np

from common import SHARED_MESH_UNITS, SHARED_MESHES, print_table
from swath.contact.tool import Tool
from swath.examples import wheel_hub
from swath.io.mesh import load_mesh
from swath.order import order_toolpath
from swath.order.sequence import snake
from swath.order.tour import (
    group_variants,
    held_karp,
    link_matrix,
    solve_gtsp,
    tour_length,
)
from swath.plan.raster import raster
from swath.plan.regions import plan_regions
from swath.segment import segment
from swath.simulate.removal import simulate_removal
from swath.trajectory.constraints import AngularSpeedLimit, CentripetalLimit, FeedLimit
from swath.trajectory.timing import time_path


def hub_table():
    hub = wheel_hub()
    tool = Tool()
    t0 = time.perf_counter()
    regions = segment(hub)
    t_seg = time.perf_counter() - t0
    spacing = raster(hub, tool).metadata["spacing_m"]            # one spacing for all regions
    tp = snake(plan_regions(hub, tool, raster, regions, spacing=spacing, fill_gaps=False))
    print(f"\n## 1. wheel hub: {len(regions)} regions ({t_seg:.2f} s), {len(tp.passes)} raster passes, "
          f"{hub.area * 1e4:.0f} cm²")
    rows = []
    for label, groups in (("regions", None), ("single passes", [[i] for i in range(len(tp.passes))])):
        base = {}
        for method in ("index", "greedy", "gtsp"):
            out = order_toolpath(tp, groups=groups, method=method)
            g = groups if groups is not None else _region_groups(tp)
            v = group_variants(tp.passes, g, clearance=0.02)
            first = np.unique(v.group, return_index=True)[1]
            inner = float(v.inner[first].sum())        # inner links are the same for every path type
            between = out.metadata["air_after_m"] - inner
            base[method] = (out.metadata["air_after_m"], between)
            rows.append(dict(groups=label, method=method, air_m=out.metadata["air_after_m"], between_m=between,
                             vs_index=100 * (1 - out.metadata["air_after_m"] / base["index"][0]),
                             between_vs_index=100 * (1 - between / base["index"][1]),
                             between_vs_greedy=(100 * (1 - between / base["greedy"][1]) if "greedy" in base else float("nan")),
                             seconds=out.metadata["order_seconds"]))
    print_table(rows, [("groups", ""), ("method", ""), ("air_m", ".3f"), ("vs_index", ".1f"), ("between_m", ".3f"),
                       ("between_vs_index", ".1f"), ("between_vs_greedy", ".1f"), ("seconds", ".3f")])
    return hub, tp


def _region_groups(tp):
    groups = {}
    for i, r in enumerate(tp.regions.tolist()):
        groups.setdefault(r, []).append(i)
    return list(groups.values())


def optimality_table(instances):
    print("\n## 2. gtsp against the exact optimum (<= 10 groups) and the best of 100 LKH runs")
    rows = []
    for name, tp, groups in instances:
        v = group_variants(tp.passes, groups, clearance=0.02)
        D = link_matrix(v, 0.02)
        t0 = time.perf_counter()
        tour = solve_gtsp(v, D, None, seed=0)
        t_gtsp = time.perf_counter() - t0
        L = tour_length(v, D, tour, None)
        if len(groups) <= 10:
            t0 = time.perf_counter()
            ref = tour_length(v, D, held_karp(v, D, None), None)
            ref_name, t_ref = "exact DP", time.perf_counter() - t0
        else:
            t0 = time.perf_counter()
            ref = min(L, tour_length(v, D, solve_gtsp(v, D, None, seed=1, runs=100), None))
            ref_name, t_ref = "best of 100 LKH runs", time.perf_counter() - t0
        rows.append(dict(instance=name, groups=len(groups), passes=len(tp.passes), gtsp_m=L, ref_m=ref,
                         gap_pct=100 * (L / ref - 1), reference=ref_name, gtsp_s=t_gtsp, ref_s=t_ref))
    print_table(rows, [("instance", ""), ("groups", "d"), ("passes", "d"), ("gtsp_m", ".4f"), ("ref_m", ".4f"),
                       ("gap_pct", ".2f"), ("reference", ""), ("gtsp_s", ".3f"), ("ref_s", ".2f")])


def subsets(name, tp, k, n_inst, rng):
    """Instances of k single-pass groups drawn from a tool path."""
    from swath.core import ToolPath

    out = []
    for j in range(n_inst):
        idx = rng.choice(len(tp.passes), size=min(k, len(tp.passes)), replace=False)
        sub = ToolPath(tp.surface, [tp.passes[i] for i in idx], tp.planner)
        out.append((f"{name} {len(idx)} passes #{j}", sub, [[i] for i in range(len(idx))]))
    return out


#: Order by link time with the trajectory stage's link speed/acceleration and the angular limit.
TIMED = dict(link_speed=0.25, link_acceleration=1.0, omega_max=1.0)


def trajectory_row(part, label, tp, tool, removal: bool):
    lo, hi = tp.surface.bounds
    cons = [FeedLimit(0.05), AngularSpeedLimit(1.0), CentripetalLimit(2.0)]
    t0 = time.perf_counter()
    traj = time_path(tp, cons)
    t_time = time.perf_counter() - t0
    air = ~traj.contact
    excess = np.maximum(np.maximum(lo - traj.position[air], traj.position[air] - hi), 0.0).max()
    row = dict(part=part, plan=label, passes=len(tp.passes), contact_m=tp.contact_length, air_m=traj.air_length,
               cycle_s=traj.duration, beyond_box_m=float(excess), time_s=t_time)
    if removal:
        rm = simulate_removal(traj, tp.surface, tool)
        row["coverage_pct"] = 100 * rm.metrics["coverage_fraction"]
    return row


def parts_table(hub, hub_tp, removal: bool, uniform_pickle: str | None):
    print("\n## 3. trajectories before/after ordering (time_path: feed 50 mm/s, 1 rad/s, 2 m/s²)")
    tool = Tool()
    rows = []
    surfaces = [("wheel_hub", hub)]
    for file in ("crs_part_5.stl", "noether_wavy_mesh_with_hole.ply", "bezier_dac_scan.ply"):
        path = SHARED_MESHES / file
        if path.exists():
            surfaces.append((file, load_mesh(path, units=SHARED_MESH_UNITS[file])))
    for name, surf in surfaces:
        big = surf.area > 1.0
        whole = snake(raster(surf, tool))                          # the planner's own order
        rows.append(trajectory_row(name, "raster", whole, tool, removal and not big))
        rows.append(trajectory_row(name, "raster + gtsp", order_toolpath(whole, method="gtsp"), tool, removal and not big))
        rows.append(trajectory_row(name, "raster + gtsp(time)", order_toolpath(whole, method="gtsp", **TIMED), tool, False))
        try:
            regions = segment(surf)
            seg = hub_tp if name == "wheel_hub" else snake(plan_regions(
                surf, tool, raster, regions, spacing=whole.metadata["spacing_m"], fill_gaps=False))
            rows.append(trajectory_row(name, f"segment({len(regions)}) raster", seg, tool, removal and not big))
            rows.append(trajectory_row(name, f"segment({len(regions)}) raster + gtsp",
                                       order_toolpath(seg, method="gtsp", groups=[[i] for i in range(len(seg.passes))]),
                                       tool, removal and not big))
            rows.append(trajectory_row(name, f"segment({len(regions)}) raster + gtsp(time)",
                                       order_toolpath(seg, method="gtsp", groups=[[i] for i in range(len(seg.passes))], **TIMED),
                                       tool, False))
        except Exception as exc:  # noqa: BLE001 - a benchmark reports and goes on
            rows.append(dict(part=name, plan=f"segment failed: {type(exc).__name__}: {exc}"[:90]))
    if uniform_pickle:
        with open(uniform_pickle, "rb") as fh:
            uni = pickle.load(fh)
        name = uni.surface.name
        rows.append(trajectory_row(name, "uniform", uni, tool, False))
        rows.append(trajectory_row(name, "uniform + gtsp", order_toolpath(uni, method="gtsp"), tool, False))
        rows.append(trajectory_row(name, "uniform + gtsp(time)", order_toolpath(uni, method="gtsp", **TIMED), tool, False))
    print_table(rows, [("part", ""), ("plan", ""), ("passes", "d"), ("contact_m", ".2f"), ("air_m", ".2f"),
                       ("cycle_s", ".1f"), ("beyond_box_m", ".3f"), ("coverage_pct", ".2f"), ("time_s", ".1f")])
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--no-removal", action="store_true", help="skip the removal simulation")
    ap.add_argument("--uniform", help="a pickled uniform ToolPath to order too (uniform is slow to plan)")
    args = ap.parse_args()
    hub, hub_tp = hub_table()
    rng = np.random.default_rng(5)
    instances = subsets("hub", hub_tp, 10, 3, rng)
    instances.append(("hub regions (4 types each)", hub_tp, _region_groups(hub_tp)))
    instances.append(("hub all passes", hub_tp, [[i] for i in range(len(hub_tp.passes))]))
    dense = raster(hub, Tool(), spacing=0.012)
    instances.append(("hub raster 12 mm", dense, [[i] for i in range(len(dense.passes))]))
    dense_seg = plan_regions(hub, Tool(), raster, segment(hub), spacing=0.01)
    instances.append(("hub regions raster 10 mm", dense_seg, [[i] for i in range(len(dense_seg.passes))]))
    dense = raster(hub, Tool(), spacing=0.005)
    instances.append(("hub raster 5 mm", dense, [[i] for i in range(len(dense.passes))]))
    optimality_table(instances)
    parts_table(hub, hub_tp, not args.no_removal, args.uniform)


if __name__ == "__main__":
    main()
