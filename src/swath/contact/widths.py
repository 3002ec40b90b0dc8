"""Swath widths from the local contact model, and the default pass spacing of a raster.

The *swath width* of a pass at a surface point is the extent of the pad's contact patch across the
feed direction (FORMATS.md "Tool model").  Here it is read from the local quadric model
(:func:`swath.contact.local_patch`) with the principal curvatures at the point:

* :func:`swath_widths` — width across a given feed direction at every vertex;
* :func:`max_swath_widths` — the widest swath over all feed directions at every vertex (for the
  coverage lower bound ``L* = ∫ dA / w_max``);
* :func:`pad_scale_samples` — surface samples about half a pad radius apart whose curvature is
  fitted over the pad (radius ``R``), the scale at which the pad feels the surface;
* :func:`raster_spacing` — the default plane spacing of :func:`swath.plan.raster`.

Pad-scale samples and subdivisions are memoised per surface (:func:`surface_memo`; a Surface is
immutable): a planner's candidate directions, its fill rounds and the coverage bound share them.

Why the default spacing uses pad-scale curvature, a low percentile and a slope floor
------------------------------------------------------------------------------------
Plane slices ``d`` apart lie ``d / |n × c|`` apart on the surface (``c`` the plane normal, ``n``
the surface normal), so a raster covers a point when ``d <= w · |n × c|`` (``w`` the swath width
across the slice there).  The literal minimum of that over all vertices is useless on real
meshes: on scans the 24-neighbour curvature has noise spikes of 100–400 1/m that predict 17 mm
swaths for a 76 mm pad, and walls that face the cutting planes (``|n × c| → 0``) cannot be covered
by any sensible equal spacing (on the bezier scan 22 % of the area has ``|n × c| < 0.5`` and the
literal rule asks for 2 mm).  So the default spacing is

    ``d = P_0.2%( w · max(|n × c|, 0.5) )``

the 0.2 % area-percentile of the effective chord, on :func:`pad_scale_samples` (curvature fitted
over the pad radius, the scale at which the pad feels the surface), with the slope factor floored
at 0.5 (planes never closer than half the chord because of slope).  It equals ``2R`` on a flat
plate and the narrowest chord on a smooth part.  What a floor or the percentile leaves uncovered
is predicted as

    ``U(d) = Σ a_i · max(0, 1 − w_i |n × c|_i / d) / A``

(the share of the area falling between neighbouring swaths) and reported, so a steep-walled part
says so instead of getting a 2 mm spacing.  0.2 % is about two to four samples on the shared
meshes; with the exact pad contact it gives 99.5–100 % coverage on the smooth ones (0.5 % gave
99.48 % on bezier_complex_shape), most of what is left being at the borders of the part, where a
plane near the end of the cross extent misses a boundary that curves away from it.
"""

from __future__ import annotations

import hashlib
import logging
import weakref
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..surface.cells import jit
from ..surface.curvature import PrincipalCurvature, principal_curvatures
from .model import LocalPatch, local_patch

log = logging.getLogger("swath.plan")

#: Curvatures are rounded to this many multiples of ``1/R`` before the contact model is solved, so
#: surfaces with repeated curvature (flats, cylinders, CAD) solve each distinct value once.  The
#: resulting width error is below 0.3 % (w ∝ k^-1/2 and the step is 0.026 1/m for a 38 mm pad).
CURVATURE_STEP = 1e-3
#: Area share of the surface allowed to have an effective chord narrower than the default spacing.
SPACING_PERCENTILE = 2e-3
#: Floor on the slope factor |n × c| in the default spacing (see module notes).
SLOPE_FLOOR = 0.5


# ----------------------------------------------------------------------------------------------
# widths from curvature
# ----------------------------------------------------------------------------------------------
def patch_widths(curvature: PrincipalCurvature, normals: np.ndarray, feed_directions: np.ndarray, tool,
                 *, n_rays: int = 180) -> np.ndarray:
    """Swath width ``(n,)`` (m) across ``feed_directions`` at points with the given curvature.

    Parameters
    ----------
    curvature : PrincipalCurvature
        ``k1, k2`` (1/m) and directions ``d1, d2`` at ``n`` points.
    normals : (n, 3) float
        Unit surface normals toward the tool at the points.
    feed_directions : (n, 3) or (3,) float
        Feed direction at each point (any length; projected into the tangent plane).
    tool : Tool
    n_rays : int
        Angular resolution of the contact model (rays over 2π).

    Returns
    -------
    (n,) float
        Width of the contact patch across the tangent feed direction, m.  Where the feed is along
        the normal (no tangent direction) the narrowest width over all directions is returned.
    """
    n = np.asarray(normals, float)
    f = np.broadcast_to(np.asarray(feed_directions, float), n.shape)
    tangent = f - np.einsum("ij,ij->i", f, n)[:, None] * n
    length = np.linalg.norm(tangent, axis=1)
    undefined = length <= 1e-9 * np.maximum(np.linalg.norm(f, axis=1), 1e-300)
    cross = np.cross(n, tangent)
    # psi: angle of the cross direction from d1 in the tangent plane.  The quadric is symmetric
    # under y -> -y, so the handedness of (d1, d2) does not matter.
    psi = np.arctan2(np.einsum("ij,ij->i", cross, curvature.d2), np.einsum("ij,ij->i", cross, curvature.d1))
    patch, inverse = unique_patches(curvature.k1, curvature.k2, tool, n_rays)
    w = widths_across(patch, inverse, psi)
    if undefined.any():
        w[undefined] = patch.min_width()[inverse[undefined]]
    return w


def swath_widths(surface, tool, feed_directions, *, n_rays: int = 180) -> np.ndarray:
    """Swath width (m) at every vertex across the given feed directions, from the local quadric model.

    Parameters
    ----------
    surface : Surface
        Its vertex curvature (:attr:`Surface.curvature`) and smooth normals are used.
    tool : Tool
    feed_directions : (n, 3) or (3,) float
        Feed direction at each vertex (or one for all), projected into the tangent plane.
    n_rays : int
        Angular resolution of the contact model.

    Returns
    -------
    (n,) float
        Extent of the contact patch across the feed at each vertex, m.  For a pass at angle ``θ``
        from ``d1`` this is ``local_patch(k1, k2, tool).width_across(θ + π/2)``.

    Notes
    -----
    The local model is solved once per distinct curvature pair (rounded to
    :data:`CURVATURE_STEP` / R); on a dense noisy scan that is still about 1 ms per vertex, so
    prefer :func:`pad_scale_samples` there.
    """
    f = np.asarray(feed_directions, float)
    if f.shape not in ((3,), (len(surface.vertices), 3)) or not np.isfinite(f).all():
        raise InputError(f"feed_directions must be (3,) or ({len(surface.vertices)}, 3) finite, got {f.shape}")
    return patch_widths(surface.curvature, surface.normals, f, tool, n_rays=n_rays)


def max_swath_widths(surface, tool, *, n_directions: int = 36, n_rays: int = 180) -> np.ndarray:
    """Widest swath (m) over all feed directions at every vertex, ``(n,)``.

    The coverage lower bound of a surface is ``L* = Σ vertex_areas / max_swath_widths`` (m of
    contact path); no pass layout can cover it with less.
    """
    c = surface.curvature
    patch, inverse = unique_patches(c.k1, c.k2, tool, n_rays)
    return patch.max_width(n_directions)[inverse]


def coverage_lower_bound(surface, tool, *, samples: PadSamples | None = None) -> float:
    """``L* = ∫ dA / w_max`` (m): the contact path no plan can undercut, with ``w_max`` the widest
    contact chord over all feed directions at each point.

    Evaluated on :func:`pad_scale_samples` (curvature read over the pad): curvature noise of a scan
    would otherwise narrow ``w_max`` and inflate the bound past what any plan can reach.  Reading
    curvature at pad scale can only widen ``w_max`` at sharp features, so the result stays a
    lower bound.
    """
    s = samples if samples is not None else pad_scale_samples(surface, tool)
    return float(np.sum(lower_bound_density(s, tool)))


def lower_bound_density(samples: PadSamples, tool) -> np.ndarray:
    """Each pad-scale sample's share ``a / w_max`` (m) of the coverage lower bound ``L*``."""
    patch, inverse = unique_patches(samples.curvature.k1, samples.curvature.k2, tool, 180)
    w = patch_rows(patch, inverse, lambda p, rows: p.max_width(36))
    return samples.areas / np.maximum(w, 1e-9)


#: The last few :func:`unique_patches` results, newest last, by tool, ray count and a digest of the
#: rounded curvature pairs.
_PATCHES: OrderedDict = OrderedDict()
PATCH_MEMO_ENTRIES = 8


def unique_patches(k1, k2, tool, n_rays):
    """Solve the local model once per distinct rounded curvature pair; returns the patch of the
    distinct pairs and the row of each input point.

    The answer depends on the rounded pairs, the tool and ``n_rays`` only, and a plan asks for it
    many times with the same pad-scale samples (the spacing and the coverage check of every
    candidate direction): the last :data:`PATCH_MEMO_ENTRIES` answers are kept (the patch is
    frozen; each caller gets its own copy of the rows).
    """
    step = CURVATURE_STEP / tool.pad_radius
    key = np.round(np.stack([np.asarray(k1, float), np.asarray(k2, float)], axis=1) / step)
    memo_key = (tool, int(n_rays), step, key.shape, hashlib.blake2b(np.ascontiguousarray(key).tobytes(),
                                                                     digest_size=20).digest())
    hit = _PATCHES.get(memo_key)
    if hit is None:
        uniq, inverse = np.unique(key, axis=0, return_inverse=True)
        hit = (local_patch(uniq[:, 0] * step, uniq[:, 1] * step, tool, n_rays=n_rays), inverse.ravel())
        _PATCHES[memo_key] = hit
        while len(_PATCHES) > PATCH_MEMO_ENTRIES:
            _PATCHES.popitem(last=False)
    else:
        _PATCHES.move_to_end(memo_key)
    return hit[0], hit[1].copy()


def widths_across(patch: LocalPatch, rows: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """``patch.width_across`` of patch row ``rows[i]`` at angle ``psi[i]``, for every ``i``: ``(k,)`` (m).

    Parameters
    ----------
    patch : LocalPatch
        Solved contact patches (``n`` rows).
    rows : (k,) int
        Patch row of each query.
    psi : (k,) float
        Angle of the direction across which the width is measured, from ``d1``, rad.

    Notes
    -----
    The same arithmetic as :meth:`LocalPatch.width_across` (the same projections, maxima and
    minima, element by element, so the same numbers), compiled in one loop over the rays instead of
    the ``(k, rays)`` temporaries and the row gather of the NumPy form.

    Where the rays are evenly spaced round the circle (as :func:`swath.contact.local_patch` lays
    them), each query visits only the rays that can hold its extremes (:func:`_widths_across_near`):
    the same maxima and minima of the same products, so the same widths bit for bit.
    """
    rows = np.ascontiguousarray(rows, np.int64)
    psi = np.ascontiguousarray(np.broadcast_to(np.asarray(psi, float), rows.shape))
    if len(rows) == 0:
        return np.zeros(0)
    phi = np.ascontiguousarray(patch.phi, float)
    rho_in = np.ascontiguousarray(patch.rho_in, float)
    rho_out = np.ascontiguousarray(patch.rho_out, float)
    spacing = _even_ray_spacing(phi)
    if spacing is None:
        return _widths_across_kernel(rows, psi, phi, rho_in, rho_out)
    offsets = np.arange(len(phi) // 2 + 1)
    # cos of the least angle between a query and a ray k rays from the nearest one, with margins
    # far above the rounding of the angles and of cos (see _widths_across_near)
    ray_bound = np.cos(np.maximum((offsets - 0.5) * spacing - 1e-9, 0.0)) + 1e-12
    return _widths_across_near(rows, psi, phi, rho_in, rho_out, float(phi[0]), spacing, ray_bound)


def _even_ray_spacing(phi: np.ndarray) -> float | None:
    """The angle between neighbouring rays, rad, when ``phi`` ``(n,)`` is ``n`` evenly spaced
    increasing angles round the whole circle (to 1e-12 rad); otherwise None."""
    n = len(phi)
    if n < 4 or not np.isfinite(phi).all():
        return None
    spacing = 2.0 * np.pi / n
    expected = phi[0] + spacing * np.arange(n)
    if float(np.max(np.abs(phi - expected))) > 1e-12:
        return None
    return float(spacing)


@jit()
def _width_all_rays(r, p, phi, rho_in, rho_out):   # pragma: no cover - compiled
    """Width of patch row ``r`` across angle ``p``, every ray visited (the kernel's inner loop)."""
    hi = -np.inf
    lo = np.inf
    for j in range(len(phi)):
        if rho_out[r, j] > rho_in[r, j]:
            proj = np.cos(phi[j] - p)
            if proj >= 0:
                a = rho_out[r, j] * proj
                b = rho_in[r, j] * proj
            else:
                a = rho_in[r, j] * proj
                b = rho_out[r, j] * proj
            if a > hi:
                hi = a
            if b < lo:
                lo = b
    return hi - lo if (np.isfinite(hi) and np.isfinite(lo)) else 0.0


@jit()
def _widths_across_kernel(rows, psi, phi, rho_in, rho_out):   # pragma: no cover - compiled
    out = np.empty(len(rows))
    for i in range(len(rows)):
        out[i] = _width_all_rays(rows[i], psi[i], phi, rho_in, rho_out)
    return out


@jit()
def _widths_across_near(rows, psi, phi, rho_in, rho_out, phi0, spacing, ray_bound):   # pragma: no cover - compiled
    """:func:`_widths_across_kernel` visiting, per query, only the rays that can hold its extremes.

    With ``0 <= rho_in < rho_out`` on every ray with contact (checked per query, a pass over the
    row without any cos), a ray's far end ``a = rho_out cos`` (cos >= 0; ``rho_in cos <= 0``
    behind) is at most ``M max(cos, 0)``, ``M`` the row's longest ray, and its near end ``b`` is at
    least ``-M max(-cos, 0)``.
    The maximum of ``a`` is searched outward from the ray nearest ``psi``, that of ``-b`` from the
    ray nearest ``psi + pi``; the rays ``k`` or more away are at least ``(k - 1/2)`` ray spacings
    off, so their cos is below ``ray_bound[k]`` and the search stops once ``M ray_bound[k]`` is
    below the extreme found (rounding is monotone, so the rays skipped cannot reach it).  The
    extremes are the same products as in the full loop, so the widths are the same bit for bit.
    A non-finite ``psi`` or a row with a ray through the centre (``rho_in < 0``) takes the full loop.
    """
    n = len(phi)
    out = np.empty(len(rows))
    for i in range(len(rows)):
        r = rows[i]
        p = psi[i]
        m = -np.inf
        row_ok = True
        for j in range(n):
            if rho_out[r, j] > rho_in[r, j]:
                if rho_in[r, j] < 0.0:
                    row_ok = False
                if rho_out[r, j] > m:
                    m = rho_out[r, j]
        if not (row_ok and np.isfinite(p)):
            out[i] = _width_all_rays(r, p, phi, rho_in, rho_out)
            continue
        hi = _reach_near(r, p, p, False, phi, rho_in, rho_out, phi0, spacing, ray_bound, m)
        lo = -_reach_near(r, p, p + np.pi, True, phi, rho_in, rho_out, phi0, spacing, ray_bound, m)
        out[i] = hi - lo if (np.isfinite(hi) and np.isfinite(lo)) else 0.0
    return out


@jit()
def _reach_near(r, p, start, behind, phi, rho_in, rho_out, phi0, spacing, ray_bound, m):   # pragma: no cover - compiled
    """How far patch row ``r`` reaches across angle ``p``: ahead (the largest ``a`` of
    :func:`_width_all_rays`), or with ``behind`` the largest ``-b``; rays searched outward from the
    one nearest ``start`` until ``m · ray_bound[k]`` (``m`` the row's longest ray) is below the
    reach found (see :func:`_widths_across_near`).  ``-inf`` when no ray has contact."""
    n = len(phi)
    best = -np.inf
    j0 = int(np.floor((start - phi0) / spacing + 0.5))
    for k in range(len(ray_bound)):
        if max(m * ray_bound[k], 0.0) < best:
            break
        for side in range(2):
            j = ((j0 + k if side == 0 else j0 - k) % n + n) % n
            if rho_out[r, j] > rho_in[r, j]:
                proj = np.cos(phi[j] - p)
                if behind:
                    v = -(rho_in[r, j] * proj if proj >= 0 else rho_out[r, j] * proj)
                else:
                    v = rho_out[r, j] * proj if proj >= 0 else rho_in[r, j] * proj
                if v > best:
                    best = v
    return best


def patch_rows(patch: LocalPatch, inverse: np.ndarray, fn, chunk: int = 20000) -> np.ndarray:
    """Apply ``fn(sub_patch, rows)`` to the patch rows of ``inverse`` in chunks; returns ``(len(inverse),)``."""
    out = np.empty(len(inverse))
    for lo in range(0, len(inverse), chunk):
        idx = inverse[lo:lo + chunk]
        sub = LocalPatch(patch.sink[idx], patch.phi, patch.rho_in[idx], patch.rho_out[idx])
        out[lo:lo + chunk] = fn(sub, np.arange(lo, lo + len(idx)))
    return out


# ----------------------------------------------------------------------------------------------
# per-surface memo
# ----------------------------------------------------------------------------------------------
#: Derived data of a surface that several planning steps (candidate directions, fill rounds, the
#: coverage bound) ask for again: keyed by the surface object (a Surface is immutable), dropped with
#: it.  At most :data:`MEMO_ENTRIES` entries per surface (oldest dropped first).
_MEMO: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
MEMO_ENTRIES = 16


def surface_memo(surface, key, make):
    """``make()`` computed once per ``(surface, key)`` and reused while ``surface`` lives.

    Parameters
    ----------
    surface : Surface
        The (immutable) surface the value derives from.
    key : hashable
        What is derived and with which parameters, e.g. ``("subdivided", 0.005)``.
    make : callable
        ``make() -> value``, a pure function of ``surface`` and ``key``.
    """
    store = _MEMO.setdefault(surface, {})
    if key not in store:
        if len(store) >= MEMO_ENTRIES:
            store.pop(next(iter(store)))
        store[key] = make()
    return store[key]


def subdivided(surface, max_edge: float, *, method: str = "long_edges"):
    """``surface.subdivided(max_edge, method=method)`` (edges at most ``max_edge`` m), computed once
    per surface, edge length and method."""
    if surface.edge_lengths.max() <= max_edge:
        # the surface itself: not memoised, a memo value holding its own key would never be freed
        return surface
    return surface_memo(surface, ("subdivided", float(max_edge), method),
                        lambda: surface.subdivided(max_edge, method=method))


# ----------------------------------------------------------------------------------------------
# pad-scale samples
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PadSamples:
    """Surface samples with curvature read at the scale of the pad.

    Attributes
    ----------
    points, normals : (s, 3) float
        Sample positions (surface vertices, m) and smooth unit normals toward the tool.
    areas : (s,) float
        Surface area each sample stands for, m² (they add up to the surface area).
    curvature : PrincipalCurvature
        Quadric fit over a ball of the pad radius around each sample.
    spacing : float
        Sampling grid size, m.
    """

    points: np.ndarray
    normals: np.ndarray
    areas: np.ndarray
    curvature: PrincipalCurvature
    spacing: float


def pad_scale_samples(surface, tool, *, spacing: float | None = None, max_samples: int = 1500) -> PadSamples:
    """Samples about ``R/2`` apart with principal curvatures fitted over the pad (radius ``R``).

    Parameters
    ----------
    surface : Surface
    tool : Tool
    spacing : float, optional
        Sampling grid size, m (default ``R/2``, enlarged so that at most ``max_samples`` remain).
    max_samples : int
        Upper bound on the number of samples (limits the cost of the contact model, ~1–2 ms each).

    Notes
    -----
    Long triangles are first split to ``R/4`` so the fit sees the surface, not a few far vertices;
    the fit cloud is the surface thinned to one vertex per ``R/6`` cell (about 110 points within
    ``R``), so its cost does not grow with the scan density.  Grid cells are split by the sign of
    the dominant normal component, so the two sides of a thin part (a blade's leading edge) are
    sampled separately.

    The samples are computed once per surface, tool and options and shared by later calls (their
    arrays are read-only).
    """
    key = ("pad_scale_samples", tool, None if spacing is None else float(spacing), int(max_samples))
    return surface_memo(surface, key, lambda: _pad_scale_samples(surface, tool, spacing, max_samples))


def _pad_scale_samples(surface, tool, spacing, max_samples) -> PadSamples:
    R = tool.pad_radius
    # the earlier 1-to-4 halving: the pad-scale samples (and the plans built on them) stay as they were
    dense = subdivided(surface, R / 4.0, method="halving")
    v, nrm, va = dense.vertices, dense.normals, dense.vertex_areas
    if spacing is None:
        spacing = max(R / 2.0, float(np.sqrt(dense.area / max(int(max_samples), 1))))
    if not (np.isfinite(spacing) and spacing > 0):
        raise InputError(f"sample spacing must be positive and finite, got {spacing!r} m")
    cloud = _grid_representatives(v, nrm, R / 6.0)[0]
    rep, inverse = _grid_representatives(v, nrm, spacing)
    areas = np.bincount(inverse, weights=va, minlength=len(rep))
    curv = principal_curvatures(v[rep], nrm[rep], neighbours=128, radius=R, cloud=v[cloud],
                                cloud_normals=nrm[cloud])
    points, normals = v[rep], nrm[rep]
    for a in (points, normals, areas, curv.k1, curv.k2, curv.d1, curv.d2):
        a.setflags(write=False)
    return PadSamples(points, normals, areas, curv, float(spacing))


def _grid_representatives(points, normals, cell):
    """One point per occupied (grid cell, normal side) bin: its index ``(s,)`` and the bin of every
    point ``(n,)``."""
    ijk = np.floor((points - points.min(axis=0)) / cell).astype(np.int64)
    axis = np.argmax(np.abs(normals), axis=1)
    side = np.sign(normals[np.arange(len(normals)), axis]).astype(np.int64)
    key = np.column_stack([ijk, 2 * axis + (side > 0)])
    # One int64 per row in mixed radix: sorts exactly as the rows do lexicographically, so the bins,
    # their order and their first points are those of np.unique(key, axis=0), at a fraction of the cost.
    radix = key.max(axis=0) + 1
    if float(np.prod(radix.astype(float))) < 2.0 ** 62:
        code = key[:, 0]
        for col in range(1, key.shape[1]):
            code = code * radix[col] + key[:, col]
        _, first, inverse = np.unique(code, return_index=True, return_inverse=True)
    else:
        _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    return first, inverse.ravel()


# ----------------------------------------------------------------------------------------------
# default raster spacing
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SpacingChoice:
    """The default raster spacing and the numbers behind it.

    Attributes
    ----------
    spacing : float
        Plane spacing, m.
    narrowest : float
        Narrowest effective chord ``w · |n × c|`` over the samples, m.
    gap_fraction : float
        Predicted share of the area left between swaths at ``spacing`` (``U(d)`` in the notes).
    steep_fraction : float
        Area share where ``|n × c|`` is below :data:`SLOPE_FLOOR` (surface facing the planes).
    rule : str
        One-line description for metadata.
    """

    spacing: float
    narrowest: float
    gap_fraction: float
    steep_fraction: float
    rule: str


def raster_spacing(surface, tool, cross_direction, *, percentile: float = SPACING_PERCENTILE,
                   slope_floor: float = SLOPE_FLOOR, samples: PadSamples | None = None) -> SpacingChoice:
    """Largest equal spacing of cutting planes (normal ``cross_direction``) that covers the surface.

    Parameters
    ----------
    surface : Surface
    tool : Tool
    cross_direction : (3,) float
        Normal of the cutting planes (any length).
    percentile : float
        Area share allowed below the spacing, in ``[0, 1)`` (0 = the narrowest chord).
    slope_floor : float
        Floor on the slope factor ``|n × c|``, in ``[0, 1]`` (0 = no floor).
    samples : PadSamples, optional
        Precomputed :func:`pad_scale_samples`.

    Returns
    -------
    SpacingChoice
        See the module notes for the rule.
    """
    if not (0.0 <= percentile < 1.0):
        raise InputError(f"percentile must lie in [0, 1), got {percentile!r}")
    if not (0.0 <= slope_floor <= 1.0):
        raise InputError(f"slope_floor must lie in [0, 1], got {slope_floor!r}")
    s = samples if samples is not None else pad_scale_samples(surface, tool)
    w_eff, slope = effective_widths(s, tool, cross_direction)
    w = w_eff / np.maximum(slope, 1e-300)
    d = area_percentile(w * np.maximum(slope, slope_floor), s.areas, percentile)
    gap = gap_fraction(w_eff, s.areas, d)
    steep = float(s.areas[slope < slope_floor].sum() / s.areas.sum())
    rule = (f"{percentile:.1%} area-percentile of the contact chord across the slice times max(|n x c|, "
            f"{slope_floor:g}), local contact model with curvature fitted over the pad radius on samples "
            f"{s.spacing * 1e3:.1f} mm apart (narrowest effective chord {w_eff.min() * 1e3:.1f} mm, "
            f"{steep:.1%} of the area steeper than the floor, predicted gap {gap:.2%})")
    log.info("raster default spacing %.1f mm (narrowest effective chord %.1f mm, predicted gap %.3f%%)",
             d * 1e3, w_eff.min() * 1e3, 100 * gap)
    return SpacingChoice(float(d), float(w_eff.min()), gap, steep, rule)


def effective_widths(samples: PadSamples, tool, cross_direction) -> tuple[np.ndarray, np.ndarray]:
    """Effective swath widths of plane slices with normal ``cross_direction`` at pad-scale samples.

    Returns
    -------
    w_eff : (s,) float
        Contact chord across the slice times the slope factor ``|n × c|``, m: the plane spacing that
        just covers each sample.
    slope : (s,) float
        ``|n × c|`` at each sample.
    """
    c = np.asarray(cross_direction, float)
    c = c / np.linalg.norm(c)
    # The slice through a point runs along n × c; the swath is measured across it.
    feed = np.cross(samples.normals, c)
    slope = np.linalg.norm(feed, axis=1)
    w = patch_widths(samples.curvature, samples.normals, feed, tool)
    return w * slope, slope


def gap_fraction(w_eff: np.ndarray, areas: np.ndarray, spacing: float) -> float:
    """Predicted area share left between swaths at plane ``spacing`` (m): ``Σ a max(0, 1 − w_eff/d) / A``."""
    return float(np.sum(areas * np.clip(1.0 - w_eff / spacing, 0.0, None)) / areas.sum())


def area_percentile(values: np.ndarray, areas: np.ndarray, fraction: float) -> float:
    """The largest sample value ``v`` such that the samples below ``v`` carry at most ``fraction``
    of the area: the area-weighted lower percentile of ``values`` ``(n,)``, weights ``areas`` ``(n,)``.

    ``fraction = 0`` gives the minimum.
    """
    order = np.argsort(values)
    v, a = np.asarray(values, float)[order], np.asarray(areas, float)[order]
    below = np.concatenate([[0.0], np.cumsum(a)[:-1]]) / a.sum()     # area strictly below each sample
    k = int(np.searchsorted(below, fraction, side="right")) - 1
    return float(v[max(k, 0)])
