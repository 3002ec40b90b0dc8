"""How much of a plan's uneven removal comes from the pad being too stiff for the part.

A compliant pad presses where it is compressed: on a flat part the whole face, evenly; on a
curved or wavy one, harder on what stands out (crests, the middle of a convex patch) and not at
all where the surface falls away by more than the pad's depression.  The pad of a job is set by
its depression on flat at the set force (:attr:`swath.contact.Tool.flat_depression`, 1 mm by
default).  On the shared scans the surface departs from a smooth quadric by 0.35-0.46 mm rms
within 20 mm (snp_part_scan, noether_raw_mesh): a third to a half of that depression, and the
simulated removal follows those bumps whatever the feed does.

:func:`softer_pad_study` answers the question a process engineer would ask next: the *same*
programme, run with a pad that compresses ``factor`` times as much at the same force, would remove
how evenly?  Preston's law at a fixed force keeps the removal rate integrated over the patch the
same, so the mean depth hardly moves and the comparison is of evenness alone.  On a flat plate the
two pads press alike (the whole face, at ``F / (pi R²)``), so the study finds no gain there.
"""

from __future__ import annotations

import dataclasses
import math

from ..contact import Tool
from .removal import RemovalMap, simulate_removal

#: The softer pad compresses this many times as much as the job's pad at the same force.
SOFTER_FACTOR = 3.0
#: ... but never more than this share of the pad radius (a foam interface pad's range).
MAX_DEPRESSION_SHARE = 0.25
#: Jobs run the study only when the removal CoV (:func:`judged_cov`) is above this: below it there
#: is little to explain.
STUDY_ABOVE_COV = 0.15
#: A softer pad is worth a warning when its CoV is at most this share of the job's.
WARN_BELOW_SHARE = 0.8


def softer_pad_study(trajectory, surface, tool: Tool, removal: RemovalMap, *, factor: float = SOFTER_FACTOR,
                     force=None, sampling: str = "mesh", rate_scale=None, holds=None) -> dict | None:
    """The removal CoV of ``trajectory`` run with a pad ``factor`` times as compliant.

    Parameters
    ----------
    trajectory : Trajectory
        The job's timed trajectory (unchanged: same poses, same feed).
    surface : Surface
    tool : Tool
        The job's pad; the softer one is the same but for its depression on flat.
    removal : RemovalMap
        The job's own simulation: its sample spacing is reused (the same samples).
    factor : float
        Depression on flat of the softer pad over the job's (> 1), capped at
        :data:`MAX_DEPRESSION_SHARE` of the pad radius.
    force : ForceTrace force array, optional
        As given to :func:`simulate_removal` for the job.
    sampling : str
        As given to :func:`simulate_removal` for the job.
    rate_scale, holds : optional
        As given to :func:`simulate_removal` for the job (pad wear; landings and lifts).

    Returns
    -------
    dict or None
        ``pad_depression_m``, ``softer_pad_depression_m`` (m), ``softer_pad_removal_cov``,
        ``softer_pad_interior_removal_cov`` and ``softer_pad_removal_mean_m`` (m), the job's metric
        names; ``None`` when the pad cannot be made softer within the cap.
    """
    e = tool.flat_depression
    e_soft = min(factor * e, MAX_DEPRESSION_SHARE * tool.pad_radius)
    if not e_soft > e * (1 + 1e-9):
        return None
    soft = dataclasses.replace(tool, depression=None, stiffness=tool.force / (e_soft * tool.pad_area))
    spacing = removal.metrics.get("removal_sample_spacing_m")
    other = simulate_removal(trajectory, surface, soft, sample_spacing=spacing, sampling=sampling, force=force,
                             rate_scale=rate_scale, holds=holds)
    return {"pad_depression_m": float(e), "softer_pad_depression_m": float(e_soft),
            "softer_pad_removal_cov": float(other.metrics["removal_cov"]),
            "softer_pad_interior_removal_cov": float(other.metrics.get("interior_removal_cov", math.nan)),
            "softer_pad_removal_mean_m": float(other.metrics["removal_mean_m"])}


def judged_cov(metrics: dict) -> float | None:
    """The removal CoV the study judges a job by: the interior one (``interior_removal_cov``, a pad
    radius in from the open edges) where the job has it, else the whole part's (``removal_cov``).
    The whole part's counts the rim every plan leaves thin, which no pad changes: on snp_part_scan
    0.36 whole and 0.28 interior, where a pad three times as soft gives 0.14 interior."""
    cov = metrics.get("interior_removal_cov")
    if cov is None or not math.isfinite(cov):
        cov = metrics.get("removal_cov")
    return None if cov is None or not math.isfinite(cov) else float(cov)


def worth_a_study(metrics: dict) -> bool:
    """Whether a job with these simulated ``metrics`` should run :func:`softer_pad_study`: its
    :func:`judged_cov` is above :data:`STUDY_ABOVE_COV`."""
    cov = judged_cov(metrics)
    return cov is not None and cov > STUDY_ABOVE_COV
