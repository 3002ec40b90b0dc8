"""The ``plan`` stage: planners that cover a surface with passes, each returning a ToolPath.

Every planner has the call shape ``planner(surface, tool, **options) -> ToolPath``.

* :func:`raster` — the baseline: parallel plane slices, snake-ordered (noether's plane slicer).
"""

from .raster import raster
from .slicing import resample, slice_mesh
from .toolpath import Pass, ToolPath
from .widths import max_swath_widths, raster_spacing, swath_widths

__all__ = ["Pass", "ToolPath", "raster", "resample", "slice_mesh", "max_swath_widths", "raster_spacing",
           "swath_widths"]
