"""The pad contact model of FORMATS.md, in two forms.

A flat pad of radius ``R`` is pressed along the tool z-axis.  Its face is a plane that sinks to
depth ``s`` below the TCP; a surface point within ``R`` of the tool axis, at height ``z`` along tool
z, is in contact where ``h = s - z > 0`` and carries pressure ``k·h``.  ``s`` is set by the force
balance ``F = k ∫ h dA``.

* :func:`mesh_contact` evaluates the model exactly on surface samples (a fine mesh) for many
  poses at once; the simulator uses it.
* :func:`local_patch` evaluates it on the local quadric ``z = (k1 x² + k2 y²) / 2`` given by the
  principal curvatures; planners use it for swath widths, default spacings and the coverage bound.

Both solve the force balance exactly for their geometry; tests check them against each other and
against the analytic flat, sphere and cylinder answers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .tool import Tool


# ----------------------------------------------------------------------------------------------
# Exact force balance over discrete samples
# ----------------------------------------------------------------------------------------------
def solve_sink(z: np.ndarray, weight: np.ndarray, group: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Solve ``sum_j weight_j · max(s_g − z_j, 0) = target_g`` for ``s_g`` in every group.

    Parameters
    ----------
    z : (N,) float
        Height of each sample along tool z, m.
    weight : (N,) float
        Area of each sample, m².
    group : (N,) int
        Group (pose) index of each sample, ``0 <= group < G``, in any order.
    target : (G,) float
        Required ``F / k`` per group, m³.

    Returns
    -------
    (G,) float
        The sink depth ``s`` per group, m; NaN for a group with no samples (or no area).

    Notes
    -----
    The left side ``f(s)`` is convex, piecewise linear and increasing.  Newton's method started at
    ``s₀ = (target + Σ w z) / Σ w`` (the answer if every sample touched, where ``f(s₀) ≥ target``)
    descends monotonically and is exact once the set of touching samples stops changing — a few
    iterations of vectorised ``bincount`` passes, no sorting.
    """
    G = len(target)
    s = np.full(G, np.nan)
    if len(z) == 0:
        return s
    wsum = np.bincount(group, weights=weight, minlength=G)
    has = wsum > 0
    s[has] = (target[has] + np.bincount(group, weights=weight * z, minlength=G)[has]) / wsum[has]
    live = np.flatnonzero(has)
    sel = has[group]
    z, weight, group = z[sel], weight[sel], group[sel]
    for _ in range(100):
        h = s[group] - z
        wa = np.where(h > 0, weight, 0.0)
        f = np.bincount(group, weights=wa * h, minlength=G)
        area = np.bincount(group, weights=wa, minlength=G)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = np.where(area[live] > 0, (f[live] - target[live]) / area[live], 0.0)
        s[live] -= step
        if np.all(np.abs(step) <= 1e-15 + 1e-12 * np.abs(s[live])):
            break
    return s


@dataclass(frozen=True)
class MeshContact:
    """Contact between the pad and surface samples for a batch of poses (sparse, pair list).

    Attributes
    ----------
    pose : (N,) int
        Pose index of each contact pair (within the batch).
    sample : (N,) int
        Surface-sample index of each pair.
    pressure : (N,) float
        Contact pressure, Pa (> 0).
    radius : (N,) float
        Distance of the sample from the tool axis, m.
    sink : (P,) float
        Pad-face depth ``s`` per pose, m (NaN where the pad touches nothing).
    """

    pose: np.ndarray
    sample: np.ndarray
    pressure: np.ndarray
    radius: np.ndarray
    sink: np.ndarray


def mesh_contact(points: np.ndarray, normals: np.ndarray, areas: np.ndarray, tree,
                 positions: np.ndarray, axes: np.ndarray, tool: Tool, *, force=None,
                 engine: str = "numpy") -> MeshContact:
    """Pad contact on surface samples for poses ``positions`` ``(P, 3)`` with tool z ``axes`` ``(P, 3)``.

    Parameters
    ----------
    points, normals : (S, 3) float
        Surface samples (m) and their unit normals toward the tool.
    areas : (S,) float
        Area each sample stands for, m².
    tree : scipy.spatial.cKDTree
        KD-tree over ``points``.
    positions : (P, 3) float
        TCP positions, m.
    axes : (P, 3) float
        Unit tool z-axes (pointing into the part).
    tool : Tool
    force : (P,) float, optional
        Normal force per pose, N (default ``tool.force`` at every pose).
    engine : {"numpy", "compiled"}
        ``"numpy"``: KD-tree pairs and :func:`solve_sink`, in the samples' dtype (float32 halves the
        memory traffic; 1e-7 relative is far below the micrometre heights that matter).
        ``"compiled"``: the numba kernels of :mod:`swath.contact.kernels` on a cell grid built for
        this call (``tree`` unused), in float64; the same pairs and sinks as ``"numpy"`` on float64
        samples, to round-off, pairs ordered by pose.

    Returns
    -------
    MeshContact
        Only pairs with positive pressure are kept.  Samples whose normal faces away from the tool
        (the far side of a thin part) never touch the pad.
    """
    from scipy.spatial import cKDTree

    if engine == "compiled":
        from . import kernels

        if not kernels.AVAILABLE:
            raise InputError("the compiled contact engine needs numba; install it or use engine='numpy'")
        grid = kernels.sample_grid(points, normals, areas, cell=kernels.default_cell(tool))
        return MeshContact(*kernels.contact_pairs(grid, positions, axes, tool, force=force))
    if engine != "numpy":
        raise InputError(f"contact engine must be 'numpy' or 'compiled', got {engine!r}")

    R = tool.pad_radius
    P = len(positions)
    # A ball of radius 1.118·R holds every point of the pad cylinder with |z| <= R/2; points farther
    # above the pad face would be inside the tool body, farther below cannot touch.
    coo = cKDTree(positions).sparse_distance_matrix(tree, np.hypot(R, 0.5 * R), output_type="coo_matrix")
    if coo.nnz == 0:
        empty = np.zeros(0)
        return MeshContact(empty.astype(int), empty.astype(int), empty, empty, np.full(P, np.nan))
    pose, sample = coo.row, coo.col
    # Work in the samples' dtype (the simulator passes float32: half the memory traffic, and
    # 1e-7 relative precision is far below the micrometre heights that matter).
    dt = points.dtype
    rel = points[sample] - positions.astype(dt)[pose]
    a = axes.astype(dt)[pose]
    z = np.einsum("ij,ij->i", rel, a)
    r2 = np.einsum("ij,ij->i", rel, rel) - z * z
    keep = (r2 <= R * R * (1 + 1e-6)) & (np.einsum("ij,ij->i", normals[sample], a) < 0.0)
    pose, sample = pose[keep], sample[keep]
    z, r2 = z[keep].astype(float), r2[keep].astype(float)
    target = np.full(P, tool.force / tool.k) if force is None else np.asarray(force, float) / tool.k
    sink = solve_sink(z, areas[sample], pose, target)
    h = sink[pose] - z
    touch = h > 0
    return MeshContact(pose[touch], sample[touch], tool.k * h[touch], np.sqrt(np.maximum(r2[touch], 0.0)), sink)


# ----------------------------------------------------------------------------------------------
# Local quadric model from principal curvatures
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class LocalPatch:
    """The pad's contact patch on local quadrics ``z = (k1 x² + k2 y²)/2`` (x along ``d1``).

    Along each ray from the pad centre at angle ``phi`` from ``d1`` the contact is the radial
    interval ``[rho_in, rho_out]`` (empty where ``rho_in >= rho_out``).

    Attributes
    ----------
    sink : (n,) float
        Pad-face depth ``s``, m.
    phi : (a,) float
        Ray angles over ``[0, 2π)``, rad.
    rho_in, rho_out : (n, a) float
        Contact interval along each ray, m.
    """

    sink: np.ndarray
    phi: np.ndarray
    rho_in: np.ndarray
    rho_out: np.ndarray

    def width_across(self, psi) -> np.ndarray:
        """Extent (m) of the patch along the tangent direction at angle ``psi`` from ``d1``.

        For a pass whose feed direction is at angle ``θ`` from ``d1`` the swath width is
        ``width_across(θ + π/2)``.  ``psi`` is a scalar or an ``(n,)`` array.
        """
        psi = np.broadcast_to(np.asarray(psi, float), self.sink.shape)
        proj = np.cos(self.phi[None, :] - psi[:, None])
        present = self.rho_out > self.rho_in
        # The extreme projections lie on the outer boundary of a ray (or at the inner end when the
        # ray points against the direction).
        hi = np.where(proj >= 0, self.rho_out * proj, self.rho_in * proj)
        lo = np.where(proj >= 0, self.rho_in * proj, self.rho_out * proj)
        hi = np.where(present, hi, -np.inf).max(axis=1)
        lo = np.where(present, lo, np.inf).min(axis=1)
        return np.where(np.isfinite(hi) & np.isfinite(lo), hi - lo, 0.0)

    def max_width(self, n_directions: int = 36) -> np.ndarray:
        """Widest swath (m) over all feed directions, ``(n,)``."""
        psis = np.linspace(0.0, np.pi, n_directions, endpoint=False)
        return np.max([self.width_across(p) for p in psis], axis=0)

    def min_width(self, n_directions: int = 36) -> np.ndarray:
        """Narrowest swath (m) over all feed directions, ``(n,)``."""
        psis = np.linspace(0.0, np.pi, n_directions, endpoint=False)
        return np.min([self.width_across(p) for p in psis], axis=0)

    @property
    def contact_area(self) -> np.ndarray:
        """Area (m²) of the contact patch, ``(n,)``."""
        dphi = 2 * np.pi / len(self.phi)
        return 0.5 * dphi * np.clip(self.rho_out**2 - self.rho_in**2, 0.0, None).sum(axis=1)


def local_patch(k1, k2, tool: Tool, *, n_rays: int = 180, chunk: int = 20000) -> LocalPatch:
    """Solve the pad contact on local quadrics with principal curvatures ``k1, k2`` (1/m).

    Positive curvature bends away from the tool (convex).  Exact for the quadric, to the angular
    resolution ``2π / n_rays``.

    Parameters
    ----------
    k1, k2 : (n,) float or scalars
        Principal curvatures, 1/m.
    tool : Tool
    n_rays : int
        Number of rays over the full circle (even).

    Returns
    -------
    LocalPatch
    """
    k1 = np.atleast_1d(np.asarray(k1, float))
    k2 = np.atleast_1d(np.asarray(k2, float))
    n = len(k1)
    phi = (np.arange(n_rays) + 0.5) * (2 * np.pi / n_rays)
    sink = np.empty(n)
    rho_in = np.empty((n, n_rays))
    rho_out = np.empty((n, n_rays))
    for lo in range(0, n, chunk):
        hi = min(lo + chunk, n)
        s, ri, ro = _solve_quadric(k1[lo:hi], k2[lo:hi], phi, tool)
        sink[lo:hi], rho_in[lo:hi], rho_out[lo:hi] = s, ri, ro
    return LocalPatch(sink, phi, rho_in, rho_out)


def _ray_interval(a: np.ndarray, s: np.ndarray, R: float) -> tuple[np.ndarray, np.ndarray]:
    """Contact interval on rays where ``z = a ρ²`` (``a = κ_φ/2``) for plane depth ``s``."""
    with np.errstate(divide="ignore", invalid="ignore"):
        lim = np.sqrt(np.where(a != 0, s / a, np.inf))
    # convex ray (a > 0): contact from 0 to min(R, sqrt(s/a)) if s > 0
    # concave ray (a < 0): contact from sqrt(s/a) (if s < 0) to R
    # flat ray: all of [0, R] if s > 0
    rho_out = np.where(a > 0, np.where(s > 0, np.minimum(R, np.nan_to_num(lim, nan=0.0)), 0.0),
                       np.where((a < 0) | (s > 0), R, 0.0))
    rho_in = np.where((a < 0) & (s < 0), np.minimum(np.nan_to_num(lim, nan=R), R), 0.0)
    return rho_in, rho_out


def _solve_quadric(k1, k2, phi, tool: Tool):
    R = tool.pad_radius
    a = 0.5 * (k1[:, None] * np.cos(phi) ** 2 + k2[:, None] * np.sin(phi) ** 2)   # (n, rays)
    dphi = 2 * np.pi / len(phi)
    target = tool.force / tool.k

    def volume(a, s):
        ri, ro = _ray_interval(a, s[:, None], R)
        prim = lambda r: s[:, None] * r**2 / 2 - a * r**4 / 4   # ∫ (s - a ρ²) ρ dρ
        vol = np.where(ro > ri, prim(ro) - prim(ri), 0.0).sum(axis=1) * dphi
        area = np.where(ro > ri, (ro**2 - ri**2) / 2, 0.0).sum(axis=1) * dphi
        return vol, area

    # Safeguarded Newton on the increasing volume(s): bracket [lo, hi], Newton step when it stays
    # inside, bisection otherwise.  Rows leave the working set as soon as they converge.
    lo = np.minimum(0.0, a.min(axis=1)) * R * R
    hi = tool.flat_depression + np.maximum(0.0, a.max(axis=1)) * R * R
    s = np.clip(np.full(len(k1), tool.flat_depression), lo, hi)
    active = np.arange(len(k1))
    for _ in range(100):
        if len(active) == 0:
            break
        sa, la, ha, aa = s[active], lo[active], hi[active], a[active]
        vol, area = volume(aa, sa)
        err = vol - target
        la = np.where(err < 0, sa, la)
        ha = np.where(err >= 0, sa, ha)
        with np.errstate(divide="ignore", invalid="ignore"):
            newton = sa - err / area
        inside = (newton > la) & (newton < ha) & np.isfinite(newton)
        s_new = np.where(inside, newton, 0.5 * (la + ha))
        # Converged when the force balance holds to 1e-9 or the step is at round-off.
        done = (np.abs(err) <= 1e-9 * target) | (np.abs(s_new - sa) <= 1e-13 + 1e-10 * np.abs(sa))
        s[active] = np.where(np.abs(err) <= 1e-9 * target, sa, s_new)
        lo[active], hi[active] = la, ha
        active = active[~done]
    ri, ro = _ray_interval(a, s[:, None], R)
    return s, ri, ro
