"""The ``surface`` stage: a triangulated part surface and its derived geometry.

:class:`Surface` is an immutable record (vertices, faces, name) with cached derived arrays
(normals, areas, boundary loops, principal curvatures) computed on first use by the pure
functions in :mod:`swath.surface.geometry` and :mod:`swath.surface.curvature`.
"""

from .surface import Surface
from .curvature import PrincipalCurvature, principal_curvatures

__all__ = ["Surface", "PrincipalCurvature", "principal_curvatures"]
