"""Regions and pass order: air moves, optimality and cycle time (issue 13).

Definitions (Wang's Table 4-1 counts the *interval movements*: the moves between his sub-surfaces,
each sub-surface being swept by one *continuous* local path; B = no planning, C = visit order
planned, D = visit order and path types planned: 853 -> 732 -> 305 mm):

* **air** = every move with the pad off the part, as the order stage estimates it: retract 20 mm
  along the normal, a straight move at that clearance, approach 20 mm (``route_links`` routes the
  hub's links exactly so); table 3 measures the timed trajectory's air instead.
* **contact step-overs** ("join" columns): a move from a pass's end to the next pass's start of at
  most one pad diameter (76.2 mm) whose chord stays on the part (or runs along the edge of a hole it
  cuts) is made in contact (:mod:`swath.order.joining`): the passes become one, the move is contact
  in the trajectory (it is timed at the feed and it removes material), and it is not air.  Wang's
  local paths are continuous in this sense.  Rows with and without it are shown; every method of
  one block uses the same rule.
* **index** (Wang's B): the regions in the segmentation's order, each region's passes in the
  planner's boustrophedon (snake) order; **order only** (C): regions' order chosen, each region
  as planned; **greedy**: from the current lift-off point, the nearest touch-down among the groups
  left; **gtsp** (D): order and path types chosen (GTSP: exact DP up to 10 groups, else LKH +
  local search).  Groups are regions (Wang's four path types each) or single passes (each pass
  in either direction, any order).
* **status quo**: the whole part rastered without segmentation, snake order, no contact step-overs.

Run: ``PYTHONPATH=src python benchmarks/bench_order.py [--no-removal] [--no-uniform] [--only N] [--hub-only]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from common import SHARED_MESH_UNITS, SHARED_MESHES, print_table
from swath.contact.tool import Tool
from swath.core import ToolPath
from swath.examples import wheel_hub
from swath.io.mesh import load_mesh
from swath.order import order_toolpath
from swath.order.routing import AirGuard
from swath.order.sequence import snake
from swath.order.tour import (
    LinkModel,
    group_variants,
    held_karp,
    improve_tour,
    link_matrix,
    link_time_estimate,
    pass_ends,
    solve,
    solve_gtsp,
    tour_length,
)
from swath.plan.raster import raster
from swath.plan.regions import plan_regions
from swath.segment import segment
from swath.simulate.removal import simulate_removal
from swath.trajectory.constraints import AngularSpeedLimit, CentripetalLimit, FeedLimit
from swath.trajectory.links import LinkSettings
from swath.trajectory.timing import time_path

TOOL = Tool()
#: Longest contact step-over: one pad diameter, m.
JOIN_GAP = 2 * TOOL.pad_radius


def _region_groups(tp):
    groups = {}
    for i, r in enumerate(tp.regions.tolist()):
        groups.setdefault(r, []).append(i)
    return list(groups.values())


def segmented_raster(surface, spacing):
    """Segment, raster each region at the whole part's spacing, fill over the whole part."""
    regions = segment(surface)
    tp = plan_regions(surface, TOOL, raster, regions, spacing=spacing, fill_gaps=False, fill_whole_part=True)
    return snake(tp), len(regions)


def hub_table():
    hub = wheel_hub()
    t0 = time.perf_counter()
    whole = raster(hub, TOOL)
    spacing = whole.metadata["spacing_m"]
    seg, n_regions = segmented_raster(hub, spacing)
    t_plan = time.perf_counter() - t0
    quo = order_toolpath(snake(whole), method="index").metadata["air_after_m"]
    print(f"\n## 1. wheel hub: {n_regions} regions, {len(seg.passes)} raster passes "
          f"({seg.metadata['n_fill_passes']} whole-part fill), spacing {1e3 * spacing:.1f} mm, "
          f"{hub.area * 1e4:.0f} cm², planned in {t_plan:.1f} s; status quo (unsegmented raster, snake, "
          f"no contact step-overs, {len(whole.passes)} passes): air {quo:.3f} m")
    rows = []
    for join in (None, JOIN_GAP):
        for label, groups in (("regions", None), ("single passes", [[i] for i in range(len(seg.passes))])):
            base = {}
            methods = [("index", "index", {}), ("greedy", "greedy", {}), ("gtsp", "gtsp", {})]
            if groups is None:
                methods.insert(1, ("order only", "gtsp", {"keep_direction": True}))
            for name, method, extra in methods:
                out = order_toolpath(seg, groups=groups, method=method, join_gap=join, **extra)
                air = out.metadata["air_after_m"]
                base[name] = air
                rows.append(dict(step_overs="contact" if join else "air", groups=label, method=name,
                                 air_m=air, lifts=len(out.passes) - 1, contact_m=out.contact_length,
                                 vs_index=100 * (1 - air / base["index"]),
                                 vs_greedy=100 * (1 - air / base["greedy"]) if "greedy" in base else float("nan"),
                                 vs_status_quo=100 * (1 - air / quo), seconds=out.metadata["order_time_s"]))
    print_table(rows, [("step_overs", ""), ("groups", ""), ("method", ""), ("air_m", ".3f"), ("lifts", "d"),
                       ("contact_m", ".2f"), ("vs_index", ".1f"), ("vs_greedy", ".1f"), ("vs_status_quo", ".1f"),
                       ("seconds", ".3f")])
    print("vs_* = % less air than that baseline (same step-over rule for index and greedy)")
    return hub, seg


def _timed(fn):
    w, c = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w, time.process_time() - c


def optimality_table(instances, *, ref_runs: int = 100):
    print("\n## 2. gtsp against the exact optimum (DP, <= 14 groups) and the best of 100 LKH runs")
    rows = []
    for name, tp, groups, force_lkh in instances:
        v = group_variants(tp.passes, groups, clearance=0.02)
        D = link_matrix(v, 0.02)
        if force_lkh:           # the LKH path of the portfolio, which the method skips below 11 groups
            def run():
                tours = [solve_gtsp(v, D, None, seed=0, runs=5, subgradient=s) for s in (False, True)]
                return improve_tour(v, D, None, min(tours, key=lambda t: tour_length(v, D, t, None)))
        else:
            def run():
                return solve(v, D, None, "gtsp")
        tour, wall, cpu = _timed(run)
        L = tour_length(v, D, tour, None)
        if len(groups) <= 14:
            ref_tour, t_ref, _ = _timed(lambda: held_karp(v, D, None))
            ref, ref_name = tour_length(v, D, ref_tour, None), "exact DP"
        else:
            ref_tour, t_ref, _ = _timed(lambda: solve_gtsp(v, D, None, seed=1, runs=ref_runs))
            ref, ref_name = min(L, tour_length(v, D, ref_tour, None)), f"best of {ref_runs} LKH runs"
        rows.append(dict(instance=name + (" (LKH path)" if force_lkh else ""), groups=len(groups),
                         passes=len(tp.passes), gtsp_m=L, ref_m=ref, gap_pct=100 * (L / ref - 1), reference=ref_name,
                         wall_s=wall, cpu_s=cpu, ref_s=t_ref))
        print(f"  {rows[-1]['instance']}: gap {rows[-1]['gap_pct']:.2f} %, {wall:.2f} s", flush=True)
    print_table(rows, [("instance", ""), ("groups", "d"), ("passes", "d"), ("gtsp_m", ".4f"), ("ref_m", ".4f"),
                       ("gap_pct", ".2f"), ("reference", ""), ("wall_s", ".3f"), ("cpu_s", ".3f"), ("ref_s", ".1f")])


def subsets(name, tp, k, n_inst, rng, *, force_lkh=False):
    """Instances of k single-pass groups drawn from a tool path."""
    out = []
    for j in range(n_inst):
        idx = rng.choice(len(tp.passes), size=min(k, len(tp.passes)), replace=False)
        sub = ToolPath(tp.surface, [tp.passes[i] for i in idx], tp.planner)
        out.append((f"{name} {len(idx)} passes #{j}", sub, [[i] for i in range(len(idx))], force_lkh))
    return out


CONSTRAINTS = [FeedLimit(0.05), AngularSpeedLimit(1.0), CentripetalLimit(2.0)]


def trajectory_row(part, label, tp, removal: bool):
    lo, hi = tp.surface.bounds
    t0 = time.perf_counter()
    traj = time_path(tp, CONSTRAINTS, links=LINKS)
    air = ~traj.contact
    excess = np.maximum(np.maximum(lo - traj.position[air], traj.position[air] - hi), 0.0).max() if air.any() else 0.0
    row = dict(part=part, plan=label, passes=len(tp.passes), contact_m=tp.contact_length, air_m=traj.air_length,
               cycle_s=traj.duration, beyond_box_m=float(excess), order_s=tp.metadata.get("order_time_s", np.nan),
               route_rounds=tp.metadata.get("order_route_rounds", 0))
    if removal:
        rm = simulate_removal(traj, tp.surface, TOOL)
        row["coverage_pct"] = 100 * rm.metrics["coverage_fraction"]
    row["time_s"] = time.perf_counter() - t0
    print(f"  {part} / {label}: air {row['air_m']:.2f} m, cycle {row['cycle_s']:.1f} s", flush=True)
    return row


#: The trajectory stage's link speed and acceleration and the tool's angular limit: what the order
#: stage costs by time (``order_objective = time``, the job's default).
LINKS = LinkSettings()
TIMED = dict(link_speed=LINKS.speed, link_acceleration=LINKS.acceleration, omega_max=1.0, feed=0.05)

#: Orders of tables 3 and 4: (label, method, contact step-overs, timed objective).
ORDERS = [("greedy", "greedy", False, False), ("gtsp(length)", "gtsp", False, False),
          ("greedy + join", "greedy", True, False), ("gtsp(length) + join", "gtsp", True, False),
          ("gtsp(time)", "gtsp", False, True), ("gtsp(time) + join", "gtsp", True, True)]


def ordered(tp, method, join, timed):
    """``tp`` ordered pass by pass (every pass its own group, as jobs do), links costed as routed."""
    singles = [[i] for i in range(len(tp.passes))]
    return order_toolpath(tp, method=method, groups=singles, join_gap=JOIN_GAP if join else None,
                          **(TIMED if timed else {}))


def parts_table(hub, hub_seg, removal: bool, with_uniform: bool, *, only_hub: bool = False):
    print("\n## 3. raster and uniform before/after ordering (time_path: feed 50 mm/s, 1 rad/s, 2 m/s²)")
    print("index = the plan as planned (snake; uniform: its zigzag); greedy / gtsp over single passes, by air "
          "length or by link time (the job's order_objective), '+ join': contact step-overs up to "
          f"{1e3 * JOIN_GAP:.1f} mm; air and cycle of the timed trajectory; vs_index / vs_greedy: % less "
          "trajectory air (greedy with the same step-over rule)")
    from swath.plan.uniform import uniform

    rows = []
    surfaces = [("wheel_hub", hub)]
    for file in () if only_hub else ("crs_part_5.stl", "noether_wavy_mesh_with_hole.ply", "bezier_dac_scan.ply"):
        path = SHARED_MESHES / file
        if path.exists():
            surfaces.append((file, load_mesh(path, units=SHARED_MESH_UNITS[file])))
    for name, surf in surfaces:
        sim = removal and surf.area < 1.0
        plans = []
        planned = raster(surf, TOOL)
        plans.append(("raster", snake(planned)))
        try:
            seg = hub_seg if name == "wheel_hub" else segmented_raster(surf, planned.metadata["spacing_m"])[0]
            plans.append((f"segment({seg.metadata['n_regions']}) raster", seg))
        except Exception as exc:  # noqa: BLE001 - a benchmark reports and goes on
            rows.append(dict(part=name, plan=f"segment failed: {type(exc).__name__}: {exc}"[:90]))
        if with_uniform and not only_hub:
            t0 = time.perf_counter()
            uni = uniform(surf, TOOL)
            print(f"  {name}: uniform planned in {time.perf_counter() - t0:.0f} s", flush=True)
            plans.append(("uniform", order_toolpath(uni)))             # its own order (zigzag)
        for label, before in plans:
            index = trajectory_row(name, f"{label} (index)", before, sim)
            rows.append(index)
            greedy = {}
            for order_label, method, join, timed in ORDERS:
                row = trajectory_row(name, f"{label} + {order_label}", ordered(before, method, join, timed), sim)
                if method == "greedy":
                    greedy[join] = row["air_m"]
                row["vs_index"] = 100 * (1 - row["air_m"] / index["air_m"])
                row["vs_greedy"] = 100 * (1 - row["air_m"] / greedy[join])
                rows.append(row)
    print_table(rows, [("part", ""), ("plan", ""), ("passes", "d"), ("contact_m", ".2f"), ("air_m", ".2f"),
                       ("vs_index", ".1f"), ("vs_greedy", ".1f"), ("cycle_s", ".1f"), ("beyond_box_m", ".3f"),
                       ("coverage_pct", ".2f"), ("order_s", ".2f"), ("route_rounds", "d"), ("time_s", ".1f")])
    return rows


def _old_link_time(length, turn):
    """Last session's link time: max(rest-to-rest trapezoid, turn at 1 rad/s), s."""
    v, a = LINKS.speed, LINKS.acceleration
    move = length / v + v / a if length >= v * v / a else 2 * np.sqrt(length / a)
    return max(move, turn / 1.0)


def link_audit(label, tp, *, show=0):
    """Every link of ``tp`` as the order stage costs it (straight at the clearance; the time of the
    order's frames) against its air route and the timed trajectory; one summary row."""
    traj = time_path(tp, CONSTRAINTS, links=LINKS)
    guard = AirGuard(tp.surface, LINKS.clearance)
    model = LinkModel(clearance=LINKS.clearance)
    step = np.r_[0.0, np.linalg.norm(np.diff(traj.position, axis=0), axis=1)]
    per = []
    for i, (a, b) in enumerate(zip(tp.passes[:-1], tp.passes[1:])):
        ia, ib = np.flatnonzero(traj.pass_index == i)[-1], np.flatnonzero(traj.pass_index == i + 1)[0]
        end, start = pass_ends(a), pass_ends(b)
        length = float(model.length(end[3], end[4], start[0], start[1]))
        turn = float(np.arccos(np.clip(0.5 * (np.trace(end[5].T @ start[2]) - 1), -1, 1)))
        route = guard.route(end[3], end[4] / np.linalg.norm(end[4]), start[0], start[1] / np.linalg.norm(start[1]))
        routed = float(np.linalg.norm(np.diff(route, axis=0), axis=1).sum())
        q0, q1 = traj.quaternion[ia], traj.quaternion[ib]
        per.append(dict(link=i, model_m=length, routed_m=routed, flown_m=float(step[ia + 1:ib + 1].sum()),
                        turn_rad=turn, flown_turn_rad=2 * float(np.arccos(min(abs(float(q0 @ q1)), 1.0))),
                        model_s=float(link_time_estimate(routed, turn, clearance=LINKS.clearance, speed=LINKS.speed,
                                                         acceleration=LINKS.acceleration, omega_max=1.0)),
                        old_model_s=_old_link_time(length, turn), flown_s=float(traj.t[ib] - traj.t[ia]),
                        detour=len(route) > 4))
    if show and per:
        worst = sorted(per, key=lambda r: -abs(r["flown_s"] - r["model_s"]))[:show]
        print(f"  {label}: the {show} links the time model misses most")
        print_table(worst, [("link", "d"), ("model_m", ".3f"), ("routed_m", ".3f"), ("flown_m", ".3f"),
                            ("turn_rad", ".2f"), ("flown_turn_rad", ".2f"), ("old_model_s", ".2f"), ("model_s", ".2f"),
                            ("flown_s", ".2f")])
    col = {k: np.array([r[k] for r in per], float) for k in per[0]} if per else \
        {k: np.zeros(1) for k in ("model_m", "routed_m", "flown_m", "turn_rad", "model_s", "old_model_s", "flown_s",
                                  "detour")}
    link_s = float(col["flown_s"].sum())
    return dict(plan=label, links=len(per), model_m=col["model_m"].sum(), routed_m=col["routed_m"].sum(),
                flown_m=col["flown_m"].sum(), traj_air_m=traj.air_length, detours=int(col["detour"].sum()),
                turns_over_2_5=int((col["turn_rad"] > 2.5).sum()), old_model_s=col["old_model_s"].sum(),
                model_s=col["model_s"].sum(), flown_s=link_s,
                worst_err_s=float(np.abs(col["flown_s"] - col["model_s"]).max()),
                contact_s=traj.duration - link_s, cycle_s=traj.duration)


def audit_table(hub_seg):
    print("\n## 4. why: every link of the hub's plans as the order stage costs it and as the trajectory flies it")
    print("model_m: retract + straight at 20 mm + approach; routed_m: AirGuard's route (what the order stage now "
          "costs); flown_m: the timed trajectory between the passes (corners rounded); traj_air_m adds the first "
          "approach and the last retract; old_model_s: last session's link time max(trapezoid, turn / 1 rad/s); "
          "model_s: the closed form now used (retract, rounded corners, turn on the move only); flown_s: toppra; "
          "contact_s: the passes (contact step-overs included)")
    rows = [link_audit("index (as planned)", hub_seg)]
    for i, (label, method, join, timed) in enumerate(ORDERS):
        rows.append(link_audit(label, ordered(hub_seg, method, join, timed), show=5 if i == 1 else 0))
    print_table(rows, [("plan", ""), ("links", "d"), ("model_m", ".3f"), ("routed_m", ".3f"), ("flown_m", ".3f"),
                       ("traj_air_m", ".3f"), ("detours", "d"), ("turns_over_2_5", "d"), ("old_model_s", ".1f"),
                       ("model_s", ".1f"), ("flown_s", ".1f"), ("worst_err_s", ".3f"), ("contact_s", ".1f"),
                       ("cycle_s", ".1f")])
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--no-removal", action="store_true", help="skip the removal simulation")
    ap.add_argument("--no-uniform", action="store_true", help="skip the uniform planner (slow on crs_part_5)")
    ap.add_argument("--only", choices=("1", "2", "3", "4"), help="run one table only")
    ap.add_argument("--hub-only", action="store_true", help="table 3 on the hub only")
    args = ap.parse_args()
    hub, hub_seg = hub_table() if args.only in (None, "1", "3", "4") else (None, None)
    if args.only in (None, "4"):
        audit_table(hub_seg)
    if args.only in (None, "2"):
        hub = hub or wheel_hub()
        rng = np.random.default_rng(5)
        dense = raster(hub, TOOL, spacing=0.005)
        seg, _ = segmented_raster(hub, raster(hub, TOOL).metadata["spacing_m"])
        instances = subsets("hub raster 5 mm", dense, 14, 3, rng, force_lkh=True)
        instances += subsets("hub raster 5 mm", dense, 10, 2, rng)
        instances.append(("hub regions (4 types each)", seg, _region_groups(seg), True))
        instances.append(("hub segmented, all passes", seg, [[i] for i in range(len(seg.passes))], False))
        for label, tp in (("hub raster 12 mm", raster(hub, TOOL, spacing=0.012)),
                          ("hub regions raster 10 mm", plan_regions(hub, TOOL, raster, segment(hub), spacing=0.01)),
                          ("hub raster 7 mm", raster(hub, TOOL, spacing=0.007)), ("hub raster 5 mm", dense)):
            instances.append((label, tp, [[i] for i in range(len(tp.passes))], False))
        optimality_table(instances)
    if args.only in (None, "3"):
        parts_table(hub, hub_seg, not args.no_removal, not args.no_uniform, only_hub=args.hub_only)


if __name__ == "__main__":
    main()
