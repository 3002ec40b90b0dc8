"""The default job's plan stage, split as the job reports it: the spacing search and the plan kept.

    PYTHONPATH=src python benchmarks/bench_plan_stage.py                      # every shared mesh
    PYTHONPATH=src python benchmarks/bench_plan_stage.py crs_part_5.stl       # some

Each part runs in a fresh process (``--one PART``): the part is loaded as the job loads it, the
default job's settings resolved and ``make_plan`` run as ``run_job`` runs it, twice (cold, then warm
on the part loaded again), the raster planner's calls and the order stage timed apart on the CPU
clock; then the raster planner alone at its default spacing (``make_plan`` with the plain
settings), warm.  Printed per part (CPU s): ``plan`` (the plan kept and its order, the job's
``plan_s``), ``spacing`` (the search, the job's ``spacing_s``), their warm figures, the planner alone,
and the first 12 hex digits of the SHA-256 of the ordered plans' points and normals (equal hashes:
the same plan to the bit).
"""

from __future__ import annotations

import functools
import json
import subprocess
import sys
import time

from common import REPO, SHARED_MESH_UNITS, SHARED_MESHES


def _one(part: str) -> dict:
    import swath.order as order
    import swath.plan.registry as registry
    from run_all import plan_hash
    from swath.cli import even_default, stages
    from swath.cli.job import JobSettings, load_part_info, make_plan

    clock = time.process_time
    calls: list[float] = []
    ordering: list[float] = []

    def timed(fn, into):
        @functools.wraps(fn)
        def run(*args, **kwargs):
            t0 = clock()
            try:
                return fn(*args, **kwargs)
            finally:
                into.append(clock() - t0)
        return run

    registry.PLANNERS["raster"] = timed(registry.PLANNERS["raster"], calls)
    for name in ("order_toolpath", "route_links"):         # make_plan imports them from swath.order
        setattr(order, name, timed(getattr(order, name), ordering))

    def job_plan() -> dict:
        settings = JobSettings(part=str(SHARED_MESHES / part), out="unused", units=SHARED_MESH_UNITS[part])
        plain = even_default.plain_alternative(settings)
        settings = even_default.resolve(settings)
        tool = stages.job_tool(settings)
        surface, info = load_part_info(settings)
        calls.clear()
        ordering.clear()
        t0 = clock()
        toolpath = make_plan(surface, settings, tool=tool, part=info.get("part"), choose_lead=plain is not None)
        total = clock() - t0
        kept = calls[-1] + sum(ordering)
        return {"plan": kept, "spacing": total - kept, "plans": len(calls), "passes": len(toolpath.passes),
                "hash": plan_hash(toolpath)}

    row = {"part": part, "cold": job_plan(), "warm": job_plan()}
    settings = JobSettings(part=str(SHARED_MESHES / part), out="unused", units=SHARED_MESH_UNITS[part])
    surface, _ = load_part_info(settings)
    row["faces"] = len(surface.faces)
    t0 = clock()
    alone = make_plan(surface, settings)
    row["alone"] = clock() - t0
    row["alone_hash"] = plan_hash(alone)
    return row


def main() -> int:
    if len(sys.argv) == 3 and sys.argv[1] == "--one":
        print("ROW " + json.dumps(_one(sys.argv[2])), flush=True)
        return 0
    parts = sys.argv[1:] or [p for p in SHARED_MESH_UNITS if (SHARED_MESHES / p).exists()]
    print("| part | faces | passes | plans | plan_s cold | spacing_s cold | plan_s warm | spacing_s warm "
          "| planner alone warm | plan hash | alone hash |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for part in parts:
        done = subprocess.run([sys.executable, __file__, "--one", part], capture_output=True, text=True, cwd=REPO)
        line = next((ln for ln in done.stdout.splitlines() if ln.startswith("ROW ")), None)
        if line is None:
            print(f"| {part} | FAILED: {(done.stderr.strip().splitlines() or ['no output'])[-1][:120]} |")
            continue
        r = json.loads(line[4:])
        c, w = r["cold"], r["warm"]
        print(f"| {part} | {r['faces']} | {c['passes']} | {c['plans']} | {c['plan']:.2f} | {c['spacing']:.2f} "
              f"| {w['plan']:.2f} | {w['spacing']:.2f} | {r['alone']:.2f} | {c['hash']} | {r['alone_hash']} |",
              flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
