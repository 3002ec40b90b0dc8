"""Air routing between passes: every link a route that keeps clear of the part and near it.

The order stage decides which pass follows which; here each move from one pass's lift-off to the
next pass's touch-down gets its waypoints (:func:`route_links` fills :attr:`ToolPath.links`).  The
trajectory stage times the routes (toppra) and routes any tool path that has no links yet the
same way.
"""

from __future__ import annotations

import logging

import numpy as np

from ..core import Link, ToolPath
from ..errors import InputError

log = logging.getLogger(__name__)


#: Pad radius (m) assumed by :class:`AirGuard` when the caller does not give one (a 3-inch pad).
DEFAULT_PAD_RADIUS = 0.0381


def _fibonacci_sphere(n: int) -> np.ndarray:
    """``n`` unit vectors ``(n, 3)`` spread evenly over the sphere (a Fibonacci lattice)."""
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    phi = np.pi * (3.0 - np.sqrt(5.0)) * k
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


_SPHERE = _fibonacci_sphere(64)


class AirGuard:
    """Finds air routes between passes that keep clear of the part and stay near it.

    Every waypoint lies inside the part's bounding box grown by ``pad_radius + clearance`` (the
    *reach box*): the tool lifts off along the surface normal (tilted where that runs into the
    part, :meth:`_lift`), and a lifted route rises along the mean normal of its two ends, the part's
    best-fit normal, away from the part's centre or, where those all run into the part, one of 64
    directions spread over the sphere, by heights that double from the clearance up to the reach
    box's face; the last resort runs round the part on the sphere about it, pulled into the reach
    box.  Routes that still pass closer than half the clearance are logged and listed in
    :attr:`near_part`.  (Before, lifts doubled up to four times the part's half-diagonal and the
    last resort ran on a sphere outside the box: on a 2 m panel that put air moves 1.8 m beyond
    the part.)

    Parameters
    ----------
    surface : Surface
    clearance : float
        Lift off the surface before an air move, m; routes keep at least half of it from the surface.
    pad_radius : float
        The pad radius, m (default :data:`DEFAULT_PAD_RADIUS`): part of the reach-box margin.
    memo : dict, optional
        Where the routes found are remembered, keyed by their ends: give the same dict to every
        guard of the same surface, clearance and pad radius to share them (it holds arrays only,
        so it may outlive the guard).
    """

    def __init__(self, surface, clearance: float, *, pad_radius: float = DEFAULT_PAD_RADIUS,
                 memo: dict | None = None):
        if not (np.isfinite(pad_radius) and pad_radius >= 0):
            raise InputError(f"pad_radius must be a length >= 0 m, got {pad_radius!r}")
        self.surface = surface
        self.clearance = clearance
        lo, hi = surface.bounds
        self.margin = pad_radius + clearance
        self.box = np.array([lo - self.margin, hi + self.margin])
        self.center = 0.5 * (lo + hi)
        self.radius = 0.5 * float(np.linalg.norm(hi - lo)) + 2 * clearance
        axes = surface.principal_axes[1]
        up = np.asarray(axes[2], float)
        if up @ (surface.face_normals * surface.face_areas[:, None]).sum(axis=0) < 0:
            up = -up
        self.up = up
        self._max_edge = float(surface.edge_lengths.max())
        self._routes: dict[tuple, np.ndarray] = {} if memo is None else memo
        #: ends ``(p_end, p_start)`` of the routes this guard found that pass closer than half the
        #: clearance to the part (a route taken from a shared memo is not listed again)
        self.near_part: list[tuple[np.ndarray, np.ndarray]] = []

    def _clear(self, route: np.ndarray) -> bool:
        seg = np.linalg.norm(np.diff(route, axis=0), axis=1)
        pieces = [a + np.linspace(0, 1, max(int(np.ceil(L / (0.25 * self.clearance))), 1), endpoint=False)[:, None] * (b - a)
               for a, b, L in zip(route[:-1], route[1:], seg)]
        pts = np.vstack(pieces + [route[-1:]])
        limit = 0.5 * self.clearance * 0.999
        # Exact shortcut before the closest-point search (the same answer as
        # ``closest_points(pts)[1].min() >= limit``, at a fraction of the cost: far from the part
        # that search visits many boxes).  Every vertex is a surface point, so a vertex nearer than
        # the limit means not clear; and every surface point lies within ``max_edge`` (the longest
        # edge) of a vertex, so a point whose nearest vertex is farther than ``limit + max_edge``
        # is clear.  Only the points in between are searched.  The relative margins (1e-9) are far
        # above the round-off of either distance.
        bound = (limit + self._max_edge) * (1.0 + 1e-9) + 1e-12
        vertex_distance, _ = self.surface.kdtree.query(pts, distance_upper_bound=bound)
        if bool((vertex_distance < limit * (1.0 - 1e-9)).any()):
            return False
        near = np.isfinite(vertex_distance)
        if not near.any():
            return True
        _, dist, _ = self.surface.closest_points(pts[near])
        return bool(dist.min() >= limit)

    def _reach(self, p: np.ndarray, u: np.ndarray) -> float:
        """Largest t >= 0 with p + t u inside the reach box (0 if p is outside)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            t_hi = np.where(u > 0, (self.box[1] - p) / u, np.where(u < 0, (self.box[0] - p) / u, np.inf))
        return max(float(np.min(t_hi)), 0.0)

    def route(self, p_end, n_end, p_start, n_start) -> np.ndarray:
        """Waypoints ``(r, 3)`` (m) from ``p_end`` (leaving along ``n_end``) to ``p_start`` (arriving
        along ``n_start``).  Routes found before by this guard are remembered (the same ends give
        the same route; re-timing a plan asks for every link again)."""
        given = (p_end, n_end, p_start, n_start)
        key = (np.ascontiguousarray(given, float).tobytes(), tuple(np.asarray(a).dtype.str for a in given))
        known = self._routes.get(key)
        if known is None:
            known = self._routes[key] = self._route(*given)
            known.setflags(write=False)
        return known.copy()

    def _lift(self, p: np.ndarray, n: np.ndarray) -> np.ndarray:
        """Top ``(3,)`` (m) of the lift off (or the descent onto) the surface point ``p`` with unit
        normal ``n``: ``clearance`` along ``n`` where that keeps clear of the part.  Where it runs
        into the part (a pass ending against a fold or under an overhang of a scan: bezier_dac_scan
        had lift tops 0.1-2 mm from the surface, so no route from them could be clear), the first
        of ``n`` tilted toward the part's up direction, the up direction, ``n`` tilted away from the
        part's centre and the direction away from it, then ``n`` tilted by 30° and 45° toward eight
        sides, within 60° of ``n``, whose lift keeps clear.  None clear: along ``n`` (the route's
        search then says so)."""
        c = self.clearance
        given = n                                    # as given first: the lift every route had before
        n = n / max(float(np.linalg.norm(n)), 1e-12)
        for u in self._lift_directions(p, given, n):
            # its upper quarter keeps clear (lower, a scan's noisy normal tilts the lift toward the
            # surface near its foot: 10° puts 10 mm along it 9.95 mm high); tilted lifts start
            # where they are 0.6 of the clearance high on a flat surface
            s0 = min(max(0.75, 0.6 / max(float(u @ n), 1e-12)), 1.0)
            if self._clear(np.array([p + s0 * c * u, p + c * u])):
                return p + c * u
        return p + c * given

    def _lift_directions(self, p: np.ndarray, given: np.ndarray, n: np.ndarray):
        """The lift directions :meth:`_lift` tries at ``p``, in order: ``given``, then the tilted ones
        (see there; ``n`` is ``given`` made unit).  A generator: most lifts keep clear along the
        normal as given, and the others are worked out only when it does not."""
        yield given
        away = p - self.center
        away = away / max(float(np.linalg.norm(away)), 1e-12)
        e1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(n, e1)
        phi = np.arange(8) * np.pi / 4
        fan = [np.cos(t) * n + np.sin(t) * (np.cos(f) * e1 + np.sin(f) * e2)
               for t in np.radians([30.0, 45.0]) for f in phi]
        for v in [n + self.up, self.up, n + away, away, *fan]:
            length = float(np.linalg.norm(v))
            if length > 1e-9 and float(v @ n) / length >= 0.5:
                yield v / length

    def _route(self, p_end, n_end, p_start, n_start) -> np.ndarray:
        c = self.clearance
        up_a, up_b = self._lift(p_end, n_end), self._lift(p_start, n_start)
        direct = np.array([p_end, up_a, up_b, p_start])
        if self._clear(direct[1:3]):
            return direct
        mid = 0.5 * (up_a + up_b)
        dirs = []
        avg = n_end + n_start
        if np.linalg.norm(avg) > 0.3:
            dirs.append(avg / np.linalg.norm(avg))
        dirs.append(self.up)
        out = mid - self.center
        if np.linalg.norm(out) > 1e-9:
            dirs.append(out / np.linalg.norm(out))
        # then 64 directions spread over the sphere, nearest the first choice first: where a scan
        # folds over the pass ends all three can run into it (bezier_dac_scan: a tenth of all
        # directions clears such a link, none of the three)
        fan = _SPHERE[np.argsort(-(_SPHERE @ dirs[0]), kind="stable")]
        for u in [*dirs, *fan]:
            h_max = min(self._reach(up_a, u), self._reach(up_b, u))
            heights = [h for h in c * 2.0 ** np.arange(40) if h < h_max] + ([h_max] if h_max > 0 else [])
            for h in heights:
                route = np.array([p_end, up_a, up_a + h * u, up_b + h * u, up_b, p_start])
                if self._clear(route[1:5]):
                    return route
        # Last resort: round the part on the sphere about it, pulled into the reach box.
        arc = np.clip(self._sphere_arc(up_a, up_b), self.box[0], self.box[1])
        route = np.vstack([[p_end, up_a], arc, [up_b, p_start]])
        if not self._clear(route[1:-1]):
            self.near_part.append((np.array(p_end, float), np.array(p_start, float)))
            # debug only: planners and the order stage route links of plans they do not keep;
            # route_links warns about the kept plan's, in the user's unit
            log.debug("no air route found within %.0f mm of the part's bounding box between (%s) and (%s) m; "
                      "the link may pass closer than half the clearance", 1e3 * self.margin,
                      np.round(p_end, 4).tolist(), np.round(p_start, 4).tolist())
        return route

    def _sphere_arc(self, a, b) -> np.ndarray:
        ua = a - self.center
        ub = b - self.center
        ua /= max(np.linalg.norm(ua), 1e-12)
        ub /= max(np.linalg.norm(ub), 1e-12)
        ang = np.arccos(np.clip(np.dot(ua, ub), -1, 1))
        n = max(int(np.ceil(ang / 0.1)), 1) + 1
        if ang > np.pi - 1e-3:   # antipodal: go round via any perpendicular
            perp = np.cross(ua, [1.0, 0, 0] if abs(ua[0]) < 0.9 else [0, 1.0, 0])
            ub_mid = perp / np.linalg.norm(perp)
            return np.vstack([self._sphere_arc(a, self.center + ub_mid * self.radius)[:-1],
                              self._sphere_arc(self.center + ub_mid * self.radius, b)])
        w = np.linspace(0, 1, n)[:, None]
        dirs = np.sin((1 - w) * ang) * ua + np.sin(w * ang) * ub
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        return self.center + self.radius * dirs


def route_links(toolpath: ToolPath, *, clearance: float, pad_radius: float = DEFAULT_PAD_RADIUS,
                units: str = "m") -> ToolPath:
    """``toolpath`` with an air route (:class:`~swath.core.Link`) between every two consecutive passes:
    up ``clearance`` (m) along the surface normal, across clear of the part and inside its bounding
    box grown by ``pad_radius + clearance``, and down (:class:`AirGuard`).  The metadata gains
    ``air_route_length_m``, ``air_route_clearance_m`` and ``air_moves_near_part_count``; routes that
    pass closer than half the clearance make one warning (in the metadata's ``warnings``, which
    the job logs and reports) naming the passes they leave and the ends of the first few, in ``units`` (the length unit
    the part was read in: m, mm, cm or in)."""
    from ..units import canonical_length_unit, length_unit_factor

    if not (np.isfinite(clearance) and clearance > 0):
        raise InputError(f"clearance must be a positive length in m, got {clearance!r}")
    units = canonical_length_unit(units)
    per_unit = length_unit_factor(units)
    guard = AirGuard(toolpath.surface, clearance, pad_radius=pad_radius)
    passes = toolpath.passes
    links, near, ends = [], [], []
    for i, (a, b) in enumerate(zip(passes[:-1], passes[1:])):
        known = len(guard.near_part)
        links.append(Link(guard.route(a.points[-1], a.normals[-1] / np.linalg.norm(a.normals[-1]),
                                      b.points[0], b.normals[0] / np.linalg.norm(b.normals[0]))))
        if len(guard.near_part) > known:
            near.append(i + 1)                            # the pass it leaves, counted from 1
            ends.append((a.points[-1], b.points[0]))
    meta = dict(toolpath.metadata, air_route_length_m=float(sum(link.length for link in links)),
                air_route_clearance_m=float(clearance), air_moves_near_part_count=len(near))
    if near:
        # into the job's warnings (and its report), not only the log
        where = ", ".join(str(i) for i in near[:10]) + (", ..." if len(near) > 10 else "")
        # four significant figures of the part's extent in the user's unit
        extent = float(np.ptp(guard.box, axis=0).max()) - 2 * guard.margin
        digits = max(0, 4 - int(np.floor(np.log10(max(extent / per_unit, 1e-12)))))

        def point(p) -> str:
            return "(" + ", ".join(f"{x / per_unit:.{digits}f}" for x in p) + ")"

        shown = "; ".join(f"after pass {i}: {point(p)} to {point(q)}" for i, (p, q) in zip(near[:3], ends[:3]))
        message = (f"{len(near)} of {len(links)} air moves pass closer than half the clearance "
                   f"({0.5e3 * clearance:.0f} mm) to the part (after passes {where}): a pass ends in a fold "
                   "or under an overhang the tool cannot lift clear of; check those moves in the cell "
                   f"({shown}{'; ...' if len(near) > 3 else ''}; part coordinates in "
                   f"{'inches' if units == 'in' else units}), or plan another direction (--direction) so the "
                   "passes end elsewhere")
        meta["warnings"] = [*meta.get("warnings", []), message]   # the job logs and reports them
    return toolpath.replace(links=tuple(links), metadata=meta)
