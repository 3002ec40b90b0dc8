"""Plain-language warnings about a plan's result: what a user must know before running it.

Each warning is one sentence that says what is wrong, by how much, and what to do.  Only the kept
plan is judged (a planner's discarded candidates never warn).
"""

from __future__ import annotations

import numpy as np

from ..simulate.compliance import WARN_BELOW_SHARE
from ..simulate.hot_spots import hot_spot_warnings

#: Coverage below this fraction is worth a warning.
MIN_COVERAGE = 0.99
#: Contact time spent below this fraction of the feed is worth a warning above WARN_SLOW_SHARE.
SLOW_FRACTION = 0.5
WARN_SLOW_SHARE = 0.05
#: An optimised feed whose predicted mean removal is below this fraction of the target's mean warns.
MIN_TARGET_SHARE = 0.9


def _depth(x: float) -> str:
    return f"{1e3 * x:.3g} mm" if x >= 1e-3 else f"{1e6 * x:.3g} um"


def plan_warnings(surface, toolpath, trajectory, metrics: dict, feed: float, pad_radius: float) -> list[str]:
    """Warnings for a planned, timed and simulated job.

    Parameters
    ----------
    surface : Surface
    toolpath : ToolPath
        The kept plan (its ``metadata["warnings"]`` are included).
    trajectory : Trajectory
    metrics : dict
        The job's metrics (``coverage_fraction``, ``efficiency``, ..., and with an optimised feed
        ``feed_target_mean_m``, ``feed_removal_mean_m``, ``feed_v_min_m_per_s``).
    feed : float
        The commanded feed, m/s.
    pad_radius : float
        m; air moves more than ``pad_radius`` + the clearance outside the part's bounding box warn.

    Returns
    -------
    list of str
    """
    out = [str(w) for w in toolpath.metadata.get("warnings", [])]
    cov = metrics.get("coverage_fraction")
    if cov is not None and np.isfinite(cov) and cov < MIN_COVERAGE:
        # two decimals: 98.96 % must not read "99.0 % (below 99 %)"
        out.append(f"coverage is {100 * cov:.2f} % (below {100 * MIN_COVERAGE:.0f} %): {100 * (1 - cov):.2f} % of "
                   "the part is never touched; lower the spacing or raise the overlap, or plan the part in regions")
    eff = metrics.get("efficiency")
    if eff is not None and np.isfinite(eff) and eff > 1.0 + 1e-9:
        out.append(f"efficiency {eff:.3f} is above 1, which no plan can reach: the coverage lower bound counts area "
                   "the passes never cover; read it with coverage_fraction")
    got, want = metrics.get("feed_removal_mean_m"), metrics.get("feed_target_mean_m")
    optimised = want is not None
    if want is not None and got is not None and np.isfinite(got) and want > 0 and got < MIN_TARGET_SHARE * want:
        limit, used = metrics.get("feed_v_min_m_per_s"), metrics.get("feed_speed_min_m_per_s")
        # the shares of the feed nodes the programme's cap holds at their fastest (slowing one would
        # take a sample where the removal is highest over the target plus the tolerance) and of those
        # at the slowest feed: a few nodes at the slowest do not make the feed range the cause
        # (crs_part_5, uniform: 47 % held by the cap, 0.2 % at 5 mm/s, the rest of the feed 25 mm/s and up)
        held, slowest = metrics.get("feed_nodes_held_by_cap_fraction"), metrics.get("feed_nodes_at_slowest_fraction")
        if used and limit and used > 1.2 * limit:
            # the feed never reached its slowest: the tolerance at the removal's highs holds the rest back
            why = (f"; the slowest feed used is {1e3 * used:.0f} mm/s (allowed down to {1e3 * limit:.0f} mm/s): "
                   "the tolerance where the removal is highest holds it back, not the feed; raise --depth-tolerance, "
                   "or on a curved part use a softer pad")
        elif held is not None and slowest is not None and held > slowest:
            at = f" ({1e3 * limit:.0f} mm/s)" if limit else ""
            why = (f"; {100 * held:.0f} % of the feed nodes run at their fastest because slowing them would remove "
                   f"more than the tolerance allows where the removal is highest, and {100 * slowest:.1f} % at the "
                   f"slowest feed{at}: the tolerance holds it back, not the feed; raise --depth-tolerance, plan the "
                   "passes closer, or on a curved part use a softer pad")
        else:
            slowest_feed = used or limit
            at = f"{1e3 * slowest_feed:.0f} mm/s" if slowest_feed else "its slowest"
            why = (f" with the feed down to {at} where needed: the slowest feed holds it back; lower the target, "
                   "raise the force, plan the passes closer, or run the job more than once")
        out.append(f"the optimised feed removes {_depth(got)} on average, {100 * got / want:.2g} % of the "
                   f"target {_depth(want)}{why}")
    # the interiors compared where both are known (the rim every plan leaves thin is no pad's doing)
    soft, cov, which = metrics.get("softer_pad_interior_removal_cov"), metrics.get("interior_removal_cov"), \
        "interior removal CoV"
    if not (soft is not None and cov is not None and np.isfinite(soft) and np.isfinite(cov)):
        soft, cov, which = metrics.get("softer_pad_removal_cov"), metrics.get("removal_cov"), "removal CoV"
    if soft is not None and cov is not None and np.isfinite(soft) and soft <= WARN_BELOW_SHARE * cov:
        e, e_soft = metrics["pad_depression_m"], metrics["softer_pad_depression_m"]
        out.append(f"{which} {cov:.2f}: the pad ({_depth(e)} compression on flat at the set force) is too stiff "
                   f"to follow this surface's curvature and waviness; the same programme with a pad compressing "
                   f"{_depth(e_soft)} would remove with {which} {soft:.2f} (simulated). Use a softer interface pad "
                   f"(--depression {1e3 * e_soft:.3g}mm), or, if the waviness is scanner noise, plan on a smooth fit of "
                   "the scan (swath fit)")
    out += hot_spot_warnings(metrics, feed)     # a patch ground far deeper than the inside
    if trajectory is not None and len(trajectory) > 1:
        dt = np.diff(trajectory.t)
        both = trajectory.contact[1:] & trajectory.contact[:-1]
        slow = both & (0.5 * (trajectory.feed[1:] + trajectory.feed[:-1]) < SLOW_FRACTION * feed)
        total = float(dt[both].sum())
        # an optimised feed slows down on purpose: the limits' share of it is not known here
        if not optimised and total > 0 and dt[slow].sum() / total > WARN_SLOW_SHARE:
            out.append(f"the speed limits hold the tool below half the feed for {100 * dt[slow].sum() / total:.0f} % "
                       "of the contact time: it dwells there and removes more; relax the limits (--max-angular, "
                       "--max-centripetal, --max-accel) or choose another direction")
        lo, hi = surface.vertices.min(axis=0), surface.vertices.max(axis=0)
        air = ~trajectory.contact
        if air.any():
            p = trajectory.position[air]
            beyond = np.maximum(np.maximum(lo - p, p - hi), 0.0).max()
            allowed = pad_radius + float(trajectory.metadata.get("clearance_m", 0.02)) + 1e-3
            if beyond > allowed:
                out.append(f"air moves go {1e3 * beyond:.0f} mm outside the part's bounding box (more than the pad "
                           f"radius plus the clearance, {1e3 * allowed:.0f} mm): check the cell for room")
    return out
