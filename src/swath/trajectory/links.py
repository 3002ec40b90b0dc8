"""Air links between contact passes: clear routes round the part, timed with toppra.

A link leaves a pass along the surface normal (retract), crosses in the air at the clearance and
comes down along the normal at the next pass (approach).  Its corners are rounded with circular
arcs (tangent length at most 45 % of the adjacent straight pieces and at most the clearance, so
the first and last ~55 % of the retract and approach stay exactly along the normal).  The rounded
route is an exact line/arc path parameterised by arc length; toppra (TOPP-RA) times it rest to
rest under

* the link speed ``|v| ≤ LinkSettings.speed`` (and ``≤ ω_max / ρ`` while the tool turns, with an
  :class:`AngularSpeedLimit`),
* the link acceleration ``|a| ≤ LinkSettings.acceleration`` — the norm of the whole TCP
  acceleration, tangential and centripetal (``a = T s̈ + κ N ṡ²``), imposed as a 16-sided polygon
  inscribed in that disk (at most 2 % conservative) and exact between grid points because grid
  points sit on every line/arc joint.

toppra's joint-box constraints (``JointVelocityConstraint``, ``JointAccelerationConstraint``)
would bound each Cartesian component separately, not the TCP speed and acceleration, so two small
canonical linear constraints are defined here instead.  If toppra fails (or is missing) on a
link, a warning is logged and the link falls back to a rest-to-rest trapezoidal profile along the
unrounded route.

The tool keeps the orientation it had at the pass end while it retracts, turns (slerp, uniformly
in arc length) on the rounded air part, and holds the next pass's orientation while it approaches.
"""

from __future__ import annotations

import logging
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from ..errors import InputError

log = logging.getLogger(__name__)

#: Sides of the polygon inscribed in the acceleration disk.
_DISK_SIDES = 16


@dataclass(frozen=True)
class LinkSettings:
    """How the tool moves between passes.

    Attributes
    ----------
    clearance : float
        Lift off the surface along its normal before an air move, m (default 20 mm); air moves keep at
        least half of it from the surface.
    speed : float
        Top TCP speed on links, m/s (default 0.25 m/s).
    acceleration : float
        Top TCP acceleration on links (norm, tangential and centripetal together), m/s² (default 1 m/s²).
    step : float
        Sample spacing on links, m (default 5 mm).
    """

    clearance: float = 0.02
    speed: float = 0.25
    acceleration: float = 1.0
    step: float = 5e-3

    def __post_init__(self):
        for name in ("clearance", "speed", "acceleration", "step"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise InputError(f"link {name} must be positive, got {v!r}")


# --- the rounded route: lines and circular arcs, parameterised by arc length ---------------------

@dataclass(frozen=True)
class RoutePath:
    """An arc-length parameterised path of straight pieces and circular arcs.

    Attributes
    ----------
    start : (m,) float
        Arc length where each piece starts, m.
    length : (m,) float
        Piece lengths, m.
    origin : (m, 3) float
        Start point of each piece, m.
    direction : (m, 3) float
        Unit direction at the start of each piece.
    inward : (m, 3) float
        Unit vector toward the arc centre (zero for lines).
    radius : (m,) float
        Arc radius, m (``inf`` for lines).
    stops : (c,) float
        Arc lengths of cusps (the route reverses on itself): the speed must be zero there.
    """

    start: np.ndarray
    length: np.ndarray
    origin: np.ndarray
    direction: np.ndarray
    inward: np.ndarray
    radius: np.ndarray
    stops: np.ndarray

    @property
    def total(self) -> float:
        """Path length, m."""
        return float(self.start[-1] + self.length[-1]) if len(self.start) else 0.0

    @property
    def joints(self) -> np.ndarray:
        """Arc lengths of all piece boundaries, including 0 and the end, m."""
        return np.concatenate([self.start, [self.total]])

    def _piece(self, s: np.ndarray) -> np.ndarray:
        return np.clip(np.searchsorted(self.start, s, side="right") - 1, 0, len(self.start) - 1)

    def evaluate(self, s: np.ndarray, order: int = 0) -> np.ndarray:
        """Position (order 0), unit tangent (1) or curvature vector (2) at arc lengths ``s`` ``(k,)``."""
        s = np.asarray(s, float)
        i = self._piece(s)
        sig = np.clip(s - self.start[i], 0.0, self.length[i])
        d, m, r = self.direction[i], self.inward[i], self.radius[i]
        arc = np.isfinite(r)
        phi = np.where(arc, sig / np.where(arc, r, 1.0), 0.0)[:, None]
        rr = np.where(arc, r, 0.0)[:, None]
        if order == 0:
            line = self.origin[i] + sig[:, None] * d
            circ = self.origin[i] + rr * (np.sin(phi) * d + (1.0 - np.cos(phi)) * m)
            return np.where(arc[:, None], circ, line)
        if order == 1:
            return np.where(arc[:, None], np.cos(phi) * d + np.sin(phi) * m, d)
        if order == 2:
            k = np.where(arc, 1.0 / np.where(arc, r, 1.0), 0.0)[:, None]
            return k * (np.cos(phi) * m - np.sin(phi) * d)
        raise ValueError(f"order must be 0, 1 or 2, got {order}")

    def curvature_bound(self, s: np.ndarray) -> np.ndarray:
        """Curvature ``(k,)`` (1/m) at ``s``, the larger of both sides at a joint."""
        s = np.asarray(s, float)
        kap = np.where(np.isfinite(self.radius), 1.0 / np.where(np.isfinite(self.radius), self.radius, 1.0), 0.0)
        right = kap[self._piece(s)]
        left = kap[np.clip(np.searchsorted(self.start, s, side="left") - 1, 0, len(self.start) - 1)]
        return np.maximum(left, right)


def route_path(route: np.ndarray, *, blend: float | None) -> RoutePath:
    """The path along waypoints ``route`` ``(r, 3)`` with corners rounded by circular arcs whose
    tangent length is at most 45 % of each adjacent leg and at most ``blend`` (m); ``blend=None``
    keeps the sharp polyline."""
    pts = np.asarray(route, float)
    keep = np.concatenate([[True], np.linalg.norm(np.diff(pts, axis=0), axis=1) > 1e-9])
    pts = pts[keep]
    if len(pts) < 2:
        pts = np.vstack([pts[:1], pts[:1]])
    legs = np.diff(pts, axis=0)
    L = np.linalg.norm(legs, axis=1)
    d = legs / np.maximum(L, 1e-300)[:, None]
    n_corner = len(L) - 1
    b = np.zeros(len(L) + 1)          # tangent length cut at each waypoint (0 at the ends)
    cusp = np.zeros(len(L) + 1, bool)
    turn = np.zeros(len(L) + 1)
    if n_corner > 0:
        cosang = np.clip(np.einsum("ij,ij->i", d[:-1], d[1:]), -1.0, 1.0)
        turn[1:-1] = np.arccos(cosang)
        cusp[1:-1] = turn[1:-1] > np.pi - 1e-3
        if blend is not None:
            cut = np.minimum(0.45 * np.minimum(L[:-1], L[1:]), blend)
            b[1:-1] = np.where((turn[1:-1] > 1e-6) & ~cusp[1:-1], cut, 0.0)
    pieces = []          # (origin, direction, inward, radius, length)
    stops = []
    s = 0.0
    for k in range(len(L)):
        a = pts[k] + b[k] * d[k]
        line_len = L[k] - b[k] - b[k + 1]
        if line_len > 1e-12 or (b[k] == 0 and b[k + 1] == 0):
            pieces.append((a, d[k], np.zeros(3), np.inf, max(line_len, 0.0)))
            s += max(line_len, 0.0)
        if k + 1 < len(L):
            if b[k + 1] > 0:
                th = turn[k + 1]
                r = b[k + 1] / np.tan(0.5 * th)
                m = d[k + 1] - np.dot(d[k + 1], d[k]) * d[k]
                m /= np.linalg.norm(m)
                pieces.append((pts[k + 1] - b[k + 1] * d[k], d[k], m, r, r * th))
                s += r * th
            elif cusp[k + 1]:
                stops.append(s)
    origin, direction, inward, radius, length = (np.array(x, float) for x in zip(*pieces))
    start = np.concatenate([[0.0], np.cumsum(length)[:-1]])
    return RoutePath(start, length, origin.reshape(-1, 3), direction.reshape(-1, 3), inward.reshape(-1, 3),
                     radius, np.array(stops))


# --- timing --------------------------------------------------------------------------------

def _toppra_squared_speeds(path: RoutePath, grid: np.ndarray, cap: np.ndarray, accel: float) -> np.ndarray | None:
    """Time-optimal ``ṡ²`` ``(g,)`` at ``grid`` under ``ṡ ≤ cap`` and ``|a| ≤ accel``, rest to rest,
    by TOPP-RA; None if toppra is missing or fails."""
    try:
        import toppra
        from toppra.constraint import DiscretizationType, LinearConstraint
        from toppra.interpolator import AbstractGeometricPath
    except ImportError:                                  # pragma: no cover - toppra is a dependency
        log.warning("toppra is not installed (pip install toppra); links use a trapezoidal profile")
        return None

    class _Path(AbstractGeometricPath):
        def __call__(self, s, order=0):
            return path.evaluate(np.atleast_1d(s), order)

        @property
        def dof(self):
            return 3

        @property
        def path_interval(self):
            return np.array([0.0, path.total])

        @property
        def waypoints(self):
            return None

    class _SpeedCap(LinearConstraint):
        """``ṡ² ≤ cap²`` at each grid point (|p'| = 1, so ṡ is the TCP speed)."""

        def __init__(self):
            super().__init__()
            self.dof = 3
            self._format_string = "    TCP speed cap\n"

        def compute_constraint_params(self, _path, gridpoints):
            xb = np.zeros((len(gridpoints), 2))
            xb[:, 1] = cap**2
            return None, None, None, None, None, None, xb

    class _AccelDisk(LinearConstraint):
        """``(s̈, κ ṡ²)`` inside a polygon inscribed in the disk of radius ``accel``."""

        def __init__(self):
            super().__init__()
            self.dof = 3
            self.identical = True
            self.discretization_type = DiscretizationType.Interpolation
            self._format_string = "    TCP acceleration norm\n"

        def compute_constraint_params(self, _path, gridpoints):
            n = len(gridpoints)
            a = np.tile([1.0, 0.0], (n, 1))
            b = np.zeros((n, 2))
            b[:, 1] = path.curvature_bound(gridpoints)
            c = np.zeros((n, 2))
            phi = 2 * np.pi * np.arange(_DISK_SIDES) / _DISK_SIDES
            F = np.stack([np.cos(phi), np.sin(phi)], axis=1)
            g = np.full(_DISK_SIDES, accel * np.cos(np.pi / _DISK_SIDES))
            return a, b, c, F, g, None, None

    try:
        algo = toppra.algorithm.TOPPRA([_SpeedCap(), _AccelDisk()], _Path(), gridpoints=grid,
                                       solver_wrapper="seidel")
        _, sd, _ = algo.compute_parameterization(0.0, 0.0)
    except Exception as exc:  # noqa: BLE001 - toppra raises assorted errors on degenerate input
        log.warning("toppra failed on a link of %.4g m (%s); using a trapezoidal profile", path.total, exc)
        return None
    if sd is None or not np.all(np.isfinite(sd)):
        log.warning("toppra found no parameterisation for a link of %.4g m; using a trapezoidal profile", path.total)
        return None
    x = np.clip(np.asarray(sd, float) ** 2, 0.0, None)
    return np.minimum(x, cap**2)


def _grid(path: RoutePath, step: float, max_turn_deg: float = 10.0) -> np.ndarray:
    """Arc lengths on ``path``: every joint, plus equal steps ≤ ``step`` (m) and ≤ ``max_turn_deg`` on arcs."""
    out = []
    for s0, L, r in zip(path.start, path.length, path.radius):
        h = min(step, np.deg2rad(max_turn_deg) * r) if np.isfinite(r) else step
        n = max(int(np.ceil(L / h)), 1)
        out.append(s0 + L * np.arange(n) / n)
    out.append([path.total])
    g = np.concatenate(out)
    return g[np.concatenate([[True], np.diff(g) > 1e-12])]


def _times_from_squared_speeds(grid: np.ndarray, x: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Times and speeds at arc lengths ``s`` when ``ṡ²`` is linear in s between ``grid`` points
    (constant acceleration per interval) with values ``x``."""
    v = np.sqrt(x)
    dt = 2.0 * np.diff(grid) / np.maximum(v[:-1] + v[1:], 1e-300)
    tg = np.concatenate([[0.0], np.cumsum(dt)])
    i = np.clip(np.searchsorted(grid, s, side="right") - 1, 0, len(grid) - 2)
    frac = np.clip((s - grid[i]) / np.maximum(grid[i + 1] - grid[i], 1e-300), 0.0, 1.0)
    vs = np.sqrt(np.clip(x[i] + frac * (x[i + 1] - x[i]), 0.0, None))
    t = tg[i] + 2.0 * (s - grid[i]) / np.maximum(v[i] + vs, 1e-300)
    return t, vs


def trapezoid_times(s: np.ndarray, vmax: float, amax: float) -> np.ndarray:
    """Times at arc lengths ``s`` (increasing from 0, m) of a rest-to-rest trapezoidal speed profile
    with top speed ``vmax`` (m/s) and acceleration ``amax`` (m/s²)."""
    L = s[-1]
    if L <= 0:
        return np.zeros_like(s)
    s_acc = vmax * vmax / (2 * amax)
    if 2 * s_acc > L:              # triangular profile
        s_acc = L / 2
        vmax = np.sqrt(amax * L)
    t_acc = vmax / amax
    t_cruise = (L - 2 * s_acc) / vmax
    return np.where(s < s_acc, np.sqrt(2 * np.maximum(s, 0) / amax),
                    np.where(s <= L - s_acc, t_acc + (s - s_acc) / vmax,
                             t_acc + t_cruise + t_acc - np.sqrt(2 * np.maximum(L - s, 0) / amax)))


@dataclass(frozen=True)
class LinkPiece:
    """A sampled, timed link (see :func:`time_link`)."""

    position: np.ndarray     #: (k, 3) m
    quaternion: np.ndarray   #: (k, 4) scalar first
    speed: np.ndarray        #: (k,) m/s
    omega: np.ndarray        #: (k, 3) rad/s, part frame
    t: np.ndarray            #: (k,) s from the start of the route
    duration: float          #: s, the whole route
    method: str              #: "toppra", "trapezoid" (the fallback) or "none" (zero length)


#: Timed links by everything they are made from (see :func:`time_link`), oldest first.
_LINK_CACHE: OrderedDict = OrderedDict()
#: At most this many timed links are kept (a few kB each).
LINK_CACHE_SIZE = 4096


def clear_link_cache() -> None:
    """Forget every timed link (see :func:`time_link`): for tests that change how links are timed."""
    _LINK_CACHE.clear()


def time_link(route: np.ndarray, q_from: np.ndarray, q_to: np.ndarray, links: LinkSettings, *,
              omega_max: float | None = None, hold_ends: bool = True, include_start: bool = True,
              include_end: bool = True) -> LinkPiece:
    """Round, time and sample one link.

    A link timed before from the same route, orientations, settings and flags is returned again
    (its arrays read-only): re-timing a plan with another feed along its passes, as the feed
    optimisation does up to a dozen times, meets the same links, and toppra's reachability sweep
    is most of a link's cost (crs_part_5: 0.8 s of every re-timing).  The result is the same
    either way.

    Parameters
    ----------
    route : (r, 3) float
        Waypoints, m: for a link between passes the pass end, the point above it, (air
        waypoints,) the point above the next start and that start.
    q_from, q_to : (4,) float
        Tool orientation (scalar-first quaternion) at the start and the end.
    links : LinkSettings
    omega_max : float, optional
        Angular speed limit, rad/s, on the turn from ``q_from`` to ``q_to``.
    hold_ends : bool
        Keep the orientation fixed on the first and last straight piece (retract and approach)
        and turn only in between.
    include_start, include_end : bool
        Whether the first/last route point is among the returned samples (the duration always
        covers the whole route).
    """
    route = np.ascontiguousarray(route, float)
    q_from = np.ascontiguousarray(q_from, float)
    q_to = np.ascontiguousarray(q_to, float)
    key = (route.shape, route.tobytes(), q_from.tobytes(), q_to.tobytes(), links,
           None if omega_max is None else float(omega_max), bool(hold_ends), bool(include_start), bool(include_end))
    piece = _LINK_CACHE.get(key)
    if piece is not None:
        _LINK_CACHE.move_to_end(key)
        return piece
    piece = _time_link(route, q_from, q_to, links, omega_max=omega_max, hold_ends=hold_ends,
                       include_start=include_start, include_end=include_end)
    for a in (piece.position, piece.quaternion, piece.speed, piece.omega, piece.t):
        a.setflags(write=False)
    _LINK_CACHE[key] = piece
    while len(_LINK_CACHE) > LINK_CACHE_SIZE:
        _LINK_CACHE.popitem(last=False)
    return piece


def _time_link(route: np.ndarray, q_from: np.ndarray, q_to: np.ndarray, links: LinkSettings, *,
               omega_max: float | None, hold_ends: bool, include_start: bool, include_end: bool) -> LinkPiece:
    """:func:`time_link` itself, without the cache."""
    rot_from = Rotation.from_quat(q_from, scalar_first=True)
    rot_to = Rotation.from_quat(q_to, scalar_first=True)
    turn = (rot_to * rot_from.inv()).as_rotvec()          # part frame
    angle = float(np.linalg.norm(turn))

    def turning_span(path):
        """Arc-length interval where the tool turns, and the speed cap there."""
        s_a, s_b = 0.0, path.total
        if hold_ends and len(path.start) >= 3 and path.start[-1] - path.length[0] > 1e-9:
            s_a, s_b = float(path.length[0]), float(path.start[-1])
        cap = np.inf
        if omega_max is not None and angle > 1e-9:
            cap = omega_max * max(s_b - s_a, 1e-12) / angle
        return s_a, s_b, cap

    path = route_path(route, blend=links.clearance)
    s_a, s_b, turn_cap = turning_span(path)
    x = None
    if path.total > 1e-9:
        grid = np.unique(np.concatenate([_grid(path, min(links.step, 2.5e-3)), path.stops]))
        cap = np.full(len(grid), links.speed)
        turning = (grid >= s_a - 1e-12) & (grid <= s_b + 1e-12)
        cap[turning] = np.minimum(cap[turning], turn_cap)
        cap[np.isin(grid, path.stops)] = 0.0
        cap[0] = cap[-1] = 0.0
        x = _toppra_squared_speeds(path, grid, cap, links.acceleration)
    method = "toppra" if x is not None else "trapezoid"
    if path.total <= 1e-9:
        method = "none"                                   # nothing to move
    if x is None:
        path = route_path(route, blend=None)
        s_a, s_b, turn_cap = turning_span(path)
    s = _grid(path, links.step, 15.0)
    if method == "toppra" and x is not None:
        t, speed = _times_from_squared_speeds(grid, x, s)
        duration = float(t[-1])
    else:
        vmax = min(links.speed, turn_cap)
        t = trapezoid_times(s, vmax, links.acceleration)
        duration = float(t[-1])
        speed = np.zeros_like(s)
        if len(s) > 1 and duration > 0:
            speed = np.nan_to_num(np.clip(np.gradient(s, t), 0.0, vmax))
    pos = path.evaluate(s)
    frac = np.clip((s - s_a) / max(s_b - s_a, 1e-12), 0.0, 1.0)
    key = Rotation.from_quat(np.array([q_from, q_to]), scalar_first=True)
    q = Slerp([0.0, 1.0], key)(frac).as_quat(scalar_first=True)
    rate = np.zeros((len(s), 3))
    if angle > 1e-9:
        rate[(s > s_a) & (s < s_b)] = turn / max(s_b - s_a, 1e-12)
    omega = rate * speed[:, None]
    keep = np.ones(len(s), bool)
    keep[0] &= include_start
    keep[-1] &= include_end
    return LinkPiece(pos[keep], q[keep], speed[keep], omega[keep], t[keep], duration, method)
