"""The ``order`` stage: sequence a planner's passes — the visiting order and each pass group's
path type — to waste least air travel (Wang §4).  Every planner's output goes through
:func:`order_toolpath`.

Methods (:data:`ORDER_METHODS`, name -> function ``f(toolpath) -> ToolPath``):

``snake``, ``zigzag``, ``index``
    the planner's levels in boustrophedon order, its order with each pass started at the nearer
    end, or its order unchanged (:mod:`.sequence`);
``greedy``, ``gtsp``, ``exact``
    pass groups (a segmented part's regions, else single passes) visited nearest-entry first, as a
    generalised TSP (Noon–Bean transform + LKH), or exactly (Held–Karp, small instances)
    (:mod:`.tour`); inside a region the passes keep their snake order.

With ``join_gap`` (m) the tour methods make short step-overs in contact where the pad can slide
along the part, and join the passes they connect (:mod:`.joining`; Wang's continuous local paths).

The tour methods cost links as the trajectory stage flies them: by air length along the route
:class:`AirGuard` gives them (a tour is solved again when one of its links must climb over the
part), or with ``link_speed`` by time (rounded, toppra-timed links in closed form; contact
step-overs at the ``feed``).  :func:`route_links` then gives every move between passes its air
route (:mod:`.routing`).
"""

from __future__ import annotations

from ..core import ToolPath
from ..errors import InputError
from . import sequence, stage
from .joining import StepOverJoiner, join_passes
from .routing import AirGuard, route_links


def _tour(method: str, *, snake_regions: bool = True):
    def run(toolpath: ToolPath, **options) -> ToolPath:
        grouped = snake_regions and "groups" not in options and len(set(toolpath.regions.tolist())) > 1 \
            and toolpath.metadata.get("order_method") != "snake"          # snake twice undoes it
        base = sequence.snake(toolpath) if grouped else toolpath
        return stage.order_toolpath(base, method=method, **options)

    run.__name__ = f"order_{method}"
    return run


#: Order methods by name; each maps a ToolPath to a re-sequenced ToolPath.
ORDER_METHODS = {
    "snake": sequence.snake,
    "zigzag": sequence.zigzag,
    "index": _tour("index", snake_regions=False),
    "greedy": _tour("greedy"),
    "gtsp": _tour("gtsp"),
    "exact": _tour("exact"),
}


def order_toolpath(toolpath: ToolPath, *, method: str | None = None, **options) -> ToolPath:
    """Re-sequence ``toolpath``'s passes with the named method; None: the planner's
    ``metadata["order_hint"]`` (raster and equidistant: ``snake``, uniform: ``zigzag``).
    ``options`` go to the tour methods (``start``, ``clearance``, ``link_speed``, ``omega_max``,
    ``feed``, ``join_gap``, ``keep_direction``, ``routed``, ``pad_radius``, ...; see
    :func:`swath.order.stage.order_toolpath`).

    Raises
    ------
    InputError
        On an unknown method.
    """
    if method is None:
        method = toolpath.metadata.get("order_hint", "snake")
    try:
        fn = ORDER_METHODS[method]
    except KeyError:
        raise InputError(f"unknown order method {method!r}; choose one of {', '.join(ORDER_METHODS)}") from None
    if options and fn in (sequence.snake, sequence.zigzag):
        raise InputError(f"the {method} order takes no options (got {', '.join(sorted(options))}); the tour "
                         "methods (greedy, gtsp, exact, index) do")
    return fn(toolpath, **options)


__all__ = ["AirGuard", "ORDER_METHODS", "StepOverJoiner", "join_passes", "order_toolpath", "route_links", "sequence",
           "tour"]
