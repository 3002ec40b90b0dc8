"""The ``order`` stage: sequence a planner's passes (and choose their directions) to waste least
air travel.  Every planner's output goes through :func:`order_toolpath`.

Methods are registered in :data:`ORDER_METHODS` (name -> function ``f(toolpath) -> ToolPath``).
"""

from __future__ import annotations

from ..core import ToolPath
from ..errors import InputError
from . import sequence

#: Order methods by name; each maps a ToolPath to a re-sequenced ToolPath.
ORDER_METHODS = {
    "snake": sequence.snake,
    "zigzag": sequence.zigzag,
    "greedy": sequence.greedy,
    "index": sequence.index,
}


def order_toolpath(toolpath: ToolPath, *, method: str | None = None) -> ToolPath:
    """Re-sequence ``toolpath``'s passes with the named method (see :mod:`.sequence`); None: the
    planner's ``metadata["order_hint"]`` (raster and equidistant: ``snake``, uniform: ``zigzag``).

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
    return fn(toolpath)


__all__ = ["ORDER_METHODS", "order_toolpath", "sequence"]
