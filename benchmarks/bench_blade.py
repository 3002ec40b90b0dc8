"""Benchmark: even removal on the built-in blade, row by row as a user's jobs run it (issue 12).

The blade (NACA 0012, 0.4 m chord, 0.6 m span) is the hardest built-in part for even removal: its
leading edge has a nose radius of 6.35 mm against the pad's 38.1 mm.

* Passes running chordwise (the default raster) wrap round the nose.  There the angular-speed limit
  slows the pad, so it dwells: at constant feed the nose takes several times the depth of the flanks.
* Passes running spanwise touch the nose with a contact only ``2·sqrt(2·e·r)`` wide (7 mm at a 1 mm
  depression).  Covering it evenly takes more passes than the coverage lower bound ``L*`` assumes,
  because ``L*`` takes the widest swath at each point (76 mm along the span at the nose).

Each row is one ``swath plan`` job (:func:`swath.cli.job.run_job` with the settings shown), written to a
temporary folder.  Columns:

* ``cov_interior`` — the simulator's removal CoV over the samples at least a pad radius in from the
  open boundary;
* ``L_over_Lstar`` — contact length over the coverage lower bound;
* ``over_um`` / ``tol_um`` — the simulated largest over-removal against the target and its
  tolerance (optimised rows);
* ``cycle_s`` — cycle time; ``at_vmin`` — the fraction of dwell nodes at the slowest feed
  (``feed_nodes_at_slowest_fraction``: where it is high, the feed range, not the target, bounds the removal);
* ``warnings`` — how many warnings the job wrote to its report (an over-removal the fastest feed
  cannot avoid is one); ``refused`` — the job's refusal, where it refused;
* ``job_s`` — the whole job's wall time.

    PYTHONPATH=src python benchmarks/bench_blade.py [--only ROW,ROW]

Measured with swath 0.2.0 on 2 vCPUs:

=============================  ======  ============  ============  =======  ======  =======  =======
row                            passes  cov_interior  L_over_Lstar  over_um  tol_um  cycle_s  at_vmin
=============================  ======  ============  ============  =======  ======  =======  =======
raster chord const                  8         0.662          1.02                       125
uniform span feed (33 um)          26         0.341          1.48    15.17    3.30     1130     0.73
uniform span lead feed (30 um)     26         0.348          1.48    14.08    3.00     1106     0.61
+ overlap 0.2 (20 um)              12         0.163          1.62     0.64    2.00     1009     0.12
+ overlap 0.25                     12         0.100          1.71     0.79    2.00     1088     0.06
+ overlap 0.3                      13         0.066          1.86     0.84    2.00     1147     0.04
raster chord ripple lead feed      12         0.165          1.52     0.92    2.00     1050     0.11
=============================  ======  ============  ============  =======  ======  =======  =======

* Spanwise at the default overlap the nose is over-removed at the fastest feed (15 and 14 µm over;
  the jobs warn, naming the samples), and 61-73 % of the dwell nodes sit at the slowest feed: the
  flanks cannot reach the target within the feed range while the nose is over it.
* A wider overlap lays fewer, longer passes here (12-13 against 26, which the nose broke) and
  evens the removal: 6.6 % at 0.3, with every node within the tolerance, at 1.86x L*.
* The optimised rows run 8-9x longer than the constant feed (1009-1147 s against 125 s): the
  target (20 µm) is several times the 2-3 µm one pass at 50 mm/s removes on the flanks.
* Peak memory 1.04 GB.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from common import max_rss_mb, print_table

BASE = {"part": "example:blade", "overwrite": True}

#: spanwise uniform passes, the pad led at the half-pad angle, the feed optimised
SPAN_LED = {"planner": "uniform", "direction": "0deg", "lead_angle": "auto", "optimise_feed": True}

#: name -> job settings over BASE (the keys of ``swath plan``'s TOML job file)
ROWS = {
    "raster chord const": {"planner": "raster"},
    "uniform span feed": {"planner": "uniform", "direction": "0deg", "optimise_feed": True, "target_depth": "33um"},
    # at the default overlap the nose takes 27.5 um at the fastest feed: 20 um is refused
    "uniform span lead feed": {**SPAN_LED, "target_depth": "30um"},
    **{f"+ overlap {o}": {**SPAN_LED, "overlap": o, "target_depth": "20um"} for o in (0.2, 0.25, 0.3)},
    "raster chord ripple lead feed": {"planner": "raster", "optimise_spacing": "ripple", "lead_angle": "auto",
                                      "optimise_feed": True, "target_depth": "20um", "max_angular": "10rad/s"},
}

COLUMNS = [("row", "s"), ("passes", "d"), ("cov_interior", ".3f"), ("L_over_Lstar", ".2f"), ("over_um", ".2f"),
           ("tol_um", ".2f"), ("cycle_s", ".0f"), ("at_vmin", ".2f"), ("warnings", "d"), ("job_s", ".1f"),
           ("rss_mb", ".0f"), ("refused", "s")]


def run_row(name: str, extra: dict, out: Path) -> dict:
    from swath.cli.job import run_job
    from swath.cli.settings import settings_from_mapping
    from swath.errors import InfeasibleError

    settings = settings_from_mapping({**BASE, **extra, "out": str(out / name.replace(" ", "_"))})
    t0 = time.perf_counter()
    try:
        m = run_job(settings)
    except InfeasibleError as exc:              # the job's own refusal, kept as the row's result
        return {"row": name, "refused": str(exc).split(";")[0], "job_s": time.perf_counter() - t0}
    row = {"row": name, "passes": m["n_passes"], "cov_interior": m["interior_removal_cov"],
           "L_over_Lstar": m["contact_length_m"] / m["coverage_lower_bound_m"], "cycle_s": m["cycle_time_s"],
           "warnings": len(m.get("warnings", [])), "job_s": time.perf_counter() - t0, "rss_mb": max_rss_mb()}
    if "feed_tolerance_m" in m:
        row.update(over_um=1e6 * m["feed_simulated_max_over_target_m"], tol_um=1e6 * m["feed_tolerance_m"],
                   at_vmin=m["feed_nodes_at_slowest_fraction"])
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--only", help="comma-separated row names (default: every row)")
    args = ap.parse_args()
    names = args.only.split(",") if args.only else list(ROWS)
    unknown = set(names) - set(ROWS)
    if unknown:
        ap.error(f"unknown rows: {', '.join(sorted(unknown))}; rows: {', '.join(ROWS)}")
    rows = []
    with tempfile.TemporaryDirectory(prefix="swath-bench-blade-") as tmp:
        for name in names:
            rows.append(run_row(name, ROWS[name], Path(tmp)))
            print_table(rows[-1:], COLUMNS)
            print(flush=True)
    print("The blade, one job per row (example:blade, 3-inch pad, 20 N, 1 mm depression, 50 mm/s):")
    print_table(rows, COLUMNS)


if __name__ == "__main__":
    main()
