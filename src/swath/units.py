"""Quantities with unit suffixes, converted to SI at the edge.

Inside swath everything is SI: metres, seconds, radians, newtons, pascals.  Text a user types
(``"38.1mm"``, ``"20N"``, ``"50mm/s"``, ``"10deg"``, ``"10%"``) is converted here, in one place.
"""

from __future__ import annotations

import math
import re

from .errors import InputError

#: Length units accepted for unitless mesh files and for length quantities, as metres per unit.
LENGTH_UNITS: dict[str, float] = {"m": 1.0, "mm": 1e-3, "cm": 1e-2, "in": 0.0254}

#: Spelled-out names of the length units (matched case-insensitively, after the symbols above).
LENGTH_UNIT_NAMES: dict[str, str] = {
    "meter": "m", "meters": "m", "metre": "m", "metres": "m",
    "millimeter": "mm", "millimeters": "mm", "millimetre": "mm", "millimetres": "mm",
    "centimeter": "cm", "centimeters": "cm", "centimetre": "cm", "centimetres": "cm",
    "inch": "in", "inches": "in",
}

# Each kind of quantity: suffix -> factor to SI.
_KINDS: dict[str, dict[str, float]] = {
    "length": dict(LENGTH_UNITS, um=1e-6, **{"µm": 1e-6}),
    "force": {"N": 1.0, "kN": 1e3},
    "speed": {"m/s": 1.0, "mm/s": 1e-3, "cm/s": 1e-2, "m/min": 1.0 / 60.0, "mm/min": 1e-3 / 60.0},
    "acceleration": {"m/s2": 1.0, "m/s^2": 1.0, "mm/s2": 1e-3, "mm/s^2": 1e-3},
    "angle": {"rad": 1.0, "deg": math.pi / 180.0},
    "angular_speed": {"rad/s": 1.0, "deg/s": math.pi / 180.0},
    "stiffness": {"Pa/m": 1.0, "N/m3": 1.0, "MPa/m": 1e6, "kPa/m": 1e3, "N/mm3": 1e9},
    "fraction": {"%": 0.01, "": 1.0},
    "frequency": {"Hz": 1.0, "rpm": 1.0 / 60.0, "1/s": 1.0, "/s": 1.0, "1/min": 1.0 / 60.0, "/min": 1.0 / 60.0,
                  "1/h": 1.0 / 3600.0, "/h": 1.0 / 3600.0},
    "time": {"s": 1.0, "ms": 1e-3, "min": 60.0, "h": 3600.0},
    "mass": {"kg": 1.0, "g": 1e-3, "lb": 0.45359237},
}

_NUMBER = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*?)\s*$")

#: The unit a message states a quantity of each kind in when the user gave none (bare numbers are
#: read in SI, angles in degrees).
DISPLAY_UNITS: dict[str, str] = {"length": "mm", "force": "N", "speed": "mm/s", "acceleration": "m/s^2",
                                 "angle": "deg", "angular_speed": "rad/s", "stiffness": "MPa/m", "fraction": "%",
                                 "frequency": "Hz", "time": "s", "mass": "kg"}


def display_unit(text, kind: str) -> tuple[str, float]:
    """The unit to state a ``kind`` quantity in, next to a value the user typed as ``text``: the
    unit they wrote (when it is one of ``kind``'s), otherwise :data:`DISPLAY_UNITS`'s; returns
    ``(unit, SI per unit)``."""
    table = _KINDS[kind]
    match = _NUMBER.match(str(text))
    unit = match.group(2) if match else ""
    if not unit or unit not in table:
        unit = DISPLAY_UNITS.get(kind, "")
    return unit, table.get(unit, 1.0)


def parse_quantity(text: str | float | int, kind: str, *, default_unit: str | None = None) -> float:
    """Convert ``text`` such as ``"38.1mm"`` to an SI float of the given ``kind``.

    Parameters
    ----------
    text : str or number
        A number with an optional unit suffix.  A bare number is read in ``default_unit`` (or SI
        when that is None).
    kind : str
        One of ``length, force, speed, acceleration, angle, angular_speed, stiffness, fraction,
        frequency``.
    default_unit : str, optional
        The unit of a bare number.

    Raises
    ------
    InputError
        If the text is not a number, the suffix is unknown for this kind, or the value is not finite.
    """
    if kind not in _KINDS:
        raise InputError(f"unknown quantity kind {kind!r}; expected one of {sorted(_KINDS)}")
    table = _KINDS[kind]
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        value, unit = float(text), ""
    else:
        match = _NUMBER.match(str(text))
        if not match:
            article = "an" if kind[:1] in "aeiou" else "a"
            raise InputError(f"expected {article} {kind} such as {_example(kind)}, got {text!r}")
        value, unit = float(match.group(1)), match.group(2)
    if not math.isfinite(value):
        raise InputError(f"expected a finite {kind}, got {text!r}")
    if unit == "":
        unit = default_unit if default_unit is not None else ("" if "" in table else _si_unit(kind))
    if unit not in table:
        raise InputError(
            f"unknown unit {unit!r} for a {kind} in {text!r}; use one of {', '.join(u for u in table if u)}"
        )
    return value * table[unit]


def canonical_length_unit(unit: str) -> str:
    """The symbol (``m``, ``mm``, ``cm``, ``in``) of a mesh file's length unit.

    Parameters
    ----------
    unit : str
        A symbol or a spelled-out name, any case, e.g. ``"MM"``, ``"inch"``, ``"Millimetres"``,
        ``"meter"``.

    Raises
    ------
    InputError
        If the text names no known length unit.
    """
    key = unit.strip() if isinstance(unit, str) else unit
    if key in LENGTH_UNITS:
        return key
    if isinstance(key, str):
        low = key.lower()
        if low in LENGTH_UNITS:
            return low
        if low in LENGTH_UNIT_NAMES:
            return LENGTH_UNIT_NAMES[low]
    raise InputError(f"unknown length unit {unit!r}; use one of {', '.join(LENGTH_UNITS)} (or a name such as "
                     "millimetres, inches, metres)")


def length_unit_factor(unit: str) -> float:
    """Metres per ``unit`` for a mesh file's unit (a symbol or a name, see :func:`canonical_length_unit`)."""
    return LENGTH_UNITS[canonical_length_unit(unit)]


def _si_unit(kind: str) -> str:
    return next(u for u, f in _KINDS[kind].items() if f == 1.0)


def _example(kind: str) -> str:
    return {
        "length": "'38.1mm'", "force": "'20N'", "speed": "'50mm/s'", "acceleration": "'2m/s2'",
        "angle": "'15deg'", "angular_speed": "'1rad/s'", "stiffness": "'4.4MPa/m'", "fraction": "'10%'",
        "frequency": "'6000rpm'", "time": "'300s'",
    }[kind]
