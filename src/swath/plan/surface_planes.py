"""Cutting planes equally far apart on the surface, not in projection.

Parallel planes ``x · c = h`` spaced ``Δh`` apart cut a surface into passes that lie ``Δh / |t|``
apart on it, ``t = c − (n · c) n`` being the cross direction ``c`` projected on the tangent plane
(``|t| = √(1 − (n · c)²)``, the rate at which the height ``h`` grows along the surface across the
passes).  On a slope of angle θ across the passes that is ``Δh / cos θ``: 41 % wider at 45°, and a
spacing chosen for its ripple no longer has it.

:func:`surface_distance` measures the mean surface distance across the level curves of ``h``:
between the levels ``h`` and ``h + dh`` lies a band of area ``dA`` whose mean width is ``dA / L(h)``
(``L(h)`` the length of the level curve), so the distance per unit of ``h`` is
``s(h) = A'(h) / L(h)``, the level curve's length-weighted mean of ``1 / |t|``.  By the co-area
formula ``L(h) = Λ'(h)`` with ``Λ(h) = ∫_{x·c < h} |t| dA``; ``A`` and ``Λ`` are summed exactly over
the triangles (the area of a triangle below a level is piecewise quadratic in it) at the edges of
fine bins, and ``S(h) = ∫ s dh`` accumulated over them.  :func:`surface_plane_offsets` then places
the planes at equal steps of ``S``.

On a cylinder of radius ``r`` cut by planes along a direction normal to its axis, ``S`` is the
arc length ``r φ`` and the offsets come out at ``r sin φ_i`` for equal steps of ``φ``; on a plane
``S`` is ``h`` and the offsets are the projected ones.

With ``relative_width`` (the raster's ``spacing_on = "swath"``) the planes sit at equal steps of
``E(h) = ∫ w_ref / w(h) dS`` instead, ``w(h)`` the swath width along the level (:func:`level_widths`):
neighbouring planes then lie ``spacing · w / w_ref`` apart on the surface (the harmonic mean of
``w`` over the step), the ratio of step to width the same everywhere.  A pass removes the same
volume per metre whatever its width (Preston, the force fixed), so at a constant feed the mean
depth then goes as ``1 / step``: the ripple's ratio is kept and the level is left to the feed.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError

#: Floor on ``|t|`` (the sine of the angle between the face normal and the cross direction): a
#: face steeper than this across the passes counts as if it sloped at ``asin`` of it (3.2 times the
#: height step on the surface at most), so a fold or a wall nearly parallel to the planes does not
#: pack the planes without bound.
SLOPE_FLOOR = 0.3

#: Bins per spacing over which ``S(h)`` is accumulated (the ratio ``A' / Λ'`` is read per bin).
BINS_PER_SPACING = 16

#: At most this many bins across a piece.
MAX_BINS = 8192


def surface_distance(heights: np.ndarray, faces: np.ndarray, face_areas: np.ndarray, face_normals: np.ndarray,
                     cross, edges: np.ndarray, *, slope_floor: float = SLOPE_FLOOR) -> np.ndarray:
    """Mean surface distance ``S`` (m) across the level curves of ``h = x · cross`` at the heights
    ``edges``, from ``S(edges[0]) = 0`` (module notes).

    Parameters
    ----------
    heights : (n,) float
        ``x · cross`` of every vertex, m.
    faces : (m, 3) int
        The triangles over which ``S`` is measured (one connected piece).
    face_areas : (m,) float
        Their areas, m².
    face_normals : (m, 3) float
        Their unit normals.
    cross : (3,) float
        Unit normal of the cutting planes.
    edges : (k,) float
        Increasing heights, m, spanning the faces' heights.
    slope_floor : float
        Floor on ``|t|`` per face (:data:`SLOPE_FLOOR`).

    Returns
    -------
    (k,) float
        ``S`` at ``edges``, m, increasing.
    """
    nc = face_normals @ np.asarray(cross, float)
    tlen = np.maximum(np.sqrt(np.clip(1.0 - nc * nc, 0.0, 1.0)), slope_floor)
    below = _cumulative(heights[faces], np.stack([face_areas, face_areas * tlen]), edges)
    d_area, d_length = np.diff(below, axis=1)
    # per bin, the band's area over its length times its height: the mean of 1/|t| along the level
    ratio = np.divide(d_area, d_length, out=np.ones_like(d_area), where=d_length > 1e-300)
    ratio = np.clip(ratio, 1.0, 1.0 / slope_floor)
    return np.concatenate([[0.0], np.cumsum(ratio * np.diff(edges))])


def _cumulative(heights: np.ndarray, weights: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """``Σ_f w_f F_f(e)`` at each of ``edges`` (k,) for each row of ``weights`` (w, m): ``F_f`` the
    share of triangle ``f``'s area below the height ``e`` given its vertex heights ``heights``
    (m, 3), piecewise quadratic in ``e``.  Returns (w, k)."""
    a, b, c = heights[:, 0], heights[:, 1], heights[:, 2]
    h0, h2 = np.minimum(np.minimum(a, b), c), np.maximum(np.maximum(a, b), c)
    h1 = (a + b + c) - h0 - h2
    h1 = np.clip(h1, h0, h2)                                     # the middle height (rounding kept inside)
    k_edges = len(edges)
    full = np.searchsorted(edges, h2, side="left")               # first edge >= h2: wholly below from there
    first = np.searchsorted(edges, h0, side="right")             # first edge above h0
    count = np.maximum(full - first, 0)                          # edges cutting the triangle
    f = np.repeat(np.arange(len(h0)), count)
    k = np.repeat(first - np.cumsum(count) + count, count) + np.arange(int(count.sum()))
    e = edges[k]
    a0, a1, a2 = h0[f], h1[f], h2[f]
    span = a2 - a0
    with np.errstate(divide="ignore", invalid="ignore"):
        share = np.where(e <= a1, (e - a0) ** 2 / (span * (a1 - a0)), 1.0 - (a2 - e) ** 2 / (span * (a2 - a1)))
    share = np.clip(np.nan_to_num(share, nan=0.0, posinf=1.0, neginf=0.0), 0.0, 1.0)
    out = np.empty((len(weights), k_edges))
    for i, w in enumerate(weights):
        whole = np.cumsum(np.bincount(full, weights=w, minlength=k_edges + 1))[:k_edges]
        out[i] = whole + np.bincount(k, weights=w[f] * share, minlength=k_edges)
    return out


def surface_plane_offsets(heights: np.ndarray, faces: np.ndarray, face_areas: np.ndarray,
                          face_normals: np.ndarray, cross, spacing: float, *, edge_margin: float = 0.0,
                          vertex_ids: np.ndarray | None = None, relative_width: tuple | None = None
                          ) -> tuple[np.ndarray, float, np.ndarray, float]:
    """Offsets ``(p,)`` (m, along ``cross``) of planes ``spacing`` apart measured on the surface
    across the passes, centred on the piece.

    The rule of :func:`swath.plan.raster.plane_offsets` applied to the surface distance ``S``
    (:func:`surface_distance`) in place of the height: ``p = ceil(S_total / spacing)``, the same
    margin left at both ends, and when that margin is below ``edge_margin`` the outer planes move
    in to ``min(edge_margin, S_total / (2 p))`` with the ``p`` planes spread evenly (in ``S``)
    between them.

    Parameters
    ----------
    heights : (n,) float
        ``x · cross`` of every vertex, m.
    faces : (m, 3) int
        One connected piece.
    face_areas, face_normals : (m,) float, (m, 3) float
        Its triangles' areas (m²) and unit normals.
    cross : (3,) float
        Unit cutting-plane normal.
    spacing : float
        Distance between neighbouring passes on the surface, m.
    edge_margin : float
        Least surface distance from the piece's extent to its outermost planes, m.
    vertex_ids : (q,) int, optional
        The piece's vertices (``np.unique(faces)``) when the caller has them.
    relative_width : ((g,) float, (g,) float), optional
        Heights ``x · cross`` (m, increasing) and the local swath width there over a reference
        width, ``w(h) / w_ref`` (:func:`level_widths`): the planes are then placed at equal steps
        of ``E(h) = ∫ w_ref / w dS`` instead of ``S``, so that neighbouring planes lie about
        ``spacing · w / w_ref`` apart on the surface, ``spacing`` being the step where the swath
        is ``w_ref`` wide (the raster's ``spacing_on = "swath"``).  ``edge_margin``, ``margin``
        and ``extent`` are then measured in ``E`` (metres at the reference width).

    Returns
    -------
    offsets : (p,) float
        Plane heights ``x · cross``, m, increasing.
    margin : float
        The surface distance left at each end, m (in ``E`` with ``relative_width``).
    steps : (p - 1,) float
        The surface distance between neighbouring planes, m.
    extent : float
        The piece's surface distance across the planes, ``S_total``, m (``E_total`` with
        ``relative_width``).
    """
    from .raster import MAX_PLANES

    piece = heights[np.unique(faces) if vertex_ids is None else vertex_ids]
    lo, hi = float(np.min(piece)), float(np.max(piece))
    extent = hi - lo
    n_bins = int(min(MAX_BINS, max(1, math.ceil(BINS_PER_SPACING * extent / spacing))))
    edges = np.linspace(lo, hi, n_bins + 1)
    s_edges = surface_distance(heights, faces, face_areas, face_normals, cross, edges)
    e_edges = s_edges
    if relative_width is not None:
        grid, ratio = (np.asarray(a, float) for a in relative_width)
        middle = np.interp(0.5 * (edges[1:] + edges[:-1]), grid, ratio)
        e_edges = np.concatenate([[0.0], np.cumsum(np.diff(s_edges) / np.clip(middle, *RATIO_CLIP))])
    total = float(e_edges[-1])
    n = max(int(math.ceil(total / spacing)), 1)
    if n > MAX_PLANES:
        raise InputError(f"spacing {spacing * 1e3:.4g} mm would need {n} cutting planes across "
                         f"{total * 1e3:.1f} mm of surface (limit {MAX_PLANES}); is the spacing in metres?")
    margin = 0.5 * (total - (n - 1) * spacing)
    step = spacing
    if n > 1 and margin < edge_margin:
        margin = min(float(edge_margin), total / (2 * n))
        step = (total - 2 * margin) / (n - 1)
    targets = margin + np.arange(n) * step if n > 1 else np.array([0.5 * total])
    offsets = np.interp(targets, e_edges, edges)
    if relative_width is None:
        return offsets, margin, np.full(n - 1, step), total
    return offsets, margin, np.diff(np.interp(offsets, edges, s_edges)), total


#: The local swath width over the reference width is held within these bounds when the planes
#: follow it (``relative_width``): a level where the model finds almost no contact (a sharp ridge, a
#: few samples on a wall) does not pack the planes, nor a flat strip spread them, beyond a factor 2.
RATIO_CLIP = (0.5, 2.0)


def level_widths(sample_heights: np.ndarray, sample_widths: np.ndarray, sample_areas: np.ndarray,
                 grid: np.ndarray, half_window: float) -> np.ndarray:
    """The swath width along the level curves of ``h``: at each height of ``grid`` the
    area-weighted median of the widths of the samples within ``half_window`` of it.

    Parameters
    ----------
    sample_heights : (s,) float
        ``x · cross`` of the samples, m.
    sample_widths : (s,) float
        The contact model's swath width across the pass at each sample, m.
    sample_areas : (s,) float
        The area each sample stands for, m².
    grid : (g,) float
        Increasing heights, m.
    half_window : float
        Half the height band read at each grid height, m (half the spacing: the strip a pass
        on that level covers alone).

    Returns
    -------
    (g,) float
        Median width at each grid height, m; a band holding no sample takes the width of the
        nearest bands that hold one (NaN everywhere when there is no sample at all).
    """
    order = np.argsort(sample_heights)
    h, w, a = sample_heights[order], sample_widths[order], sample_areas[order]
    lo = np.searchsorted(h, grid - half_window, side="left")
    hi = np.searchsorted(h, grid + half_window, side="right")
    out = np.full(len(grid), np.nan)
    for i in np.flatnonzero(hi > lo):
        ww, aa = w[lo[i]:hi[i]], a[lo[i]:hi[i]]
        k = np.argsort(ww)
        cdf = np.cumsum(aa[k])
        out[i] = ww[k][min(int(np.searchsorted(cdf, 0.5 * cdf[-1])), len(k) - 1)]
    held = np.isfinite(out)
    if held.any() and not held.all():
        out = np.interp(grid, grid[held], out[held])
    return out
