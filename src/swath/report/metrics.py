"""Metrics and settings as JSON, and how to read the unit out of a key's name.

Every figure swath reports is named with its unit at the end (``contact_length_m``,
``cycle_time_s``, ``pad_radius_m``, ``coverage_fraction``), so ``metrics.json`` needs no separate
schema to be read by a person or a program.  This module

* turns metric/setting values into plain JSON (numpy scalars and arrays to numbers and lists,
  NaN and infinities to ``null``), see :func:`to_jsonable`;
* writes ``metrics.json`` atomically, see :func:`write_metrics_json`;
* parses the unit suffix of a key and formats a value for people (mm, m, s, %), see
  :func:`key_unit` and :func:`format_value`, which the HTML report uses.
"""

from __future__ import annotations

import datetime as _dt
import json
import logging
import math
from dataclasses import dataclass
from pathlib import Path, PurePath

import numpy as np

from .. import __version__
from ..errors import InputError
from ..io.atomic import write_text_atomic

log = logging.getLogger(__name__)

#: Layout version of ``metrics.json``; bump when a top-level field changes meaning.
METRICS_JSON_VERSION = 1


@dataclass(frozen=True)
class KeyUnit:
    """What a key's name says about its value.

    Attributes
    ----------
    label : str
        The key without its unit suffix, in words (``"contact length"``).
    unit : str
        The SI unit symbol the value is in (``"m"``, ``"s"``, ``"m/s"``, ``""`` for pure numbers).
    kind : str
        How to show it: ``"length"``, ``"area"``, ``"volume"``, ``"time"``, ``"speed"``,
        ``"fraction"`` (a ratio shown in %), ``"count"``, ``"plain"`` (a number in ``unit``) or
        ``"unknown"`` (no unit recognised in the name).
    """

    label: str
    unit: str
    kind: str


# Unit suffixes (as underscore-separated tokens at the end of a key), longest match wins.
# value: (unit symbol, kind, label) where label is how the suffix reads in the row's label:
# None drops it (the unit is shown with the value), a string replaces it.
_SUFFIXES: dict[tuple[str, ...], tuple[str, str, str | None]] = {
    ("m", "per", "s2"): ("m/s²", "plain", None),
    ("m", "per", "s"): ("m/s", "speed", None),
    ("rad", "per", "s2"): ("rad/s²", "plain", None),
    ("rad", "per", "s"): ("rad/s", "plain", None),
    ("pa", "per", "m"): ("Pa/m", "plain", None),
    ("n", "per", "m"): ("N/m", "plain", None),
    ("m3", "per", "s"): ("m³/s", "plain", None),
    ("per", "pa"): ("1/Pa", "plain", None),
    ("per", "s"): ("1/s", "plain", None),           # a rate, e.g. the pad's wear rate
    ("m",): ("m", "length", None),
    ("m2",): ("m²", "area", None),
    ("m3",): ("m³", "volume", None),
    ("s",): ("s", "time", None),
    ("rad",): ("rad", "plain", None),
    ("deg",): ("°", "plain", None),
    ("n",): ("N", "plain", None),
    ("pa",): ("Pa", "plain", None),
    ("hz",): ("Hz", "plain", None),
    ("rpm",): ("rpm", "plain", None),
    ("kg",): ("kg", "plain", None),
    ("j",): ("J", "plain", None),
    ("w",): ("W", "plain", None),
    ("percent",): ("%", "plain", None),
    ("fraction",): ("", "fraction", None),      # a ratio in [0, 1], shown in %
    ("cov",): ("", "fraction", "CoV"),         # coefficient of variation, std / mean
    ("efficiency",): ("", "fraction", "efficiency"),
    ("ratio",): ("", "plain", "ratio"),
    ("count",): ("", "count", "count"),
    ("index",): ("", "count", "index"),
    ("seed",): ("", "count", "seed"),
    # dimensionless measures whose name says what they are
    ("sin",): ("", "plain", "sine"),                    # |sin| of a joint angle (0 at a singularity)
    ("manipulability",): ("", "plain", "manipulability"),   # Yoshikawa, linear rows over the reach
    ("score",): ("", "plain", "score"),
    ("gain", "margin"): ("", "plain", "gain margin"),   # a ratio (x), not in dB
}
_MAX_SUFFIX = max(len(k) for k in _SUFFIXES)


def key_unit(key: str) -> KeyUnit:
    """Read the unit from the end of a metric or setting name.

    Parameters
    ----------
    key : str
        A name such as ``"contact_length_m"``, ``"feed_m_per_s"``, ``"coverage_fraction"`` or
        ``"n_passes"`` (a leading ``n_`` marks a count).

    Returns
    -------
    KeyUnit
        The label without the unit, the unit symbol and how to show the value.
    """
    tokens = str(key).split("_")
    low = tuple(t.lower() for t in tokens)
    for n in range(min(_MAX_SUFFIX, len(low)), 0, -1):
        found = _SUFFIXES.get(low[-n:])
        if found is None or (n == len(low) and found[2] is None):
            continue                       # a bare unit ("m") is not a name with a unit
        unit, kind, word = found
        label = tokens[:-n] + ([word] if word else [])
        return KeyUnit(" ".join(label), unit, kind)
    if low[0] == "n" and len(low) > 1:
        return KeyUnit("number of " + " ".join(tokens[1:]), "", "count")
    return KeyUnit(" ".join(tokens), "", "unknown")


def to_jsonable(value):
    """Convert a metric or setting value into plain JSON types.

    numpy scalars become Python numbers, arrays become (nested) lists, NaN and ±inf become
    ``None`` (JSON ``null``), paths become strings, tuples and sets become lists and mappings keep
    their keys as strings.  Anything else that JSON cannot hold raises :class:`InputError`.
    """
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        v = float(value)
        return v if math.isfinite(v) else None
    if isinstance(value, np.ndarray):
        return to_jsonable(value.tolist())
    if isinstance(value, dict):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, set, frozenset)):
        items = sorted(value) if isinstance(value, (set, frozenset)) else value
        return [to_jsonable(v) for v in items]
    if isinstance(value, PurePath):
        return str(value)
    if isinstance(value, (_dt.datetime, _dt.date)):
        return value.isoformat()
    raise InputError(f"cannot write a value of type {type(value).__name__} to JSON ({value!r}); "
                     "convert it to a number, string, list or dict first")


def keys_without_unit(values: dict, prefix: str = "") -> list[str]:
    """Names of numeric entries of ``values`` (searched recursively) whose name states no unit.

    Strings, booleans, ``None``, whole numbers (counts) and lists (direction vectors, per-candidate
    tables) are not measured figures and are never listed.
    """
    missing = []
    for key, v in values.items():
        name = f"{prefix}{key}"
        if isinstance(v, dict):
            missing += keys_without_unit(v, prefix=name + ".")
        elif isinstance(v, (bool, np.bool_, str, list, tuple, np.ndarray, int, np.integer)) or v is None:
            continue                      # not a measured figure (whole numbers are counts)
        elif key_unit(key).kind == "unknown":
            missing.append(name)
    return missing


def metrics_document(metrics: dict, settings: dict) -> dict:
    """The dictionary written as ``metrics.json``: version, creation time, metrics, settings."""
    if not isinstance(metrics, dict) or not isinstance(settings, dict):
        raise InputError(f"metrics and settings must be dicts, got {type(metrics).__name__} and "
                         f"{type(settings).__name__}")
    for what, d in (("metric", metrics), ("setting", settings)):
        missing = keys_without_unit(d)
        if missing:
            log.warning("%s names without a unit suffix (e.g. _m, _s, _fraction): %s", what, ", ".join(missing))
    return {
        "format_version": METRICS_JSON_VERSION,
        "swath_version": __version__,
        "created_utc": _dt.datetime.now(_dt.UTC).replace(microsecond=0).isoformat(),
        "metrics": to_jsonable(metrics),
        "settings": to_jsonable(settings),
    }


def write_metrics_json(path, metrics: dict, settings: dict) -> Path:
    """Write ``metrics.json`` atomically.

    Parameters
    ----------
    path : str or Path
        File to write (its directory is created if missing).
    metrics : dict
        Figures of the job; each key ends in its unit (``cycle_time_s``, ``coverage_fraction``).
    settings : dict
        The settings that produced them, named the same way (``pad_radius_m``, ``force_n``).

    Returns
    -------
    Path
        ``path``.

    Notes
    -----
    The file holds ``{"format_version", "swath_version", "created_utc", "metrics", "settings"}``;
    numpy values are written as plain numbers and NaN or infinite values as ``null``.  Numeric
    keys whose name carries no recognised unit are written as given and logged as a warning.
    """
    path = Path(path)
    doc = metrics_document(metrics, settings)
    write_text_atomic(path, json.dumps(doc, indent=2, allow_nan=False) + "\n")
    return path


# --- human formatting ----------------------------------------------------------------------------
def _num(v: float, digits: int = 4) -> str:
    """``v`` with ``digits`` significant digits, no exponent for everyday magnitudes."""
    if v == 0:
        return "0"
    a = abs(v)
    if 1e-3 <= a < 1e6:
        decimals = max(digits - 1 - int(math.floor(math.log10(a))), 0)
        s = f"{v:,.{decimals}f}"
        return s.rstrip("0").rstrip(".") if "." in s else s
    return f"{v:.{digits - 1}e}"


def format_value(key: str, value) -> str:
    """A value formatted for people from the unit in its key's name.

    Lengths under 1 µm are shown in nm (under 1 nm, round-off such as a forward-kinematics check's
    error, as "< 1 nm"), under 1 mm in µm, under 1 m in mm, else in m; angles in degrees (under
    0.001°, "< 0.001°"); areas in m² or mm²; times
    over two minutes also in min:s; fractions (``_fraction``, ``_cov``, ``efficiency``) in %;
    ``None``/NaN as ``"–"``.  Unrecognised names show the bare number.
    """
    if value is None:
        return "–"
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, str):
        return value
    if isinstance(value, (dict, list, tuple, np.ndarray)):
        return json.dumps(_rounded(to_jsonable(value)))
    try:
        v = float(value)
    except (TypeError, ValueError):
        return str(value)
    if not math.isfinite(v):
        return "–"
    ku = key_unit(key)
    a = abs(v)
    if ku.kind == "length":
        if a == 0:
            return "0 mm"
        if a < 1e-9:
            return "< 1 nm" if v > 0 else "> −1 nm"
        if a < 1e-6:
            return f"{_num(v * 1e9)} nm"
        if a < 1e-3:
            return f"{_num(v * 1e6)} µm"
        if a < 1.0:
            return f"{_num(v * 1e3)} mm"
        return f"{_num(v)} m"
    if ku.kind == "area":
        return f"{_num(v * 1e6)} mm²" if 0 < a < 1e-2 else f"{_num(v)} m²"
    if ku.kind == "volume":
        return f"{_num(v * 1e9)} mm³" if 0 < a < 1e-3 else f"{_num(v)} m³"
    if ku.kind == "speed":
        return f"{_num(v * 1e3)} mm/s" if a < 1.0 else f"{_num(v)} m/s"
    if ku.kind == "time":
        if a >= 120:
            m, s = divmod(v, 60.0)
            return f"{_num(v)} s ({int(m)} min {s:.0f} s)"
        return f"{_num(v)} s"
    if ku.kind == "fraction":
        return f"{_num(v * 100, 3)} %"
    if ku.kind == "count":
        return f"{int(v):,}" if v == int(v) else _num(v)
    if ku.unit == "rad":
        if 0 < a and math.degrees(a) < 1e-3:
            return "< 0.001°" if v > 0 else "> −0.001°"
        return f"{_num(math.degrees(v))}°"
    return f"{_num(v)} {ku.unit}".strip()


def _rounded(value, digits: int = 4):
    """Floats in nested lists/dicts rounded to ``digits`` significant figures (for display)."""
    if isinstance(value, float):
        return float(f"{value:.{digits}g}")
    if isinstance(value, list):
        return [_rounded(v, digits) for v in value]
    if isinstance(value, dict):
        return {k: _rounded(v, digits) for k, v in value.items()}
    return value


def unit_suffix_markdown() -> str:
    """A Markdown table of the unit suffixes :func:`key_unit` reads (the docs' file formats page)."""
    rows = ["| key ends with | unit | shown as |", "|---|---|---|"]
    for suffix, (unit, kind, _) in sorted(_SUFFIXES.items(), key=lambda kv: (-len(kv[0]), kv[0])):
        rows.append(f"| `_{'_'.join(suffix)}` | {unit or '(none)'} | {kind} |")
    return "\n".join(rows) + "\n"
