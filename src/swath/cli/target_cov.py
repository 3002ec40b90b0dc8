"""``--target-cov``: the shortest plan whose predicted interior removal CoV reaches an asked evenness.

The search is over a small, stated set of candidates, each planned, timed and simulated with the
job's own pipeline (:func:`swath.cli.job.make_plan`, :func:`swath.trajectory.time_path`,
:func:`swath.simulate.simulate_removal`):

* the job's planner (raster, or uniform with ``--planner uniform``);
* the pass spacing: the planner's own covering spacing (the shortest path), or the least-ripple
  spacing (:func:`swath.feed.ripple_spacing`, for the uniform planner its overlap) within a length
  budget of 1.5, 2.0 or 2.5 times the coverage bound L*;
* the lead angle: 0, auto (half the pad presses, ``Tool.half_pad_lead``), 11° or 15°, or, as the
  default job chooses it, on the part's curvature (:func:`swath.cli.curved_spacing.curved_spacing_plan`
  with the lead chosen, then :func:`swath.cli.even_default.settle_plan_lead` and
  :func:`swath.cli.even_spacing.evener_passes`, the equidistant passes where the raster's planes
  spread and the lead by simulation): on a convex part the raster's own direction at another lead
  can read other curvatures and lay other passes;
* the feed: constant (the job's ``--feed``), and when no candidate reaches the target at constant
  feed, the :data:`FEED_CANDIDATES` evenest with the feed optimised as the default job does it
  (:func:`swath.cli.stages.even_feed_stage`: the target depth within the cycle-time factor).

All candidates are planned and timed first (cheap), then simulated in order of cycle time, the
shortest first; the first whose interior removal CoV is at or below the target is the plan.  When
none reaches it, the job is refused with the least CoV found, its length ratio and cycle time.

Before any of that, a target below the plane's floor is refused at once: straight, equally spaced
passes on a plane cannot remove more evenly than :func:`plane_floor` (the least ripple over the
candidate leads within the largest length budget, :mod:`swath.feed.ripple`), and a curved part
does no better.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace
from typing import Any

log = logging.getLogger(__name__)

#: The lead angles tried (rad; None is ``auto``, the half-pad lead).
LEADS: tuple = (0.0, None, math.radians(11.0), math.radians(15.0))
#: The length budgets (multiples of L*) the least-ripple spacing may use.
BUDGETS: tuple = (1.5, 2.0, 2.5)
#: How many of the evenest constant-feed candidates get the optimised feed when none reaches the target.
FEED_CANDIDATES = 2


@dataclass(frozen=True)
class Candidate:
    """One plan tried: its settings, and once simulated its interior removal CoV.

    Attributes
    ----------
    settings : JobSettings
        The job's settings with this candidate's planner, spacing rule and lead.
    label : str
        How the candidate reads (``"raster, ripple spacing within 1.5 L*, lead 11°"``).
    toolpath, trajectory : ToolPath, Trajectory
        The planned and timed path.
    length_ratio : float
        Contact length over the coverage bound L* (filled in from the simulation).
    cycle_time_s : float
        Predicted cycle time, s.
    interior_removal_cov : float or None
        The simulated interior CoV (None: not simulated, a cheaper candidate reached the target).
    removal : RemovalMap or None
    """

    settings: Any
    label: str
    toolpath: Any
    trajectory: Any
    cycle_time_s: float
    length_ratio: float = float("nan")
    interior_removal_cov: float | None = None
    removal: Any = None

    def record(self, target: float) -> dict:
        """The candidate as a row of ``metrics.json`` (units in the keys)."""
        s = self.settings
        cov = self.interior_removal_cov
        return {"label": self.label, "planner": s.planner, "spacing_rule": s.optimise_spacing or "cover",
                "length_budget_ratio": s.length_budget if s.optimise_spacing else None,
                "lead_angle_rad": s.lead(), "cycle_time_s": self.cycle_time_s,
                "feed": "optimised" if s.target_depth else "constant", "target_depth_m": s.target_depth,
                "length_ratio": None if math.isnan(self.length_ratio) else self.length_ratio,
                "interior_removal_cov": cov, "simulated": cov is not None,
                "reached": cov is not None and cov <= target}


@dataclass(frozen=True)
class SearchResult:
    """The chosen candidate and every candidate, in the order simulated (then the unsimulated)."""

    chosen: Candidate
    candidates: list = field(default_factory=list)

    def metrics(self, target: float) -> dict:
        """``target_cov``, the chosen candidate's label and the table of candidates."""
        return {"target_cov": target, "target_cov_choice": self.chosen.label,
                "target_cov_candidates": [c.record(target) for c in self.candidates]}


def summary_line(m: dict) -> str:
    """The CLI's line on a ``--target-cov`` job (``metrics.json``'s ``target_cov*`` figures), or ``""``:
    the evenness asked, the plan chosen, what the job's trajectory reaches and how many candidates
    were simulated."""
    target, rows = m.get("target_cov"), m.get("target_cov_candidates")
    if target is None or not rows:
        return ""
    simulated = sum(1 for r in rows if r.get("simulated"))
    inner = m.get("interior_removal_cov")
    got = f"interior CoV {100 * inner:.1f} %" if inner is not None and math.isfinite(inner) else "interior CoV unknown"
    return (f"  --target-cov {100 * target:.3g} %: {m.get('target_cov_choice')}, {got}: of {len(rows)} distinct candidate plans, "
            f"the one of shortest cycle time that reaches it ({simulated} simulated, in order of cycle time)")


def _lead_words(lead) -> str:
    return "lead auto" if lead is None else f"lead {math.degrees(lead):.0f}°"


def candidate_settings(settings) -> list[tuple]:
    """The candidates' ``(label, JobSettings, choose_lead)``: the covering spacing flat, and the
    least-ripple spacing within each of :data:`BUDGETS` at each of :data:`LEADS` and with the
    lead chosen on the part's curvature (``choose_lead`` True, as the default job does)."""
    base = replace(settings, target_cov=None, optimise_spacing=None, spacing=None, overlap=None)
    out: list[tuple] = [(f"{settings.planner}, covering spacing, lead 0°", replace(base, lead_angle=0.0), False)]
    for budget in BUDGETS:
        ripple = replace(base, optimise_spacing="ripple", length_budget=budget)
        for lead in LEADS:
            out.append((f"{settings.planner}, least-ripple spacing within {budget:g} L*, {_lead_words(lead)}",
                        replace(ripple, lead_angle=lead), False))
        out.append((f"{settings.planner}, least-ripple spacing within {budget:g} L*, lead on the curvature",
                    replace(ripple, lead_angle=None), True))
    return out


def plane_floor(tool, *, leads=LEADS, budget: float = max(BUDGETS)) -> tuple[float, float, float]:
    """The least removal CoV of straight, equally spaced passes on a plane over ``leads`` (rad, None
    for the half-pad lead) within ``budget`` times L*: ``(CoV, lead (rad), spacing (m))``
    (:func:`swath.feed.ripple_spacing`)."""
    from ..feed import ripple_spacing

    best = (math.inf, 0.0, 0.0)
    for lead in leads:
        angle = tool.half_pad_lead if lead is None else float(lead)
        spacing, cov = ripple_spacing(tool, lead_angle=angle, max_length_ratio=budget, steps=31)
        if cov < best[0]:
            best = (float(cov), angle, float(spacing))
    return best


def check_target_cov(settings) -> None:
    """Refuse, before any work, a ``target_cov`` below the plane's floor (:func:`plane_floor`)."""
    from ..errors import InfeasibleError

    target = settings.target_cov
    if target is None:
        return
    floor, lead, spacing = plane_floor(settings.tool())
    if target < floor:
        raise InfeasibleError(
            f"--target-cov {target * 100:.3g} % is below the floor of straight passes on a plane: "
            f"{floor * 100:.1f} % at best within {max(BUDGETS):g} L* (lead {math.degrees(lead):.0f}°, passes "
            f"{spacing * 1e3:.1f} mm apart, this pad and force); a curved part does no better. Ask for "
            f"{math.ceil(floor * 1000) / 10:.1f} % or more (the least reachable on the part is found by the search)")


def search_target_cov(surface, tool, settings, *, candidates=None, progress=None,
                      plan_options: dict | None = None) -> SearchResult:
    """The candidate with the shortest cycle time whose simulated interior removal CoV is at most
    ``settings.target_cov`` (module notes).

    Parameters
    ----------
    surface : Surface
    tool : Tool
        The job's tool (calibrated, if the job is).
    settings : JobSettings
        With ``target_cov`` (a fraction, e.g. 0.05).
    candidates : list of (str, JobSettings) or (str, JobSettings, bool), optional
        The candidates (default :func:`candidate_settings`); the third item, True: the plan
        chooses its lead on the part's curvature.
    progress : callable, optional
        ``progress(stage, done, total)``.
    plan_options : dict, optional
        More keyword arguments of :func:`swath.cli.job.make_plan` for every candidate (the job's
        own, e.g. its tool and selected part).

    Raises
    ------
    InfeasibleError
        When no candidate reaches the target: the message gives the least CoV found, its L / L* and
        cycle time.
    """
    from ..errors import InfeasibleError, SwathError
    from ..simulate import simulate_removal
    from ..trajectory import time_path
    from .job import make_plan

    say = progress or (lambda stage, done, total: None)
    target = float(settings.target_cov)
    pool: list[tuple] = candidate_settings(settings) if candidates is None else list(candidates)
    planned, seen = [], set()
    for i, entry in enumerate(pool):
        label, cand, choose = entry[0], entry[1], bool(entry[2]) if len(entry) > 2 else False
        say(f"--target-cov: planning candidate {i + 1} of {len(pool)} ({label})", i, len(pool))
        try:
            toolpath = make_plan(surface, cand, choose_lead=choose, **(plan_options or {}))
        except SwathError as exc:               # e.g. no direction the uniform planner can lay at that overlap
            log.warning("--target-cov: candidate %s cannot be planned on %s (%s); left out [W-TARGET-COV-CANDIDATE]",
                        label, surface.name, exc)
            continue
        run = None
        if choose:                      # as the default job: the lead for the plan's spacing, then by simulation
            from .even_default import settle_plan_lead
            from .even_spacing import evener_passes

            settle_plan_lead(toolpath, surface, tool)
            toolpath, run = evener_passes(toolpath, surface, tool, cand, part=(plan_options or {}).get("part"))
            lead = toolpath.metadata.get("ripple_lead_rad")
            if lead is not None:
                cand = replace(cand, lead_angle=float(lead))
                label = f"{label} ({math.degrees(float(lead)):.0f}°)"
        # a larger budget whose least-ripple spacing is the smaller budget's lays the same passes
        same = (round(cand.lead(), 9), len(toolpath.passes), round(toolpath.contact_length, 6))
        if same in seen:
            log.info("--target-cov: %s lays the same passes as a candidate before it; skipped", label)
            continue
        seen.add(same)
        if run is not None:             # timed and simulated at that lead already
            planned.append(Candidate(cand, label, toolpath, run[0], run[0].duration, removal=run[1]))
            continue
        trajectory = time_path(toolpath, cand.constraints(), links=cand.links(), lead_angle=cand.lead())
        planned.append(Candidate(cand, label, toolpath, trajectory, trajectory.duration))
    if not planned:
        raise InfeasibleError(f"--target-cov: none of the {len(pool)} candidate plans could be planned on "
                              f"{surface.name}; see the warnings above, or plan without --target-cov")
    planned.sort(key=lambda c: c.cycle_time_s)
    tried = []
    for i, cand in enumerate(planned):
        say(f"--target-cov: simulating candidate {i + 1} ({cand.label}, {cand.cycle_time_s:.0f} s)", i, len(planned))
        removal = cand.removal if cand.removal is not None else simulate_removal(
            cand.trajectory, surface, tool, sample_spacing=settings.sample_spacing, sampling=settings.removal_sampling)
        m = removal.metrics
        cov = float(m["interior_removal_cov"])
        done = replace(cand, interior_removal_cov=cov, removal=removal,
                       length_ratio=float(m["contact_length_m"] / m["coverage_lower_bound_m"]))
        tried.append(done)
        log.info("target CoV %.3f: %s: CoV %.3f, %.2f L*, %.0f s", target, done.label, cov, done.length_ratio,
                 done.cycle_time_s)
        if cov <= target:
            return SearchResult(done, tried + planned[i + 1:])
    fed = []
    for cand in sorted(tried, key=lambda c: float(c.interior_removal_cov or 0.0))[:FEED_CANDIDATES]:
        say(f"--target-cov: optimising the feed along {cand.label}", 0, 1)
        with_feed = _with_feed(cand, surface, tool, settings)
        if with_feed is None:
            continue
        fed.append(with_feed)
        log.info("target CoV %.3f: %s: CoV %.3f, %.2f L*, %.0f s", target, with_feed.label,
                 with_feed.interior_removal_cov, with_feed.length_ratio, with_feed.cycle_time_s)
    reached = [c for c in fed if (c.interior_removal_cov or 0.0) <= target]
    tried += fed
    if reached:
        return SearchResult(min(reached, key=lambda c: c.cycle_time_s), tried)
    best = min(tried, key=lambda c: (c.interior_removal_cov, c.cycle_time_s))
    least = float(best.interior_removal_cov or 0.0)
    raise InfeasibleError(
        f"--target-cov {target * 100:.3g} % is out of reach on {surface.name}: least reachable "
        f"{least * 100:.2f} % at {best.length_ratio:.2f} L*, {best.cycle_time_s:.0f} s "
        f"({best.label}; {len(tried)} candidates simulated). Ask for {math.ceil(least * 1000) / 10:.1f} % or more")


def _with_feed(cand: Candidate, surface, tool, settings) -> Candidate | None:
    """``cand`` (simulated at constant feed) with the feed optimised along its passes as the default
    job does it (the target depth chosen within ``cand.settings.cycle_time_factor``), simulated; None
    when the feed cannot be optimised to that target.  Its settings keep ``optimise_feed`` False:
    the trajectory already runs the optimised feed."""
    from ..simulate import simulate_removal
    from . import stages

    s = replace(cand.settings, optimise_feed=True, constant_feed=False, target_depth=None, target_floor="fastest",
                lead_angle=cand.settings.lead())          # the lead the candidate was timed with
    s, timed, result, _ = stages.even_feed_stage(cand.toolpath, tool, s, cand.trajectory, surface, {},
                                                 constant=cand.removal)
    if result is None or s.target_depth is None:
        return None
    removal = simulate_removal(timed, surface, tool, sample_spacing=settings.sample_spacing,
                               sampling=settings.removal_sampling)
    m = removal.metrics
    return Candidate(replace(s, optimise_feed=False), f"{cand.label}, feed optimised to {s.target_depth * 1e6:.2g} um",
                     cand.toolpath, timed, float(timed.duration),
                     length_ratio=float(m["contact_length_m"] / m["coverage_lower_bound_m"]),
                     interior_removal_cov=float(m["interior_removal_cov"]), removal=removal)
