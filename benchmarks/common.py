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
