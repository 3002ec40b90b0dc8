"""Time a ToolPath into a Trajectory: contact passes at the feed, links through the air between them.

The call shape follows toppra: a path, a list of constraint objects, and the result is again a
path (here a :class:`Trajectory`)::

    trajectory = time_path(toolpath, [FeedLimit(0.05)], links=LinkSettings(clearance=0.02))
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from ..errors import InputError
from ..plan.toolpath import Pass, ToolPath
from .orientation import make_continuous, pass_tangents, quaternions_from_frames, tool_frames
from .trajectory import Trajectory

log = logging.getLogger(__name__)

#: FORMATS.md: in-contact samples at most this far apart (m) ...
MAX_CONTACT_STEP = 2e-3
#: ... and at most this long apart (s).
MAX_CONTACT_DT = 0.02


@dataclass(frozen=True)
class FeedLimit:
    """Constant feed (TCP speed along contact passes), m/s."""

    speed: float = 0.05

    def __post_init__(self):
        if not (np.isfinite(self.speed) and self.speed > 0):
            raise InputError(f"feed must be a positive speed, got {self.speed!r} m/s")


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
        TCP acceleration on links (trapezoidal speed profile), m/s² (default 1 m/s²).
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


def time_path(toolpath: ToolPath, constraints=(FeedLimit(),), *, links: LinkSettings = LinkSettings()) -> Trajectory:
    """Turn ``toolpath`` into timed TCP poses.

    Contact passes run at the feed of the :class:`FeedLimit` in ``constraints``, sampled at most
    2 mm and 20 ms apart (passes are densified on the surface if their points are sparser).  Each
    pass is entered by an approach along the surface normal and left by a retract; air moves between
    passes keep clear of the part.  The tool frame follows FORMATS.md: z = −normal, x = travel.

    Parameters
    ----------
    toolpath : ToolPath
    constraints : sequence
        Constraint objects; here :class:`FeedLimit` (required).
    links : LinkSettings

    Returns
    -------
    Trajectory
        With ``feed`` (m/s) and ``pass_index`` per sample.
    """
    feeds = [c for c in constraints if isinstance(c, FeedLimit)]
    unknown = [c for c in constraints if not isinstance(c, FeedLimit)]
    if unknown:
        raise InputError(f"time_path does not know the constraint(s) {unknown}; supported: FeedLimit")
    if len(feeds) != 1:
        raise InputError("time_path needs exactly one FeedLimit (the feed along contact passes)")
    feed = feeds[0].speed
    if not toolpath.passes:
        raise InputError("the tool path has no passes to time")
    surface = toolpath.surface
    # 5 % below the FORMATS.md limits so rounding in the CSV never crosses them.
    step = 0.95 * min(MAX_CONTACT_STEP, feed * MAX_CONTACT_DT)
    guard = _AirGuard(surface, links.clearance)

    # Each piece: positions, quaternions, contact, feed, pass index, and the time of each sample
    # relative to the start of the piece's route.  Links do not repeat the pass endpoints.
    passes = [_densify(p, surface, step) for p in toolpath.passes]
    frames = [quaternions_from_frames(tool_frames(p.normals, pass_tangents(p.points))) for p in passes]
    out = {k: [] for k in ("pos", "quat", "contact", "feed", "pass", "t")}
    clock = 0.0

    def emit(pos, quat, contact, feed_v, pass_i, t_rel, duration):
        nonlocal clock
        out["pos"].append(pos), out["quat"].append(quat), out["contact"].append(contact)
        out["feed"].append(feed_v), out["pass"].append(pass_i), out["t"].append(clock + t_rel)
        clock += duration

    first, last = passes[0], passes[-1]
    above = first.points[0] + links.clearance * first.normals[0]
    emit(*_link_piece(np.array([above, first.points[0]]), frames[0][0], frames[0][0], links, include_end=False))
    for i, (p, q) in enumerate(zip(passes, frames)):
        n = len(p.points)
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p.points, axis=0), axis=1))])
        emit(p.points, q, np.ones(n, bool), np.full(n, feed), np.full(n, i), s / feed, s[-1] / feed)
        if i + 1 < len(passes):
            nxt = passes[i + 1]
            route = guard.route(p.points[-1], p.normals[-1], nxt.points[0], nxt.normals[0])
            emit(*_link_piece(route, q[-1], frames[i + 1][0], links, include_start=False, include_end=False))
    above = last.points[-1] + links.clearance * last.normals[-1]
    emit(*_link_piece(np.array([last.points[-1], above]), frames[-1][-1], frames[-1][-1], links,
                      include_start=False))

    t = np.concatenate(out["t"])
    return Trajectory(t=t - t[0], position=np.concatenate(out["pos"]),
                      quaternion=make_continuous(np.concatenate(out["quat"])),
                      contact=np.concatenate(out["contact"]), feed=np.concatenate(out["feed"]),
                      pass_index=np.concatenate(out["pass"]).astype(int),
                      metadata={"feed_m_per_s": feed, "clearance_m": links.clearance,
                                "link_speed_m_per_s": links.speed, "tool_tilt": "none (z = -surface normal)"})


def _densify(p: Pass, surface, step: float) -> Pass:
    """Insert points so consecutive points are at most ``step`` apart, projected back on the surface."""
    seg = np.linalg.norm(np.diff(p.points, axis=0), axis=1)
    if seg.max(initial=0.0) <= step * 1.0001:
        return p
    n_sub = np.maximum(np.ceil(seg / step).astype(int), 1)
    frac = np.concatenate([np.arange(k) / k for k in n_sub])
    seg_id = np.repeat(np.arange(len(seg)), n_sub)
    pts = p.points[seg_id] + frac[:, None] * (p.points[seg_id + 1] - p.points[seg_id])
    pts = np.vstack([pts, p.points[-1:]])
    new = frac > 0
    new = np.concatenate([new, [False]])
    out_pts, out_n = pts.copy(), np.empty_like(pts)
    out_n[~new] = p.normals[np.concatenate([seg_id[frac == 0], [len(p.points) - 1]])]
    if new.any():
        closest, _, face = surface.closest_points(pts[new])
        out_pts[new] = closest
        out_n[new] = surface.interpolate_normals(closest, face)
    return Pass(out_pts, out_n)


def _trapezoid_times(s: np.ndarray, vmax: float, amax: float) -> np.ndarray:
    """Times at arc lengths ``s`` (increasing from 0) for a rest-to-rest trapezoidal speed profile."""
    L = s[-1]
    if L <= 0:
        return np.zeros_like(s)
    s_acc = vmax * vmax / (2 * amax)
    if 2 * s_acc > L:              # triangular profile
        s_acc = L / 2
        vmax = np.sqrt(amax * L)
    t_acc = vmax / amax
    t_cruise = (L - 2 * s_acc) / vmax
    t = np.where(s < s_acc, np.sqrt(2 * np.maximum(s, 0) / amax),
                 np.where(s <= L - s_acc, t_acc + (s - s_acc) / vmax,
                          t_acc + t_cruise + t_acc - np.sqrt(2 * np.maximum(L - s, 0) / amax)))
    return t


def _link_piece(route: np.ndarray, q_from: np.ndarray, q_to: np.ndarray, links: LinkSettings, *,
                include_start: bool = True, include_end: bool = True):
    """Sample a link polyline ``route`` (r, 3) and time it with a trapezoidal profile."""
    seg = np.linalg.norm(np.diff(route, axis=0), axis=1)
    pieces = []
    for a, b, L in zip(route[:-1], route[1:], seg):
        n = max(int(np.ceil(L / links.step)), 1)
        pieces.append(a + np.linspace(0, 1, n, endpoint=False)[:, None] * (b - a))
    pts = np.vstack(pieces + [route[-1:]])
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    t = _trapezoid_times(s, links.speed, links.acceleration)
    speed = np.gradient(s, t, edge_order=1) if len(t) > 1 and t[-1] > 0 else np.zeros_like(s)
    speed = np.nan_to_num(np.clip(speed, 0, links.speed))
    frac = s / s[-1] if s[-1] > 0 else np.zeros_like(s)
    key = Rotation.from_quat(np.array([q_from, q_to]), scalar_first=True)
    q = Slerp([0.0, 1.0], key)(frac).as_quat(scalar_first=True)
    keep = np.ones(len(pts), bool)
    keep[0] &= include_start
    keep[-1] &= include_end
    n = int(keep.sum())
    # Time is measured from the route's start; the piece lasts until the route's end.
    return pts[keep], q[keep], np.zeros(n, bool), speed[keep], np.full(n, -1), t[keep], float(t[-1])


class _AirGuard:
    """Finds air routes between passes that keep clear of the part."""

    def __init__(self, surface, clearance: float):
        self.surface = surface
        self.clearance = clearance
        lo, hi = surface.bounds
        self.center = 0.5 * (lo + hi)
        self.radius = 0.5 * float(np.linalg.norm(hi - lo)) + 2 * clearance

    def _clear(self, route: np.ndarray) -> bool:
        seg = np.linalg.norm(np.diff(route, axis=0), axis=1)
        pts = [a + np.linspace(0, 1, max(int(np.ceil(L / (0.25 * self.clearance))), 1), endpoint=False)[:, None] * (b - a)
               for a, b, L in zip(route[:-1], route[1:], seg)]
        pts = np.vstack(pts + [route[-1:]])
        _, dist, _ = self.surface.closest_points(pts)
        return bool(dist.min() >= 0.5 * self.clearance * 0.999)

    def route(self, p_end, n_end, p_start, n_start) -> np.ndarray:
        """Waypoints from ``p_end`` (leaving along ``n_end``) to ``p_start`` (arriving along ``n_start``)."""
        c = self.clearance
        up_a, up_b = p_end + c * n_end, p_start + c * n_start
        direct = np.array([p_end, up_a, up_b, p_start])
        if self._clear(direct[1:3]):
            return direct
        mid = 0.5 * (up_a + up_b)
        dirs = []
        avg = n_end + n_start
        if np.linalg.norm(avg) > 0.3:
            dirs.append(avg / np.linalg.norm(avg))
        out = mid - self.center
        if np.linalg.norm(out) > 1e-9:
            dirs.append(out / np.linalg.norm(out))
        for u in dirs:
            h = c
            while h < 4 * self.radius:
                route = np.array([p_end, up_a, up_a + h * u, up_b + h * u, up_b, p_start])
                if self._clear(route[1:5]):
                    return route
                h *= 2
        # Guaranteed fallback: out to a sphere around the whole part, along it, and back in.
        return np.vstack([[p_end, up_a], self._sphere_arc(up_a, up_b), [up_b, p_start]])

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
