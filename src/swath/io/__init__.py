"""The ``io`` stage: read part meshes and point clouds, write surfaces, units at the edge.

- :func:`load_mesh` reads STL/PLY/OBJ into a :class:`~swath.surface.Surface` in metres, refusing
  or repairing (with a logged warning) what a file can get wrong.
- :func:`load_points` reads point clouds (XYZ/TXT/CSV, PLY, PCD) for surface fitting.
- :func:`save_surface_ply` writes a surface with its normals, atomically.
- :mod:`swath.io.atomic` writes files and directories so nothing half-written is left behind.

Everything is logged on the ``swath.io`` logger.
"""

from .atomic import atomic_directory, atomic_file, write_text_atomic
from .mesh import MESH_EXTENSIONS, likely_unit, load_mesh, parse_side, save_surface_ply
from .points import POINT_EXTENSIONS, load_points

__all__ = [
    "load_mesh", "load_points", "save_surface_ply", "parse_side", "likely_unit",
    "MESH_EXTENSIONS", "POINT_EXTENSIONS",
    "atomic_file", "write_text_atomic", "atomic_directory",
]
