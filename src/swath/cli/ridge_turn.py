"""Passes that turn round a sharp ridge, held back by the tool's angular speed limit.

A pass that crosses a ridge of radius ``r`` turns the tool frame at ``ω = v / r`` (the normal
turns by the arc's angle over its length).  Under the job's angular speed limit ``ω_max`` the feed
there is held to ``ω_max · r``: on the blade's 6.35 mm leading edge at the default 1 rad/s that
is 6.35 mm/s against the 50 mm/s feed, and the pad dwells 7.9 times as long over the nose as over
the flanks.  No feed programme
within a 1.5x cycle-time budget undoes that: the flanks would have to run 7.9 times slower.

Nor does a raster along the ridge: its cutting planes are level sets of the height across the
passes, which folds at the ridge (the blade's planes ``x = const`` cut the upper and the lower
surface both, two passes 2 mm apart at the nose; interior CoV 0.757 at 1.99 L* with the feed
optimised).  The uniform planner lays its passes by the distance along the surface and its
bisection follows the swath narrowing over the ridge, without turning round it (the blade:
interior CoV 0.373 at 1.43 L* against the raster's 0.573).

So when the even-removal default plans a raster whose direction it chose itself, it measures from
the first plan's passes alone the share of the contact length where the limit holds the feed
below :data:`~swath.plan.folds.HOLD_FRACTION` of it (:func:`held_share`).  From :data:`HOLD_SHARE` up,
:func:`uniform_if_evener` plans the part with the uniform planner too and keeps the plan that
removes more evenly at constant feed in the simulation (the blade: 0.512 against the raster's
0.733; ``example:hub``, whose rim holds the raster's feed at 22 mm/s over 4.8 % of its passes,
keeps the raster: the uniform planner's passes are held over 6.0 %).  The job's simulation then
compares the plan kept with the plain plan.
"""

from __future__ import annotations

import logging

import numpy as np

# (the held stretches are measured as swath.plan.folds measures them at a part's rim)
from ..plan.folds import HOLD_FRACTION, ridge_runs, rotation_per_metre

log = logging.getLogger(__name__)

#: The uniform planner is tried when the raster's feed is held over at least this share of the
#: contact length (the blade across its nose: 3.9 %; ``example:hub`` 4.8 %; crs_part_5 0.08 %; the
#: plate, the panel and ``bezier_dac_cad``: 0 %).
HOLD_SHARE = 0.02

#: The tightest radius a plan turns round is read where this share of its held length turns tighter
#: (a mesh's facets make the very tightest turns noisy).
TIGHT_SHARE = 0.05

#: The uniform plan replaces the raster only where its own held share is below this fraction of the
#: raster's (the uniform planner chooses its own direction, and may cross the ridge too).
RELIEF = 0.5


def held_share(toolpath, feed: float, omega_max: float | None) -> dict:
    """Where the angular speed limit holds the feed of ``toolpath``'s passes.

    Parameters
    ----------
    toolpath : ToolPath
    feed : float
        The job's feed, m/s.
    omega_max : float or None
        The tool's angular speed limit, rad/s (None: no limit).

    Returns
    -------
    dict
        ``held_share`` (the share of the contact length where ``omega_max / ρ`` is below
        :data:`~swath.plan.folds.HOLD_FRACTION` times ``feed``, ρ the normal's rotation per metre, on the stretches
        that turn round a ridge: :func:`~swath.plan.folds.ridge_runs`), ``held_feed_m_per_s``
        (the feed the limit allows there, length-weighted median; NaN when nowhere held) and
        ``held_radius_m`` (``1 / ρ`` there, the same median), ``tightest_radius_m`` (``1 / ρ`` where
        :data:`TIGHT_SHARE` of the held length turns tighter) and ``extra_dwell`` (the contact time
        the limit adds, over the contact time at ``feed``).
    """
    nan = float("nan")
    if omega_max is None or not omega_max > 0:
        return {"held_share": 0.0, "held_feed_m_per_s": nan, "held_radius_m": nan, "tightest_radius_m": nan,
                "extra_dwell": 0.0}
    rates, lengths, helds = [], [], []
    for p in toolpath.passes:
        r, s = rotation_per_metre(p.points, p.normals)
        rates.append(r)
        lengths.append(s)
        helds.append(ridge_runs(p.normals, omega_max / np.maximum(r, 1e-12) < HOLD_FRACTION * feed))
    if not rates:
        return {"held_share": 0.0, "held_feed_m_per_s": nan, "held_radius_m": nan, "tightest_radius_m": nan,
                "extra_dwell": 0.0}
    rate, length, held = np.concatenate(rates), np.concatenate(lengths), np.concatenate(helds)
    total = float(length.sum())
    cap = omega_max / np.maximum(rate, 1e-12)
    if not (total > 0 and held.any()):
        return {"held_share": 0.0, "held_feed_m_per_s": nan, "held_radius_m": nan, "tightest_radius_m": nan,
                "extra_dwell": 0.0}
    order = np.argsort(cap[held])
    w = length[held][order]
    mid = order[min(int(np.searchsorted(np.cumsum(w), 0.5 * w.sum())), len(order) - 1)]
    extra = float(np.sum(length * np.maximum(feed / cap - 1.0, 0.0)) / total)
    # (``order`` runs from the tightest turn: the radius that a share TIGHT_SHARE of the held length is tighter than)
    tight = order[min(int(np.searchsorted(np.cumsum(w), TIGHT_SHARE * w.sum())), len(order) - 1)]
    return {"held_share": float(length[held].sum() / total), "held_feed_m_per_s": float(cap[held][mid]),
            "held_radius_m": float(1.0 / rate[held][mid]), "tightest_radius_m": float(1.0 / rate[held][tight]),
            "extra_dwell": extra}


def constant_feed_cov(toolpath, surface, tool, settings) -> float:
    """The interior removal CoV of ``toolpath``'s passes timed at the job's constant feed and
    limits, at the lead the plan was chosen for (``metadata["ripple_lead_rad"]``, else the job's),
    as the removal simulator finds it."""
    from ..simulate import simulate_removal
    from ..trajectory import time_path

    lead = float(toolpath.metadata.get("ripple_lead_rad", settings.lead()))
    timed = time_path(toolpath, settings.constraints(), links=settings.links(), lead_angle=lead)
    removal = simulate_removal(timed, surface, tool, sample_spacing=settings.sample_spacing,
                               sampling=settings.removal_sampling)
    return float(removal.metrics["interior_removal_cov"])


def uniform_if_evener(toolpath, surface, tool, settings, held: dict, *, choose_lead: bool = False, progress=None):
    """The raster plan ``toolpath``, or the uniform planner's least-ripple plan of the part when the
    angular speed limit holds the raster's feed round a ridge and the uniform plan removes more
    evenly (module notes).

    Parameters
    ----------
    toolpath : ToolPath
        The raster's least-ripple plan (:func:`swath.cli.curved_spacing.curved_spacing_plan`), its
        direction chosen by the raster.
    surface : Surface
    tool : Tool
    settings : JobSettings
        The job's (the feed, the limits, the length budget and the lead are read).
    held : dict
        :func:`held_share` of the raster's first plan.
    choose_lead : bool
        The default job chose the lead: the uniform plan chooses it on the part's curvature too.
    progress : callable, optional
        ``progress(stage, done, total)``: a stage line when the uniform planner is tried, then the
        uniform planner's steps (its working mesh, candidate directions and re-plans: about 6 s of
        the blade's 8 s spacing search), then the two plans' simulations.

    Returns
    -------
    ToolPath
        The plan kept.  With ``held["held_share"]`` at least :data:`HOLD_SHARE`, its ``metadata``
        holds ``ridge_held_fraction``, ``ridge_held_feed_m_per_s`` and ``ridge_radius_m`` (the
        raster's figures) and, when the uniform plan was simulated, ``ridge_raster_cov_fraction`` and
        ``ridge_uniform_cov_fraction`` (the interior CoVs at constant feed); ``ridge_planner =
        "uniform"`` when the uniform plan is returned.  It is returned when its own passes are held
        over less than :data:`RELIEF` times the raster's share and remove more evenly at constant feed.
    """
    from dataclasses import replace

    from ..errors import InputError, SwathError
    from ..plan import get_planner
    from .curved_spacing import curved_spacing_plan
    from .job import planner_arguments

    if held["held_share"] < HOLD_SHARE:
        return toolpath
    figures = {"ridge_held_fraction": held["held_share"], "ridge_held_feed_m_per_s": held["held_feed_m_per_s"],
               "ridge_radius_m": held["held_radius_m"], "ridge_tightest_radius_m": held["tightest_radius_m"]}
    toolpath.metadata.update(figures)
    log.info("the angular speed limit %.3g rad/s holds the raster's feed at %.1f mm/s over %.1f %% of its contact "
             "length, where the passes turn round a %.1f mm radius: trying the uniform planner",
             settings.max_angular, 1e3 * held["held_feed_m_per_s"], 100 * held["held_share"],
             1e3 * held["held_radius_m"])
    uniform = replace(settings, planner="uniform")
    if progress is not None:
        progress(f"the raster's feed is held round a ridge ({1e3 * held['held_radius_m']:.0f} mm radius): "
                 "trying the uniform planner", 0, 1)
    try:
        planned = curved_spacing_plan(surface, tool, get_planner("uniform"), uniform,
                                      planner_arguments(uniform, progress=progress), choose_lead=choose_lead)
    except InputError as exc:           # raster options the uniform planner does not take: the raster stays
        log.info("the uniform planner cannot take this job (%s): the raster stays", exc)
        return toolpath
    except SwathError as exc:           # e.g. no direction the uniform planner can lay
        log.info("the uniform planner cannot plan the part (%s): the raster stays", exc)
        return toolpath
    turned = held_share(planned, settings.feed, settings.max_angular)["held_share"]
    if not turned < RELIEF * held["held_share"]:
        log.info("the uniform planner's passes are held over %.1f %% of their contact length: the raster stays",
                 100 * turned)
        return toolpath
    if progress is not None:
        progress("comparing the raster's and the uniform planner's passes by their removal", 0, 1)
    cov_raster = constant_feed_cov(toolpath, surface, tool, settings)
    cov_uniform = constant_feed_cov(planned, surface, tool, settings)
    figures.update(ridge_raster_cov_fraction=cov_raster, ridge_uniform_cov_fraction=cov_uniform)
    toolpath.metadata.update(figures)
    log.info("interior CoV at constant feed: raster %.3f, uniform %.3f", cov_raster, cov_uniform)
    if not cov_uniform < cov_raster:
        return toolpath
    planned.metadata.update(figures, ridge_planner="uniform")
    return planned


def ridge_warnings(metadata: dict, settings) -> list[str]:
    """The job's warning (``[W-EVEN-RIDGE]``) when the angular speed limit held the raster's feed
    round a ridge (``metadata``: a plan's, with :func:`uniform_if_evener`'s figures), else ``[]``:
    where, how slow, which plan is written, and the angular speed that would let the raster cross
    the ridge at the full feed."""
    share = metadata.get("ridge_held_fraction")
    if share is None:
        return []
    radius, held = float(metadata["ridge_radius_m"]), float(metadata["ridge_held_feed_m_per_s"])
    where = (f"even removal: the angular speed limit {settings.max_angular:g} rad/s holds the raster's feed at "
             f"{1e3 * held:.0f} mm/s over {100 * share:.1f} % of its contact length, where its passes turn round a "
             f"{1e3 * radius:.0f} mm radius, and the pad dwells there; ")
    if metadata.get("ridge_planner") == "uniform":
        what = (f"the uniform planner's passes, which do not turn round it, are planned instead (interior CoV "
                f"{metadata['ridge_uniform_cov_fraction']:.3f} against {metadata['ridge_raster_cov_fraction']:.3f} "
                "at constant feed)")
    elif "ridge_uniform_cov_fraction" in metadata:
        what = (f"the uniform planner's passes removed less evenly ({metadata['ridge_uniform_cov_fraction']:.3f} "
                f"against {metadata['ridge_raster_cov_fraction']:.3f} at constant feed), so the raster's stay")
    else:
        what = "the uniform planner's passes turn round it too, so the raster's stay"
    tightest = float(metadata.get("ridge_tightest_radius_m", radius))
    advice = (f"; a robot that turns the tool at {settings.feed / tightest:.1f} rad/s there (--max-angular) lets the "
              "raster cross it at the full feed [W-EVEN-RIDGE]")
    return [where + what + advice]
