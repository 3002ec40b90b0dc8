"""The default job's least-ripple passes: the raster's planes, or geodesic-parallel passes where their spacing spreads.

A raster cuts the part with parallel planes.  On a part whose slope changes across the passes the
planes' distance on the surface changes too: on crs_part_5 the passes of the default job lie 46 to
55 mm apart (10th to 90th percentile of each point's distance to the nearest other pass) for a
spacing of 50.4 mm, and the 11° lead chosen for that spacing ripples from 4.8 % to 15 % over that
range on the part's quadric.  The equidistant planner (:func:`swath.plan.equidistant`) keeps every
pass the same distance along the surface from the next, so the ripple is the one the spacing was
chosen for.

:func:`evener_passes` estimates on the passes' representative quadric how much the spread costs:
the root mean square of the cross-profile ripple over the plan's local spacings against the ripple
at its spacing (:func:`spread_ratio`).  From :data:`SPREAD_RATIO` up it plans the equidistant passes
at the raster's spacing and lead, times and simulates both at constant feed, and keeps the one that
removes more evenly on the interior.  The passes kept are then simulated at the other leads of
:func:`lead_choices` and the evenest lead is kept: the lead was chosen on one representative
quadric, and a part whose planes spread is one whose curvature changes.  A raster under the ratio
keeps its passes, and its lead is checked the same way, the flat pad among the leads: the quadric
stands for the part only as well as one curvature does, and on a scan not even that
(snp_part_scan: the quadric ranks the flat pad first, 0.124 against 0.159 at 11°, where the
passes simulate 0.294 flat, 0.281 at 7° and 0.274 at 11°).  The run
at the lead kept is handed to the job, which would otherwise time and simulate it again.  The
uniform planner's passes keep the model's lead: on the blade they lie 18 to 66 mm apart, and the
lead that simulates evenest at constant feed (7°, 0.506 against 0.549 flat) came out less even
once the feed was optimised along them (0.386 against 0.373).  Measured (default job,
``swath plan PART``, interior CoV at constant feed):

=================  ============  ==============================================================
part               spread ratio  outcome
=================  ============  ==============================================================
crs_part_5         1.25          equidistant kept (raster 0.193, equidistant 0.150 at 11°), then
                                 15° (7°: 0.209, 15°: 0.127) at 1.51 L*
bezier_dac_cad     1.15          raster kept (0.066 against 0.380), flat pad kept
example:panel      1.00          the raster's planes, 11° kept (0.050)
snp_part_scan      0.88          the raster's planes, 0° -> 11° (0.294 -> 0.274)
noether_wavy       < 1.1         the raster's planes, 11° -> 7° (interior 0.401 -> 0.380 with the
                                 optimised feed)
=================  ============  ==============================================================
"""

from __future__ import annotations

import logging
import math
from dataclasses import replace

import numpy as np

log = logging.getLogger(__name__)

#: From this ratio of the ripple over the plan's local spacings to the ripple at its spacing
#: (:func:`spread_ratio`), the equidistant passes are planned and simulated against the raster's.
SPREAD_RATIO = 1.1

#: Equidistant passes, or another lead, are kept only where they cover at least the raster's coverage
#: less this fraction of the part, and no less than :data:`COVERAGE_FLOOR` unless the raster covers less
#: (bezier_complex_shape: interior CoV 0.356 -> 0.340 by equidistant passes, but 99.94 -> 99.19 % covered;
#: crs_part_5: 0.150 -> 0.127 at 15°, 99.71 -> 99.56 %).
COVERAGE_SLACK = 0.005

#: The figures of :func:`evener_passes` a job's ``metrics.json`` carries (``equidistant_kept`` true or false).
FIGURES = ("spacing_spread_ratio", "raster_interior_removal_cov", "equidistant_interior_removal_cov",
           "equidistant_kept")

#: The coverage fraction below which the job warns (``W-COVERAGE-LOW``).
COVERAGE_FLOOR = 0.99


def covers_as_much(coverage: float, base: float) -> bool:
    """Whether a plan covering ``coverage`` (fraction) may replace one covering ``base``:
    :data:`COVERAGE_SLACK` less at most, and :data:`COVERAGE_FLOOR` or more unless no less than ``base``."""
    return coverage >= base - COVERAGE_SLACK and (coverage >= COVERAGE_FLOOR or coverage >= base)


def spread_ratio(toolpath, surface, tool) -> tuple[float, float]:
    """``(ratio, ripple)``: the root mean square of the cross-profile ripple on ``toolpath``'s
    representative quadric (with its twist, at its lead ``metadata["ripple_lead_rad"]``) over the
    quantiles :data:`swath.cli.even_default.SPACING_QUANTILES` of its local spacings, over the
    ripple at its spacing ``metadata["spacing_m"]``; ``(1, nan)`` without two passes or a spacing."""
    from ..feed.curved_ripple import (
        CELLS_PER_RADIUS,
        lattice_ripple,
        pass_curvatures,
        pass_twist,
        quadric_cross_profile,
    )
    from .even_default import SPACING_QUANTILES, local_spacings

    d = toolpath.metadata.get("spacing_m")
    spacings = local_spacings(toolpath)
    if not d or len(spacings) == 0:
        return 1.0, float("nan")
    k_feed, k_cross = pass_curvatures(toolpath, surface)
    k_twist = pass_twist(toolpath, surface)
    R = tool.pad_radius
    u = (np.arange(-2 * CELLS_PER_RADIUS, 2 * CELLS_PER_RADIUS) + 0.5) * (R / CELLS_PER_RADIUS)
    lead = float(toolpath.metadata.get("ripple_lead_rad", tool.half_pad_lead))
    profile = quadric_cross_profile(tool, u, k_feed, k_cross, lead_angle=lead, k_twist=k_twist)
    at = lattice_ripple(u, profile, float(d))
    spread = float(np.sqrt(np.mean([lattice_ripple(u, profile, float(x)) ** 2
                                    for x in np.quantile(spacings, SPACING_QUANTILES)])))
    return (spread / at if at > 0 else 1.0), at


def _constant_run(toolpath, surface, tool, settings):
    from ..simulate import simulate_removal
    from ..trajectory import time_path

    trajectory = time_path(toolpath, settings.constraints(), links=settings.links(), lead_angle=settings.lead())
    removal = simulate_removal(trajectory, surface, tool, sample_spacing=settings.sample_spacing,
                               sampling=settings.removal_sampling)
    return trajectory, removal


def evener_passes(toolpath, surface, tool, settings, *, part=None, progress=None):
    """The default job's raster ``toolpath``, or equidistant passes at its spacing and lead where
    they remove more evenly, at the lead that simulates evenest (module notes).

    Returns ``(toolpath, run)``: the tool path to go on with (its ``metadata["ripple_lead_rad"]``
    the lead kept) and ``run``, its ``(trajectory, removal)`` timed and simulated at constant feed
    at that lead (the job's own timing of it, :func:`swath.trajectory.time_path` with the job's
    constraints and links), or None where that run was not kept.

    Only a raster planned at the least-ripple spacing on the part's curvature
    (``metadata["ripple_model"] == "curved"``) whose :func:`spread_ratio` is at least
    :data:`SPREAD_RATIO` is compared.  The figures go into the returned path's ``metadata``:
    ``spacing_spread_ratio``, and when compared ``raster_interior_removal_cov``,
    ``equidistant_interior_removal_cov`` (constant feed, the job's lead) and ``equidistant_kept``
    (evener, and covering as much: :func:`covers_as_much`).
    """
    from .job import make_plan

    meta = toolpath.metadata
    if toolpath.planner != "raster" or meta.get("ripple_model") != "curved":
        return toolpath, None
    say = progress or (lambda stage, done, total: None)
    lead = float(meta.get("ripple_lead_rad", tool.half_pad_lead))
    ratio, ripple = spread_ratio(toolpath, surface, tool)
    meta["spacing_spread_ratio"] = float(ratio)
    if not ratio >= SPREAD_RATIO:
        # the passes stay; their lead is checked by simulation all the same (the quadric's choice
        # is one representative curvature's)
        trajectory, removal = _constant_run(toolpath, surface, tool, replace(settings, lead_angle=lead))
        return toolpath, _simulated_lead(toolpath, surface, tool, settings, lead, (trajectory, removal), say,
                                         flat=True)
    spacing = float(meta["spacing_m"])
    # four steps: the plan (about as long as the two simulations together, crs_part_5: 2.2 s and
    # 2 x 1.5 s), then each simulation, so the stage can say how long it has left
    stage = f"the raster's passes spread ({ratio:.2f}x the ripple at {spacing * 1e3:.1f} mm): trying equidistant passes"
    say(stage, 0, 4)
    other_settings = replace(settings, planner="equidistant", spacing=spacing, optimise_spacing=None, overlap=None,
                             lead_angle=lead, planner_options={})
    try:
        other = make_plan(surface, other_settings, tool=tool, part=part)
    except Exception as exc:        # noqa: BLE001 - the raster stays whatever the other planner meets
        log.info("equidistant passes could not be planned (%s); the raster's stay", exc)
        return toolpath
    run_settings = replace(settings, lead_angle=lead)
    say(stage, 2, 4)
    _, raster_removal = _constant_run(toolpath, surface, tool, run_settings)
    say(stage, 3, 4)
    _, other_removal = _constant_run(other, surface, tool, run_settings)
    say(stage, 4, 4)
    cov_raster = float(raster_removal.metrics["interior_removal_cov"])
    cov_other = float(other_removal.metrics["interior_removal_cov"])
    figures = {"spacing_spread_ratio": float(ratio), "raster_interior_removal_cov": cov_raster,
               "equidistant_interior_removal_cov": cov_other}
    # evener, and covering as much: a plan that leaves more of the part untouched is not traded for its interior
    covered = covers_as_much(float(other_removal.metrics["coverage_fraction"]),
                             float(raster_removal.metrics["coverage_fraction"]))
    keep = bool(np.isfinite(cov_other) and cov_other < cov_raster and covered)
    log.info("raster %.3f, equidistant %.3f interior CoV at constant feed (spacing %.1f mm, lead %.1f deg): %s kept",
             cov_raster, cov_other, spacing * 1e3, math.degrees(lead), "equidistant" if keep else "raster")
    meta.update(figures, equidistant_kept=keep)
    kept, removal = (other, other_removal) if keep else (toolpath, raster_removal)
    if keep:
        # the least-ripple choice is the same; the passes are the equidistant planner's
        for key in ("ripple_model", "ripple_lead_rad", "ripple_spacing_m", "ripple_length_ratio",
                    "lead_ripple_spacing_m", "lead_ripple_cov"):
            if key in meta and key not in other.metadata:
                other.metadata[key] = meta[key]
        other.metadata.update(figures, equidistant_kept=True)
    run = (None, removal)                    # timed at the job's lead, not the kept one: timed again below
    return kept, _simulated_lead(kept, surface, tool, settings, lead, run, say, flat=False)


def _simulated_lead(toolpath, surface, tool, settings, lead: float, run, say, *, flat: bool):
    """Simulate ``toolpath``'s passes at constant feed at each lead of :func:`lead_choices` (``flat``:
    the flat pad among them) besides ``lead`` (rad), whose ``run`` ``(trajectory or None, removal)``
    is known, and set ``metadata["ripple_lead_rad"]`` to the evenest of those covering as much as
    ``lead`` does (:func:`covers_as_much`); ``metadata["lead_simulated_interior_removal_cov"]`` and
    ``metadata["lead_simulated_coverage_fraction"]`` hold every lead's figures as ``[lead in degrees,
    value]`` pairs.  Returns the kept lead's ``(trajectory, removal)`` at constant feed, or None
    when its trajectory was not timed here.

    The coverage is judged against the job's lead, not the best-covering one: the flat pad may
    cover a little more where the lead's pad is lifted (a 0.35 m bowl, before the lead was laid flat
    at pass ends: 98.5 % covered at 11°, all of it flat), but its 0.41 interior CoV is no trade for
    0.065 at 11°.  (The pad is now laid flat at pass ends instead: :func:`swath.trajectory.time_path`.)"""
    runs = {float(lead): run}
    for other in lead_choices(tool, flat=flat):
        if abs(other - lead) < 1e-9:
            continue
        say(f"simulating the passes at a {math.degrees(other):.1f} deg lead", 0, 1)
        runs[float(other)] = _constant_run(toolpath, surface, tool, replace(settings, lead_angle=other))
    cov = {a: float(r[1].metrics["interior_removal_cov"]) for a, r in runs.items()}
    covered = {a: float(r[1].metrics["coverage_fraction"]) for a, r in runs.items()}
    eligible = [a for a in runs if np.isfinite(cov[a]) and covers_as_much(covered[a], covered[float(lead)])] or [float(lead)]
    best = min(eligible, key=lambda a: (cov[a], a != lead))          # ties keep the job's lead
    log.info("interior CoV at constant feed (coverage) by lead (deg): %s; lead %.1f deg kept",
             {round(math.degrees(a), 1): (round(cov[a], 4), round(covered[a], 4)) for a in sorted(runs)},
             math.degrees(best))
    toolpath.metadata.update(
        ripple_lead_rad=float(best),
        lead_simulated_interior_removal_cov=[[round(math.degrees(a), 1), cov[a]] for a in sorted(runs)],
        lead_simulated_coverage_fraction=[[round(math.degrees(a), 1), covered[a]] for a in sorted(runs)])
    kept = runs[best]
    return kept if kept[0] is not None else None


def lead_choices(tool, *, flat: bool = False) -> list[float]:
    """The leads (rad) :func:`evener_passes` simulates the passes it keeps at: the half-pad lead and
    :data:`swath.cli.curved_spacing.LEAD_CHOICES_DEG`, the flat pad only when ``flat`` (a raster
    whose planes spread is on a part curved enough for the model to have led it)."""
    from .curved_spacing import LEAD_CHOICES_DEG

    return sorted({float(tool.half_pad_lead), *(math.radians(a) for a in LEAD_CHOICES_DEG if flat or a > 0)})
