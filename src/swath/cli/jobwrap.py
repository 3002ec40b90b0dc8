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


#: The module of the kernels every plan job runs (the removal simulation's): when numba's disk cache
#: holds none of them, this is the first run after installing or upgrading swath.
SIMULATION_KERNELS = "swath.contact.kernels"

#: About how many seconds more a job takes while numba compiles the kernels it uses (a fresh
#: install of swath 0.2.0 on the 2-CPU reference machine: `swath demo` 27 s against 14 s the next
#: time, `swath plan example:plate` 8.6-14 s against 5.5-6 s).
FIRST_RUN_EXTRA_S = 15
FIRST_RUN_STAGE = "compiling swath's kernels as they are first used"


def first_run_notice(say) -> bool:
    """Tell ``say(stage, done, total)`` (once, before the job's first stage) when numba's disk cache
    holds none of the removal simulation's kernels, which every plan job runs: numba compiles each
    kernel on its first use, so this run takes up to :data:`FIRST_RUN_EXTRA_S` s longer than the
    stages' estimates say (the first run after installing or upgrading; the next ones load them).
    True when said."""
    import importlib
    import logging

    importlib.import_module(SIMULATION_KERNELS)
    from ..surface import cells

    ours = cells.kernels_of(SIMULATION_KERNELS)
    cold = cells.kernels_to_compile(SIMULATION_KERNELS)
    if not ours or len(cold) < len(ours):
        return False
    logging.getLogger(__name__).info("numba's cache holds none of the %d simulation kernels: compiling them", len(ours))
    if not any(cells.disk_cached(k) for k in ours):
        # no writable cache directory (swath.surface.cells.jit compiled them without one): every run
        say(f"{FIRST_RUN_STAGE} (up to about {FIRST_RUN_EXTRA_S} s more at every run: numba has no writable "
            "cache directory; set NUMBA_CACHE_DIR to one)", 0, 1)
    else:
        say(f"{FIRST_RUN_STAGE} (this run only: up to about {FIRST_RUN_EXTRA_S} s more)", 0, 1)
    return True
