"""Constraint objects for :func:`swath.trajectory.time_path` (toppra style: a path plus a list of
constraints).

Along contact passes every constraint caps the TCP speed at each grid point through its own
``speed_cap(grid)`` method (the smallest cap wins), given the pass's :class:`PassGrid`; a
constraint with a ``shape_profile(caps, s)`` method (:class:`TangentialAccelLimit`) then turns the
caps into the speed profile.  A new limit (a force, a joint speed) plugs in as a new class with
``speed_cap``; :func:`time_path` needs no change.  :class:`AngularSpeedLimit` also caps the speed
on air links while the tool turns.

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
from scipy.ndimage import minimum_filter1d

from ..errors import InputError
from .geometry import path_curvature


@dataclass(frozen=True, eq=False)
class PassGrid:
    """One contact pass on its timing grid, as constraints see it.

    Attributes
    ----------
    index : int
        The pass's index in the tool path.
    s : (k,) float
        Arc length of the grid points, m.
    points : (k, 3) float
        TCP positions, m.
    spacing : float
        Nominal grid step, m.
    rotation_per_metre : (k,) float
        Rotation of the tool frame per metre of travel at each grid point (the larger of the two
        adjacent steps), rad/m.
    source_index : (k,) float
        Fractional index of each grid point in the pass's own points.
    """

    index: int
    s: np.ndarray
    points: np.ndarray
    spacing: float
    rotation_per_metre: np.ndarray
    source_index: np.ndarray


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

    def speed_cap(self, grid: PassGrid) -> np.ndarray:
        """The feed everywhere, m/s."""
        return np.full(len(grid.s), float(self.speed))


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

    def speed_cap(self, grid: PassGrid) -> np.ndarray:
        """``sqrt(a_max / κ)`` with κ read at ``scale`` (the smallest of each point's neighbours), m/s."""
        kappa = path_curvature(grid.points, grid.spacing, self.scale)
        return minimum_filter1d(np.sqrt(self.a_max / np.maximum(kappa, 1e-12)), 3, mode="nearest")


@dataclass(frozen=True)
class AngularSpeedLimit:
    """Limit on the tool frame's angular speed ``|ω| = ρ·v ≤ omega_max``, ρ the frame's rotation
    per metre of travel (rad/m).  Applies on contact passes and on air links (where the tool turns
    between the orientations of consecutive passes)."""

    omega_max: float

    def __post_init__(self):
        _positive("angular speed limit", self.omega_max, "rad/s")

    def speed_cap(self, grid: PassGrid) -> np.ndarray:
        """``omega_max / ρ``, ρ the frame's rotation per metre, m/s."""
        return self.omega_max / np.maximum(grid.rotation_per_metre, 1e-12)


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

    def speed_cap(self, grid: PassGrid) -> None:
        """No pointwise cap (see :meth:`shape_profile`)."""
        return None

    def shape_profile(self, caps: np.ndarray, s: np.ndarray) -> np.ndarray:
        """The fastest profile under ``caps`` whose ``v²`` changes by at most ``2·a_t·Δs``, m/s."""
        return speed_profile(caps, s, self.a_t, rest_at_ends=self.rest_at_ends)


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

    def speed_cap(self, grid: PassGrid) -> np.ndarray:
        """The planned speeds of this pass, interpolated at the grid points, m/s."""
        speeds = self.speeds[grid.index]
        return np.interp(grid.source_index, np.arange(len(speeds)), speeds)

    def check(self, passes) -> None:
        """Raise :class:`InputError` unless there is one speed per point of every pass."""
        if len(self.speeds) != len(passes):
            raise InputError(f"feed profile has {len(self.speeds)} passes, the tool path {len(passes)}; "
                             "give one array of speeds per pass")
        for i, (a, p) in enumerate(zip(self.speeds, passes)):
            if len(a) != len(p.points):
                raise InputError(f"feed profile of pass {i} has {len(a)} speeds for {len(p.points)} points; "
                                 "give one speed per pass point")


#: The constraint classes swath ships (any object with ``speed_cap(grid)`` is accepted).
CONSTRAINT_TYPES = (FeedLimit, FeedProfile, CentripetalLimit, AngularSpeedLimit, TangentialAccelLimit)


def speed_profile(caps: np.ndarray, s: np.ndarray, accel: float | None, *, rest_at_ends: bool = True) -> np.ndarray:
    """The fastest speed profile under pointwise caps whose ``v²`` changes by at most
    ``2·accel·Δs`` between samples: a forward and a backward sweep, each a running minimum.

    Parameters
    ----------
    caps : (n,) float
        Speed caps at the samples, m/s.
    s : (n,) float
        Arc length of the samples, m, increasing.
    accel : float or None
        Tangential acceleration limit, m/s² (None: no limit, the caps are returned).
    rest_at_ends : bool
        Start and end at rest.

    Returns
    -------
    (n,) float
        Speeds, m/s.
    """
    c2 = np.square(np.asarray(caps, float))
    if accel is None:
        return np.sqrt(c2)
    if rest_at_ends:
        c2 = c2.copy()
        c2[0] = c2[-1] = 0.0
    s = np.asarray(s, float)
    ramp = 2.0 * accel * (s - s[0])
    fwd = ramp + np.minimum.accumulate(c2 - ramp)
    back = 2.0 * accel * (s[-1] - s[::-1])
    bwd = (back + np.minimum.accumulate(c2[::-1] - back))[::-1]
    return np.sqrt(np.clip(np.minimum(fwd, bwd), 0.0, None))
