"""The ``surface`` stage: a triangulated part surface and its derived geometry.

:class:`Surface` is an immutable record (vertices, faces, name) with cached derived arrays
(normals, areas, boundary loops, principal curvatures) computed on first use by the pure
functions in :mod:`swath.surface.geometry` and :mod:`swath.surface.curvature`.

Smooth parts come as :class:`BSplinePatch` (exact derivatives and curvature; ``to_surface`` for
a triangulation).  Fitting patches to scans and registering a CAD surface on a scan are the
:mod:`swath.scan` stage's.
"""

from .bspline import BSplinePatch
from .curvature import PrincipalCurvature, principal_curvatures
from .surface import Surface

__all__ = ["Surface", "PrincipalCurvature", "principal_curvatures", "BSplinePatch"]
