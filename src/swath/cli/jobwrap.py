"""Small wrappers the job (:mod:`swath.cli.job`) puts around its stages: a planner timed call by
call, the plan's figures taken into ``metrics.json``, the feed figures drawn beside the report put
back in their place."""

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


def plan_figures(metadata: dict, taken) -> dict:
    """The figures of a plan's ``metadata`` that go into the job's ``metrics.json``, leaving out
    the names in ``taken``: the even default's comparison of raster and equidistant passes
    (:data:`swath.cli.even_spacing.FIGURES`) and every other number whose name ends in a unit
    (``_m``, ``_rad``, ``_s``).  Numbers as floats; a flag (``equidistant_kept``) stays true or
    false, as the job's other ``..._kept`` flags are, since a number of no unit would be a
    figure without one (W-METRIC-UNIT)."""
    from .even_spacing import FIGURES

    return {k: v if isinstance(v, bool) else float(v) for k, v in metadata.items()
            if isinstance(v, (int, float)) and k not in taken
            and (k in FIGURES or not isinstance(v, bool) and k.endswith(("_m", "_rad", "_s")))}
