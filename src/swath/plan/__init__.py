"""The ``plan`` stage: planners that cover a surface with passes, each returning a ToolPath.

Every planner has the call shape ``planner(surface, tool, **options) -> ToolPath``.

* :func:`raster` — the baseline: parallel plane slices, snake-ordered (noether's plane slicer).
* :func:`uniform` — contact-aware uniform coverage (Jaeger ch. 4).
* :func:`equidistant` — geodesic-parallel passes on meshes, arc-length-equidistant passes on
  B-spline patches (:func:`equidistant_patch`; Amersdorfer & Meurer).
"""

from .arclength import equidistant_patch
from .equidistant import equidistant
from .raster import raster
from .slicing import resample, slice_mesh
from .toolpath import Pass, ToolPath
from .uniform import uniform
from .widths import max_swath_widths, raster_spacing, swath_widths

__all__ = ["Pass", "ToolPath", "equidistant", "equidistant_patch", "raster", "uniform", "resample", "slice_mesh", "max_swath_widths", "raster_spacing",
           "swath_widths"]
