"""The STEP tube with a flange all round on a rotary positioner, in one program (issue 38).

    python benchmarks/bench_positioner.py [--robots ur10e,irb4600,kr120]

The tube (300 mm, Ø100 mm, 5 mm wall, Ø180 x 10 mm flange; :func:`swath.examples.cad.tube_with_flange`)
is written as STEP and read back, planned with the wrap planner about a horizontal positioner axis
along the robot base's y, timed, and run through :func:`swath.robot.positioner.run_positioner_stage`
with the default 3-inch sander; per robot the table reports:

* ``turns`` the axis range in turns, ``w`` and ``a`` the largest axis speed and acceleration over
  their limits;
* ``sw_contact`` branch changes in contact, ``fk_mm`` FK of every written row with its axis angle
  against its pose in the part frame, ``dt_ms`` the longest contact step;
* ``hits`` collisions of the arm and the tool with the turning part, the cell and themselves, over
  ``poses`` checked poses;
* ``outer`` the tessellated outer cylinder's area the pressed pad touches, ``flange`` the flange
  top's (0: the pad stays clear of it);
* ``plan_s``, ``robot_s``, ``check_s`` wall times.
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

#: Where each robot's positioner axis stands (x, z in the base frame, m) and what it writes.
CELLS = {"ur10e": (0.8, 0.3, ("ros", "csv")), "irb4600": (1.2, 0.7, ("rapid", "csv")),
         "kr120": (1.3, 0.8, ("krl", "csv"))}


def _faces(part, name):
    ids = [f.id for f in part.faces if f.name == name]
    return part.surface.sub_surface(np.flatnonzero(np.isin(part.face_ids, ids)))


def run(robots) -> list[dict]:
    from swath.cell import cell_from_mapping, default_sander
    from swath.contact.tool import Tool
    from swath.examples import cad
    from swath.io.step import load_step
    from swath.plan import wrap
    from swath.robot.positioner import check_positioner_collisions, run_positioner_stage
    from swath.simulate import simulate_removal
    from swath.trajectory import time_path

    tool = Tool()
    sander = default_sander()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        shape = cad.tube_with_flange()
        part = load_step(cad.write_step(shape, Path(tmp) / "tube.step", names=cad.tube_face_names(shape)))
        for robot in robots:
            x, z, programs = CELLS[robot]
            cell = cell_from_mapping({"positioner": {"axis_point": [x, -0.15, z], "axis_direction": [0, 1, 0]}})
            cell = replace(cell, tool=sander, tcp2flange=sander.tcp2flange)
            t0 = time.perf_counter()
            tp = wrap(part.surface, tool, axis=cell.positioner.axis_in_part())
            tr = time_path(tp)
            t1 = time.perf_counter()
            res = run_positioner_stage(tr, cell=cell, robot=robot, programs=programs, out_dir=Path(tmp) / robot,
                                       warn=False)
            t2 = time.perf_counter()
            rep = check_positioner_collisions(res.program_view[0], res.solution, res.model, cell,
                                              part_vertices=part.surface.vertices, part_faces=part.surface.faces)
            t3 = time.perf_counter()
            m = res.metrics
            rows.append({
                "robot": robot, "turns": m["positioner_range_rad"] / (2 * math.pi),
                "w": m["positioner_max_speed_ratio"], "a": m["positioner_max_accel_ratio"],
                "sw_contact": m["branch_changes_in_contact"], "fk_mm": 1e3 * m["max_fk_position_error_m"],
                "dt_ms": 1e3 * m["max_contact_dt_s"], "hits": len(rep.events), "poses": rep.n_poses,
                "outer": simulate_removal(res.trajectory, _faces(part, "tube_outer"), tool).metrics["coverage_fraction"],
                "flange": simulate_removal(res.trajectory, _faces(part, "flange_top"), tool).metrics["coverage_fraction"],
                "plan_s": t1 - t0, "robot_s": t2 - t1, "check_s": t3 - t2})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", default="ur10e,irb4600,kr120")
    args = ap.parse_args()
    rows = run([r.strip() for r in args.robots.split(",") if r.strip()])
    keys = list(rows[0])
    print(" | ".join(keys))
    for r in rows:
        print(" | ".join(f"{r[k]:.4g}" if isinstance(r[k], float) else str(r[k]) for k in keys))


if __name__ == "__main__":
    main()
