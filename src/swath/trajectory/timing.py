"""Time a ToolPath into a Trajectory: contact passes under speed limits, links through the air.

The call shape follows toppra: a path, a list of constraint objects, and the result is again a
path (here a :class:`Trajectory`)::

    trajectory = time_path(toolpath, [FeedLimit(0.05), CentripetalLimit(2.0), AngularSpeedLimit(1.0),
                                      TangentialAccelLimit(1.0)], links=LinkSettings(clearance=0.02))

Contact passes
--------------
Each pass is densified onto the surface and resampled at equal arc-length steps ``h``
(``h ≤ 1 mm`` and ``h ≤ 0.95 · feed · 20 ms``, and fine enough that the surface normal turns by
at most 2° per step, down to 0.1 mm — a sharp leading edge is sampled at about 0.2 mm, so that
interpolating between samples follows the surface's own normal field).  On that grid:

1. the tool frame follows FORMATS.md and the Darboux frame of the pass: ``z = −n`` (the smooth
   surface normal), ``x`` = the travel direction in the tangent plane, ``y = z × x``.  The travel
   direction is averaged over a Gaussian window of ``heading_scale`` (default 5 mm), so that where
   a pass turns sharply (the corner of a zig-zag) the tool turns about its axis over about
   ±2·heading_scale instead of spinning on the spot; on smooth passes it is the tangent.
2. every constraint caps the speed at each grid point (see :mod:`.constraints`): the feed, a feed
   profile, ``sqrt(a_c / κ)`` with the path curvature κ read at the limit's ``scale``, and
   ``ω_max / ρ`` with ρ the frame's rotation per metre on the grid steps either side;
3. a tangential acceleration limit turns the caps into the largest profile whose ``v²`` changes by
   at most ``2·a_t·Δs`` per step (forward and backward sweep, rest at the pass ends by default);
4. between grid points ``v²`` is linear in arc length (constant acceleration), which gives the
   time of every step; steps longer than 19 ms are split in time, so samples stay within 2 mm and
   20 ms (FORMATS.md) with a 5 % margin at any speed.

Angular velocity
----------------
``ω`` (the ``wx, wy, wz`` columns) is the discrete derivative of the written frames:
``Ω_j = log(R[j+1] R[j]ᵀ) / Δs_j`` per grid step (rad/m, part frame, ``Δs_j`` the chord) times the
speed; at grid points the mean of the two adjacent steps.  Between grid points the frame turns
uniformly in arc length (slerp), so integrating the written ω reproduces the written quaternions.
It equals the Darboux formula ``v·(τ_g T − κ_n B + κ_g n)`` (:func:`.geometry.darboux`) wherever
the heading is not smoothed — ``tests/test_timing_limits.py`` checks one against the other on a
helix on a cylinder (κ_g = 0, κ_n = −cos²α/R, τ_g = sinα cosα/R).

Lead angle
----------
``time_path(..., lead_angle=θ)`` turns every contact frame by ``θ`` about its y-axis
(:func:`.orientation.with_lead`): the pad's leading edge lifts and it presses with its trailing
part (``Tool.half_pad_lead`` makes that exactly half the pad on a plane).  The TCP stays on the
surface; the contact model finds the pad's sink for the tilted face.  The trajectory's metadata
says so (``tool_tilt``, ``lead_angle_rad``, ``lead_end_ramp_m``), as FORMATS.md asks of a
deliberate tilt.

Over the last :func:`lead_end_ramp` of each pass the turn falls linearly to none, so the pad is
flat where the pass ends.  A led pad lifts its front: at a pass that ends at the part's edge the
patch ahead of its last pose is never touched, and on a 0.35 m bowl planned at 11° that left 1.5 %
of the part untouched at the pass ends (98.5 % covered); with the pad laid flat over the last
10 mm every point is touched and the default job's interior CoV moves from 0.065 to 0.066 (a
0.4 m saddle at 15°, 14 mm: 98.5 % covered to all of it, 0.075 to 0.076).  Running the pass on past the edge instead over-grinds the
rim (the pad hanging over the edge presses its whole force there).  The ramp is as long as the
angular speed limit needs to lay the pad flat at the full feed (:func:`lead_end_ramp`), so on a
straight pass end the limit does not slow the feed; elsewhere the turn is the same for every
frame, so ω, the angular-speed caps and the timing do not change.

Links
-----
Approach, retract and air moves are rounded and timed with toppra (:mod:`.links`).
"""

from __future__ import annotations

import logging
import weakref

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from ..contact.widths import surface_memo
from ..core import Pass, ToolPath
from ..errors import InputError
from ..order.routing import AirGuard
from ..surface.polyline import densify, resample_uniform
from .constraints import (
    CONSTRAINT_TYPES,
    AngularSpeedLimit,
    CentripetalLimit,
    FeedLimit,
    FeedProfile,
    PassGrid,
    TangentialAccelLimit,
    speed_profile,
)
from .geometry import rotation_steps, smoothed_directions
from .links import LinkSettings, time_link
from .orientation import make_continuous, quaternions_from_frames, tool_frames, with_lead_ramped
from .trajectory import Trajectory

log = logging.getLogger(__name__)

#: FORMATS.md: in-contact samples at most this far apart (m) ...
MAX_CONTACT_STEP = 2e-3
#: ... and at most this long apart (s).
MAX_CONTACT_DT = 0.02
#: Safety factor on both, so rounding in the CSV never crosses them.
_MARGIN = 0.95
#: Largest grid step along contact passes (m): also bounds the chord error to h²κ/8.
GRID_STEP = 1e-3
#: Largest turn of the surface normal between grid points (rad); passes where the normal turns
#: faster are sampled more finely, down to MIN_GRID_STEP (m).
MAX_NORMAL_TURN = np.deg2rad(2.0)
MIN_GRID_STEP = 1e-4

__all__ = ["FeedLimit", "FeedProfile", "CentripetalLimit", "AngularSpeedLimit", "TangentialAccelLimit",
           "LinkSettings", "time_path", "speed_profile", "MAX_CONTACT_STEP", "MAX_CONTACT_DT"]


def time_path(toolpath: ToolPath, constraints=None, *, links: LinkSettings | None = None,
              heading_scale: float = 5e-3, lead_angle: float = 0.0, timed: list | None = None) -> Trajectory:
    """Turn ``toolpath`` into timed TCP poses.

    Parameters
    ----------
    toolpath : ToolPath
        The passes to time, in order.
    constraints : sequence, optional
        Constraint objects, each with a ``speed_cap(grid)`` method (:mod:`.constraints`): exactly
        one :class:`FeedLimit`, and at most one of each kind (default: ``[FeedLimit()]``).
    links : LinkSettings, optional
        Clearance, speed (m/s), acceleration (m/s²) and sample step (m) of the air links.
    heading_scale : float
        Gaussian scale, m, over which the tool's x-axis (heading) follows the travel direction
        (default 5 mm; 0 = the raw chord direction).
    lead_angle : float
        Tilt of the tool about its y-axis in contact, rad (default 0: ``z = −normal``); positive
        lifts the pad's leading edge (module notes).  ``Tool.half_pad_lead`` presses half the pad.
    timed : list, optional
        What :func:`time_passes` returned for this very tool path, constraints, heading scale and
        lead angle: the passes are not timed again.

    Returns
    -------
    Trajectory
        With ``feed`` (commanded speed, m/s), ``pass_index`` and the extra columns ``wx, wy, wz``
        (angular velocity of the tool frame, rad/s, part frame).

    Raises
    ------
    InputError
        On unknown or repeated constraints, a missing feed, an empty tool path, a feed profile that
        does not match the passes, a negative ``heading_scale`` or a lead angle outside ±45°.
    """
    cons, step, lead_angle = _checked(toolpath, constraints, heading_scale, lead_angle)
    ramp = lead_end_ramp(cons, lead_angle)
    links = LinkSettings() if links is None else links
    feed = cons[FeedLimit].speed
    angular = cons.get(AngularSpeedLimit)
    omega_max = angular.omega_max if angular else None
    surface = toolpath.surface
    # routes between the same pass ends are found once per surface and clearance (re-timing a plan
    # with another feed, as the feed optimisation does, asks for every link again)
    guard = AirGuard(surface, links.clearance, memo=surface_memo(surface, ("air routes", links.clearance), dict))

    if timed is None:
        timed = [_time_pass(i, p, surface, step, list(cons.values()), heading_scale, lead_angle, ramp)
                 for i, p in enumerate(toolpath.passes)]
    elif len(timed) != len(toolpath.passes):
        raise InputError(f"timed holds {len(timed)} passes, the tool path {len(toolpath.passes)}; give what "
                         "time_passes returned for this tool path")
    out: dict[str, list] = {k: [] for k in ("pos", "quat", "contact", "feed", "pass", "t", "omega")}
    clock = 0.0
    methods = {"toppra": 0, "trapezoid": 0, "none": 0}

    def emit(pos, quat, contact, speed, pass_i, omega, t_rel, duration):
        nonlocal clock
        out["pos"].append(pos), out["quat"].append(quat), out["contact"].append(np.full(len(pos), contact))
        out["feed"].append(speed), out["pass"].append(np.full(len(pos), pass_i)), out["omega"].append(omega)
        out["t"].append(clock + t_rel)
        clock += duration

    def emit_link(route, q_from, q_to, **kw):
        lp = time_link(route, q_from, q_to, links, omega_max=omega_max, **kw)
        methods[lp.method] += 1
        emit(lp.position, lp.quaternion, False, lp.speed, -1, lp.omega, lp.t, lp.duration)

    first, last = timed[0], timed[-1]
    above = first["position"][0] + links.clearance * first["normal_start"]
    emit_link(np.array([above, first["position"][0]]), first["quaternion"][0], first["quaternion"][0],
              include_end=False)
    for i, tp in enumerate(timed):
        emit(tp["position"], tp["quaternion"], True, tp["speed"], i, tp["omega"], tp["t"], tp["t"][-1])
        if i + 1 < len(timed):
            nxt = timed[i + 1]
            if toolpath.links is not None:              # routed by the order stage
                route = toolpath.links[i].waypoints
            else:
                route = guard.route(tp["position"][-1], tp["normal_end"], nxt["position"][0], nxt["normal_start"])
            emit_link(route, tp["quaternion"][-1], nxt["quaternion"][0], include_start=False, include_end=False)
    above = last["position"][-1] + links.clearance * last["normal_end"]
    emit_link(np.array([last["position"][-1], above]), last["quaternion"][-1], last["quaternion"][-1],
              include_start=False)
    if methods["trapezoid"]:
        log.warning("%d of %d links were timed with the trapezoidal fallback", methods["trapezoid"],
                    sum(methods.values()))

    t = np.concatenate(out["t"])
    omega = np.concatenate(out["omega"])
    meta = {"feed_m_per_s": feed, "clearance_m": links.clearance, "link_speed_m_per_s": links.speed,
            "link_accel_m_per_s2": links.acceleration, "tool_tilt": describe_lead(lead_angle, ramp),
            "lead_angle_rad": lead_angle, "lead_end_ramp_m": ramp,
            "heading_scale_m": heading_scale, "contact_grid_step_m": step,
            "angular_velocity": "discrete derivative of the tool frames (part frame)",
            "link_timing": methods, "constraints": [_describe(c) for c in cons.values()]}
    return Trajectory(t=t - t[0], position=np.concatenate(out["pos"]),
                      quaternion=make_continuous(np.concatenate(out["quat"])),
                      contact=np.concatenate(out["contact"]), feed=np.concatenate(out["feed"]),
                      pass_index=np.concatenate(out["pass"]).astype(int),
                      extra={"wx": omega[:, 0], "wy": omega[:, 1], "wz": omega[:, 2]}, metadata=meta)


def time_passes(toolpath: ToolPath, constraints=None, *, heading_scale: float = 5e-3,
                lead_angle: float = 0.0) -> list:
    """The contact half of :func:`time_path`: every pass of ``toolpath`` timed on its own, under the
    same checks and arguments.  Give the list to :func:`time_path` (``timed=``) to finish the
    trajectory without timing the passes again.

    :func:`contact_duration` of the list (s) is a lower bound of that trajectory's cycle time (the
    links only add time), so a caller ranking candidate tool paths by cycle time can stop here for
    a candidate whose contact time alone exceeds the best cycle time found so far.

    Returns
    -------
    list of dict
        One record per pass, in order: positions ``(k, 3)`` m, quaternions ``(k, 4)``, speeds m/s,
        times ``t`` ``(k,)`` s from the pass's start, angular velocities ``(k, 3)`` rad/s.
    """
    cons, step, lead_angle = _checked(toolpath, constraints, heading_scale, lead_angle)
    ramp = lead_end_ramp(cons, lead_angle)
    return [_time_pass(i, p, toolpath.surface, step, list(cons.values()), heading_scale, lead_angle, ramp)
            for i, p in enumerate(toolpath.passes)]


def contact_duration(timed: list) -> float:
    """Seconds in contact of the passes :func:`time_passes` timed: the sum of their durations."""
    return float(sum(tp["t"][-1] for tp in timed))


def links_duration_bound(toolpath: ToolPath, timed: list, links: LinkSettings | None = None,
                         omega_max: float | None = None) -> float:
    """A lower bound (s) of the time :func:`time_path` spends on the air links of ``toolpath``,
    whose passes :func:`time_passes` timed as ``timed``.

    Every link is flown rest to rest along a route at least as long as the straight chord between
    its ends, at a TCP speed at most ``links.speed`` and a tangential acceleration at most
    ``links.acceleration``: the shortest such motion over a length ``L`` takes ``L/v + v/a``
    (``2 sqrt(L/a)`` when it cannot reach ``v``).  With ``omega_max`` (rad/s, the job's
    :class:`AngularSpeedLimit`) it also turns the tool from the last pose of one pass to the first
    of the next, an angle ``θ`` taking at least ``θ / omega_max``; a link takes the longer of the
    two.  The approach and the retreat each cover the clearance.  The sum is scaled by 0.95, a
    margin for the timing's discretisation.
    """
    links = LinkSettings() if links is None else links
    v, a = links.speed, links.acceleration
    pairs = list(zip(timed, timed[1:]))
    if toolpath.links is not None:
        chords = [float(np.linalg.norm(k.waypoints[-1] - k.waypoints[0])) for k in toolpath.links]
    else:
        chords = [float(np.linalg.norm(nxt["position"][0] - tp["position"][-1])) for tp, nxt in pairs]
    lengths = np.array(chords + [links.clearance, links.clearance])
    least = np.where(lengths >= v * v / a, lengths / v + v / a, 2.0 * np.sqrt(lengths / a))
    if omega_max is not None and pairs and len(chords) == len(pairs):
        dots = np.array([abs(float(np.dot(tp["quaternion"][-1], nxt["quaternion"][0]))) for tp, nxt in pairs])
        turns = 2.0 * np.arccos(np.clip(dots, 0.0, 1.0)) / omega_max
        least[:len(pairs)] = np.maximum(least[:len(pairs)], turns)
    return 0.95 * float(least.sum())


def _checked(toolpath, constraints, heading_scale, lead_angle):
    """The constraints by type, the contact grid step (m) and the checked lead angle (rad) of a
    timing request; refuses a bad one (see :func:`time_path`)."""
    cons = _collect([FeedLimit()] if constraints is None else constraints)
    feed = cons[FeedLimit].speed
    if not toolpath.passes:
        raise InputError("the tool path has no passes to time")
    if not (np.isfinite(heading_scale) and heading_scale >= 0):
        raise InputError(f"heading_scale must be a length >= 0 in m, got {heading_scale!r}")
    lead_angle = check_lead_angle(lead_angle)
    for c in cons.values():
        if hasattr(c, "check"):
            c.check(toolpath.passes)
    return cons, min(GRID_STEP, _MARGIN * feed * MAX_CONTACT_DT, _MARGIN * MAX_CONTACT_STEP), lead_angle


def _collect(constraints) -> dict:
    """Constraints by type; checks that each caps the speed, none is repeated, and a feed is given."""
    if hasattr(constraints, "speed_cap"):
        constraints = [constraints]
    cons = {}
    for c in constraints:
        kind = type(c)
        if not callable(getattr(c, "speed_cap", None)):
            names = ", ".join(k.__name__ for k in CONSTRAINT_TYPES)
            raise InputError(f"time_path does not know the constraint {c!r}: a constraint needs a speed_cap(grid) "
                             f"method (swath's own: {names})")
        if kind in cons:
            raise InputError(f"time_path got two {kind.__name__} constraints; give each kind at most once")
        cons[kind] = c
    if FeedLimit not in cons:
        raise InputError("time_path needs exactly one FeedLimit (the feed along contact passes)")
    return cons


def _describe(c) -> dict:
    d: dict[str, object] = {"type": type(c).__name__}
    if isinstance(c, FeedProfile):
        d["passes"] = len(c.speeds)
    else:
        d.update({k: v for k, v in vars(c).items()})
    return d


def check_lead_angle(lead_angle) -> float:
    """``lead_angle`` (rad) as a float, refused unless finite and within ±45° (a pad tilted further
    presses on its rim alone)."""
    try:
        value = float(lead_angle)
    except (TypeError, ValueError):
        raise InputError(f"the lead angle must be an angle in rad, got {lead_angle!r}") from None
    if not (np.isfinite(value) and abs(value) <= np.pi / 4):
        raise InputError(f"the lead angle must lie within ±45° (±0.785 rad), got {lead_angle!r} rad")
    return value


def describe_lead(lead_angle: float, ramp: float = 0.0) -> str:
    """The ``tool_tilt`` line of a trajectory's metadata for a lead angle (rad) laid flat over the
    last ``ramp`` m of each pass."""
    if lead_angle == 0.0:
        return "none (z = -surface normal)"
    flat = (f"; the turn falls linearly to none over the last {ramp * 1e3:.3g} mm of each pass (the pad flat "
            "where the pass ends)") if ramp > 0 else ""
    return (f"lead {np.degrees(lead_angle):.2f} deg about tool y in contact: z = -surface normal turned toward the "
            f"travel direction, the pad's {'leading' if lead_angle > 0 else 'trailing'} edge lifted{flat}")


#: The least length (m) over which a pass's lead is laid flat at its end (:func:`lead_end_ramp`).
LEAD_END_RAMP_MIN = 3e-3
#: The angular speed (rad/s) the ramp is sized for when the job sets no limit: the default limit.
LEAD_END_RAMP_OMEGA = 1.0


def lead_end_ramp(constraints: dict, lead_angle: float) -> float:
    """The length (m) over which a pass's lead falls to none at its end (module notes): the turn
    ``|θ|`` at 0.95 of the angular speed limit at the full feed, ``|θ| · v / (0.95 ω_max)``, at
    least :data:`LEAD_END_RAMP_MIN`; 0 without a lead.  ``constraints``: by type, as
    :func:`time_path` collects them."""
    if lead_angle == 0.0:
        return 0.0
    angular = constraints.get(AngularSpeedLimit)
    omega = angular.omega_max if angular is not None else LEAD_END_RAMP_OMEGA
    return max(abs(lead_angle) * constraints[FeedLimit].speed / (0.95 * omega), LEAD_END_RAMP_MIN)


def _pass_geometry(p: Pass, surface, step: float, heading_scale: float, lead_angle: float = 0.0,
                   ramp: float = 0.0) -> dict:
    """What timing a pass needs that no speed limit changes: its grid (arc length ``s`` (n,) m on
    the chords, points and unit normals (n, 3), fractional source index ``u`` (n,), step ``h`` m),
    the tool's quaternions (n, 4), the chord of each step ``ds`` (n-1,) m and the tool's rotation
    per metre on each step ``Omega`` (n-1, 3) rad/m and at each grid point ``rho_node`` (n,).
    ``ds``, ``Omega`` and ``rho_node`` are absent for a pass of zero length.

    Kept with the pass (while it lives) for the same surface, grid step, heading scale, lead
    angle and end ramp (m), read-only: the feed optimisation times the same passes with a new feed
    profile up to a dozen times."""
    known = _PASS_GEOMETRY.get(p)
    if known is not None and known[0]() is surface and known[1] == (step, heading_scale, lead_angle, ramp):
        return known[2]
    s, pts, nrm, u = _grid(p, surface, step)
    s, pts, nrm, u = _refine(s, pts, nrm, u, surface)
    h = float(s[1] - s[0]) if len(s) > 1 else 0.0
    frames = tool_frames(nrm, smoothed_directions(pts, max(h, 1e-12), heading_scale))
    if lead_angle != 0.0:
        chords = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        left = np.concatenate([np.cumsum(chords[::-1])[::-1], [0.0]])     # arc length to the pass's end
        frames = with_lead_ramped(frames, lead_angle, left, ramp)
    g = {"s": s, "points": pts, "normals": nrm, "u": u, "h": h, "quaternion": quaternions_from_frames(frames)}
    if h > 1e-12:
        # The grid is uniform up to the projection of refined points; time with the true chords.
        ds = np.maximum(np.linalg.norm(np.diff(pts, axis=0), axis=1), 1e-12)
        g["ds"], g["s"] = ds, np.concatenate([[0.0], np.cumsum(ds)])
        g["Omega"] = rotation_steps(frames) / ds[:, None]                       # (n−1, 3) rad/m
        rho = np.linalg.norm(g["Omega"], axis=1)
        g["rho_node"] = np.maximum(np.concatenate([[0.0], rho]), np.concatenate([rho, [0.0]]))
    for v in g.values():
        if isinstance(v, np.ndarray):
            v.setflags(write=False)
    _PASS_GEOMETRY[p] = (weakref.ref(surface), (step, heading_scale, lead_angle, ramp), g)
    return g


#: :func:`_pass_geometry` of each pass: ``(surface weakref, (step, heading_scale, lead_angle, ramp), geometry)``.
_PASS_GEOMETRY: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _time_pass(index: int, p: Pass, surface, step: float, constraints: list, heading_scale: float,
               lead_angle: float = 0.0, ramp: float = 0.0) -> dict:
    """Sample and time one contact pass (see the module notes)."""
    g = _pass_geometry(p, surface, step, heading_scale, lead_angle, ramp)
    s, pts, nrm, u, h, quat = g["s"], g["points"], g["normals"], g["u"], g["h"], g["quaternion"]
    if h <= 1e-12:                                   # a pass of zero length: touch and go
        k = len(pts)
        return {"position": pts, "quaternion": quat, "speed": np.zeros(k), "omega": np.zeros((k, 3)),
                "t": np.zeros(k), "normal_start": nrm[0], "normal_end": nrm[-1]}
    ds, Omega, rho_node = g["ds"], g["Omega"], g["rho_node"]
    grid = PassGrid(index=index, s=s, points=pts, spacing=h, rotation_per_metre=rho_node, source_index=u)
    caps = np.full(len(s), np.inf)
    for c in constraints:
        cap = c.speed_cap(grid)
        if cap is not None:
            caps = np.minimum(caps, cap)
    shapers = [c for c in constraints if hasattr(c, "shape_profile")]
    v = caps
    for c in shapers:
        v = c.shape_profile(v, s)

    # Time each grid step (constant acceleration), then split steps longer than the time limit.
    dt = 2.0 * ds / np.maximum(v[:-1] + v[1:], 1e-300)
    acc = (v[1:] ** 2 - v[:-1] ** 2) / (2.0 * ds)
    n_sub = np.maximum(np.ceil(dt / (_MARGIN * MAX_CONTACT_DT) - 1e-9).astype(int), 1)
    j = np.repeat(np.arange(len(dt)), n_sub)
    k = np.arange(len(j)) - np.repeat(np.cumsum(n_sub) - n_sub, n_sub)
    tau = k * dt[j] / n_sub[j]
    frac = np.clip((v[j] * tau + 0.5 * acc[j] * tau**2) / ds[j], 0.0, 1.0)
    frac[k == 0] = 0.0
    t_grid = np.concatenate([[0.0], np.cumsum(dt)])
    t_out = np.concatenate([t_grid[j] + tau, t_grid[-1:]])
    speed = np.concatenate([v[j] + acc[j] * tau, v[-1:]])
    pos = np.concatenate([pts[j] + frac[:, None] * (pts[j + 1] - pts[j]), pts[-1:]])
    rot = Slerp(np.arange(len(s), dtype=float), Rotation.from_quat(quat, scalar_first=True))(
        np.concatenate([j + frac, [len(s) - 1.0]]))
    # Rotation per metre at each sample: its grid step's, or the mean of both at a grid point.
    node = np.vstack([Omega[:1], 0.5 * (Omega[:-1] + Omega[1:]), Omega[-1:]])
    rate = np.concatenate([np.where((k == 0)[:, None], node[j], Omega[j]), node[-1:]])
    return {"position": pos, "quaternion": rot.as_quat(scalar_first=True), "speed": speed,
            "omega": rate * speed[:, None], "t": t_out, "normal_start": nrm[0], "normal_end": nrm[-1]}


def _grid(p: Pass, surface, step: float):
    """Arc length, points, unit normals and fractional original index on a uniform grid of
    spacing at most ``step`` (m) along pass ``p`` (densified onto the surface first)."""
    dense, u = _densify(p, surface, step)
    n_grid = max(int(np.ceil(dense.length / step - 1e-9)), 2) + 1          # at least 3 grid points
    s, pts, nrm, u = resample_uniform(dense.points, dense.length / (n_grid - 1) if dense.length > 0 else step,
                                      dense.normals, u)
    nrm = nrm / np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-300)
    return s, pts, nrm, u


def _refine(s, pts, nrm, u, surface):
    """Where the surface normal turns by more than MAX_NORMAL_TURN per grid step (a sharp leading
    edge), refine the whole grid uniformly so that it does not, down to MIN_GRID_STEP, and take the
    new points in those fast-turning stretches from the surface itself (projection and its smooth
    normals): interpolating between samples then follows the surface's own normal field there.
    Elsewhere the new points are interpolated along the grid."""
    if len(s) < 2:
        return s, pts, nrm, u
    turn = np.arccos(np.clip(np.einsum("ij,ij->i", nrm[1:], nrm[:-1]), -1.0, 1.0))     # per step
    h = s[1] - s[0]
    if turn.max() <= MAX_NORMAL_TURN or h <= MIN_GRID_STEP:
        return s, pts, nrm, u
    fine = max(h * MAX_NORMAL_TURN / turn.max(), MIN_GRID_STEP)
    s2, pts2, nrm2, u2 = resample_uniform(pts, fine, nrm, u)
    step_of = np.clip(np.searchsorted(s, s2, side="right") - 1, 0, len(turn) - 1)
    fast = turn > 0.5 * MAX_NORMAL_TURN
    fast = fast | np.concatenate([[False], fast[:-1]]) | np.concatenate([fast[1:], [False]])
    sel = fast[step_of]
    if sel.any():
        closest, _, face = surface.closest_points(pts2[sel])
        pts2[sel] = closest
        nrm2[sel] = surface.interpolate_normals(closest, face)
    nrm2 /= np.maximum(np.linalg.norm(nrm2, axis=1, keepdims=True), 1e-300)
    return s2, pts2, nrm2, u2


#: Densified passes (:func:`_densify`) kept while their pass lives, by surface and step: a job times
#: the same passes again and again (the feed programme five to seven times, the leads compared, the
#: job's own timing), and projecting the new points on the surface is a fifth of each timing.
_DENSE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _densify(p: Pass, surface, step: float) -> tuple[Pass, np.ndarray]:
    """Insert points so consecutive points are at most ``step`` apart, projected back on the surface.

    Returns the densified pass and, per point, its fractional index in the original pass (read-only;
    computed once per pass, surface and step)."""
    seg = np.linalg.norm(np.diff(p.points, axis=0), axis=1)
    if seg.max(initial=0.0) <= step * 1.0001:
        return p, np.arange(len(p.points), dtype=float)
    key = (id(surface), float(step))
    kept = _DENSE.get(p, {}).get(key)
    if kept is not None and kept[0]() is surface:
        return kept[1]
    dense, u = _densify_pass(p, surface, step)
    u.setflags(write=False)
    try:
        _DENSE.setdefault(p, {})[key] = (weakref.ref(surface), (dense, u))
    except TypeError:                             # a surface that cannot be weakly referred to: not kept
        pass
    return dense, u


def _densify_pass(p: Pass, surface, step: float) -> tuple[Pass, np.ndarray]:
    """:func:`_densify` of a pass with a step over ``step``, without the keeping."""
    pts, u = densify(p.points, step)
    new = u != np.round(u)
    out_pts, out_n = pts.copy(), np.empty_like(pts)
    out_n[~new] = p.normals[np.round(u[~new]).astype(int)]
    if new.any():
        closest, _, face = surface.closest_points(pts[new])
        out_pts[new] = closest
        out_n[new] = surface.interpolate_normals(closest, face)
    return Pass(out_pts, out_n), u
