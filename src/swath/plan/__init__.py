"""The ``plan`` stage: planners that cover a surface with passes, each returning a ToolPath.

Every planner has the call shape ``planner(surface, tool, *, ...) -> ToolPath`` and is listed in
:data:`PLANNERS` (:mod:`.registry`); its passes carry their ``level`` and ``region`` and the
``order`` stage sequences them.

* :func:`raster` — the baseline: parallel plane slices (noether's plane slicer).
* :func:`uniform` — contact-aware uniform coverage (Jaeger ch. 4).
* :func:`equidistant` — geodesic-parallel passes on meshes, arc-length-equidistant passes on
  B-spline patches (:func:`equidistant_patch`; Amersdorfer & Meurer).
"""

from ..core import Pass, ToolPath
from .arclength import equidistant_patch
from .equidistant import equidistant
from .raster import raster
from .registry import PLANNERS, get_planner, planner_options, planners_taking
from .slicing import resample, slice_mesh
from .uniform import uniform
from .wrap import wrap

__all__ = ["PLANNERS", "Pass", "ToolPath", "equidistant", "equidistant_patch", "get_planner", "planner_options",
           "planners_taking", "raster", "resample", "slice_mesh", "uniform", "wrap"]
