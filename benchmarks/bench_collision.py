"""Collision checking of a whole job in its cell: crs_part_5 on an IRB 4600, time per stage.

    python benchmarks/bench_collision.py [--robot irb4600] [--part-xyz 1.45,0,-0.45] [--place]

Plans crs_part_5 (raster, the job defaults), times it, solves it on the robot (the part placed at
``--part-xyz``, or by the placement search with ``--place``), then checks the whole joint path
for collisions in the default cell (the 3-inch sander, the table under the part's lowest point):
robot link capsules, the tool body, the part's mesh (BVH), the table, at joint steps of at most 2°.
Prints the time of each stage, the poses checked, the narrow-phase (coal) queries and the
collisions found.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np

from common import SHARED_MESHES, print_table


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="irb4600")
    ap.add_argument("--part-xyz", default="1.45,0,-0.45", help="the part frame's origin in the base frame, m")
    ap.add_argument("--place", action="store_true", help="search the placement instead (slow)")
    args = ap.parse_args()

    from swath.cell import Cell, default_sander, parse_pose
    from swath.cli.job import JobSettings, load_part_info, make_plan
    from swath.robot import run_robot_stage
    from swath.robot.collision import check_job_collisions
    from swath.trajectory import time_path

    part = SHARED_MESHES / "crs_part_5.stl"
    times = {}
    t0 = time.perf_counter()
    s = JobSettings(part=str(part), out="unused", units="m", planner="raster")
    surface, _ = load_part_info(s)
    toolpath = make_plan(surface, s)
    tr = time_path(toolpath, s.constraints(), links=s.links())
    times["plan_and_time_s"] = time.perf_counter() - t0

    tool = default_sander()
    v = surface.vertices
    centre = (v.min(axis=0) + v.max(axis=0)) / 2
    x, y, z = (float(c) for c in args.part_xyz.split(","))
    part2base = parse_pose(f"{x - centre[0]},{y - centre[1]},{z - v[:, 2].min()},0,0,0")
    cell = replace(Cell(part2base=part2base), tool=tool, tcp2flange=tool.tcp2flange)
    t0 = time.perf_counter()
    res = run_robot_stage(tr, robot=args.robot, cell=cell, place=args.place, table_z=z, warn=False)
    times["robot_stage_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    rep = check_job_collisions(res.trajectory, res.solution, res.model, res.cell, part_vertices=v,
                               part_faces=surface.faces)
    times["collision_check_s"] = time.perf_counter() - t0
    dq = np.abs(np.diff(res.solution.q[res.solution.reachable], axis=0)).max(axis=1)
    row = {"part": part.name, "faces": len(surface.faces), "robot": res.model.name, "samples": len(tr),
           "reachable_%": 100 * res.solution.reachable_fraction, "max_step_deg": float(np.degrees(dq.max())),
           "poses_checked": rep.n_poses, "coal_queries": rep.n_queries, "collisions": len(rep.events),
           **times, **{f"check_{k}": v for k, v in rep.timings.items()}}
    print_table([row], [(k, ".4g" if isinstance(val, float) else "s" if isinstance(val, str) else "d")
                        for k, val in row.items()])
    for e in rep.events[:10]:
        print(" ", e.sentence())


if __name__ == "__main__":
    main()
