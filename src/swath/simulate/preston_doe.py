"""Designs of experiments for the Preston calibration: full and fractional factorials, and the
trials template CSV that ``swath calibrate`` reads back (columns in :data:`.calibrate.TRIAL_COLUMNS`).

Factors are columns of the trials CSV with their levels, e.g. Jaeger's Table 6.1::

    {"grit": ["80", "120", "150", "180"], "force_N": [15, 20, 25, 30],
     "spindle_speed_rpm": [1000, 2000, 3000, 4000]}

The full factorial runs every combination (here 64).  A fractional factorial names *generators*:
a generated factor takes the level number ``(i₁ + i₂ + …) mod L`` of its base factors' level
numbers, so ``{"spindle_speed_rpm": ("grit", "force_N")}`` turns the design above into the 16-run
Latin square in which every pair of factors meets at every pair of levels once; with two-level
factors it is the classic ``2^(k−p)`` half fraction (levels listed low, high: ``C = −AB`` in ±1
coding, i.e. the fraction ``I = −ABC``; list C's levels high, low for ``C = AB``).
"""

from __future__ import annotations

import csv
import io
import itertools
import math
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.atomic import write_text_atomic
from ..units import parse_quantity
from .calibrate import TRIAL_COLUMNS

#: Short factor names a user may type, with the column and the quantity kind they parse as.
FACTOR_ALIASES = {
    "grit": ("grit", None),
    "force": ("force_N", "force"),
    "speed": ("spindle_speed_rpm", "frequency"),
    "spindle_speed": ("spindle_speed_rpm", "frequency"),
    "rpm": ("spindle_speed_rpm", "frequency"),
    "feed": ("feed_m_per_s", "speed"),
    "passes": ("passes", None),
    "orbit": ("orbit_radius_m", "length"),
    "orbit_radius": ("orbit_radius_m", "length"),
    "pad_radius": ("pad_radius_m", "length"),
    "pad_age": ("pad_age_s", "time"),
}


def parse_factor(text: str) -> tuple[str, list]:
    """``"force=10N,20N,30N"`` -> ``("force_N", [10.0, 20.0, 30.0])`` (values in the column's unit).

    Known names (:data:`FACTOR_ALIASES`, or a column name itself) parse units; any other name is
    kept as a column with its levels as text.
    """
    if "=" not in text:
        raise InputError(f"expected a factor as NAME=LEVEL,LEVEL,... (e.g. force=10N,20N), got {text!r}")
    name, _, levels = text.partition("=")
    name = name.strip()
    raw = [v.strip() for v in levels.split(",") if v.strip()]
    if len(raw) < 2:
        raise InputError(f"factor {name!r} needs at least 2 levels, got {raw!r}")
    column, kind = FACTOR_ALIASES.get(name, (name, None))
    if kind is None and column in TRIAL_COLUMNS and column not in ("grit", "trial", "passes"):
        kind = {"force_N": "force", "spindle_speed_rpm": "frequency", "feed_m_per_s": "speed",
                "orbit_radius_m": "length", "pad_radius_m": "length", "depth_m": "length",
                "hardness_Pa": None, "pad_age_s": "time"}.get(column)
    values: list
    if kind is None:
        values = raw if column != "passes" else [_int(v, name) for v in raw]
    elif kind == "frequency":
        values = [parse_quantity(v, kind, default_unit="rpm") * 60.0 for v in raw]
    else:
        values = [parse_quantity(v, kind) for v in raw]
    if len(set(map(str, values))) != len(values):
        raise InputError(f"factor {name!r} repeats a level: {raw!r}")
    return column, values


def parse_generator(text: str) -> tuple[str, tuple[str, ...]]:
    """``"speed=grit+force"`` -> ``("spindle_speed_rpm", ("grit", "force_N"))`` (for ``--generator``):
    the generated factor and its base factors, by the names :func:`parse_factor` knows."""
    name, sep, rhs = str(text).partition("=")
    bases = tuple(b.strip() for b in rhs.split("+") if b.strip())
    if not sep or not name.strip() or not bases:
        raise InputError(f"expected a generator as FACTOR=BASE+BASE (e.g. speed=grit+force), got {text!r}")
    col = lambda n: FACTOR_ALIASES.get(n, (n, None))[0]
    return col(name.strip()), tuple(col(b) for b in bases)


def _int(v: str, name: str) -> int:
    try:
        i = int(v)
    except ValueError:
        raise InputError(f"factor {name!r}: levels must be whole numbers, got {v!r}") from None
    if i < 1:
        raise InputError(f"factor {name!r}: levels must be positive, got {i}")
    return i


def factorial_design(factors: dict, *, generators: dict | None = None, replicates: int = 1,
                     seed: int | None = None) -> list[dict]:
    """Runs of a full or fractional factorial design.

    Parameters
    ----------
    factors : dict of str -> sequence
        Column name -> levels (in the column's unit), in the order the columns vary (the last fastest).
    generators : dict of str -> sequence of str, optional
        Generated factor -> its base factors (module docstring).  A generated factor must have as
        many levels as each of its base factors.
    replicates : int
        Copies of every run (default 1).
    seed : int, optional
        Shuffle the run order with this seed (default: standard order).

    Returns
    -------
    list of dict
        One dict per run: column -> level.
    """
    generators = dict(generators or {})
    if not factors:
        raise InputError("a design needs at least one factor")
    if not (isinstance(replicates, int) and replicates >= 1):
        raise InputError(f"replicates must be a positive integer, got {replicates!r}")
    for g, bases in generators.items():
        if g not in factors:
            raise InputError(f"generated factor {g!r} is not among the factors {', '.join(factors)}")
        bases = list(bases)
        if not bases or any(b not in factors or b in generators for b in bases) or g in bases:
            raise InputError(f"generator of {g!r} must name base (not generated) factors other than itself, got {bases!r}")
        L = len(factors[g])
        if any(len(factors[b]) != L for b in bases):
            raise InputError(f"generated factor {g!r} has {L} levels; each of its base factors {bases} needs {L} too")
    base = [f for f in factors if f not in generators]
    runs = []
    for combo in itertools.product(*(range(len(factors[f])) for f in base)):
        idx = dict(zip(base, combo))
        for g, bases in generators.items():
            idx[g] = sum(idx[b] for b in bases) % len(factors[g])
        runs.append({f: factors[f][idx[f]] for f in factors})
    runs = [dict(r) for r in runs for _ in range(replicates)]
    if seed is not None:
        order = np.random.default_rng(seed).permutation(len(runs))
        runs = [runs[i] for i in order]
    return runs


def doe_csv_text(runs: list[dict], *, fixed: dict | None = None) -> str:
    """A trials template: ``trial``, the trials columns (factors and ``fixed`` values filled in),
    ``depth_m`` left blank for the measurement."""
    fixed = dict(fixed or {})
    present = set().union(*(r.keys() for r in runs)) | set(fixed)
    cols = ["trial"] + [c for c in TRIAL_COLUMNS if c != "trial" and (c in present or c == "depth_m")]
    cols += sorted(present - set(cols))
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    for i, r in enumerate(runs, start=1):
        row = {"trial": i, **fixed, **r}
        w.writerow([_fmt(row.get(c, "")) for c in cols])
    return buf.getvalue()


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.10g}" if math.isfinite(v) else ""
    return str(v)


def tool_columns(tool) -> dict:
    """The trials columns that state the tool (:class:`swath.contact.Tool`): spindle speed (rpm),
    orbit radius (m, 0 for a rotary pad) and pad radius (m)."""
    return {"spindle_speed_rpm": tool.spindle_speed * 60.0 / (2.0 * math.pi),
            "orbit_radius_m": tool.orbit_radius if tool.motion == "orbital" else 0.0,
            "pad_radius_m": tool.pad_radius}


def write_doe(path, factors: dict, *, generators: dict | None = None, replicates: int = 1, seed: int | None = None,
              fixed: dict | None = None, tool=None, overwrite: bool = False) -> Path:
    """Write the trials template of :func:`factorial_design` to ``path`` atomically.

    ``fixed`` holds the columns every run shares (e.g. ``{"pad_radius_m": 0.0381, "passes": 3,
    "feed_m_per_s": 0.05}``); ``tool`` (a :class:`swath.contact.Tool`, default the plan's default
    tool: an orbital 3-inch pad at 10 000 rpm on a 2.5 mm orbit) fills the tool's columns that are
    neither factors nor fixed (:func:`tool_columns`), so that ``swath calibrate`` reads the template
    back and the calibration states the tool ``swath plan`` runs.  ``depth_m`` and ``pad_age_s``
    stay blank for the user to fill in.  An existing file (it may hold measurements) is refused
    unless ``overwrite``.  Returns the path.
    """
    from ..contact import Tool

    path = Path(path)
    if path.is_dir():
        raise InputError(f"{path} is a folder; give the trials template a file name, e.g. {path / 'trials.csv'}")
    if path.exists() and not overwrite:
        raise InputError(f"{path} exists and may hold measurements: write the template under another name, or add "
                         "--overwrite to replace it")
    runs = factorial_design(factors, generators=generators, replicates=replicates, seed=seed)
    overlap = set(fixed or {}) & set(factors)
    if overlap:
        raise InputError(f"{', '.join(sorted(overlap))} is both a factor and fixed; give it once")
    fixed = dict(fixed or {})
    for col, value in tool_columns(tool if tool is not None else Tool()).items():
        if col not in factors and col not in fixed:
            fixed[col] = value
    if "pad_age_s" not in factors:
        fixed.setdefault("pad_age_s", "")
    write_text_atomic(path, doe_csv_text(runs, fixed=fixed))
    return path
