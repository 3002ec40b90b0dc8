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


def large_blade(*, n_faces: int = 5_000_000, length: float = 20.0, root_chord: float = 1.0,
                max_chord: float = 1.6, tip_chord: float = 0.35, twist: float = np.deg2rad(14.0),
                first: float = 0.1, last: float = 0.95) -> Surface:
    """The upper (suction) skin of a wind-turbine-blade-like part: airfoil sections along a span (m).

    The span runs along +x from 0 to ``length``; each section at span fraction ``r = x / length``
    is the upper surface of a cambered NACA-like profile (2 % camber at 40 % chord) of chord
    ``c(r)`` and relative thickness ``t(r)``, from ``first`` to ``last`` of the chord (the nose
    and the thin trailing edge left out), laid along +y and turned by the twist ``θ(r)`` about
    the quarter-chord line.  The chord rises as a sine arc from ``root_chord`` to ``max_chord``
    at ``r = 0.2`` and falls linearly to ``tip_chord`` at the tip; ``t(r) = 0.18 + 0.12 (1 −
    r)³``; ``θ(r) = twist · (1 − r)²``.  The skin is one structured grid with nearly square
    cells, built vectorised (about 0.1 kB of memory per face), normals toward +z (the tool).

    Parameters
    ----------
    n_faces : int
        Target number of triangles (within 1 % above 10k faces).
    length : float
        Span, m (default 20 m).
    root_chord, max_chord, tip_chord : float
        Chord at the root, at 20 % span and at the tip, m.
    twist : float
        Twist at the root, rad (0 at the tip).
    first, last : float
        Chord fractions where the skin starts and ends, ``0 <= first < last <= 1``.

    Returns
    -------
    Surface
        ``2 (n_u − 1)(n_v − 1)`` faces (``n_u`` sections along the span, ``n_v`` points across the
        chord), named ``blade_{length}m_{n_faces // 1000}k``.
    """
    if not (n_faces >= 2 and length > 0 and min(root_chord, max_chord, tip_chord) > 0 and 0 <= first < last <= 1):
        raise InputError(f"large_blade needs n_faces >= 2, positive length and chords and 0 <= first < last <= 1; "
                         f"got n_faces={n_faces}, length={length} m, chords {root_chord}/{max_chord}/{tip_chord} m, "
                         f"chord range {first}..{last}")
    # Square cells: n_u / n_v = span / mean arc across the chord (about the mean chord's span).
    mean_width = (last - first) * 0.5 * (max_chord + tip_chord) * 1.05
    cells_v = max(round(np.sqrt(n_faces / 2.0 * mean_width / length)), 1)
    cells_u = max(round(n_faces / 2.0 / cells_v), 1)
    r = np.linspace(0.0, 1.0, cells_u + 1)
    chord = np.where(r < 0.2, root_chord + (max_chord - root_chord) * np.sin(0.5 * np.pi * r / 0.2),
                     max_chord + (tip_chord - max_chord) * (r - 0.2) / 0.8)
    thick = 0.18 + 0.12 * (1.0 - r) ** 3
    theta = twist * (1.0 - r) ** 2
    s = np.linspace(first, last, cells_v + 1)        # chord fraction
    # NACA 4-digit half thickness (closed trailing edge) and a 2 % / 40 % camber line.
    half = 5.0 * (0.2969 * np.sqrt(s) - 0.1260 * s - 0.3516 * s**2 + 0.2843 * s**3 - 0.1036 * s**4)
    m, p = 0.02, 0.4
    camber = np.where(s < p, m / p**2 * (2 * p * s - s**2), m / (1 - p) ** 2 * (1 - 2 * p + 2 * p * s - s**2))
    # section coordinates (chord along y from the quarter chord, height along z), (n_u, n_v)
    y = (s[None, :] - 0.25) * chord[:, None]
    z = (camber[None, :] + thick[:, None] * half[None, :]) * chord[:, None]
    cos_t, sin_t = np.cos(theta)[:, None], np.sin(theta)[:, None]
    y, z = cos_t * y - sin_t * z, sin_t * y + cos_t * z
    x = np.broadcast_to((r * length)[:, None], y.shape)
    vertices = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    return Surface(vertices, grid_faces(len(r), len(s)), name=f"blade_{length:g}m_{n_faces // 1000}k")
