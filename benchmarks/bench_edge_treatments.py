"""Benchmark: two edge treatments tried on a written plan, and why neither is kept (docs: the edge band).

Both start from a job's ``trajectory.csv`` (run ``swath plan PART --out DIR`` first): its
in-contact stretches become passes again (points as written, normals from the tool axis less the
lead), and the plan is timed with the job's constraints and lead and simulated as the job does.

* ``band-feed``: the passes over the band slowed, never sped up (at most 1.5 times their dwell),
  by a linear programme on the removal kernel (:mod:`swath.feed.kernel`): the band's depth
  matched to the core's mean (L1, area-weighted), the other interior samples those passes reach
  capped at 3 % over the larger of their own depth and the core's mean.
* ``edge-pass``: a pass along each stretch of the open boundary that no pass point comes within
  ``R`` of (widened by ``R / 2`` at both ends, stretches under ``R / 4`` dropped), the tool centre
  on the boundary: it cannot reach the interior.

Printed: the interior CoV, coverage and cycle time before and after, the band's figures
(:func:`swath.simulate.edge_band.band_causes`), and for ``edge-pass`` the depth within ``R`` of the
boundary over the interior mean (99.9th percentile, largest).

Run: ``PYTHONPATH=src python benchmarks/bench_edge_treatments.py band-feed|edge-pass PART DIR LEAD_DEG``
(``PART`` as ``swath plan`` takes it, shared meshes in metres; ``LEAD_DEG`` the lead the job wrote:
``lead_angle_deg`` in its ``metrics.json``).
"""

from __future__ import annotations

import math
import sys

import numpy as np

import common  # noqa: F401  (puts src/ on the path)


def load(part: str, folder: str, lead_deg: float):
    """The job's settings, surface, tool, its passes rebuilt from ``folder/trajectory.csv`` and lead (rad)."""
    from swath.cli.job import JobSettings, load_part_info
    from swath.cli.stages import job_tool
    from swath.core import Pass, ToolPath
    from swath.trajectory.trajectory import read_csv

    settings = JobSettings(part=part, units="m", out="unused")
    surface, _ = load_part_info(settings)
    tool = job_tool(settings)
    written = read_csv(f"{folder}/trajectory.csv")
    lead = math.radians(lead_deg)
    live = written.contact & (written.pass_index >= 0)
    z_tool, x_tool = written.tool_z(), written.tool_x()
    passes = []
    for k in np.unique(written.pass_index[live]):
        idx = np.flatnonzero(live & (written.pass_index == k))
        keep = np.concatenate([[True], np.linalg.norm(np.diff(written.position[idx], axis=0), axis=1) > 1e-6])
        idx = idx[keep]
        near = surface.normals[surface.kdtree.query(written.position[idx])[1]]
        # the normal is the tool axis turned back by the lead, one way or the other
        options = [-(math.cos(lead) * z_tool[idx] + s * math.sin(lead) * x_tool[idx]) for s in (1.0, -1.0)]
        normal = max(options, key=lambda n: float(np.sum(n * near)))
        passes.append(Pass(written.position[idx], normal / np.linalg.norm(normal, axis=1, keepdims=True), level=int(k)))
    return settings, surface, tool, ToolPath(surface, passes, "rebuilt", {}), lead


def run(settings, surface, tool, toolpath, lead, constraints=None):
    from swath.simulate import simulate_removal
    from swath.trajectory import time_path

    trajectory = time_path(toolpath, constraints or settings.constraints(), links=settings.links(), lead_angle=lead)
    removal = simulate_removal(trajectory, surface, tool, sample_spacing=settings.sample_spacing,
                               sampling=settings.removal_sampling)
    return trajectory, removal


def report(name, tool, trajectory, removal, spacing):
    from swath.simulate.edge_band import band_causes

    m = removal.metrics
    c = band_causes(removal, trajectory, tool, spacing=spacing)
    print(f"{name:10s} interior CoV {m['interior_removal_cov']:.4f}, coverage {100 * m['coverage_fraction']:.2f} %, "
          f"cycle {trajectory.duration:.0f} s; band / core {c['band_mean_over_core_mean_ratio']:.3f}, band own CoV "
          f"{c['band_own_cov']:.3f}, core CoV {c['core_cov']:.3f}, excess {100 * c['band_excess_variance_fraction']:+.0f} pt, "
          f"side band / core {c['band_side_mean_over_core_mean_ratio']:.3f}")
    inner = removal.surface.farther_from_boundary(tool.pad_radius)
    a, z = removal.surface.vertex_areas, removal.depth
    mean = float(np.average(z[inner], weights=a[inner]))
    strip = z[~inner] / mean
    print(f"{'':10s} within R of the edge: depth / interior mean p99.9 {np.percentile(strip, 99.9):.2f}, "
          f"largest {strip.max():.2f}")


def band_feed(settings, surface, tool, toolpath, lead, spacing, cap=0.03):
    """The band-deficit feed (module notes): ``(trajectory, removal)``."""
    import scipy.sparse as sp
    from scipy.optimize import linprog

    from swath.feed.kernel import build_kernel, trajectory_node_dwell
    from swath.feed.timed import dwell_to_profile

    constant, _ = run(settings, surface, tool, toolpath, lead)
    kernel = build_kernel(toolpath, tool, trajectory=constant)
    t0 = trajectory_node_dwell(constant, kernel.nodes, toolpath)
    z0 = kernel.removal(t0)
    samples, a = kernel.samples, kernel.samples.vertex_areas
    inner = samples.farther_from_boundary(tool.pad_radius)
    core = samples.farther_from_boundary(tool.pad_radius + spacing) & inner
    band = np.flatnonzero(inner & ~core)
    matrix = kernel.matrix.tocsr()
    nodes = np.unique(matrix[band].indices)                     # the nodes that reach the band
    sub = matrix.tocsc()[:, nodes].tocsr()
    capped = np.setdiff1d(np.unique(sub.nonzero()[0]), band)
    capped = capped[inner[capped]]
    rest = z0 - sub @ t0[nodes]                                 # what the other nodes remove
    mu_c = float(np.average(z0[core], weights=a[core]))
    n, nb = len(nodes), len(band)
    kb = sub[band]
    a_ub = sp.vstack([sp.hstack([kb, -sp.eye(nb)]), sp.hstack([-kb, -sp.eye(nb)]),
                      sp.hstack([sub[capped], sp.csr_matrix((len(capped), nb))])]).tocsc()
    b_ub = np.concatenate([mu_c - rest[band], rest[band] - mu_c,
                           np.maximum(z0[capped], mu_c) * (1 + cap) - rest[capped]])
    cost = np.concatenate([np.zeros(n), a[band] / a[band].sum()])
    bounds = [(t, 1.5 * t) for t in t0[nodes]] + [(0, None)] * nb
    solved = linprog(cost * 1e6, A_ub=a_ub * 1e6, b_ub=b_ub * 1e6, bounds=bounds, method="highs")
    dwell = t0.copy()
    dwell[nodes] = solved.x[:n]
    profile = dwell_to_profile(toolpath, kernel.nodes, dwell)
    return run(settings, surface, tool, toolpath, lead, [*settings.constraints(), profile])


def _boundary(surface, loop, step):
    from swath.surface.polyline import densify

    ring = np.append(loop, loop[0])
    points, source = densify(surface.vertices[ring], step)
    i = np.minimum(np.floor(source).astype(int), len(ring) - 2)
    f = (source - i)[:, None]
    normals = (1 - f) * surface.normals[ring[i]] + f * surface.normals[ring[i + 1]]
    return points[:-1], (normals / np.linalg.norm(normals, axis=1, keepdims=True))[:-1]


def _runs(gap, arc, total, widen):
    """Index runs (in order round a closed loop) over the ``gap`` points, widened by ``widen`` m."""
    if not gap.any():
        return []
    if gap.all():
        return [np.arange(len(gap))]
    shift = int(np.flatnonzero(~gap)[0])
    order = (np.arange(len(gap)) + shift) % len(gap)
    s, g = (arc[order] - arc[shift]) % total, gap[order]
    edges = np.flatnonzero(np.diff(np.concatenate([[0], g.astype(np.int8), [0]])))
    merged: list[list[float]] = []
    for lo, hi in ([s[i] - widen, s[j - 1] + widen] for i, j in zip(edges[::2], edges[1::2])):
        if merged and lo <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], hi)
        else:
            merged.append([lo, hi])
    if len(merged) > 1 and merged[-1][1] - total >= merged[0][0]:
        merged[0][0] = merged.pop()[0] - total
    runs = []
    for lo, hi in merged:
        along = (s - lo) % total
        pick = np.flatnonzero(along <= hi - lo)
        runs.append(order[pick[np.argsort(along[pick])]])
    return runs


def edge_pass(settings, surface, tool, toolpath, lead, step=1e-3):
    """The plan with the edge passes (module notes): ``(trajectory, removal)``."""
    from scipy.spatial import cKDTree

    from swath.core import Pass

    R = tool.pad_radius
    tree = cKDTree(np.vstack([p.points for p in toolpath.passes]))
    added, beyond, total_points = [], 0, 0
    for loop in surface.boundary_loops:
        points, normals = _boundary(surface, loop, step)
        gap = tree.query(points)[0] > R
        beyond, total_points = beyond + int(gap.sum()), total_points + len(gap)
        seg = np.linalg.norm(np.diff(points, axis=0, append=points[:1]), axis=1)
        arc = np.concatenate([[0.0], np.cumsum(seg[:-1])])
        for run_ in _runs(gap, arc, float(seg.sum()), 0.5 * R):
            if np.linalg.norm(np.diff(points[run_], axis=0), axis=1).sum() >= 0.25 * R:
                added.append(Pass(points[run_], normals[run_], level=10_000 + len(added), kind="touch_up"))
    length = sum(float(np.linalg.norm(np.diff(p.points, axis=0), axis=1).sum()) for p in added)
    print(f"{'':10s} boundary beyond R of every pass: {100 * beyond / max(total_points, 1):.1f} %; "
          f"{len(added)} edge passes, {length:.2f} m")
    return run(settings, surface, tool, toolpath.replace(passes=[*toolpath.passes, *added]), lead)


def main(argv: list[str]) -> None:
    from swath.simulate.ripple import pass_period

    if len(argv) != 4 or argv[0] not in ("band-feed", "edge-pass"):
        raise SystemExit("usage: bench_edge_treatments.py band-feed|edge-pass PART DIR LEAD_DEG")
    which, part, folder, lead_deg = argv[0], argv[1], argv[2], float(argv[3])
    settings, surface, tool, toolpath, lead = load(part, folder, lead_deg)
    trajectory, removal = run(settings, surface, tool, toolpath, lead)
    spacing = pass_period(trajectory)
    report("as written", tool, trajectory, removal, spacing)
    if which == "band-feed":
        treated = band_feed(settings, surface, tool, toolpath, lead, spacing)
    else:
        treated = edge_pass(settings, surface, tool, toolpath, lead)
    report(which, tool, *treated, spacing)


if __name__ == "__main__":
    main(sys.argv[1:])
