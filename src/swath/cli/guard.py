"""A memory and size guard: estimate a job's work from the part before planning, and refuse it
with the numbers and the fix when it would not fit the memory budget."""

from __future__ import annotations

import logging
import os

import numpy as np

from ..errors import InfeasibleError

log = logging.getLogger(__name__)

#: Bytes per removal-simulation sample and per mesh face (measured: crs_part_5's 1.44 M samples
#: peaked at 1.76 GB), and the interpreter's own share.
BYTES_PER_SAMPLE = 1300
BYTES_PER_FACE = 600
BASE_BYTES = 500e6
#: Share of the machine's memory a job may use by default.
DEFAULT_SHARE = 0.75


def machine_memory() -> float:
    """Physical memory of this machine, bytes."""
    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return 8e9


def estimate_bytes(surface, settings) -> dict:
    """The estimated peak memory of planning and simulating ``surface`` under ``settings``.

    The removal samples are counted exactly for ``removal_sampling = "lattice"``
    (:func:`swath.simulate.samples.count_removal_samples`, a few vectorised passes over the faces)
    and estimated from the area for ``"mesh"`` (:func:`swath.simulate.removal.samples_for_area`, an
    upper estimate except on meshes of slivers).

    Returns a dict with ``removal_samples`` (count, after the simulation's own cap), ``bytes``.
    """
    from ..contact.tool import sample_spacing_for
    from ..simulate.removal import MAX_REMOVAL_SAMPLES, samples_for_area
    from ..simulate.samples import count_removal_samples

    tool = settings.tool()
    spacing = settings.sample_spacing or sample_spacing_for(tool)
    if getattr(settings, "removal_sampling", "mesh") == "lattice":
        count = count_removal_samples(surface, spacing)
    else:
        count = samples_for_area(surface.area, spacing)
    samples = min(count, MAX_REMOVAL_SAMPLES)
    total = BASE_BYTES + BYTES_PER_FACE * len(surface.faces) + BYTES_PER_SAMPLE * samples
    return {"removal_samples": int(samples), "bytes": float(total)}


def check_budget(surface, settings) -> dict:
    """Refuse the job when the part is smaller than the pad (a unit slip, or the wrong pad), or when
    :func:`estimate_bytes` exceeds the budget (``settings.memory_budget`` or 3/4 of the machine's
    memory); returns the estimate."""
    size = float(np.ptp(surface.vertices, axis=0).max())
    if size < 2 * settings.pad_radius and not settings.force_units:
        from ..io.checks import likely_unit
        from ..units import length_unit_factor

        example = str(settings.part).startswith("example:")       # its units are known
        in_file = size / length_unit_factor(settings.units)
        guess = None if example else likely_unit(in_file, exclude=settings.units)
        if guess and in_file * length_unit_factor(guess) < 2 * settings.pad_radius:
            guess = None          # a unit that leaves it smaller than the pad is no explanation
        hint = (f"; read with --units {guess} it would be {in_file * length_unit_factor(guess):.3g} m across; or"
                if guess else ";")
        raise InfeasibleError(f"{surface.name or 'the part'} is {size * 1e3:.1f} mm across, smaller than the pad "
                              f"({2e3 * settings.pad_radius:.1f} mm){hint} choose a smaller --pad-radius"
                              + ("" if example else ", or pass --force-units"))
    est = estimate_bytes(surface, settings)
    budget = settings.memory_budget or DEFAULT_SHARE * machine_memory()
    log.info("estimated peak memory %.2f GB (budget %.2f GB), %d removal samples", est["bytes"] / 1e9, budget / 1e9,
             est["removal_samples"])
    if est["bytes"] > budget:
        raise InfeasibleError(
            f"{surface.name or 'the part'} ({surface.area:.3g} m², {len(surface.faces):,} faces) would need about "
            f"{est['bytes'] / 2**30:.1f} GiB, over the memory budget of {budget / 2**30:.1f} GiB; check the units "
            "(--units), simplify the mesh, or raise --memory-budget")
    return est
