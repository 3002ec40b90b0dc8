"""Tensor-product B-spline (NURBS-capable) surface patches with exact differential geometry.

A :class:`BSplinePatch` is ``S(u, v) = Σ N_i,p(u) N_j,q(v) w_ij P_ij / Σ N_i,p(u) N_j,q(v) w_ij``
(weights optional: without them the patch is a plain, polynomial B-spline).  Everything the
planners need is exact, not finite-differenced:

* points and partial derivatives up to any order (the basis-function derivatives are the
  Cox–de Boor recursion differentiated; the rational case applies the quotient rule);
* unit normals ``S_u × S_v / |S_u × S_v|`` — this side is the patch's *normal side* (the tool side);
* first and second fundamental forms, the shape operator and principal curvatures/directions,
  with swath's sign convention: **positive curvature = convex toward the normal side** (the
  outside of a sphere with outward normals has ``k1 = k2 = +1/r``, as in
  :mod:`swath.surface.curvature`);
* closest-point projection (vectorised Newton from a coarse-grid KD-tree start);
* conversion to a triangulated :class:`~swath.surface.Surface`, and a JSON-ready dictionary
  (:meth:`BSplinePatch.to_dict`; patch files are read and written by :mod:`swath.io.patch`).

The basis functions are in :mod:`swath.surface.bspline_basis`; exact test geometry (cylinder,
sphere, torus as rational patches) in :mod:`swath.surface.exact_shapes`.
"""

from __future__ import annotations

import math
from functools import cached_property

import numpy as np

from ..errors import InputError
from .bspline_basis import _check_knots, basis_derivatives, span_samples
from .curvature import PrincipalCurvature
from .geometry import normalize

#: The value of the ``"type"`` key in a patch's JSON document.
JSON_TYPE = "swath.BSplinePatch"
JSON_VERSION = 1


# ----------------------------------------------------------------------------------------------
# The patch
# ----------------------------------------------------------------------------------------------
class BSplinePatch:
    """A tensor-product B-spline or NURBS surface patch (immutable).

    Parameters
    ----------
    control_points : (nu, nv, 3) float
        Control net, m, part frame.
    knots_u : (nu + p + 1,) float
        Non-decreasing knot vector in u (any units; fits use metres of arc length).
    knots_v : (nv + q + 1,) float
        Non-decreasing knot vector in v.
    degree : (int, int)
        Degrees ``(p, q)`` in u and v, each at least 1.
    weights : (nu, nv) float, optional
        Positive rational weights (NURBS); ``None`` for a polynomial B-spline.
    name : str
        A label.

    Notes
    -----
    The parameter domain is ``[t_p, t_nu] × [s_q, s_nv]`` (:attr:`domain`).  Interior knots may be
    repeated up to ``p`` times (the patch stays continuous); derivatives at a repeated knot are
    taken from the span on its right.

    Raises
    ------
    InputError
        On wrong shapes, non-finite values, decreasing knots, non-positive weights or an empty
        domain.
    """

    def __init__(self, control_points, knots_u, knots_v, degree=(3, 3), weights=None, *, name: str = ""):
        P = np.array(control_points, dtype=float)
        if P.ndim != 3 or P.shape[2] != 3:
            raise InputError(f"expected control points of shape (nu, nv, 3), got {P.shape}")
        try:
            p, q = (int(d) for d in degree)
        except (TypeError, ValueError):
            raise InputError(f"expected degree as a pair of integers (p, q), got {degree!r}") from None
        if p < 1 or q < 1:
            raise InputError(f"degrees must be at least 1, got ({p}, {q})")
        nu, nv = P.shape[:2]
        if nu < p + 1 or nv < q + 1:
            raise InputError(f"a degree ({p}, {q}) patch needs at least ({p + 1}, {q + 1}) control points, "
                             f"got ({nu}, {nv})")
        tu = _check_knots(knots_u, nu, p, "u")
        tv = _check_knots(knots_v, nv, q, "v")
        if not np.isfinite(P).all():
            raise InputError("control points contain NaN or infinite values")
        W = None
        if weights is not None:
            W = np.array(weights, dtype=float)
            if W.shape != (nu, nv):
                raise InputError(f"expected weights of shape ({nu}, {nv}), got {W.shape}")
            if not (np.isfinite(W).all() and (W > 0).all()):
                raise InputError("NURBS weights must be positive and finite")
            W.setflags(write=False)
        for a in (P, tu, tv):
            a.setflags(write=False)
        self.control_points = P
        self.knots_u = tu
        self.knots_v = tv
        self.degree = (p, q)
        self.weights = W
        self.name = name

    # --- basic properties -----------------------------------------------------------------------
    def __repr__(self) -> str:
        kind = "NURBS" if self.is_rational else "B-spline"
        return (f"BSplinePatch({self.name!r}, {kind}, degree={self.degree}, "
                f"control net {self.shape[0]}x{self.shape[1]}, domain={self.domain.tolist()})")

    @property
    def shape(self) -> tuple[int, int]:
        """Control-net size ``(nu, nv)``."""
        return self.control_points.shape[:2]

    @property
    def is_rational(self) -> bool:
        """Whether the patch has weights (NURBS)."""
        return self.weights is not None

    @cached_property
    def domain(self) -> np.ndarray:
        """``[[u0, u1], [v0, v1]]``, the parameter domain."""
        (p, q), (nu, nv) = self.degree, self.shape
        d = np.array([[self.knots_u[p], self.knots_u[nu]], [self.knots_v[q], self.knots_v[nv]]])
        d.setflags(write=False)
        return d

    @cached_property
    def _homogeneous(self) -> np.ndarray:
        """(nu, nv, 3 or 4) control points in homogeneous form ``(w P, w)`` (or ``P``)."""
        if self.weights is None:
            return self.control_points
        return np.concatenate([self.control_points * self.weights[..., None], self.weights[..., None]], axis=2)

    # --- evaluation -------------------------------------------------------------------------------
    def _params(self, u, v) -> tuple[np.ndarray, np.ndarray]:
        u, v = np.broadcast_arrays(np.asarray(u, float), np.asarray(v, float))
        u, v = u.ravel(), v.ravel()
        (u0, u1), (v0, v1) = self.domain
        tol_u, tol_v = 1e-9 * max(u1 - u0, 1.0), 1e-9 * max(v1 - v0, 1.0)
        if not (np.isfinite(u).all() and np.isfinite(v).all()):
            raise InputError("parameter values must be finite")
        if u.size and (u.min() < u0 - tol_u or u.max() > u1 + tol_u or v.min() < v0 - tol_v or v.max() > v1 + tol_v):
            raise InputError(f"parameters outside the patch domain u in [{u0:.6g}, {u1:.6g}], "
                             f"v in [{v0:.6g}, {v1:.6g}]; clamp them or use project()")
        return np.clip(u, u0, u1), np.clip(v, v0, v1)

    def derivatives(self, u, v, order: int = 2, *, chunk: int = 50000) -> np.ndarray:
        """Exact partial derivatives ``∂^{a+b} S / ∂u^a ∂v^b`` for ``a + b <= order``.

        Parameters
        ----------
        u, v : (k,) float
            Parameter values (broadcast against each other) inside :attr:`domain`.
        order : int
            Highest total derivative order (0 gives points only).

        Returns
        -------
        (k, order + 1, order + 1, 3) float
            ``D[:, a, b]`` is ``∂^{a+b} S / ∂u^a ∂v^b`` (m per parameter unit^(a+b)); entries with
            ``a + b > order`` are zero.
        """
        u, v = self._params(u, v)
        order = int(order)
        if order < 0:
            raise InputError(f"derivative order must be >= 0, got {order}")
        out = np.zeros((u.size, order + 1, order + 1, 3))
        for lo in range(0, u.size, chunk):
            hi = min(lo + chunk, u.size)
            out[lo:hi] = self._derivatives_chunk(u[lo:hi], v[lo:hi], order)
        return out

    def _derivatives_chunk(self, u: np.ndarray, v: np.ndarray, order: int) -> np.ndarray:
        (p, q) = self.degree
        su, Nu = basis_derivatives(self.knots_u, p, u, order)
        sv, Nv = basis_derivatives(self.knots_v, q, v, order)
        iu = su[:, None] - p + np.arange(p + 1)
        iv = sv[:, None] - q + np.arange(q + 1)
        Pw = self._homogeneous
        local = Pw[iu[:, :, None], iv[:, None, :]]               # (k, p+1, q+1, dim)
        k, dim = u.size, Pw.shape[2]
        A = np.zeros((k, order + 1, order + 1, dim))
        for a in range(order + 1):
            tmp = np.einsum("ka,kabd->kbd", Nu[a], local)        # (k, q+1, dim)
            for b in range(order + 1 - a):
                A[:, a, b] = np.einsum("kb,kbd->kd", Nv[b], tmp)
        if self.weights is None:
            return A
        # Quotient rule for S = A / w, all mixed orders (Piegl & Tiller, eq. 4.20).
        Aw, w = A[..., :3], A[..., 3]
        S = np.zeros((k, order + 1, order + 1, 3))
        for a in range(order + 1):
            for b in range(order + 1 - a):
                val = Aw[:, a, b].copy()
                for j in range(1, b + 1):
                    val -= math.comb(b, j) * w[:, 0, j, None] * S[:, a, b - j]
                for i in range(1, a + 1):
                    val -= math.comb(a, i) * w[:, i, 0, None] * S[:, a - i, b]
                    for j in range(1, b + 1):
                        val -= math.comb(a, i) * math.comb(b, j) * w[:, i, j, None] * S[:, a - i, b - j]
                S[:, a, b] = val / w[:, 0, 0, None]
        return S

    def evaluate(self, u, v) -> np.ndarray:
        """Points ``(k, 3)`` (m) at parameters ``u, v`` ``(k,)``."""
        return self.derivatives(u, v, 0)[:, 0, 0]

    def normals(self, u, v) -> np.ndarray:
        """Unit normals ``(k, 3)``, ``S_u × S_v`` normalised (the patch's normal side)."""
        D = self.derivatives(u, v, 1)
        return normalize(np.cross(D[:, 1, 0], D[:, 0, 1]))

    # --- differential geometry ------------------------------------------------------------------
    def fundamental_forms(self, u, v) -> tuple[np.ndarray, np.ndarray]:
        """First and second fundamental forms at ``u, v`` ``(k,)``.

        Returns
        -------
        first : (k, 2, 2) float
            ``[[E, F], [F, G]]`` with ``E = S_u·S_u``, ``F = S_u·S_v``, ``G = S_v·S_v``.
        second : (k, 2, 2) float
            ``[[L, M], [M, N]]`` with ``L = n·S_uu``, ``M = n·S_uv``, ``N = n·S_vv`` (``n`` the unit
            normal).  Note ``L/E`` is then *minus* swath's curvature along ``S_u``.
        """
        return _forms(self.derivatives(u, v, 2))[:2]

    def shape_operator(self, u, v) -> np.ndarray:
        """The differential of the Gauss map ``dN`` in the ``(S_u, S_v)`` basis, ``(k, 2, 2)``.

        ``dN = −I⁻¹ II`` (columns: the ``(S_u, S_v)`` components of ``N_u`` and ``N_v``).  Its
        eigenvalues are the principal curvatures in swath's sign convention (convex toward the
        normal side positive) and its eigenvectors the principal directions.
        """
        I, II, _ = _forms(self.derivatives(u, v, 2))
        return -np.linalg.solve(I, II)

    def curvature(self, u, v) -> PrincipalCurvature:
        """Principal curvatures (1/m, ``k1 >= k2``, positive = convex toward the normal side) and
        unit principal directions ``(k, 3)`` at ``u, v`` ``(k,)``."""
        return principal_from_derivatives(self.derivatives(u, v, 2))

    # --- orientation ------------------------------------------------------------------------------
    def flipped(self) -> BSplinePatch:
        """The same surface with the u direction reversed, hence the normal side flipped."""
        u0, u1 = self.domain[0]
        knots = (u0 + u1) - self.knots_u[::-1]
        W = None if self.weights is None else self.weights[::-1]
        return BSplinePatch(self.control_points[::-1], knots, self.knots_v, self.degree, W, name=self.name)

    # --- projection -----------------------------------------------------------------------------
    @cached_property
    def closed(self) -> tuple[bool, bool]:
        """Whether the patch closes on itself in u and in v (first and last control rows coincide,
        as on a full cylinder or torus).  Projection wraps round a closed direction."""
        P, W = self.control_points, self.weights
        tol = 1e-12 * max(float(np.ptp(P.reshape(-1, 3), axis=0).max()), 1e-300)

        def same(a, b, wa, wb):
            return bool(np.abs(a - b).max() <= tol and (wa is None or np.abs(wa - wb).max() <= 1e-12 * wa.max()))

        cu = same(P[0], P[-1], None if W is None else W[0], None if W is None else W[-1])
        cv = same(P[:, 0], P[:, -1], None if W is None else W[:, 0], None if W is None else W[:, -1])
        return cu, cv

    @cached_property
    def _seed_grid(self):
        """(u, v, kd-tree) of a coarse grid for projection starts: a few samples per knot span."""
        from scipy.spatial import cKDTree

        gu = span_samples(self.knots_u, self.degree[0], 4, cap=400)
        gv = span_samples(self.knots_v, self.degree[1], 4, cap=400)
        U, V = np.meshgrid(gu, gv, indexing="ij")
        pts = self.evaluate(U.ravel(), V.ravel())
        return U.ravel(), V.ravel(), cKDTree(pts)

    def project(self, points, *, initial=None, tol: float = 1e-10, max_iter: int = 40,
                chunk: int = 100000) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Closest points on the patch (within its domain) to ``points``.

        Vectorised Newton iteration on ``½|S(u, v) − x|²``, started from the nearest node of a
        coarse parameter grid (a few samples per knot span) found with a KD-tree, with the step
        clamped to the domain and halved while it does not decrease the distance.  Where the
        Hessian is not positive definite the Gauss–Newton step is used.

        Parameters
        ----------
        points : (k, 3) float
            Query points, m.
        initial : ((k,), (k,)) float, optional
            Starting parameters (e.g. from a previous projection); default: the coarse grid.
        tol : float
            Stop when the step moves the surface point less than ``tol`` metres.
        max_iter : int
            Newton iterations at most.

        Returns
        -------
        u, v : (k,) float
            Parameters of the closest points.
        distance : (k,) float
            Distances, m.
        """
        X = np.asarray(points, float)
        if X.ndim != 2 or X.shape[1] != 3:
            raise InputError(f"expected points of shape (k, 3), got {X.shape}")
        if not np.isfinite(X).all():
            raise InputError("points to project contain NaN or infinite values")
        u = np.empty(len(X))
        v = np.empty(len(X))
        if initial is None:
            gu, gv, tree = self._seed_grid
            _, idx = tree.query(X)
            u[:], v[:] = gu[idx], gv[idx]
        else:
            (u0, u1), (v0, v1) = self.domain
            u[:] = np.clip(np.asarray(initial[0], float).ravel(), u0, u1)
            v[:] = np.clip(np.asarray(initial[1], float).ravel(), v0, v1)
        for lo in range(0, len(X), chunk):
            hi = min(lo + chunk, len(X))
            u[lo:hi], v[lo:hi] = self._newton(X[lo:hi], u[lo:hi], v[lo:hi], tol, max_iter)
        dist = np.linalg.norm(self.evaluate(u, v) - X, axis=1)
        return u, v, dist

    def _newton(self, X, u, v, tol, max_iter):
        (u0, u1), (v0, v1) = self.domain
        u, v = u.copy(), v.copy()
        active = np.arange(len(X))
        D = self.derivatives(u, v, 2)
        for _ in range(max_iter):
            if active.size == 0:
                break
            Da = D
            S, Su, Sv = Da[:, 0, 0], Da[:, 1, 0], Da[:, 0, 1]
            r = S - X[active]
            f0 = np.einsum("ij,ij->i", r, r)
            g = np.stack([np.einsum("ij,ij->i", r, Su), np.einsum("ij,ij->i", r, Sv)], axis=1)
            H = np.empty((active.size, 2, 2))
            H[:, 0, 0] = np.einsum("ij,ij->i", Su, Su) + np.einsum("ij,ij->i", r, Da[:, 2, 0])
            H[:, 1, 1] = np.einsum("ij,ij->i", Sv, Sv) + np.einsum("ij,ij->i", r, Da[:, 0, 2])
            H[:, 0, 1] = H[:, 1, 0] = np.einsum("ij,ij->i", Su, Sv) + np.einsum("ij,ij->i", r, Da[:, 1, 1])
            det = H[:, 0, 0] * H[:, 1, 1] - H[:, 0, 1] ** 2
            bad = (det <= 1e-12 * np.abs(H[:, 0, 0] * H[:, 1, 1])) | (H[:, 0, 0] <= 0)
            if np.any(bad):   # Gauss–Newton where Newton's Hessian is indefinite
                H[bad, 0, 0] = np.einsum("ij,ij->i", Su[bad], Su[bad])
                H[bad, 1, 1] = np.einsum("ij,ij->i", Sv[bad], Sv[bad])
                H[bad, 0, 1] = H[bad, 1, 0] = np.einsum("ij,ij->i", Su[bad], Sv[bad])
            H[:, 0, 0] += 1e-300
            H[:, 1, 1] += 1e-300
            step = -np.linalg.solve(H, g[..., None])[..., 0]
            ua, va = u[active], v[active]
            alpha = np.ones(active.size)
            todo = np.arange(active.size)
            nu_, nv_ = ua.copy(), va.copy()
            Dn = np.empty_like(Da)
            for _halving in range(8):
                cu = self._wrap_or_clip(ua[todo] + alpha[todo] * step[todo, 0], u0, u1, self.closed[0])
                cv = self._wrap_or_clip(va[todo] + alpha[todo] * step[todo, 1], v0, v1, self.closed[1])
                Dt = self.derivatives(cu, cv, 2)
                rt = Dt[:, 0, 0] - X[active[todo]]
                ft = np.einsum("ij,ij->i", rt, rt)
                ok = ft <= f0[todo] * (1 + 1e-12) + 1e-30
                nu_[todo[ok]], nv_[todo[ok]] = cu[ok], cv[ok]
                Dn[todo[ok]] = Dt[ok]
                todo = todo[~ok]
                if todo.size == 0:
                    break
                alpha[todo] *= 0.5
            # points whose line search failed keep their current parameters (and are converged)
            Dn[todo] = Da[todo]
            moved = np.linalg.norm(Dn[:, 0, 0] - Da[:, 0, 0], axis=1)
            u[active], v[active] = nu_, nv_
            keep = moved > tol
            keep[todo] = False
            active = active[keep]
            D = Dn[keep]
        return u, v

    @staticmethod
    def _wrap_or_clip(x, lo, hi, closed):
        if closed:
            return lo + np.mod(x - lo, hi - lo)
        return np.clip(x, lo, hi)

    # --- conversion -------------------------------------------------------------------------------
    def grid_parameters(self, *, resolution=None, spacing: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Parameter values of a sampling grid, ``(nu_s,)`` and ``(nv_s,)``.

        Parameters
        ----------
        resolution : int or (int, int), optional
            Samples per direction, uniform in the parameters.
        spacing : float, optional
            Target distance between samples, m: samples are spaced uniformly in arc length along
            the averaged iso-parameter curves.  Default (neither given): spacing =
            max(2 mm, longest extent / 400).
        """
        if resolution is not None and spacing is not None:
            raise InputError("give either resolution or spacing, not both")
        (u0, u1), (v0, v1) = self.domain
        if resolution is not None:
            res = np.broadcast_to(np.asarray(resolution), (2,))
            try:
                ru, rv = (int(r) for r in res)
            except (TypeError, ValueError):
                raise InputError(f"resolution must be an int or a pair of ints, got {resolution!r}") from None
            if ru < 2 or rv < 2:
                raise InputError(f"resolution must be at least 2 samples per direction, got {resolution!r}")
            return np.linspace(u0, u1, ru), np.linspace(v0, v1, rv)
        gu = span_samples(self.knots_u, self.degree[0], 8, cap=4000)
        gv = span_samples(self.knots_v, self.degree[1], 8, cap=4000)
        cu = np.linspace(v0, v1, 5)
        cv = np.linspace(u0, u1, 5)
        Pu = self.evaluate(np.repeat(gu[None, :], 5, 0).ravel(), np.repeat(cu[:, None], gu.size, 1).ravel())
        Pv = self.evaluate(np.repeat(cv[:, None], gv.size, 1).ravel(), np.repeat(gv[None, :], 5, 0).ravel())
        su = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(Pu.reshape(5, -1, 3), axis=1), axis=2).mean(0))])
        sv = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(Pv.reshape(5, -1, 3), axis=1), axis=2).mean(0))])
        if spacing is None:
            spacing = max(2e-3, max(su[-1], sv[-1]) / 400.0)
        if not (np.isfinite(spacing) and spacing > 0):
            raise InputError(f"spacing must be a positive length in metres, got {spacing!r}")
        nu_s = max(int(np.ceil(su[-1] / spacing)), 1) + 1
        nv_s = max(int(np.ceil(sv[-1] / spacing)), 1) + 1
        if nu_s * nv_s > 5_000_000:
            raise InputError(f"spacing {spacing:g} m gives {nu_s}x{nv_s} samples; choose a larger spacing")
        return (np.interp(np.linspace(0, su[-1], nu_s), su, gu),
                np.interp(np.linspace(0, sv[-1], nv_s), sv, gv))

    def to_surface(self, *, resolution=None, spacing: float | None = None, name: str | None = None):
        """Triangulate the patch into a swath :class:`~swath.surface.Surface`.

        Vertices lie on the patch at the grid of :meth:`grid_parameters` (row-major in u, so vertex
        ``i * nv_s + j`` is at ``(u_i, v_j)``); triangles are wound so that their normals point to
        the patch's normal side.

        Parameters
        ----------
        resolution : int or (int, int), optional
            Samples per direction, uniform in the parameters.
        spacing : float, optional
            Target vertex spacing, m (see :meth:`grid_parameters`).
        name : str, optional
            Name of the surface (default: the patch's name).
        """
        from .grid import grid_faces
        from .surface import Surface

        gu, gv = self.grid_parameters(resolution=resolution, spacing=spacing)
        U, V = np.meshgrid(gu, gv, indexing="ij")
        verts = self.evaluate(U.ravel(), V.ravel())
        return Surface(verts, grid_faces(gu.size, gv.size), name=self.name if name is None else name)

    # --- serialisation ----------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """A JSON-ready description (lengths in metres)."""
        return {
            "type": JSON_TYPE,
            "version": JSON_VERSION,
            "name": self.name,
            "units": "m",
            "degree": list(self.degree),
            "knots_u": self.knots_u.tolist(),
            "knots_v": self.knots_v.tolist(),
            "control_points": self.control_points.tolist(),
            "weights": None if self.weights is None else self.weights.tolist(),
        }

    @classmethod
    def from_dict(cls, data: dict) -> BSplinePatch:
        """Rebuild a patch from :meth:`to_dict` output.

        Raises
        ------
        InputError
            When keys are missing, the type or version is not one swath writes, or the arrays are
            inconsistent.
        """
        if not isinstance(data, dict):
            raise InputError(f"expected a JSON object describing a B-spline patch, got {type(data).__name__}")
        if data.get("type") != JSON_TYPE:
            raise InputError(f"not a swath B-spline patch: \"type\" is {data.get('type')!r}, expected {JSON_TYPE!r}")
        if data.get("version") != JSON_VERSION:
            raise InputError(f"unsupported patch format version {data.get('version')!r}; this swath reads "
                             f"version {JSON_VERSION}")
        if data.get("units", "m") != "m":
            raise InputError(f"patch units must be 'm', got {data.get('units')!r}")
        missing = [k for k in ("degree", "knots_u", "knots_v", "control_points") if k not in data]
        if missing:
            raise InputError(f"patch description lacks {', '.join(missing)}")
        try:
            ctrl = np.array(data["control_points"], dtype=float)
            ku = np.array(data["knots_u"], dtype=float)
            kv = np.array(data["knots_v"], dtype=float)
            w = None if data.get("weights") is None else np.array(data["weights"], dtype=float)
        except (TypeError, ValueError) as exc:
            raise InputError(f"patch arrays are not numeric or ragged: {exc}") from None
        return cls(ctrl, ku, kv, tuple(data["degree"]) if isinstance(data["degree"], list) else data["degree"],
                   w, name=str(data.get("name", "")))


def _forms(D: np.ndarray):
    """First form ``(k,2,2)``, second form ``(k,2,2)`` and unit normals ``(k,3)`` from derivatives."""
    Su, Sv = D[:, 1, 0], D[:, 0, 1]
    n = normalize(np.cross(Su, Sv))
    I = np.empty((len(D), 2, 2))
    II = np.empty((len(D), 2, 2))
    I[:, 0, 0] = np.einsum("ij,ij->i", Su, Su)
    I[:, 1, 1] = np.einsum("ij,ij->i", Sv, Sv)
    I[:, 0, 1] = I[:, 1, 0] = np.einsum("ij,ij->i", Su, Sv)
    II[:, 0, 0] = np.einsum("ij,ij->i", n, D[:, 2, 0])
    II[:, 1, 1] = np.einsum("ij,ij->i", n, D[:, 0, 2])
    II[:, 0, 1] = II[:, 1, 0] = np.einsum("ij,ij->i", n, D[:, 1, 1])
    return I, II, n


def principal_from_derivatives(D: np.ndarray) -> PrincipalCurvature:
    """Principal curvatures and directions from derivatives ``(k, >=3, >=3, 3)`` of a surface.

    Solves ``det(II + k I) = 0`` (swath's sign: convex toward the normal ``S_u × S_v`` positive)
    in closed form; the direction of ``k1`` is the null vector of ``II + k1 I`` mapped to 3D, and
    ``d2 = n × d1``.  At umbilics ``d1`` is along ``S_u``.
    """
    I, II, n = _forms(D)
    E, F, G = I[:, 0, 0], I[:, 0, 1], I[:, 1, 1]
    L, M, N = II[:, 0, 0], II[:, 0, 1], II[:, 1, 1]
    det_I = E * G - F * F
    H = -(L * G + N * E - 2 * M * F) / (2 * det_I)
    K = (L * N - M * M) / det_I
    root = np.sqrt(np.maximum(H * H - K, 0.0))
    k1, k2 = H + root, H - root
    # Null vector of [[L + kE, M + kF], [M + kF, N + kG]] for k = k1 (two candidate rows).
    a, b, c = L + k1 * E, M + k1 * F, N + k1 * G
    w1 = np.stack([-b, a], axis=1)
    w2 = np.stack([c, -b], axis=1)
    use2 = np.linalg.norm(w2, axis=1) > np.linalg.norm(w1, axis=1)
    w = np.where(use2[:, None], w2, w1)
    Su, Sv = D[:, 1, 0], D[:, 0, 1]
    d1 = w[:, :1] * Su + w[:, 1:] * Sv
    # At (near-)umbilics every tangent is principal: take S_u.
    umbilic = root <= 1e-6 * (np.abs(H) + np.sqrt(np.abs(K))) + 1e-300
    d1 = np.where(umbilic[:, None] | (np.linalg.norm(d1, axis=1) == 0)[:, None], Su, d1)
    d1 = normalize(d1 - np.einsum("ij,ij->i", d1, n)[:, None] * n)
    d2 = np.cross(n, d1)
    return PrincipalCurvature(k1, k2, d1, d2)
