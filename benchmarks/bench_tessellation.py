"""Benchmark: what a coarse tessellation costs the removal, and where it shows.

Two reports.

``kinks`` (default): for every shared mesh and built-in example, the tessellation check of
:mod:`swath.contact.tessellation` with the default pad: the 90th percentile (by edge length) of
the angle between neighbouring facets and of the kink height over the depression, and whether the
job warns ``W-MESH-COARSE``.

``JOB_DIR PART [UNITS]``: the ``trajectory.csv`` a job wrote is simulated again on the part as
meshed and on a smooth surface through the same vertices (:func:`swath.surface.phong.phong_smoothed`,
subdivided to the removal sample spacing): the interior CoV of the same passes on both, and the
removal against the distance to the nearest marked facet kink
(:func:`swath.simulate.facets.ridge_profile`).

Run: ``PYTHONPATH=src python benchmarks/bench_tessellation.py [kinks | JOB_DIR PART [UNITS]]``.
"""

from __future__ import annotations

import sys
import time

from common import SHARED_MESH_UNITS, SHARED_MESHES

EXAMPLES = ("plate", "panel", "blade", "hub")


def kinks_table() -> None:
    from swath.contact import Tool
    from swath.contact.tessellation import tessellation_check
    from swath.examples import example_part
    from swath.io.mesh import load_mesh

    tool = Tool()
    print(f"pad radius {tool.pad_radius * 1e3:.1f} mm, depression {tool.flat_depression * 1e3:.2f} mm at {tool.force:g} N")
    print("| part | faces | facet angle, 90th pct | kink height / depression, 90th pct | W-MESH-COARSE |")
    print("|---|---|---|---|---|")
    parts = [(f"example:{n}", lambda n=n: example_part(n)) for n in EXAMPLES]
    parts += [(name, lambda name=name: load_mesh(str(SHARED_MESHES / name), units=SHARED_MESH_UNITS[name]))
              for name in sorted(SHARED_MESH_UNITS)]
    for label, load in parts:
        surface = load()
        c = tessellation_check(surface, tool)
        print(f"| {label} | {len(surface.faces)} | {c.angle_deg:.2f}° | {c.ratio:.3f} | {'yes' if c.coarse else 'no'} |")


def resimulate(job_dir: str, part: str, units: str = "m") -> None:
    from pathlib import Path

    from swath.contact import Tool
    from swath.contact.tool import sample_spacing_for
    from swath.examples import example_part
    from swath.io.mesh import load_mesh
    from swath.simulate import simulate_removal
    from swath.simulate.facets import ridge_profile
    from swath.surface.phong import phong_smoothed
    from swath.trajectory.trajectory import read_csv

    tool = Tool()
    trajectory = read_csv(Path(job_dir) / "trajectory.csv")
    surface = example_part(part.split(":", 1)[1]) if part.startswith("example:") else load_mesh(part, units=units)
    smooth = phong_smoothed(surface, sample_spacing_for(tool))
    for label, s in (("as meshed", surface), ("smooth through its vertices", smooth)):
        t0 = time.perf_counter()
        removal = simulate_removal(trajectory, s, tool)
        prof = ridge_profile(removal, surface if s is surface else s, tool) if s is surface else None
        m = removal.metrics
        print(f"{label}: interior CoV {m['interior_removal_cov']:.3f}, coverage {m.get('coverage_fraction', float('nan')):.4f}, "
              f"({time.perf_counter() - t0:.0f} s)")
        if prof is not None:
            print(f"  marked kinks: {prof['convex_marked_edges']} convex ({prof['convex_marked_length_m']:.1f} m), "
                  f"{prof['concave_marked_edges']} concave ({prof['concave_marked_length_m']:.1f} m)")
            print(f"  near a kink (< 10 mm, {prof['near_area_fraction']:.0%} of the interior): CoV {prof['near_cov']:.3f}; "
                  f"far from any (>= 40 mm, {prof['far_area_fraction']:.0%}): CoV {prof['far_cov']:.3f}")
            for kind in ("convex", "concave"):
                rows = ", ".join(f"{lo * 1e3:.0f}-{hi * 1e3:.0f} mm: {mean:.2f} ({share:.0%})"
                                 for lo, hi, share, mean in prof[f"{kind}_bins"])
                print(f"  depth / interior mean by distance to a {kind} kink: {rows}")


def main(argv: list[str]) -> None:
    if not argv or argv[0] == "kinks":
        kinks_table()
    else:
        resimulate(*argv[:3])


if __name__ == "__main__":
    main(sys.argv[1:])
