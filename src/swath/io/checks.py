"""Checks at the edge shared by the mesh and point-cloud readers: the file itself and the part size."""

from __future__ import annotations

import logging
from pathlib import Path

from ..errors import InputError
from ..units import canonical_length_unit, length_unit_factor

log = logging.getLogger("swath.io")

#: Accepted part size (largest bounding-box extent) in metres, and the comfortable range.
SIZE_LIMITS = (0.005, 20.0)
PREFERRED_SIZE = (0.05, 3.0)
#: A part larger than this (m), or smaller than SMALL_PART, whose size another unit makes
#: comfortable (PREFERRED_SIZE) is refused as a likely unit slip unless units are forced.
LARGE_PART = 5.0
SMALL_PART = 0.02
#: Units suggested when the size is implausible, in order of preference.
SUGGESTED_UNITS = ("m", "mm", "in")

def check_file(path: Path, extensions, what: str, *, others: str = "") -> str:
    """The lower-case extension of ``path`` after checking it is one of ``extensions`` and a non-empty file
    (``others``: what else the caller's command reads, named in the refusal).

    Raises
    ------
    InputError
        For an unsupported extension, a missing path, a directory or an empty file.
    """
    ext = path.suffix.lower()
    if path.is_dir():
        raise InputError(f"{path} is a directory; give the path of a {what} file ({', '.join(extensions)}) in it")
    if ext not in extensions:
        raise InputError(f"{path.name}: unsupported {what} file type {ext or '(no extension)'!r}; "
                         f"use one of {', '.join(extensions)}{others}")
    if not path.exists():
        raise InputError(f"{path}: no such file; check the path")
    if not path.is_file():
        raise InputError(f"{path} is not a file; give the path of a {what} file")
    if path.stat().st_size == 0:
        raise InputError(f"{path.name} is empty (0 bytes); re-export the {what}")
    return ext


def _unit_words(unit: str) -> str:
    """A length unit as prose reads it after "in": ``mm``, but ``inches`` (not "read in in")."""
    return "inches" if unit == "in" else unit


def check_extent(extent_file_units: float, units: str, force_units: bool, label: str) -> None:
    """Refuse or warn about an implausible part size (largest extent in the file's unit)."""
    units = canonical_length_unit(units)
    size = float(extent_file_units) * length_unit_factor(units)
    lo, hi = SIZE_LIMITS
    guess = likely_unit(extent_file_units, exclude=units)
    hint = ""
    if guess is not None:
        hint = (f"; read in {_unit_words(guess)} it would be "
                f"{extent_file_units * length_unit_factor(guess):.3g} m")
    if not lo <= size <= hi:
        if force_units:
            log.warning("%s: part is %.4g m across read in %s (outside %g mm .. %g m); accepted because "
                        "units were forced%s", label, size, _unit_words(units), lo * 1e3, hi, hint)
            return
        fix = (f"it is probably in {_unit_words(guess)} ({extent_file_units * length_unit_factor(guess):.3g} m): "
               "pass "
               f"--units {guess}, or --force-units to keep {units}" if guess is not None else
               f"no unit among {', '.join(SUGGESTED_UNITS)} gives a plausible size: check the file, or pass "
               f"--force-units to keep {units}")
        raise InputError(f"{label}: part is {size:.4g} m across when read in {_unit_words(units)}, outside "
                         f"{lo * 1e3:g} mm .. {hi:g} m; {fix}")
    if size > LARGE_PART or size < SMALL_PART:
        comfortable = guess is not None and PREFERRED_SIZE[0] <= extent_file_units * length_unit_factor(guess) \
            <= PREFERRED_SIZE[1]
        if comfortable and not force_units:
            raise InputError(f"{label}: part is {size:.4g} m across when read in {_unit_words(units)}, "
                             "which looks like a unit "
                             f"slip{hint}; pass --units {guess}, or --force-units to keep {units}")
        log.warning("%s: part is %.4g m across read in %s; the file may not be in %s%s%s", label, size,
                    _unit_words(units), "metres" if units == "m" else _unit_words(units), hint,
                    f" (pass --units {guess})" if guess is not None else "")


def likely_unit(extent_file_units: float, *, exclude: str | None = None) -> str | None:
    """The unit among m, mm, in that makes a part of this extent (file units) 5 mm .. 20 m across,
    preferring 0.05 .. 3 m; None when no unit does."""
    exclude = None if exclude is None else canonical_length_unit(exclude)
    sizes = {u: extent_file_units * length_unit_factor(u) for u in SUGGESTED_UNITS if u != exclude}
    ok = [u for u, s in sizes.items() if SIZE_LIMITS[0] <= s <= SIZE_LIMITS[1]]
    good = [u for u in ok if PREFERRED_SIZE[0] <= sizes[u] <= PREFERRED_SIZE[1]]
    return (good or ok)[0] if (good or ok) else None
