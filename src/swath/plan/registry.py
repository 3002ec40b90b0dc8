"""The planner table: every planner by name, and the options each one takes.

A planner is a function ``planner(surface, tool, *, ...) -> ToolPath`` whose keyword-only options
default to None for "choose automatically".  A new planner plugs in by adding one entry here.
"""

from __future__ import annotations

import inspect

from ..errors import InputError
from .equidistant import equidistant
from .raster import raster
from .uniform import uniform
from .wrap import wrap

#: Planner name -> planner function.
PLANNERS = {
    "raster": raster,
    "uniform": uniform,
    "equidistant": equidistant,
    "wrap": wrap,
}


def get_planner(name: str):
    """The planner function called ``name``; :class:`InputError` listing the known ones otherwise."""
    try:
        return PLANNERS[name]
    except KeyError:
        raise InputError(f"unknown planner {name!r}; choose one of {', '.join(PLANNERS)}") from None


def planner_options(name: str) -> set[str]:
    """Names of the keyword options planner ``name`` takes."""
    params = inspect.signature(get_planner(name)).parameters.values()
    return {p.name for p in params if p.kind is inspect.Parameter.KEYWORD_ONLY}


def planners_taking(option: str) -> list[str]:
    """Names of the planners that take ``option``."""
    return [name for name in PLANNERS if option in planner_options(name)]
