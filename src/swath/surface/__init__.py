"""The ``surface`` stage: a triangulated part surface and its derived geometry.

:class:`Surface` is an immutable record (vertices, faces, name) with cached derived arrays
(normals, areas, boundary loops, principal curvatures) computed on first use by the pure
functions in :mod:`swath.surface.geometry` and :mod:`swath.surface.curvature`.

Smooth parts come as :class:`BSplinePatch` (exact derivatives and curvature; ``to_surface`` for
a triangulation), fitted to scans by :func:`fit_patch`; a nominal CAD surface is placed on a scan
by :func:`register_rigid` or :func:`register_on_table`, which return a :class:`Registration`.
"""

from .bspline import BSplinePatch
from .curvature import PrincipalCurvature, principal_curvatures
from .fit import FitReport, fit_patch
from .register import Registration, register_on_table, register_rigid
from .surface import Surface

__all__ = ["Surface", "PrincipalCurvature", "principal_curvatures", "BSplinePatch", "FitReport", "fit_patch",
           "Registration", "register_on_table", "register_rigid"]
