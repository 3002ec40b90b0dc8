"""Path types (variants) of pass groups and what links between them cost (Wang §4).

:func:`group_variants` enumerates each group's path types with their touch-down and lift-off
points and frames; :class:`LinkModel` costs a link by air length or by time (a rest-to-rest move
at the link speed, at least the tool's turn at the angular-speed limit); :func:`link_matrix` and
:func:`tour_length` cost whole tours.  The solvers are in :mod:`swath.order.tour`.
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
    """

    clearance: float = 0.02
    speed: float | None = None
    acceleration: float = 1.0
    omega_max: float | None = None

    def __post_init__(self):
        if not (np.isfinite(self.clearance) and self.clearance >= 0):
            raise InputError(f"clearance must be a length >= 0 m, got {self.clearance!r}")
        for name in ("speed", "omega_max"):
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
        """Link time (s) for ``length`` (m) between frames ``(..., 3, 3)``, or the length if untimed."""
        if not self.timed:
            return length
        v, a = self.speed, self.acceleration
        t = np.where(length >= v * v / a, length / v + v / a, 2 * np.sqrt(np.maximum(length, 0) / a))
        if self.omega_max is not None:
            tr = np.einsum("...ij,...ij->...", exit_frame, entry_frame)
            turn = np.arccos(np.clip(0.5 * (tr - 1.0), -1.0, 1.0))
            t = np.maximum(t, turn / self.omega_max)
        return t


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


def _ends(p, flip: bool):
    """(start point, start normal, start frame, end point, end normal, end frame) of a pass."""
    pts, nrm = (p.points[::-1], p.normals[::-1]) if flip else (p.points, p.normals)
    t0, t1 = pts[1] - pts[0], pts[-1] - pts[-2]
    return pts[0], nrm[0], _frame(nrm[0], t0), pts[-1], nrm[-1], _frame(nrm[-1], t1)


def group_variants(passes, groups, *, clearance: float = 0.02, model: LinkModel | None = None,
                   joiner=None, keep_direction: bool = False) -> Variants:
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
    """
    model = LinkModel(clearance=clearance) if model is None else model
    rows = []
    for g, idx in enumerate(groups):
        types = [(False, False)] if keep_direction else [(False, False), (False, True)] if len(idx) == 1 else \
            [(False, False), (False, True), (True, False), (True, True)]
        for rev, flip in types:
            order = list(idx)[::-1] if rev else list(idx)
            seq = [_ends(passes[i], flip) for i in order]
            inner_len = inner = 0.0
            for a, b in pairwise(seq):
                if joiner is not None and joiner.feasible(a[3][None], b[0][None], a[5][None, :, 0], b[2][None, :, 0])[0]:
                    inner += float(contact_cost(model, np.linalg.norm(b[0] - a[3]), a[5], b[2]))
                    continue
                L = float(model.length(a[3], a[4], b[0], b[1]))
                inner_len += L
                inner += float(model.cost(L, a[5], b[2]))
            first, last = seq[0], seq[-1]
            rows.append((g, rev, flip, first[0], first[1], first[2], last[3], last[4], last[5], inner_len, inner))
    cols = list(zip(*rows))
    return Variants(*(np.array(c) for c in cols))


#: A step-over made in contact counts this share of its chord (m) in the air-length objective:
#: no air, but of two contact step-overs the shorter is preferred.
CONTACT_WEIGHT = 0.1


def contact_cost(model: LinkModel, chord, exit_frame, entry_frame):
    """Objective cost of a step-over of ``chord`` (m) made in contact: ``CONTACT_WEIGHT * chord``
    by length; by time, the link time of a move of that length (the tool still turns)."""
    if not model.timed:
        return CONTACT_WEIGHT * np.asarray(chord, float)
    return model.cost(np.asarray(chord, float), exit_frame, entry_frame)


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
