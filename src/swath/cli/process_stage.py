"""The job's process stage: pad wear along the trajectory, media changes and the feed that
compensates the wear (:mod:`swath.process.media`).

Each function reads the stage's own record, :class:`~swath.cli.stage_settings.ProcessSettings`
(or :class:`~swath.cli.stage_settings.SimulateSettings`), and takes the job's settings or that record.
"""

from __future__ import annotations

import math

from .stage_settings import ProcessSettings, SimulateSettings


def wants_wear_stage(tool, settings) -> bool:
    """Whether the job models pad wear or changes media."""
    process = ProcessSettings.of(settings)
    return tool.wear_rate > 0 or process.media_change is not None or process.media_change_loss is not None


def wear_stage(trajectory, tool, settings):
    """Media schedule (and, with a wearing pad and ``wear_compensation``, the compensating feed)
    along ``trajectory``; returns ``(trajectory with media columns, MediaSchedule, metrics)``."""
    from ..process import compensate_wear, media_schedule, trajectory_with_media

    process = ProcessSettings.of(settings)
    rule = {"every": process.media_change, "loss": process.media_change_loss}
    compensate = tool.wear_rate > 0 and process.wear_compensation
    before = trajectory.duration
    if compensate:
        trajectory, schedule = compensate_wear(trajectory, tool.wear_rate, **rule)
    else:
        schedule = media_schedule(trajectory, tool.wear_rate, **rule)
    trajectory = trajectory_with_media(trajectory, schedule)
    metrics = {"wear_rate_per_s": tool.wear_rate, "media_changes": schedule.changes,
               "media_change_times_s": [float(t) for t in schedule.change_time],
               "media_change_limit_s": schedule.limit if math.isfinite(schedule.limit) else None,
               "media_age_max_s": float(schedule.age.max()) if len(schedule.age) else 0.0,
               "wear_removal_rate_min_fraction": float(schedule.factor.min()) if len(schedule.factor) else 1.0,
               "wear_compensation": bool(compensate),
               "wear_compensation_added_time_s": float(trajectory.duration - before)}
    return trajectory, schedule, metrics


def removal_rate_scale(trajectory, tool, settings):
    """(n,) removal-rate factor of the pad's wear along the final ``trajectory`` (None: no wear)."""
    if not tool.wear_rate > 0:
        return None
    from ..process import media_schedule

    process = ProcessSettings.of(settings)
    return media_schedule(trajectory, tool.wear_rate, every=process.media_change, loss=process.media_change_loss).factor


def transient_metrics(trajectory, surface, tool, trace, settings, removal) -> dict:
    """Depth the landings and the lifts of a force-controlled run add on their own (m), from
    ``trace.holds`` simulated on the job's removal samples: ``landing_depth_excess_m`` (deepest),
    ``lift_depth_excess_m``, and the landing's share of the mean removal."""
    from dataclasses import replace

    import numpy as np

    from ..simulate import simulate_removal

    simulate = SimulateSettings.of(settings)
    holds = trace.holds
    out = {}
    idle = replace(trajectory, contact=np.zeros(len(trajectory), bool))
    spacing = removal.metrics.get("removal_sample_spacing_m")
    for name, sel in (("landing", ~holds["lift"]), ("lift", holds["lift"])):
        part = {k: np.asarray(v)[sel] for k, v in holds.items()}
        if not len(part["dwell"]):
            out[f"{name}_depth_excess_m"] = 0.0
            continue
        rm = simulate_removal(idle, surface, tool, sample_spacing=spacing, sampling=simulate.removal_sampling,
                              holds=part)
        out[f"{name}_depth_excess_m"] = float(rm.depth.max())
    mean = removal.metrics.get("removal_mean_m") or 0.0
    out["landing_depth_excess_fraction"] = out["landing_depth_excess_m"] / mean if mean > 0 else math.nan
    return out
