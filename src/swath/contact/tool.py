"""The :class:`Tool` record: a flat, circular, compliant pad (FORMATS.md "Tool model")."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError


@dataclass(frozen=True)
class Tool:
    """A flat circular pad on an elastic foundation, pressed with a set normal force.

    Compliance belongs to the pad: give either its ``stiffness`` ``k`` (Pa/m) or the ``depression``
    ``e₀`` (m) it sinks on a flat surface at ``reference_force`` ``F₀``, ``k = F₀ / (e₀ π R²)``; when
    both are None the pad sinks 1 mm at 20 N.  The set ``force`` then presses this pad to
    ``e = F / (k π R²)`` (twice the force, twice the depression on a flat surface): the force changes
    the depression, the contact width on curved parts and the removal.

    Attributes
    ----------
    pad_radius : float
        Pad radius ``R``, m (default 38.1 mm, a 3-inch pad).
    force : float
        Normal force ``F``, N (default 20 N).
    depression : float or None
        Depression on a flat surface at ``reference_force``, m.
    stiffness : float or None
        Foundation stiffness ``k``, Pa/m.
    reference_force : float
        The force at which ``depression`` was measured, N (default 20 N).
    pad_thickness : float or None
        Thickness of the compliant layer, m; when given, the pad must not press through it
        (``e < thickness``).
    damping_time : float
        The pad's viscous relaxation time ``η / k``, s (default 0: purely elastic): pressed at the
        rate ``ḣ`` the pad carries ``k·(h + damping_time·ḣ)``, so it resists a fast landing and
        lets go late on a fast lift (:mod:`swath.simulate.force`).
    wear_rate : float
        Pad (abrasive) wear, 1/s: the Preston coefficient falls as ``k_p(a) = preston · exp(−wear_rate · a)``
        with ``a`` the media's time in contact since it was fitted, s (default 0: no wear).
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
    reference_force: float = 20.0
    pad_thickness: float | None = None
    wear_rate: float = 0.0
    damping_time: float = 0.0
    _k: float = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        if self.depression is not None and self.stiffness is not None:
            raise InputError("give either the pad stiffness or the depression on flat, not both")
        for name in ("pad_radius", "force", "spindle_speed", "preston", "reference_force"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise InputError(f"tool {name} must be a positive finite number, got {value!r}")
        if not (isinstance(self.wear_rate, (int, float)) and math.isfinite(self.wear_rate) and self.wear_rate >= 0):
            raise InputError(f"pad wear rate must be a non-negative number (1/s), got {self.wear_rate!r}")
        if not (isinstance(self.damping_time, (int, float)) and math.isfinite(self.damping_time)
                and self.damping_time >= 0):
            raise InputError(f"pad damping time must be a non-negative number (s), got {self.damping_time!r}")
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
            k = self.reference_force / (e * math.pi * self.pad_radius**2)
        object.__setattr__(self, "_k", k)
        e_set = self.flat_depression
        if not e_set < self.pad_radius:
            raise InputError(f"at {self.force:g} N this pad sinks {e_set * 1e3:.3g} mm on a flat surface, more than its "
                             f"radius {self.pad_radius * 1e3:.3g} mm: lower the force or give a stiffer pad")
        if self.pad_thickness is not None:
            t = self.pad_thickness
            if not (isinstance(t, (int, float)) and math.isfinite(t) and t > 0):
                raise InputError(f"pad thickness must be a positive number of metres, got {t!r}")
            if not e_set < t:
                raise InputError(f"at {self.force:g} N this pad sinks {e_set * 1e3:.3g} mm on a flat surface, through "
                                 f"its {t * 1e3:.3g} mm compliant layer: lower the force or give a stiffer or "
                                 "thicker pad")

    @property
    def k(self) -> float:
        """Foundation stiffness, Pa/m."""
        return self._k

    @property
    def flat_depression(self) -> float:
        """Depression ``e = F / (k π R²)`` on a flat surface at the set force, m."""
        return self.force / (self._k * math.pi * self.pad_radius**2)

    def depression_at(self, force: float) -> float:
        """Depression (m) of this pad on a flat surface at ``force`` (N): ``F / (k π R²)``."""
        return float(force) / (self._k * math.pi * self.pad_radius**2)

    def with_force(self, force: float) -> Tool:
        """The same pad (same stiffness) pressed with ``force`` (N)."""
        from dataclasses import replace

        return replace(self, force=float(force), depression=None, stiffness=self._k)

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

    def preston_at(self, age):
        """Preston coefficient (1/Pa) of media that has been in contact for ``age`` s (scalar or array)."""
        return self.preston * np.exp(-self.wear_rate * np.asarray(age, float))

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
