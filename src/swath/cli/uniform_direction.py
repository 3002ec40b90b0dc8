"""The even-removal job's uniform pass direction: chosen by the removal it simulates, then kept.

The uniform planner ranks its candidate directions by predicted cycle time (:func:`swath.plan.uniform.uniform`),
and on a curved part those cycle times lie within a few per cent of each other while the evenness
does not.  On the blade (``example:blade``, the default job with the direction given) the interior
removal CoV is 0.358 at 0°, 0.360 at 30°, 0.514 at 60°, 0.558 at 90° and 0.551 at 120° and 150°
(0.548 to 0.677 at constant feed), with cycle times of 200 to 271 s.  At 0° the passes run along
the span, beside the 6.35 mm nose; from 60° on they wrap round it, and the swath narrows from
about 74 mm to 17 mm along each pass there.  Which of the near-tied directions
the cycle time picked decided the result: a 0.07 mm change of the distance field turned the
demo's plan from 0° (0.373) to 90° (0.551).

So the default job (which chooses the spacing and the lead itself) reads its first uniform plan's
candidates, every one that covers enough ranked in full, takes each direction whose cycle time is
within :data:`COST_SHARE` of the best (its passes as the first plan laid them, ``candidate_paths``
of :func:`swath.plan.uniform.uniform`) and simulates each at constant feed.  Where the planner's
own choice is within :data:`COV_TIE` of the least interior removal CoV, it stands and nothing
changes.  Otherwise the evenest direction (within :data:`COV_TIE`, the shortest cycle time) is
taken, and the re-plans keep it, as the raster's re-plans keep theirs: the lead and spacing are
chosen on the curvature read along these passes, and each re-plan is one layout instead of one
per direction.

A direction is not held where the cycle time already chose it: on crs_part_5, 0° was both the
cheapest and the evenest at the first plan's overlap (interior CoV 0.194 at constant feed), but
held through the re-plan at the least-ripple overlap its plan stopped early and removed at 0.710,
where the re-plan choosing afresh turns to 30° and 0.210.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from ..core.beside import Beside

log = logging.getLogger(__name__)

#: Candidate directions whose predicted cycle time is within this fraction of the best are
#: simulated.  The blade's four ranked directions lay within 3 % (its evenest 2.9 % over the best);
#: snp_part_scan's next-best lay 6.7 % and 7.0 % over and removed no more evenly (interior CoV 0.269
#: and 0.271 at constant feed against 0.262).
COST_SHARE = 0.05

#: Interior removal CoVs within this of the least count as equal: the shortest cycle time wins.
COV_TIE = 0.005

#: The plan's ``direction_rule`` where this module chose the direction.
DIRECTION_RULE = (f"auto: the least interior removal CoV at constant feed among the directions within "
                  f"{100 * COST_SHARE:.0f} % of the shortest predicted cycle time")

#: The plan metadata this module sets, carried to the re-plans' plan.
CARRIED = ("direction_rule", "direction_evenness", "direction_candidates")


def contenders(metadata: dict) -> list[tuple[float, float]]:
    """``(angle rad, cost)`` of the candidate directions of a uniform plan's ``metadata`` that are
    worth simulating: ranked (cost not None) and within :data:`COST_SHARE` of the least cost,
    cheapest first.  Empty for a plan of one given direction or of several pieces."""
    if metadata.get("pieces"):
        return []
    rows = [r for r in metadata.get("candidates") or [] if r.get("cost") is not None]
    if not rows:
        return []
    best = min(r["cost"] for r in rows)
    kept = sorted((r for r in rows if r["cost"] <= best * (1.0 + COST_SHARE)), key=lambda r: r["cost"])
    return [(math.radians(r["direction_deg"]), float(r["cost"])) for r in kept]


def constant_feed_cov(toolpath, surface, tool, settings) -> tuple[float, float]:
    """``toolpath`` timed at the job's constant feed and simulated: ``(interior removal CoV, cycle
    time s)``.  The air moves go straight up, across and down (:func:`straight_links`): they remove
    nothing, and routing them round the part (2 s for a uniform plan of crs_part_5) would only
    lengthen the cycle time a little."""
    from dataclasses import replace

    from ..simulate import simulate_removal
    from ..trajectory import time_path

    links = settings.links()
    toolpath = replace(toolpath, links=straight_links(toolpath, links.clearance))
    trajectory = time_path(toolpath, settings.constraints(), links=links, lead_angle=settings.lead())
    removal = simulate_removal(trajectory, surface, tool, sample_spacing=settings.sample_spacing,
                               sampling=settings.removal_sampling)
    return float(removal.metrics["interior_removal_cov"]), float(trajectory.duration)


def evenest_direction(first, paths: dict, surface, tool, settings, *, progress=None):
    """The plan among ``first`` (a uniform plan with automatic direction) and the other contenders
    (:func:`contenders`; ``paths``: ``{direction rad: ToolPath}``, the first plan's
    ``candidate_paths``) whose constant-feed removal is the most even (module notes);
    ``(toolpath, angle)``, with the angle None where there is nothing to compare (then ``first``
    is returned).  The chosen plan's ``metadata`` gains ``direction_rule``, ``direction_evenness``
    (per direction its interior CoV and cycle time at constant feed) and ``direction_candidates``
    (the first plan's ``candidates``).  ``progress(stage, done, total)`` hears of each direction
    compared."""
    chosen = float(first.metadata["direction_rad"])
    rows = [(angle, cost) for angle, cost in contenders(first.metadata)
            if math.isclose(angle, chosen, abs_tol=1e-9) or angle in paths]
    if len(rows) < 2:
        return first, None
    plans = [first if math.isclose(angle, chosen, abs_tol=1e-9) else paths[angle] for angle, _ in rows]

    # directions that share a seed lay the same passes (120 and 150 degrees on the blade): simulated once
    same: dict[tuple, int] = {}
    first_of = [same.setdefault(_passes_key(tp), i) for i, tp in enumerate(plans)]
    unique = sorted(set(first_of))

    def simulated(indices) -> list[tuple[float, float]]:
        return [constant_feed_cov(plans[i], surface, tool, settings) for i in indices]

    # The first simulation here loads the timing and the simulator (about a second, once per
    # job); then a forked child simulates every other one of the rest meanwhile.
    say = progress or (lambda stage, done, total: None)
    stage = f"planning (uniform): comparing {len(unique)} directions by their removal"
    say(stage, 0, len(unique))
    figures = dict(zip(unique[:1], simulated(unique[:1])))
    beside = Beside(simulated, unique[1::2])
    for k in range(2, len(unique), 2):
        say(stage, k, len(unique))
        figures[unique[k]] = simulated([unique[k]])[0]
    figures.update(zip(unique[1::2], beside.result()))
    tried = []
    for i, (angle, cost) in enumerate(rows):
        cov, cycle = figures[first_of[i]]
        log.info("uniform direction %.0f deg: interior removal CoV %.3f at constant feed, cycle time %.1f s",
                 math.degrees(angle), cov, cycle)
        tried.append(dict(direction_deg=math.degrees(angle), interior_removal_cov=cov, cycle_time_s=cycle,
                          predicted_cycle_time_s=cost, toolpath=plans[i]))
    least = min(t["interior_removal_cov"] for t in tried)
    by_cost = tried[0]                                # contenders come cheapest first: the planner's choice
    if by_cost["interior_removal_cov"] <= least + COV_TIE:
        # nothing to overrule: the re-plans choose their direction as they did before
        log.info("uniform direction: %.0f deg, ranked first by cycle time, is also the evenest at constant feed "
                 "(interior CoV %.3f)", by_cost["direction_deg"], by_cost["interior_removal_cov"])
        return first, None
    best = min((t for t in tried if t["interior_removal_cov"] <= least + COV_TIE), key=lambda t: t["cycle_time_s"])
    toolpath = best["toolpath"]
    table = [{k: v for k, v in t.items() if k != "toolpath"} for t in tried]
    # (not as "candidates": the re-plans keep this direction, so the other directions' lengths no
    # longer bear on how far a re-plan's length can be predicted, swath.cli.curved_spacing)
    toolpath.metadata.update(direction_evenness=table, direction_candidates=first.metadata.get("candidates"),
                             direction_rule=DIRECTION_RULE)
    log.info("uniform direction: %.0f deg, the evenest at constant feed (interior CoV %.3f against %.3f at the "
             "%.0f deg the planner ranked first by cycle time); the re-plans keep it", best["direction_deg"],
             best["interior_removal_cov"], by_cost["interior_removal_cov"], by_cost["direction_deg"])
    return toolpath, math.radians(best["direction_deg"])


def _passes_key(toolpath) -> tuple:
    """A key equal for tool paths whose passes are equal point for point."""
    import hashlib

    digest = hashlib.sha256()
    for p in toolpath.passes:
        digest.update(np.ascontiguousarray(p.points, float).tobytes())
    return len(toolpath.passes), digest.hexdigest()


def straight_links(toolpath, clearance: float) -> tuple:
    """An air move between each pair of consecutive passes of ``toolpath``: up ``clearance`` (m)
    along the surface normal, straight across, and down (a :class:`swath.core.Link` each)."""
    from ..core import Link

    links = []
    for a, b in zip(toolpath.passes[:-1], toolpath.passes[1:]):
        end, start = a.points[-1], b.points[0]
        links.append(Link(np.array([end, end + clearance * a.normals[-1], start + clearance * b.normals[0], start])))
    return tuple(links)
