"""Robot stage: IK speed per model, and the whole stage on the demo blade and crs_part_5.

    python benchmarks/bench_robot.py [--skip-crs] [--point-spacing 0.002]

Table 1 — IK time per 1000 poses (random reachable flange poses from FK of random joint values
inside the limits): closed form (UR through ur_analytic_ik + branch slotting; OPW in numpy, all 8
branches) and the numerical DH solver (damped Newton with a scipy least-squares fallback, each pose
seeded by the previous one along a random-walk path).

Table 2 — ``run_robot_stage`` with the part placed by the placement search (``--place auto``) on
example:blade (raster planner, the job defaults: 38.1 mm pad, 50 mm/s) and crs_part_5 (raster;
the mesh is in metres, 1.68 x 1.97 x 0.67 m).  Every joint row written to ``joints.csv`` is read back
and run through FK: largest position (mm) and angle (deg) error against its pose; configuration
flips inside passes; largest joint speed / limit ratio by finite differences on the read-back rows;
reachable fraction of the trajectory and of the part's vertices with the tool normal to the surface; placement found (x, y, z mm, yaw deg); duration before/after re-timing (s).
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

import numpy as np

from common import SHARED_MESHES, print_table


def ik_speed_rows(n: int = 1000) -> list[dict]:
    from swath.robot import dh_robot, get_robot

    rows = []
    rng = np.random.default_rng(0)
    models = [get_robot(k) for k in ("ur3e", "ur5e", "ur10e", "ur16e", "irb4600", "kr120")]
    d, a = (0.1625, 0, 0, 0.1333, 0.0997, 0.0996), (0, -0.425, -0.3922, 0, 0, 0)
    models.append(dh_robot("dh-numeric (ur5e DH)", d, a, (math.pi / 2, 0, 0, math.pi / 2, -math.pi / 2, 0),
                           lower=[-2 * math.pi] * 6, upper=[2 * math.pi] * 6, max_speed=[math.pi] * 6,
                           max_accel=[2 * math.pi] * 6))
    for model in models:
        q = rng.uniform(np.maximum(model.lower, -math.pi), np.minimum(model.upper, math.pi), (n, 6))
        if model.kind == "numeric":
            q = q[0] + np.cumsum(rng.normal(scale=2e-3, size=(n, 6)), axis=0)   # a path: each seeded by the last
        target = model.fk(q)
        t0 = time.perf_counter()
        sols = model.ik(target, seed=q[0] if model.kind == "numeric" else None)
        dt = time.perf_counter() - t0
        from swath.robot.pose import pose_error

        ok = np.isfinite(sols[..., 0])
        dp, da = pose_error(model.fk(sols[ok]), np.repeat(target[:, None], sols.shape[1], axis=1)[ok])
        rows.append({"model": model.name, "solver": {"ur": "ur_analytic_ik", "opw": "OPW numpy", "numeric": "Newton (+scipy)"}[model.kind],
                     "ms_per_1000": 1e3 * dt * 1000 / n, "solutions_per_pose": ok.sum() / n,
                     "max_fk_err_m": float(dp.max()), "max_fk_err_rad": float(da.max())})
    return rows


def job_trajectory(part: str, units: str, point_spacing: float):
    from swath.cli.job import JobSettings, load_part_info, make_plan
    from swath.trajectory import time_path

    s = JobSettings(part=part, out="unused", units=units, planner="raster", point_spacing=point_spacing)
    surface, _ = load_part_info(s)
    return surface, time_path(make_plan(surface, s), s.constraints(), links=s.links())


def stage_row(name, trajectory, robot: str, out: Path, surface=None) -> dict:
    from swath.cell import parse_pose
    from swath.robot import Cell, flips_inside_passes, run_robot_stage
    from swath.robot.pose import pose_error, poses_from_trajectory
    from swath.robot.readers import read_joint_csv

    cell = Cell(tcp2flange=parse_pose("0,0,150mm,0,0,0"))
    t0 = time.perf_counter()
    from swath.robot import get_robot
    from swath.robot.programs import FORMAT_VENDOR, robot_vendor

    own = [f for f, v in FORMAT_VENDOR.items() if v == robot_vendor(get_robot(robot))]   # the maker's program only
    res = run_robot_stage(trajectory, robot=robot, cell=cell, programs=["csv", "ros", *own],
                          out_dir=out, place=True, surface=surface)
    wall = time.perf_counter() - t0
    rows = read_joint_csv(out / "joints.csv")
    idx = np.flatnonzero(res.solution.reachable)
    dp, da = pose_error(res.cell.tcp2part(res.model.fk(rows["q"])), poses_from_trajectory(res.trajectory)[idx])
    v = np.abs(np.diff(rows["q"], axis=0)) / np.diff(rows["t"])[:, None] / res.model.max_speed
    # rows either side of an unreachable gap are not consecutive motion; leave those steps out
    consecutive = np.diff(idx) == 1
    p = res.placement
    return {"part": name, "robot": res.model.name, "poses": len(trajectory),
            "reach_%": 100 * res.solution.reachable_fraction,
            "surf_reach_%": 100 * res.metrics.get("surface_reachable_fraction", float("nan")), "stretches": len(res.solution.stretches),
            "switches": len(res.solution.switches), "flips_in_pass": flips_inside_passes(res.solution, res.trajectory),
            "fk_err_mm": 1e3 * float(dp.max(initial=0)), "fk_err_deg": float(np.degrees(da.max(initial=0))),
            "max_qd/limit": float(v[consecutive].max(initial=0)),
            "place_xyz_mm": f"{p.x * 1e3:.0f},{p.y * 1e3:.0f},{p.z * 1e3:.0f}", "yaw_deg": math.degrees(p.yaw),
            "T0_s": trajectory.duration, "T_s": res.trajectory.duration, "ik_s": res.metrics["ik_time_s"],
            "place_s": res.metrics["placement_time_s"], "wall_s": wall}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--skip-crs", action="store_true")
    ap.add_argument("--point-spacing", type=float, default=2e-3, help="planner point spacing, m")
    ap.add_argument("--robots", default="ur10e,irb4600")
    args = ap.parse_args()

    print("IK time per 1000 poses")
    print_table(ik_speed_rows(), [("model", "s"), ("solver", "s"), ("ms_per_1000", ".1f"), ("solutions_per_pose", ".2f"),
                                  ("max_fk_err_m", ".1e"), ("max_fk_err_rad", ".1e")])
    parts = [("example:blade", "m")]
    crs = SHARED_MESHES / "crs_part_5.stl"
    if not args.skip_crs and crs.exists():
        parts.append((str(crs), "m"))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for part, units in parts:
            surface, tr = job_trajectory(part, units, args.point_spacing)
            for robot in args.robots.split(","):
                out = Path(tmp) / f"{Path(part).stem}_{robot}"
                rows.append(stage_row(Path(part).name, tr, robot, out, surface))
                print_table(rows[-1:], [(k, ".4g") for k in rows[-1]])
    print("\nrobot stage with the placement search (raster planner; 150 mm TCP along the flange axis)")
    print_table(rows, [("part", "s"), ("robot", "s"), ("poses", "d"), ("reach_%", ".1f"), ("surf_reach_%", ".1f"), ("stretches", "d"),
                       ("switches", "d"), ("flips_in_pass", "d"), ("fk_err_mm", ".1e"), ("fk_err_deg", ".1e"),
                       ("max_qd/limit", ".4f"), ("place_xyz_mm", "s"), ("yaw_deg", ".0f"), ("T0_s", ".1f"),
                       ("T_s", ".1f"), ("ik_s", ".2f"), ("place_s", ".1f"), ("wall_s", ".1f")])


if __name__ == "__main__":
    main()
