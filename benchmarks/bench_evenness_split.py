"""Benchmark: where the default job's interior removal CoV comes from, on the curved parts.

For each part the default job (``swath plan PART`` and the part's units, plus any extra options
given after ``--``) runs in its own process, and its ``metrics.json`` gives the interior CoV, L / L*,
the cycle time, the plan written and the split of the CoV's variance
(:func:`swath.simulate.evenness.evenness_split`): the ripple across the passes (within one period),
along the passes, between passes, and the band one spacing inside the interior's edge, with the
CoV without that band and the ripple of the profile across the passes averaged along them.

Run: ``PYTHONPATH=src python benchmarks/bench_evenness_split.py [PART ...] [-- OPTION ...]``
(default parts: the panel, the blade, ``bezier_dac_cad`` and ``crs_part_5``).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import REPO, SHARED_MESH_UNITS, SHARED_MESHES

PARTS = ("example:panel", "example:blade", "bezier_dac_cad.ply", "crs_part_5.stl")
SHARES = ("within_cells", "along_passes", "between_passes", "band")


def part_args(part: str) -> list[str]:
    """``swath plan`` arguments naming ``part`` (a shared mesh file name or ``example:NAME``)."""
    if part.startswith("example:"):
        return [part]
    return [str(SHARED_MESHES / part), "--units", SHARED_MESH_UNITS[part]]


def run(part: str, options: list[str]) -> dict:
    """The default job on ``part`` in a fresh process: its metrics and wall time (s)."""
    env = dict(os.environ, PYTHONPATH=str(REPO / "src"))
    with tempfile.TemporaryDirectory(prefix="swath-bench-") as tmp:
        out = Path(tmp) / "job"
        t0 = time.perf_counter()
        done = subprocess.run([sys.executable, "-m", "swath.cli.main", "--quiet", "plan", *part_args(part),
                               *options, "--out", str(out)], capture_output=True, text=True, cwd=REPO, env=env)
        wall = time.perf_counter() - t0
        if done.returncode != 0:
            return {"failed": (done.stderr.strip().splitlines() or ["?"])[-1]}
        metrics = json.loads((out / "metrics.json").read_text())["metrics"]
    metrics["wall_s"] = wall
    return metrics


def main(argv: list[str]) -> None:
    options = argv[argv.index("--") + 1:] if "--" in argv else []
    parts = (argv[:argv.index("--")] if "--" in argv else argv) or list(PARTS)
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs; options: {' '.join(options) or '(none)'}")
    print("| part | interior CoV | L / L* | cycle time | plan written | lead | ripple across | along | between "
          "| edge band | CoV without the band | across-profile ripple | wall time |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for part in parts:
        m = run(part, options)
        if "failed" in m:
            print(f"| {part} | FAILED: {m['failed']} ||||||||||||")
            continue
        kept = "plain" if m.get("plain_plan_kept") else "constant" if m.get("constant_feed_kept") else "even"
        shares = " | ".join(f"{100 * m[f'evenness_{k}_variance_fraction']:.0f} %" for k in SHARES)
        print(f"| {part} | {m['interior_removal_cov']:.3f} | {m['contact_length_m'] / m['coverage_lower_bound_m']:.2f} "
              f"| {m['cycle_time_s']:.0f} s | {kept} | {m.get('lead_angle_deg', 0.0):.1f}° | {shares} "
              f"| {m['evenness_core_cov']:.3f} | {m['evenness_across_profile_cov']:.3f} | {m['wall_s']:.0f} s |",
              flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
