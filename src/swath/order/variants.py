"""Path types (variants) of pass groups and what links between them cost (Wang §4).

:func:`group_variants` enumerates each group's path types with their touch-down and lift-off
points and frames; :class:`LinkModel` costs a link by air length or by time
(:func:`link_time_estimate`: the trajectory stage's rounded link, timed in closed form, the tool
turning at the angular-speed limit); :func:`contact_cost` costs a step-over made in contact;
:func:`link_matrix` and :func:`tour_length` cost whole tours.  The solvers are in
:mod:`swath.order.tour`.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import pairwise

import numpy as np

from ..errors import InputError


@dataclass(frozen=True)
class LinkModel:
    """How a link between two passes is costed.

    Attributes
    ----------
    clearance : float
        Lift along the normal before and after the move, m.
    speed : float or None
        Link speed, m/s; None costs links by length (m) instead of time (s).
    acceleration : float
        Link acceleration, m/s² (rest-to-rest trapezoid).
    omega_max : float or None
        Angular speed limit of the tool, rad/s: the link lasts at least the turn from the lift-off
        frame to the touch-down frame (tool z = -normal, x = travel direction) divided by it.
    feed : float or None
        Contact feed, m/s: with ``speed``, step-overs made in contact cost the contact time they
        add (:func:`contact_cost`); None: they cost :meth:`straight_time`.
    """

    clearance: float = 0.02
    speed: float | None = None
    acceleration: float = 1.0
    omega_max: float | None = None
    feed: float | None = None

    def __post_init__(self):
        if not (np.isfinite(self.clearance) and self.clearance >= 0):
            raise InputError(f"clearance must be a length >= 0 m, got {self.clearance!r}")
        for name in ("speed", "omega_max", "feed"):
            v = getattr(self, name)
            if v is not None and not (np.isfinite(v) and v > 0):
                raise InputError(f"link {name} must be positive or None, got {v!r}")
        if not (np.isfinite(self.acceleration) and self.acceleration > 0):
            raise InputError(f"link acceleration must be positive, got {self.acceleration!r} m/s²")

    @property
    def timed(self) -> bool:
        return self.speed is not None

    def length(self, exit_p, exit_n, entry_p, entry_n) -> np.ndarray:
        """Retract + straight move at the clearance + approach, m (broadcasts over leading axes)."""
        c = self.clearance
        return 2 * c + np.linalg.norm((exit_p + c * exit_n) - (entry_p + c * entry_n), axis=-1)

    def cost(self, length, exit_frame, entry_frame) -> np.ndarray:
        """Link time (s) for a link of route ``length`` (m) between frames ``(..., 3, 3)``, or the
        length if untimed.

        The time is that of the trajectory stage's rounded, toppra-timed link
        (:mod:`swath.trajectory.links`), estimated in closed form: the route is a retract of
        ``clearance`` along the normal, a move of ``length - 2 clearance`` and an approach; its two
        corners (taken as right angles) are rounded with the stage's arcs (tangent length
        ``min(clearance, 0.45 x the shorter leg)``) and passed at most at ``sqrt(a r)``; the tool
        turns only between retract and approach, at most at ``omega_max``; rest to rest, at the
        acceleration ``a`` (the stage's 16-gon inscribed in the acceleration disk, ``0.981 a``).
        On the hub's links this is within 0.05 s of the timed trajectory (the earlier estimate,
        ``max(trapezoid, turn / omega_max)``, was 0.24-0.40 s short per link).
        """
        if self.speed is None:
            return length
        return link_time_estimate(length, _turn_angle(exit_frame, entry_frame), clearance=self.clearance,
                                  speed=self.speed, acceleration=self.acceleration, omega_max=self.omega_max)

    def straight_time(self, length, exit_frame, entry_frame) -> np.ndarray:
        """A rest-to-rest move of ``length`` (m) at the link speed and acceleration, or the turn at
        ``omega_max`` if that takes longer, s (no retract or approach: a contact step-over)."""
        if self.speed is None:
            raise InputError("straight_time needs a link speed (LinkModel(speed=...)); this model costs length")
        v, a = self.speed, self.acceleration
        length = np.asarray(length, float)
        t: np.ndarray = np.where(length >= v * v / a, length / v + v / a, 2 * np.sqrt(np.maximum(length, 0) / a))
        if self.omega_max is not None:
            t = np.maximum(t, _turn_angle(exit_frame, entry_frame) / self.omega_max)
        return t


def _turn_angle(frame_a, frame_b) -> np.ndarray:
    """Rotation angle (rad) between frames ``(..., 3, 3)``."""
    tr = np.einsum("...ij,...ij->...", frame_a, frame_b)
    return np.arccos(np.clip(0.5 * (tr - 1.0), -1.0, 1.0))


#: The trajectory stage bounds the acceleration by a 16-gon inscribed in the disk of radius a.
_DISK = float(np.cos(np.pi / 16))


def _segment_time(length, v0, v1, cap, a):
    """Time (s) to run ``length`` (m) from speed ``v0`` to ``v1`` (m/s) under ``cap`` at
    acceleration ``a`` (m/s²); the speeds must be reachable (forward/backward passes done)."""
    peak = np.minimum(cap, np.sqrt(np.maximum(a * length + 0.5 * (v0 * v0 + v1 * v1), 0.0)))
    peak = np.maximum(peak, np.maximum(v0, v1))
    ramp = (2 * peak * peak - v0 * v0 - v1 * v1) / (2 * a)
    return (2 * peak - v0 - v1) / a + np.maximum(length - ramp, 0.0) / np.maximum(peak, 1e-12)


def link_time_estimate(length, turn, *, clearance: float, speed: float, acceleration: float,
                       omega_max: float | None = None) -> np.ndarray:
    """Time (s) of a link of route ``length`` (m, retract + move + approach) with the tool turning
    by ``turn`` (rad) between retract and approach, as the trajectory stage times it (see
    :meth:`LinkModel.cost`); broadcasts over ``length`` and ``turn``."""
    length = np.asarray(length, float)
    turn = np.asarray(turn, float)
    c, v, a = clearance, speed, acceleration * _DISK
    mid = np.maximum(length - 2 * c, 0.0)
    cut = np.minimum(c, 0.45 * np.minimum(c, mid))          # corner tangent length = radius (right angle)
    arc = 0.5 * np.pi * cut
    straight = np.maximum(mid - 2 * cut, 0.0)
    span = straight + 2 * arc                                # where the tool turns
    side = c - cut                                           # retract / approach lines
    turning = turn > 1e-9
    cap = np.full(np.broadcast(length, turn).shape, v)
    if omega_max is not None:
        cap = np.where(turning, np.minimum(v, omega_max * span / np.maximum(turn, 1e-12)), cap)
    # On a corner arc the centripetal acceleration uses the whole budget: the pad runs it at
    # sqrt(a r) (or less), at constant speed.
    v_arc = np.minimum(np.minimum(np.sqrt(a * np.maximum(cut, 1e-12)), cap), np.sqrt(2 * a * side))
    t = (2 * _segment_time(side, 0.0, v_arc, v, a) + 2 * arc / np.maximum(v_arc, 1e-12)
         + _segment_time(straight, v_arc, v_arc, np.maximum(cap, v_arc), a))
    # Straight up and down (no move between): the route stops at the top and the tool turns on the way.
    up_cap = np.full(cap.shape, v)
    if omega_max is not None:
        up_cap = np.where(turning, np.minimum(v, omega_max * 2 * c / np.maximum(turn, 1e-12)), up_cap)
    t_up = 2 * _segment_time(np.full(cap.shape, c), 0.0, 0.0, up_cap, a)
    return np.where(mid > 1e-9, t, t_up)


@dataclass(frozen=True, eq=False)
class Variants:
    """The path types of every group, flattened into one list of nodes.

    Attributes
    ----------
    group : (N,) int
        Group of each node.
    reverse_order, flip : (N,) bool
        Whether the node runs the group's passes in reverse order, and flips every pass.
    entry_point, exit_point : (N, 3) float
        Touch-down and lift-off points on the surface, m.
    entry_normal, exit_normal : (N, 3) float
        Unit surface normals there.
    entry_frame, exit_frame : (N, 3, 3) float
        Tool frames there (columns x = travel direction, y, z = -normal).
    inner_length : (N,) float
        Air length of the links inside the group for this variant, m.
    inner : (N,) float
        Cost of those links (m, or s with a timed :class:`LinkModel`).
    """

    group: np.ndarray
    reverse_order: np.ndarray
    flip: np.ndarray
    entry_point: np.ndarray
    entry_normal: np.ndarray
    entry_frame: np.ndarray
    exit_point: np.ndarray
    exit_normal: np.ndarray
    exit_frame: np.ndarray
    inner_length: np.ndarray
    inner: np.ndarray

    @property
    def n_groups(self) -> int:
        return int(self.group.max()) + 1 if len(self.group) else 0


def _frame(normal, tangent) -> np.ndarray:
    """Tool frame (3, 3), columns x (travel), y, z = -normal."""
    z = -np.asarray(normal, float)
    z = z / max(np.linalg.norm(z), 1e-300)
    x = np.asarray(tangent, float) - (np.asarray(tangent, float) @ z) * z
    nx = np.linalg.norm(x)
    if nx < 1e-12:
        x = np.cross(z, [1.0, 0, 0] if abs(z[0]) < 0.9 else [0, 1.0, 0])
        nx = np.linalg.norm(x)
    x = x / nx
    return np.column_stack([x, np.cross(z, x), z])


def pass_ends(p, flip: bool = False):
    """(start point, start normal, start frame, end point, end normal, end frame) of a pass run as
    given or flipped: points (3,) m, normals (3,), tool frames (3, 3) (columns x = travel, y, z = -normal)."""
    pts, nrm = (p.points[::-1], p.normals[::-1]) if flip else (p.points, p.normals)
    t0, t1 = pts[1] - pts[0], pts[-1] - pts[-2]
    return pts[0], nrm[0], _frame(nrm[0], t0), pts[-1], nrm[-1], _frame(nrm[-1], t1)


def group_variants(passes, groups, *, clearance: float = 0.02, model: LinkModel | None = None,
                   joiner=None, keep_direction: bool = False, guard=None) -> Variants:
    """Enumerate the path types of each group (see the module notes).

    Parameters
    ----------
    passes : sequence of Pass
    groups : list of list of int
        Pass indices of each group, in the group's own processing order.
    clearance : float
        Lift along the normal before an air move, m (used when ``model`` is None).
    model : LinkModel, optional
        Link costing (default: by length, with ``clearance``).
    joiner : StepOverJoiner, optional
        When given, a step-over inside a group that it can make in contact costs no air
        (``inner_length``) and :func:`contact_cost` (``inner``).
    keep_direction : bool
        Offer only each group's given path type (its passes in the given order and direction):
        the order alone is chosen (Wang's "visit order planning", Table 4-1 column C).
    guard : AirGuard, optional
        When given, the air links inside a group cost their routes' length (a route that climbs
        over the part is longer than the straight move at the clearance).
    """
    model = LinkModel(clearance=clearance) if model is None else model
    rows = []
    for g, idx in enumerate(groups):
        types = [(False, False)] if keep_direction else [(False, False), (False, True)] if len(idx) == 1 else \
            [(False, False), (False, True), (True, False), (True, True)]
        for rev, flip in types:
            order = list(idx)[::-1] if rev else list(idx)
            seq = [pass_ends(passes[i], flip) for i in order]
            inner_len = inner = 0.0
            for a, b in pairwise(seq):
                if joiner is not None and joiner.feasible(a[3][None], b[0][None], a[5][None, :, 0], b[2][None, :, 0])[0]:
                    inner += float(contact_cost(model, b[0] - a[3], a[5], b[2]))
                    continue
                L = float(model.length(a[3], a[4], b[0], b[1]))
                if guard is not None:
                    route = guard.route(a[3], a[4] / np.linalg.norm(a[4]), b[0], b[1] / np.linalg.norm(b[1]))
                    L = max(L, float(np.linalg.norm(np.diff(route, axis=0), axis=1).sum()))
                inner_len += L
                inner += float(model.cost(L, a[5], b[2]))
            first, last = seq[0], seq[-1]
            rows.append((g, rev, flip, first[0], first[1], first[2], last[3], last[4], last[5], inner_len, inner))
    cols = list(zip(*rows))
    return Variants(*(np.array(c) for c in cols))


#: A step-over made in contact counts this share of its chord (m) in the air-length objective:
#: no air, but of two contact step-overs the shorter is preferred.
CONTACT_WEIGHT = 0.1


#: A contact step-over's turns cost this share of ``turn / omega_max`` on top of ``chord / feed``:
#: the tool turns while it moves.  Measured with the trajectory stage on a plate (feed 50 mm/s,
#: 1 rad/s, 5 mm heading scale): U-turn and L-turn step-overs of 20-60 mm took
#: ``chord / feed + (0.81 +- 0.01) turn / omega_max`` more contact time than the two passes apart.
CONTACT_TURN_SHARE = 0.81


def contact_cost(model: LinkModel, chord, exit_frame, entry_frame):
    """Objective cost of step-overs made in contact along ``chord`` ((..., 3) float, m: from the
    lift-off point to the touch-down point) between tool frames ``(..., 3, 3)``.

    By length ``CONTACT_WEIGHT * |chord|``; by time with ``model.feed`` (m/s) the contact time the
    step-over adds, ``|chord| / feed + CONTACT_TURN_SHARE * (turn onto the chord + turn off it) /
    omega_max`` (the trajectory stage runs it at the feed and turns the tool's heading with the
    travel direction); by time without a feed, :meth:`LinkModel.straight_time`.
    """
    chord = np.asarray(chord, float)
    length = np.linalg.norm(chord, axis=-1)
    if not model.timed:
        return CONTACT_WEIGHT * length
    if model.feed is None:
        return model.straight_time(length, exit_frame, entry_frame)
    u = chord / np.maximum(length, 1e-12)[..., None]
    x_exit, x_entry = np.asarray(exit_frame)[..., :, 0], np.asarray(entry_frame)[..., :, 0]
    turns = np.arccos(np.clip((x_exit * u).sum(-1), -1, 1)) + np.arccos(np.clip((u * x_entry).sum(-1), -1, 1))
    t = length / model.feed
    if model.omega_max is not None:
        t = t + CONTACT_TURN_SHARE * turns / model.omega_max
    return t


def link_matrix(variants: Variants, clearance: float = 0.02, *, model: LinkModel | None = None,
                cost: bool = False) -> np.ndarray:
    """(N, N) air length (m) from each node's exit to each node's entry (retract and approach
    included), or with ``cost`` the link cost of ``model`` (m or s)."""
    model = LinkModel(clearance=clearance) if model is None else model
    L = model.length(variants.exit_point[:, None], variants.exit_normal[:, None],
                     variants.entry_point[None], variants.entry_normal[None])
    if not cost:
        return L
    return model.cost(L, variants.exit_frame[:, None], variants.entry_frame[None])


def tour_length(variants: Variants, D: np.ndarray, nodes, start_cost: np.ndarray | None, *,
                inner: np.ndarray | None = None) -> float:
    """Cost (air length in m, or time in s) of visiting ``nodes`` in order: links between groups
    (``D``), links inside groups (``inner``, default ``variants.inner``) and the move from the start
    point (``start_cost[node]``) when one is given."""
    nodes = list(nodes)
    inner = variants.inner if inner is None else inner
    total = float(sum(D[a, b] for a, b in pairwise(nodes)) + inner[nodes].sum())
    if start_cost is not None and nodes:
        total += float(start_cost[nodes[0]])
    return total


# --- solvers: each returns a list of nodes, one per group, in visiting order -------------------------
