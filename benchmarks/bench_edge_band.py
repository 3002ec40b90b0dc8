"""Benchmark: what makes the edge band uneven, on the built-in and shared parts, and on a plane.

Parts: for each part the default job (``swath plan PART`` and the part's units, plus any extra
options given after ``--``) runs in its own process; its ``metrics.json`` gives the interior CoV,
coverage, cycle time, L / L* and the band's causes (:func:`swath.simulate.edge_band.band_causes`:
the band's share of the interior variance against its area share, the excess over a band removed
like the core, the share that is its mean, and per group — beside the outermost passes, at the
pass ends, oblique — area, variance share and mean over the core's mean).

Plane (``--plane``): six straight passes at the least-ripple spacing for the half-pad lead
(1.40 R), constant feed, on flat plates sized so the outermost passes lie ``m`` in from both sides,
for ``m`` from 0 to half a spacing: the side band's mean over the core's mean and its own CoV, the
core's CoV and the band's first sixth (nearest the edge) over the core's mean.

Run: ``PYTHONPATH=src python benchmarks/bench_edge_band.py [PART ...] [-- OPTION ...]``
(default parts: plate, panel, blade, ``bezier_dac_cad``, ``snp_part_scan``, ``crs_part_5``), or
``PYTHONPATH=src python benchmarks/bench_edge_band.py --plane [LEAD_DEG SPACING_OVER_R]``.
"""

from __future__ import annotations

import math
import os
import sys

from bench_evenness_split import run

PARTS = ("example:plate", "example:panel", "example:blade", "bezier_dac_cad.ply", "snp_part_scan.ply",
         "crs_part_5.stl")
GROUPS = ("side", "ends", "oblique")


def _finite(x) -> bool:
    return x is not None and math.isfinite(x)            # metrics.json writes NaN as null


def _pc(x) -> str:
    return f"{100 * x:.0f} %" if _finite(x) else "—"


def _group(m: dict, g: str) -> str:
    ratio = m.get(f"evenness_band_{g}_mean_over_core_mean_ratio")
    return (f"{_pc(m.get(f'evenness_band_{g}_area_fraction'))}, {_pc(m.get(f'evenness_band_{g}_variance_fraction'))}, "
            + (f"{ratio:.3f}" if _finite(ratio) else "—"))


def parts_table(parts, options) -> None:
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs; options: {' '.join(options) or '(none)'}")
    print("| part | interior CoV | coverage | cycle time | L / L* | band area | band variance | excess | mean offset "
          "| band / core | band own CoV | core CoV | side: area, variance, mean | ends | oblique |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for part in parts:
        m = run(part, options)
        name = part.removesuffix(".ply").removesuffix(".stl")
        if "failed" in m:
            print(f"| {name} | failed: {m['failed']} |")
            continue
        print(f"| {name} | {m['interior_removal_cov']:.3f} | {100 * m['coverage_fraction']:.2f} % | "
              f"{m['cycle_time_s']:.0f} s | {m['contact_length_m'] / m['coverage_lower_bound_m']:.2f} | "
              f"{_pc(m['evenness_band_area_fraction'])} | {_pc(m['evenness_band_variance_fraction'])} | "
              f"{100 * m['evenness_band_excess_variance_fraction']:+.0f} pt | "
              f"{_pc(m['evenness_band_mean_offset_variance_fraction'])} | "
              f"{m['evenness_band_mean_over_core_mean_ratio']:.3f} | {m['evenness_band_own_cov']:.3f} | "
              f"{m['evenness_core_cov']:.3f} | " + " | ".join(_group(m, g) for g in GROUPS) + " |", flush=True)


def plane_table(lead_deg: float | None, spacing_over_r: float) -> None:
    import numpy as np

    from shapes import plate_with_straight_passes  # tests/ is on the path through common
    from swath.cli.job import JobSettings
    from swath.simulate import simulate_removal
    from swath.simulate.edge_band import band_causes
    from swath.trajectory import time_path

    settings = JobSettings(part="example:plate", out="unused")
    tool = settings.tool()
    lead = tool.half_pad_lead if lead_deg is None else math.radians(lead_deg)
    d = spacing_over_r * tool.pad_radius
    print(f"plane: lead {math.degrees(lead):.1f} deg, spacing {d * 1e3:.1f} mm ({spacing_over_r:g} R), six passes "
          "0.3 m long, constant feed, samples every 4 mm")
    print("| outermost pass in from the side | side band / core | side band own CoV | core CoV | first sixth / core |")
    print("|---|---|---|---|---|")
    for frac in np.arange(0.0, 0.5001, 0.1):
        m = frac * d
        surface, toolpath = plate_with_straight_passes(d, m)
        trajectory = time_path(toolpath, settings.constraints(), links=settings.links(), lead_angle=lead)
        removal = simulate_removal(trajectory, surface, tool, sample_spacing=4e-3)
        c = band_causes(removal, trajectory, tool, spacing=d)
        print(f"| {m * 1e3:.1f} mm ({frac:.1f} d) | {c['band_side_mean_over_core_mean_ratio']:.3f} | "
              f"{c['band_side_own_cov']:.3f} | {c['core_cov']:.3f} | {c['band_side_profile'][0]:.2f} |", flush=True)


def main(argv: list[str]) -> None:
    if argv and argv[0] == "--plane":
        rest = argv[1:]
        plane_table(float(rest[0]) if rest else None, float(rest[1]) if len(rest) > 1 else 1.40)
        return
    options = argv[argv.index("--") + 1:] if "--" in argv else []
    parts = (argv[:argv.index("--")] if "--" in argv else argv) or list(PARTS)
    parts_table(parts, options)


if __name__ == "__main__":
    main(sys.argv[1:])
