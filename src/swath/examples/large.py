"""A large generated part for scale benchmarks: a smooth doubly curved panel with any face count.

:func:`large_panel` makes a 1.2 m x 0.8 m panel (an aircraft-skin-like crown with a gentle
swell) triangulated on a structured grid, 500k faces by default.  The same call with a smaller
``n_faces`` gives the same shape at coarser resolution, so plan times can be compared across
resolutions on one geometry.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..surface import Surface
from ..surface.grid import grid_faces


def large_panel(*, n_faces: int = 500_000, size_x: float = 1.2, size_y: float = 0.8, radius_x: float = 1.5,
                radius_y: float = 4.0, swell: float = 0.01) -> Surface:
    """A smooth doubly curved panel ``z = f(x, y)`` centred at the origin, normals +z (m).

    The crown is the product of two circular arcs (radius ``radius_x`` across x, ``radius_y``
    across y) plus a swell ``swell * cos(pi x / size_x) * cos(pi y / size_y)``, one smooth bump
    over the whole panel, so both principal curvatures vary over the part and stay well below
    1 / pad radius.

    Parameters
    ----------
    n_faces : int
        Target number of triangles (the grid keeps cells nearly square; the count is within
        1 % of the target above 10k faces).
    size_x, size_y : float
        Extent of the panel along x and y, m (default 1.2 m x 0.8 m).
    radius_x, radius_y : float
        Crown radii of curvature across x and across y, m; each must exceed half its extent.
    swell : float
        Height of the central swell, m (default 10 mm).

    Returns
    -------
    Surface
        ``n_u * n_v`` vertices, ``2 (n_u - 1)(n_v - 1)`` faces, named ``panel_{n_faces // 1000}k``.
    """
    if not (n_faces >= 2 and size_x > 0 and size_y > 0):
        raise InputError(f"large_panel needs n_faces >= 2 and positive sizes; got n_faces={n_faces}, "
                         f"size {size_x} m x {size_y} m")
    if not (radius_x > size_x / 2 and radius_y > size_y / 2):
        raise InputError(f"large_panel needs radius_x > size_x / 2 and radius_y > size_y / 2; got radii "
                         f"{radius_x} m, {radius_y} m for size {size_x} m x {size_y} m")
    # 2 (n_u - 1)(n_v - 1) = n_faces with square cells: (n_u - 1) / (n_v - 1) = size_x / size_y.
    cells_v = max(round(np.sqrt(n_faces / 2.0 * size_y / size_x)), 1)
    cells_u = max(round(n_faces / 2.0 / cells_v), 1)
    xs = np.linspace(-size_x / 2, size_x / 2, cells_u + 1)
    ys = np.linspace(-size_y / 2, size_y / 2, cells_v + 1)
    x, y = np.meshgrid(xs, ys, indexing="ij")
    z = (np.sqrt(radius_x**2 - x**2) - radius_x) + (np.sqrt(radius_y**2 - y**2) - radius_y)
    z += swell * np.cos(np.pi * x / size_x) * np.cos(np.pi * y / size_y)
    vertices = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    return Surface(vertices, grid_faces(len(xs), len(ys)), name=f"panel_{n_faces // 1000}k")
