"""Robot programs a controller can run: configurations, force direction, timing, FK of every written row.

    python benchmarks/bench_robot_programs.py [--parts blade,crs,snp] [--robots ur10e,irb4600]
                                              [--fixed crs:ur10e:1.1,0,-0.2,0,0,0]

For each part (example:blade; crs_part_5 and snp_part_scan in metres) planned with the job defaults
and each robot placed by the placement search (``--place``; TCP 150 mm along the flange axis), the
robot stage runs as a job runs it (with the part's mesh: joint moves checked along their sweep and
lifted where needed) and writes the maker's program (URScript for a UR, RAPID for an ABB), ROS 2
JointTrajectory YAML and joints.csv; then the job's collision check runs on what was written.  A
``--fixed`` part:robot:pose row uses that part2base (``--base``) instead of the search.  The table
reports, read back from the written files where a file says it:

* ``at`` the part's placement (x, y in m, yaw in deg), ``solved`` the cells the search solved;
* ``sw`` branch changes, ``sw_in_contact`` branch changes between two contact samples of a pass,
  ``sw_clear_mm`` the smallest distance to the part (mesh) of the swept tool, TCP, pad disc and arm
  along the whole joint move of any branch change, against the job's clearance ``clear_mm``;
  ``jmoves`` joint moves written as such, ``lifted`` those lifted or given via-points, ``routed``
  those routed through via-points found in joint space, ``not_clear`` those nothing cleared;
* ``dq_contact`` the largest joint step between contact samples of a pass (rad; must be ≤ 0.05);
* ``fk_mm``, ``fk_deg`` FK of every row of joints.csv and of the ROS YAML against its TCP pose;
* ``force_deg`` the largest angle between a contact sample's tool z (minus the surface normal: lead
  angle 0) and the force direction the URScript's re-issued force frame commands there (RAPID's
  FCPressL presses along the interpolated tool z; the same frames bound it), after gaps too;
* ``dt_ms`` the longest contact step after re-timing (FORMATS.md: ≤ 20 ms); ``ros_v0`` the
  largest joint speed at the YAML's first and last point (rad/s; 0 = at rest);
* ``place_s`` the placement search, ``wall_s`` the robot stage's wall time with it, ``coll_s`` the
  collision check of the whole job, ``hits`` the collisions it reports (a job refuses them).

A part the search cannot place is reported with the time the refusal took.
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

import numpy as np

from common import SHARED_MESHES, print_table

PARTS = {"blade": ("example:blade", "m"), "crs": (str(SHARED_MESHES / "crs_part_5.stl"), "m"),
         "snp": (str(SHARED_MESHES / "snp_part_scan.ply"), "m")}


def job_trajectory(part: str, units: str):
    from swath.cli.job import JobSettings, load_part_info, make_plan
    from swath.trajectory import time_path

    s = JobSettings(part=part, out="unused", units=units)
    surface, _ = load_part_info(s)
    return surface, time_path(make_plan(surface, s), s.constraints(), links=s.links()), s.clearance


def program_row(name: str, trajectory, robot: str, out: Path, clearance: float, surface, base: str | None = None) -> dict:
    from swath.cell import parse_pose
    from swath.robot import Cell, get_robot, run_robot_stage
    from swath.robot.collision import check_job_collisions
    from swath.robot.pose import pose_error, poses_from_trajectory
    from swath.robot.programs import FORMAT_VENDOR, ProgramInput, commanded_force_angles, robot_vendor
    from swath.robot.readers import read_joint_csv, read_ros_yaml

    own = [f for f, v in FORMAT_VENDOR.items() if v == robot_vendor(get_robot(robot))]
    cell = Cell(tcp2flange=parse_pose("0,0,150mm,0,0,0"))
    if base is not None:
        cell = cell.with_base(parse_pose(base))
    t0 = time.perf_counter()
    res = run_robot_stage(trajectory, robot=robot, cell=cell, programs=["csv", "ros", *own], out_dir=out,
                          place=base is None, warn=False, surface=surface, clearance=clearance, reach_vertices=300)
    wall = time.perf_counter() - t0
    rep = check_job_collisions(res.trajectory, res.solution, res.model, res.cell, part_vertices=surface.vertices,
                               part_faces=surface.faces)
    tr, sol, m = res.trajectory, res.solution, res.metrics
    idx = np.flatnonzero(sol.reachable)
    want = poses_from_trajectory(tr)[idx]
    fk_p, fk_a = [], []
    for rows in (read_joint_csv(out / "joints.csv"), read_ros_yaml(out / "joint_trajectory.yaml")):
        dp, da = pose_error(res.cell.tcp2part(res.model.fk(rows["q"])), want)
        fk_p.append(dp.max(initial=0.0))
        fk_a.append(da.max(initial=0.0))
    ros = read_ros_yaml(out / "joint_trajectory.yaml")
    ang = commanded_force_angles(ProgramInput(tr, sol, res.model, res.cell))
    b = sol.branch
    change = (b[1:] != b[:-1]) & (b[1:] >= 0) & (b[:-1] >= 0)
    p2b = res.cell.part2base
    routed = sum("routed" in r["lift_direction"] for r in m.get("joint_move_sweeps", []))
    return {"part": name, "robot": res.model.name, "base": "search" if base is None else "fixed",
            "at": f"{p2b[0, 3]:.3f},{p2b[1, 3]:.3f},{math.degrees(math.atan2(p2b[1, 0], p2b[0, 0])):.0f}",
            "solved": m.get("placements_solved", 0), "routed": routed,
            "poses": len(trajectory), "rows": len(idx),
            "reach_%": 100 * m["reachable_fraction"], "sw": int(change.sum()),
            "sw_in_contact": m["branch_changes_in_contact"], "sw_clear_mm": 1e3 * m["min_switch_clearance_m"],
            "clear_mm": 1e3 * clearance, "jmoves": m["n_joint_moves"], "lifted": m.get("n_lifted_joint_moves", 0),
            "not_clear": m.get("n_joint_moves_not_clear", 0), "dq_contact": m["max_contact_joint_step_rad"],
            "fk_mm": 1e3 * max(fk_p), "fk_deg": math.degrees(max(fk_a)),
            "force_deg": math.degrees(np.nanmax(ang)) if np.isfinite(ang).any() else float("nan"),
            "dt_ms": 1e3 * m["max_contact_dt_s"], "ros_v0": float(np.abs(ros["qd"][[0, -1]]).max()),
            "T0_s": trajectory.duration, "T_s": tr.duration, "place_s": m.get("placement_time_s", 0.0), "wall_s": wall,
            "coll_s": rep.seconds, "hits": len(rep.events)}


COLUMNS = [("part", "s"), ("robot", "s"), ("base", "s"), ("at", "s"), ("solved", "d"), ("poses", "d"), ("rows", "d"),
           ("reach_%", ".1f"), ("sw", "d"), ("sw_in_contact", "d"), ("sw_clear_mm", ".1f"), ("clear_mm", ".0f"),
           ("jmoves", "d"), ("lifted", "d"), ("routed", "d"), ("not_clear", "d"), ("dq_contact", ".4f"), ("fk_mm", ".1e"), ("fk_deg", ".1e"),
           ("force_deg", ".2f"), ("dt_ms", ".1f"), ("ros_v0", ".1g"), ("T0_s", ".1f"), ("T_s", ".1f"),
           ("place_s", ".1f"), ("wall_s", ".1f"), ("coll_s", ".1f"), ("hits", "d")]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--parts", default="blade,crs,snp")
    ap.add_argument("--robots", default="ur10e,irb4600")
    ap.add_argument("--fixed", default="crs:ur10e:1.1,0,-0.2,0,0,0",
                    help="part:robot:part2base rows with a fixed placement (comma-free separator ';'), '' for none")
    args = ap.parse_args()
    rows = []
    fixed = [f.split(":", 2) for f in args.fixed.split(";") if f]
    with tempfile.TemporaryDirectory() as tmp:
        for key in args.parts.split(","):
            part, units = PARTS[key]
            if not part.startswith("example:") and not Path(part).exists():
                print(f"skipping {part}: not found")
                continue
            surface, tr, clearance = job_trajectory(part, units)
            runs = [(robot, None) for robot in args.robots.split(",")] + [(r, b) for k, r, b in fixed if k == key]
            for robot, base in runs:
                out = Path(tmp) / f"{key}_{robot}_{'search' if base is None else 'fixed'}"
                t0 = time.perf_counter()
                try:
                    rows.append(program_row(Path(part).name, tr, robot, out, clearance, surface, base))
                except Exception as exc:          # a part the robot cannot be placed for: say so, go on
                    print(f"{key} / {robot}: refused after {time.perf_counter() - t0:.2f} s: {type(exc).__name__}: {exc}")
                    continue
                print_table(rows[-1:], COLUMNS)
    print("\nrobot programs (raster planner; 150 mm TCP along the flange axis; placement search unless 'fixed')")
    print_table(rows, COLUMNS)


if __name__ == "__main__":
    main()
