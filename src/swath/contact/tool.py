"""The :class:`Tool` record: a flat, circular, compliant pad (FORMATS.md "Tool model")."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..errors import InputError


@dataclass(frozen=True)
class Tool:
    """A flat circular pad on an elastic foundation, pressed with a set normal force.

    Compliance is given either as ``stiffness`` (Pa/m) or as ``depression`` (m): the depth the pad
    sinks on a flat surface at the set force, ``e = F / (k π R²)``.  Give one; when both are None the
    default depression of 1 mm is used.

    Attributes
    ----------
    pad_radius : float
        Pad radius ``R``, m (default 38.1 mm, a 3-inch pad).
    force : float
        Normal force ``F``, N (default 20 N).
    depression : float or None
        Depression on a flat surface at ``force``, m.
    stiffness : float or None
        Foundation stiffness ``k``, Pa/m.
    motion : str
        ``"orbital"`` (relative speed uniform over the pad) or ``"rotary"`` (``ω·r``).
    spindle_speed : float
        Pad angular speed ``ω``, rad/s (default 10 000 rpm).
    orbit_radius : float
        Orbit eccentricity of an orbital pad, m (default 2.5 mm); its relative speed is ``ω·orbit_radius``.
    preston : float
        Preston coefficient ``k_p``, 1/Pa (m of depth per Pa of pressure per m of sliding).
    """

    pad_radius: float = 0.0381
    force: float = 20.0
    depression: float | None = None
    stiffness: float | None = None
    motion: str = "orbital"
    spindle_speed: float = 10000.0 * 2.0 * math.pi / 60.0
    orbit_radius: float = 2.5e-3
    preston: float = 1e-10
    _k: float = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        if self.depression is not None and self.stiffness is not None:
            raise InputError("give either the pad stiffness or the depression on flat, not both")
        for name in ("pad_radius", "force", "spindle_speed", "preston"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise InputError(f"tool {name} must be a positive finite number, got {value!r}")
        if self.motion not in ("orbital", "rotary"):
            raise InputError(f"tool motion must be 'orbital' or 'rotary', got {self.motion!r}")
        if self.stiffness is not None:
            if not (math.isfinite(self.stiffness) and self.stiffness > 0):
                raise InputError(f"pad stiffness must be positive, got {self.stiffness!r} Pa/m")
            k = float(self.stiffness)
        else:
            e = 1e-3 if self.depression is None else self.depression
            if not (math.isfinite(e) and 0 < e < self.pad_radius):
                raise InputError(f"depression on flat must lie in (0, pad radius), got {e!r} m")
            k = self.force / (e * math.pi * self.pad_radius**2)
        object.__setattr__(self, "_k", k)

    @property
    def k(self) -> float:
        """Foundation stiffness, Pa/m."""
        return self._k

    @property
    def flat_depression(self) -> float:
        """Depression ``e = F / (k π R²)`` on a flat surface, m."""
        return self.force / (self._k * math.pi * self.pad_radius**2)

    @property
    def half_pad_lead(self) -> float:
        """The lead angle (rad) at which the pad, pressed on a plane at ``force``, touches it on
        exactly half its face (its trailing half): 7.00° for the default 1 mm on a 38.1 mm pad.

        Tilted by ``θ`` about the axis across the feed (the leading edge raised), the pad face lies
        ``h = s − u sin θ`` under a plane point ``u`` ahead of the TCP, and the points within ``R`` of
        the tool axis form an ellipse ``(u cos θ)² + v² <= R²``.  The force balance
        ``F = k ∫ h⁺ dA`` puts the contact's front edge through the TCP (``s = 0``) when
        ``F = k (sin θ / cos² θ) · 2R³/3``, i.e. ``sin θ / cos² θ = q = 3π e / (2R)`` (``e`` the
        depression on flat), solved as ``sin θ = (√(1 + 4q²) − 1) / (2q)``.  The pressure then
        falls linearly from the trailing rim to zero at the centre line, and a straight pass of an
        orbital pad removes the parabola ``∝ R² − y²`` across its width instead of the untilted
        pad's semicircle (:func:`swath.feed.ripple.cross_profile`)."""
        q = 3.0 * math.pi * self.flat_depression / (2.0 * self.pad_radius)
        return math.asin((math.sqrt(1.0 + 4.0 * q * q) - 1.0) / (2.0 * q))

    @property
    def pad_area(self) -> float:
        """Pad face area ``π R²``, m²."""
        return math.pi * self.pad_radius**2

    def relative_speed(self, r):
        """Sliding speed (m/s) of the abrasive over the part at distance ``r`` (m) from the pad centre."""
        if self.motion == "orbital":
            return self.spindle_speed * self.orbit_radius + 0.0 * r
        return self.spindle_speed * r


def sample_spacing_for(tool: Tool) -> float:
    """Default removal-sample spacing, m: an eighth of the pad radius, at most 3 mm."""
    return min(3e-3, tool.pad_radius / 8)
