"""How many threads or processes swath's own parallel work may use."""

from __future__ import annotations

import os


def usable_cpus() -> int:
    """CPUs this process may use: ``OMP_NUM_THREADS`` when set to a positive integer (Ray sets it
    to a task's CPU share, so a batch job on one CPU does not start threads or workers of its own),
    else the CPUs the process is allowed to run on."""
    text = os.environ.get("OMP_NUM_THREADS", "").strip()
    if text.isdigit() and int(text) > 0:
        return int(text)
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:                      # not on Linux
        return max(1, os.cpu_count() or 1)
