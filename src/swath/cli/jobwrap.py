"""Small wrappers the job (:mod:`swath.cli.job`) puts around its stages: a planner timed call by
call, the feed figures drawn beside the report put back in their place."""

from __future__ import annotations

import functools
import time


def timed(planner, calls: list):
    """``planner``, appending the time (s) each call takes to ``calls``."""
    @functools.wraps(planner)
    def run(*args, **kwargs):
        t0 = time.perf_counter()
        try:
            return planner(*args, **kwargs)
        finally:
            calls.append(time.perf_counter() - t0)
    return run


#: Where the feed figures, drawn beside the report, go among the job's figures.
FEED_PLOTS = "<feed plots>"


def in_place(figures: dict, drawn) -> dict:
    """``figures`` with the entry :data:`FEED_PLOTS` replaced, in place, by the figures ``drawn()`` returns."""
    out: dict = {}
    for name, path in figures.items():
        out.update(drawn() if name == FEED_PLOTS else {name: path})
    return out

