"""Force control against registration error and tool weight; removal with the simulated force.

    python benchmarks/bench_force.py

Rasters on ``example:plate`` (flat, 0.4 m × 0.3 m) and ``example:panel`` (a convex doubly curved
panel, 0.5 m × 0.4 m, slopes up to 45°) at 50 mm/s, run by a
robot with a 10 ms servo lag and an 8 ms command latency (Jaeger's figure for joint-velocity
commands), a 2 kg tool below the force sensor, and the cell tilted so that a tool pointing down
the part's z-axis is 30° from hanging straight down (on the plate every pose is tilted 30°; on the
panel the part's own slope adds to it).  The real part is off the plan by a rigid
registration error (0.5 mm translation plus a small tilt; and a 2 mm / 0.5° case).

Prints, per scenario and controller: the RMS and largest contact-force error as % of the 20 N set
point over the contact passes (ticks where the tool travels along a pass; the initial contact
phases are excluded), contact loss, simulation time, and the removal CoV with the nominal force
against the CoV with the simulated per-sample force.  Target: force control with gravity
compensation at most 5 % RMS.
"""

from __future__ import annotations

import math
import time

import numpy as np

from common import print_table


def main():
    from scipy.spatial.transform import Rotation

    from swath.contact import Tool
    from swath.examples import doubly_curved_panel, flat_plate
    from swath.plan.raster import raster
    from swath.simulate import Disturbance, ForceController, gravity_for_tilt, simulate_force, simulate_removal
    from swath.simulate.force import force_gains
    from swath.trajectory import FeedLimit, time_path

    tool = Tool()
    gravity = gravity_for_tilt(math.radians(30.0))
    errors = {
        "0.5 mm": (0.2e-3, 0.1e-3, 0.45e-3, 0.0005, 0.0005, 0.0),
        "2 mm, 0.5 deg": (1.0e-3, 0.5e-3, 1.7e-3, math.radians(0.4), math.radians(0.3), 0.0),
    }
    controllers = {
        "(a) force + gravity comp.": ForceController(latency=0.008),
        "(b) force, no gravity comp.": ForceController(latency=0.008, gravity_compensation=False),
        "(c) position control": ForceController(latency=0.008, mode="position"),
    }
    cases = [("example:plate", flat_plate(), ["0.5 mm"]),
             ("example:panel", doubly_curved_panel(), ["0.5 mm", "2 mm, 0.5 deg"])]
    rows = []
    for pname, part, names in cases:
        tp = raster(part, tool, angle=0.0)
        tr = time_path(tp, [FeedLimit(0.05)])
        nominal = simulate_removal(tr, part, tool)
        print(f"plan: raster on {pname}, {len(tp.passes)} passes, {tr.contact_length:.2f} m in contact, "
              f"{int(tr.contact.sum())} contact samples; nominal removal CoV {nominal.metrics['removal_cov']:.4f}")
        centre = part.principal_axes[0]
        for sname in names:
            offset = errors[sname]
            R = Rotation.from_rotvec(offset[3:]).as_matrix()
            moved = (part.vertices - centre) @ R.T + centre + np.asarray(offset[:3])
            disp = float(np.max(np.linalg.norm(moved - part.vertices, axis=1)))
            dist = Disturbance(part_offset=offset, tool_mass=2.0, gravity=gravity)
            for cname, ctrl in controllers.items():
                t0 = time.perf_counter()
                trace = simulate_force(tr, part, tool, controller=ctrl, disturbance=dist)
                sim_s = time.perf_counter() - t0
                removal = simulate_removal(tr, part, tool, force=trace.force)
                m = trace.metrics
                rows.append(dict(part=pname, error=sname, max_disp_mm=1e3 * disp, controller=cname,
                                 rms_pct=100 * m["rms_force_error_fraction"],
                                 max_pct=100 * m["max_abs_force_error_n"] / m["set_force_n"],
                                 mean_N=m["mean_force_n"], loss_pct=100 * m["contact_loss_fraction"],
                                 cov_nominal=nominal.metrics["removal_cov"], cov_sim=removal.metrics["removal_cov"],
                                 mean_depth_ratio=removal.metrics["removal_mean_m"] / nominal.metrics["removal_mean_m"],
                                 wait_s=m["hold_time_s"], sim_s=sim_s, ticks=len(trace.t)))
                print(f"  done {pname} {sname} / {cname}", flush=True)
    print_table(rows, [("part", ""), ("error", ""), ("max_disp_mm", ".2f"), ("controller", ""), ("rms_pct", ".2f"),
                       ("max_pct", ".1f"), ("mean_N", ".2f"), ("loss_pct", ".1f"), ("cov_nominal", ".4f"),
                       ("cov_sim", ".4f"), ("mean_depth_ratio", ".3f"), ("wait_s", ".2f"), ("sim_s", ".1f"),
                       ("ticks", "d")])
    print(f"weight share of a 2 kg tool tilted 30 deg: {2.0 * 9.80665 * (1 - math.cos(math.radians(30))):.2f} N "
          f"= {100 * 2.0 * 9.80665 * (1 - math.cos(math.radians(30))) / tool.force:.1f} % of the set force")
    st = trace.stability
    kp, ki, fst = force_gains(tool, controllers["(a) force + gravity comp."])
    print(f"force loop (a, b): K_p {kp:.3g} m/s/N, K_i {ki:.3g} m/s2/N, gain margin {fst.gain_margin:.2f}, "
          f"phase margin {math.degrees(fst.phase_margin):.1f} deg, slowest pole {fst.time_constant * 1e3:.0f} ms; "
          f"position loop phase margin {math.degrees(st['position'].phase_margin):.1f} deg")


if __name__ == "__main__":
    main()
