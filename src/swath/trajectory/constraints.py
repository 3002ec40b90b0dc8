"""Constraint objects for :func:`swath.trajectory.time_path` (toppra style: a path plus a list of
constraints).

Along contact passes every constraint becomes a cap on the TCP speed at each sample (the smallest
cap wins); :class:`TangentialAccelLimit` then limits how fast the speed may change between
samples.  :class:`AngularSpeedLimit` also caps the speed on air links while the tool turns.

=========================  =================================================================
constraint                 speed cap at arc length s along a pass
=========================  =================================================================
``FeedLimit(v)``           ``v`` (required: the process feed)
``FeedProfile(speeds)``    the given speed, interpolated between the pass's own points
``CentripetalLimit(a)``    ``sqrt(a / κ(s))``, κ the TCP path curvature read at ``scale``
``AngularSpeedLimit(w)``   ``w / ρ(s)``, ρ the tool frame's rotation per metre of travel
``TangentialAccelLimit``   none; ``v²`` changes by at most ``2·a·Δs`` between samples
=========================  =================================================================
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError


def _positive(name: str, value: float, unit: str) -> None:
    if not (isinstance(value, (int, float, np.floating, np.integer)) and np.isfinite(value) and value > 0):
        raise InputError(f"{name} must be a positive number in {unit}, got {value!r}")


@dataclass(frozen=True)
class FeedLimit:
    """Constant feed: the TCP speed along contact passes, m/s (the top speed; other constraints
    only slow the tool below it)."""

    speed: float = 0.05

    def __post_init__(self):
        if not (np.isfinite(self.speed) and self.speed > 0):
            raise InputError(f"feed must be a positive speed, got {self.speed!r} m/s")


@dataclass(frozen=True)
class CentripetalLimit:
    """Centripetal acceleration limit on contact passes: ``v ≤ sqrt(a_max / κ)``.

    Attributes
    ----------
    a_max : float
        Largest centripetal acceleration ``v²·κ`` of the TCP, m/s².
    scale : float
        Length scale at which the path curvature κ is read, m (default 1 mm): the standard
        deviation of the Gaussian window of the local quadratic fit (see
        :mod:`swath.trajectory.geometry`).  It resolves features down to a few mm radius (a 6.3 mm
        leading edge within 1 %); on noisy scans raise it (2–5 mm) so that scan noise does not
        read as curvature — noise of amplitude ε adds roughly ε / scale² to κ.
    """

    a_max: float
    scale: float = 1e-3

    def __post_init__(self):
        _positive("centripetal acceleration limit", self.a_max, "m/s²")
        _positive("curvature scale", self.scale, "m")


@dataclass(frozen=True)
class AngularSpeedLimit:
    """Limit on the tool frame's angular speed ``|ω| = ρ·v ≤ omega_max``, ρ the frame's rotation
    per metre of travel (rad/m).  Applies on contact passes and on air links (where the tool turns
    between the orientations of consecutive passes)."""

    omega_max: float

    def __post_init__(self):
        _positive("angular speed limit", self.omega_max, "rad/s")


@dataclass(frozen=True)
class TangentialAccelLimit:
    """Limit on speed changes along contact passes: ``|dv/dt| ≤ a_t``.

    The speed profile is the largest one under the caps of the other constraints whose ``v²``
    changes by at most ``2·a_t·Δs`` between samples (a forward and a backward sweep).

    Attributes
    ----------
    a_t : float
        Largest tangential acceleration and deceleration, m/s².
    rest_at_ends : bool
        True (default): each pass starts and ends at rest, so the speed is continuous through
        touch-down and lift-off (the approach and retract are rest-to-rest moves).  False: a pass
        starts and ends at its capped speed (the speed jumps at touch-down, as without this limit).
    """

    a_t: float
    rest_at_ends: bool = True

    def __post_init__(self):
        _positive("tangential acceleration limit", self.a_t, "m/s²")


@dataclass(frozen=True, eq=False)
class FeedProfile:
    """A planned feed along every pass (from dwell planning): a speed per pass point, m/s.

    Attributes
    ----------
    speeds : sequence of (k_i,) float
        One array per pass of the tool path, as long as that pass's ``points``; the speed is
        interpolated linearly between the points (in arc length) and caps the feed pointwise.
    """

    speeds: tuple

    def __post_init__(self):
        try:
            arrays = tuple(np.array(s, dtype=float).reshape(-1) for s in self.speeds)
        except (TypeError, ValueError) as exc:
            raise InputError(f"a feed profile is one sequence of speeds (m/s) per pass: {exc}") from None
        for i, a in enumerate(arrays):
            if not (np.isfinite(a).all() and (a > 0).all()):
                raise InputError(f"feed profile of pass {i} must hold positive finite speeds (m/s)")
            a.setflags(write=False)
        object.__setattr__(self, "speeds", arrays)

    def check(self, passes) -> None:
        """Raise :class:`InputError` unless there is one speed per point of every pass."""
        if len(self.speeds) != len(passes):
            raise InputError(f"feed profile has {len(self.speeds)} passes, the tool path {len(passes)}; "
                             "give one array of speeds per pass")
        for i, (a, p) in enumerate(zip(self.speeds, passes)):
            if len(a) != len(p.points):
                raise InputError(f"feed profile of pass {i} has {len(a)} speeds for {len(p.points)} points; "
                                 "give one speed per pass point")


#: Constraint classes :func:`time_path` understands.
CONSTRAINT_TYPES = (FeedLimit, FeedProfile, CentripetalLimit, AngularSpeedLimit, TangentialAccelLimit)
