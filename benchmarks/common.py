"""Shared helpers for the benchmark scripts: the parts, timing and memory measurement, tables."""

from __future__ import annotations

import resource
import sys
import time
import tracemalloc
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))
sys.path.insert(0, str(REPO / "tests"))

# The shared meshes and the unit each is read in: one table, kept with the tests.
from conftest import SHARED_MESH_UNITS, SHARED_MESHES  # noqa: E402


def parts(include_shared: bool = True):
    """Yield (name, Surface) for the built-in parts and every shared mesh found."""
    from swath.examples import PARTS
    from swath.io.mesh import load_mesh

    for name, make in PARTS.items():
        yield f"example:{name}", make()
    if include_shared:
        for file, units in SHARED_MESH_UNITS.items():
            path = SHARED_MESHES / file
            if path.exists():
                yield file, load_mesh(path, units=units)


class Measure:
    """Context manager: wall time (s) and peak traced Python memory (MB) of a block."""

    def __enter__(self):
        tracemalloc.start()
        self.t0 = time.perf_counter()
        return self

    def __exit__(self, *exc):
        self.seconds = time.perf_counter() - self.t0
        self.peak_mb = tracemalloc.get_traced_memory()[1] / 1e6
        tracemalloc.stop()


def max_rss_mb() -> float:
    """Peak resident memory of this process so far, MB."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def print_table(rows: list[dict], columns: list[tuple[str, str]]) -> None:
    """Print ``rows`` as a fixed-width table; ``columns`` are (key, format) pairs."""
    heads = [k for k, _ in columns]
    cells = [[format(r[k], f) if isinstance(r.get(k), (int, float)) else str(r.get(k, "")) for k, f in columns] for r in rows]
    widths = [max(len(h), *(len(c[i]) for c in cells)) if cells else len(h) for i, h in enumerate(heads)]
    print("  ".join(h.rjust(w) for h, w in zip(heads, widths)))
    for c in cells:
        print("  ".join(v.rjust(w) for v, w in zip(c, widths)))


def rows_per_part(script: str, names: list[str], columns: list[tuple[str, str]], extra_args=()) -> list[dict]:
    """Run ``script --one NAME *extra_args`` for every part name in its own process (so each part's
    peak memory is its own), collect the rows it prints after ``ROWS `` (JSON), print each part's
    table as it comes and all of them at the end; a part whose process fails gets a ``FAILED`` row
    naming the error's last line."""
    import json
    import subprocess

    rows: list[dict] = []
    for name in names:
        proc = subprocess.run([sys.executable, script, "--one", name, *extra_args], capture_output=True, text=True,
                              cwd=REPO, timeout=3600)
        line = next((ln for ln in proc.stdout.splitlines() if ln.startswith("ROWS ")), None)
        if line is None:
            rows.append({"part": name, "run": "FAILED: " + (proc.stderr.strip().splitlines() or ["?"])[-1][:100]})
        else:
            rows.extend(json.loads(line[5:]))
        print_table([r for r in rows if r.get("part") == name], columns)
        sys.stdout.flush()
    print()
    print_table(rows, columns)
    return rows
