"""The default job: even removal at a stated cost in cycle time.

Unless the job asks for ``constant_feed`` (``--constant-feed``) or a ``target_cov``, ``swath plan``,
``swath demo`` and job files plan for even removal:

* **spacing** — the least-ripple spacing within ``length_budget`` times the coverage bound L*
  (``optimise_spacing = "ripple"``; with the uniform planner the overlap that gives it), unless
  the job gives ``spacing``, ``overlap``, ``optimise_spacing`` or ``segment = "auto"``, or plans
  with another planner;
* **lead** — the half-pad lead (``lead_angle = "auto"``, :attr:`swath.contact.Tool.half_pad_lead`),
  unless the job gives ``lead_angle``.  Chosen by the removal simulator, which is what an
  independent check sees: with the ripple spacing and the optimised feed it removes more evenly
  than a flat pad and than 11° on the plate, the blade and crs_part_5 (docs: the even-removal
  default);
* **feed** — optimised along every pass to a target depth (:func:`swath.cli.stages.feed_stage`).
  Unless the job gives ``target_depth`` or ``target_map``, the target is chosen by
  :func:`choose_target_depth` so that the cycle time stays within ``cycle_time_factor`` (1.5)
  times that of running the same passes at the constant feed; where the passes remove more
  than that at the fastest feed (a curved part's ridges), the target rises to it
  (``target_floor = "fastest"``).

A job planned all round in setups (``side = "all"``) runs at constant feed.
"""

from __future__ import annotations

import logging
import math
from dataclasses import replace

import numpy as np

log = logging.getLogger(__name__)

#: Planners the least-ripple spacing applies to.
RIPPLE_PLANNERS = ("raster", "uniform")


def is_even(settings) -> bool:
    """Whether ``settings`` run the even-removal default (not constant feed, no ``target_cov``, one setup)."""
    return not settings.constant_feed and settings.target_cov is None and settings.side != "all"


def resolve(settings):
    """The job's settings with the default job's choices made (module notes): the lead is a number
    or ``None`` (auto) afterwards, never ``"default"``.

    Parameters
    ----------
    settings : JobSettings

    Returns
    -------
    JobSettings
    """
    changes: dict = {}
    if settings.lead_angle == "default":
        changes["lead_angle"] = settings.lead()          # auto when even, 0 otherwise (JobSettings.lead)
    if is_even(settings):
        changes["optimise_feed"] = True
        if (settings.optimise_spacing is None and settings.spacing is None and settings.overlap is None
                and settings.segment != "auto" and settings.planner in RIPPLE_PLANNERS):
            changes["optimise_spacing"] = "ripple"
        if settings.target_depth is None and settings.target_map is None:
            changes["target_floor"] = "fastest"         # a ridge the fastest feed over-removes raises the target
    return replace(settings, **changes) if changes else settings


#: Quantiles of the plan's local pass spacing the lead is judged over (:func:`settle_lead`).
SPACING_QUANTILES = (0.1, 0.3, 0.5, 0.7, 0.9)

#: The plan's lead changes (:func:`settle_plan_lead`) only where another lead is predicted to ripple
#: less than this fraction of its ripple: the quadric is one representative curvature.  On the panel
#: (uniform planner) 5.8 % at 7° against 9.4 % at 11° (0.62; simulated 0.070 against 0.096); on
#: crs_part_5, whose curvature varies, 7.8 % against 8.6 % (0.91), and the simulation found 7°
#: worse (0.226 against 0.204).
LEAD_SWITCH_RATIO = 0.8


def local_spacings(toolpath, *, step: float = 2e-3) -> np.ndarray:
    """The distance (m) from points of every pass (about ``step`` m apart along it) to the nearest
    point of another pass: the plan's local pass spacing, one figure per point ``(k,)``."""
    from scipy.spatial import cKDTree

    pts, labels = [], []
    for k, p in enumerate(toolpath.passes):
        q = np.asarray(p.points, float)
        if len(q) < 2:
            continue
        travel = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(q, axis=0), axis=1))])
        keep = np.concatenate([[True], np.diff(np.floor(travel / step)) > 0])
        pts.append(q[keep])
        labels.append(np.full(int(keep.sum()), k))
    if len(pts) < 2:
        return np.zeros(0)
    points, label = np.vstack(pts), np.concatenate(labels)
    out = []
    for k in np.unique(label):
        mine = label == k
        out.append(cKDTree(points[~mine]).query(points[mine])[0])
    return np.concatenate(out)


def settle_lead(toolpath, surface, tool, leads) -> tuple[float, dict, dict] | None:
    """The lead (rad, one of ``leads``) whose cross-profile on the passes' representative quadric
    ripples least at the spacing the plan actually has, or None with fewer than two passes.

    The least-ripple spacing chooses its lead for the spacing it asks for; the plan then lays its
    passes where the planner can (the uniform planner by the local width) and the length budget
    may widen them, so the real spacing differs, and a steep lead's ripple rises fast away from
    its best spacing.  On the panel with the uniform planner the lead was chosen at 11° for the
    spacing asked; the plan's passes came 54 mm apart, where the quadric ripples 9.3 % at 11° and
    5.7 % at 7° (simulated interior CoV 0.096 and 0.070, the same passes).  Each lead is judged by
    the root mean square of its ripple (:func:`swath.feed.curved_ripple.quadric_cross_profile`
    summed over straight passes) over the quantiles :data:`SPACING_QUANTILES` of the plan's
    local spacings (:func:`local_spacings`).

    Returns
    -------
    (float, dict, dict) or None
        The lead; ``lead_ripple_spacing_m`` (the median local spacing) with ``lead_ripple_cov``
        (the chosen lead's predicted ripple); and every lead's predicted ripple, by lead (rad).
    """
    from ..feed.curved_ripple import (
        CELLS_PER_RADIUS,
        lattice_ripple,
        pass_curvatures,
        pass_twist,
        quadric_cross_profile,
    )

    spacings = local_spacings(toolpath)
    if len(spacings) == 0:
        return None
    d = np.quantile(spacings, SPACING_QUANTILES)
    k_feed, k_cross = pass_curvatures(toolpath, surface)
    k_twist = pass_twist(toolpath, surface)
    R = tool.pad_radius
    u = (np.arange(-2 * CELLS_PER_RADIUS, 2 * CELLS_PER_RADIUS) + 0.5) * (R / CELLS_PER_RADIUS)
    scored = []
    for lead in leads:
        profile = quadric_cross_profile(tool, u, k_feed, k_cross, lead_angle=float(lead), k_twist=k_twist)
        ripple = float(np.sqrt(np.mean([lattice_ripple(u, profile, float(x)) ** 2 for x in d])))
        scored.append((ripple, float(lead)))
        log.info("lead %.1f deg at the plan's spacing %.1f mm (%.1f..%.1f): ripple %.3f", math.degrees(lead),
                 d[2] * 1e3, d[0] * 1e3, d[-1] * 1e3, ripple)
    ripple, lead = min(scored)
    return lead, {"lead_ripple_spacing_m": float(d[2]), "lead_ripple_cov": ripple}, {a: r for r, a in scored}


def settle_plan_lead(toolpath, surface, tool) -> None:
    """In the default job, on a curved part (``toolpath.metadata["ripple_model"] == "curved"``):
    choose the lead again among the half-pad lead and
    :data:`swath.cli.curved_spacing.LEAD_CHOICES_DEG` for the spacing the plan has
    (:func:`settle_lead`), and record it in ``toolpath.metadata`` (``ripple_lead_rad``, with
    ``lead_ripple_spacing_m`` and ``lead_ripple_cov``).  A plane's spacing keeps its lead."""
    from .curved_spacing import LEAD_CHOICES_DEG

    if toolpath.metadata.get("ripple_model") != "curved":
        return
    leads = sorted({float(tool.half_pad_lead), *(math.radians(a) for a in LEAD_CHOICES_DEG)})
    settled = settle_lead(toolpath, surface, tool, leads)
    if settled is None:
        return
    lead, figures, by_lead = settled
    chosen = float(toolpath.metadata.get("ripple_lead_rad", tool.half_pad_lead))
    current = by_lead.get(chosen)
    if current is not None and not figures["lead_ripple_cov"] < LEAD_SWITCH_RATIO * current:
        lead, figures["lead_ripple_cov"] = chosen, current          # not clearly better: the lead stays
    if lead != chosen:
        log.info("the plan's passes lie %.1f mm apart: lead %.1f deg (chosen for the spacing asked: %.1f deg)",
                 figures["lead_ripple_spacing_m"] * 1e3, math.degrees(lead), math.degrees(chosen))
    toolpath.metadata.update(figures, ripple_lead_rad=lead)


def wants_target_depth(settings) -> bool:
    """Whether the job's target depth is still to be chosen (:func:`choose_target_depth`)."""
    return settings.optimise_feed and settings.target_depth is None and settings.target_map is None


def interior_mean(removal, pad_radius: float) -> float:
    """Area-weighted mean depth (m) over the samples more than ``pad_radius`` (m) from the open
    boundary: the interior ``interior_removal_cov`` is taken over (the whole part when closed)."""
    inner = removal.surface.farther_from_boundary(pad_radius)
    a = removal.surface.vertex_areas[inner]
    if not len(a) or not a.sum() > 0:
        return float("nan")
    return float(np.sum(a * removal.depth[inner]) / a.sum())


def _floor_2(x: float) -> float:
    """``x`` rounded down to two significant figures (a depth stated as 3.4 um, not 3.4172 um)."""
    if not (x > 0 and math.isfinite(x)):
        return x
    scale = 10.0 ** (math.floor(math.log10(x)) - 1)
    return math.floor(x / scale + 1e-9) * scale


def choose_target_depth(constant_removal, constant_cycle_s: float, factor: float, pad_radius: float) -> tuple[float, dict]:
    """The default target depth (m) of the even-removal job, and the figures it was chosen from.

    The constant-feed run of the same passes removes ``mean`` on the interior (m), with
    ``contact`` s of its ``cycle`` s in contact.  Optimised to a target ``D``, the feed slows down
    by about ``D / mean`` in contact and the air moves keep their time, so the cycle time is about
    ``cycle + contact (D / mean - 1)``; the target is the largest ``D`` whose estimate is within
    ``factor`` times ``cycle``, rounded down to two figures::

        D = mean (1 + (factor - 1) cycle / contact)

    The estimate is conservative where the feed cannot slow everywhere in proportion (speed
    limits already hold it, the edge band): the cycle time reached is measured and stated.

    Parameters
    ----------
    constant_removal : RemovalMap
        The simulated removal of the passes at the constant feed.
    constant_cycle_s : float
        Its cycle time, s.
    factor : float
        The allowed cycle time over the constant-feed cycle time (> 1).
    pad_radius : float
        m (the interior is a pad radius in from the edges).

    Returns
    -------
    depth : float
        m.
    figures : dict
        ``constant_feed_interior_removal_mean_m``, ``constant_feed_interior_removal_cov``,
        ``constant_feed_cycle_time_s``, ``constant_feed_contact_time_s``.
    """
    m = constant_removal.metrics
    mean = interior_mean(constant_removal, pad_radius)
    if not mean > 0:
        mean = float(m["removal_mean_m"])
    contact = float(m["contact_time_s"])
    ratio = constant_cycle_s / contact if contact > 0 else 1.0
    depth = _floor_2(mean * (1.0 + (factor - 1.0) * ratio))
    figures = {"constant_feed_interior_removal_mean_m": mean,
               "constant_feed_interior_removal_cov": float(m["interior_removal_cov"]),
               "constant_feed_removal_cov": float(m["removal_cov"]),
               "constant_feed_cycle_time_s": float(constant_cycle_s), "constant_feed_contact_time_s": contact}
    return depth, figures


def lower_target(depth: float, mean: float, factor: float, reached: float) -> float:
    """A second target (m) when the first, ``depth``, gave a cycle ``reached`` times the
    constant-feed one, over ``factor``: the slowing down above the constant-feed ``mean`` (m)
    scaled by ``(factor - 1) / (reached - 1)``, rounded down to two figures."""
    scale = (factor - 1.0) / (reached - 1.0) if reached > 1.0 else 1.0
    return _floor_2(mean + (depth - mean) * min(scale, 1.0))


def feed_used(trajectory) -> dict:
    """The feeds the written trajectory runs at in contact, weighted by contact length: the
    slowest (2nd percentile: the pass-end ramps left out) and the fastest, m/s."""
    c = trajectory.contact[1:] & trajectory.contact[:-1]
    if not c.any():
        return {}
    seg = np.linalg.norm(np.diff(trajectory.position, axis=0), axis=1)[c]
    v = 0.5 * (trajectory.feed[1:] + trajectory.feed[:-1])[c]
    order = np.argsort(v)
    cdf = np.cumsum(seg[order]) / max(seg.sum(), 1e-300)
    slow = float(v[order][min(int(np.searchsorted(cdf, 0.02)), len(v) - 1)])
    return {"feed_used_p2_m_per_s": slow, "feed_used_max_m_per_s": float(v.max())}


def even_metrics(settings, removal, trajectory, figures: dict, tool) -> dict:
    """What the even-removal job states (units in the keys): the target depth, the factor asked and
    the cycle-time ratio reached, the depth reached on the interior against the target, the feeds
    used, and L / L*; all from the simulated removal of the written ``trajectory``."""
    m = removal.metrics
    out = dict(figures)
    out["even_removal_default"] = True
    out["target_depth_m"] = settings.target_depth
    out["cycle_time_allowed_ratio"] = settings.cycle_time_factor
    const = figures.get("constant_feed_cycle_time_s")
    if const and (figures.get("plain_feed_optimised") or not figures.get("plain_plan_kept")):
        out["cycle_time_ratio"] = float(trajectory.duration / const)
    mean = interior_mean(removal, tool.pad_radius)
    out["interior_removal_mean_m"] = mean
    if settings.target_depth and not figures.get("constant_feed_kept"):
        # (the constant feed written does not aim at the target: no fraction of it is stated)
        out["target_depth_reached_fraction"] = mean / settings.target_depth
    out["length_ratio"] = float(m["contact_length_m"] / m["coverage_lower_bound_m"])
    out["lead_angle_deg"] = math.degrees(settings.lead())
    out["length_budget_ratio"] = settings.length_budget if settings.optimise_spacing == "ripple" else None
    out.update(feed_used(trajectory))
    return out


def summary_line(m: dict) -> str:
    """The CLI's line on the even-removal default (from :func:`even_metrics`), or ``""``."""
    if not m.get("even_removal_default"):
        return ""
    if m.get("plain_plan_kept") and not m.get("plain_feed_optimised"):
        return (f"  even removal (default): the plain plan removes more evenly here (interior CoV "
                f"{m['plain_interior_removal_cov']:.3f} against {m['even_plan_interior_removal_cov']:.3f}) and is "
                f"written; {m['length_ratio']:.2f} L*")
    target = m.get("target_depth_m")
    lead = ("" if not m.get("plain_plan_kept") else
            f"  even removal (default): the plain plan's passes remove more evenly here than the least-ripple "
            f"spacing (interior CoV {m['plain_interior_removal_cov']:.3f} against "
            f"{m['even_plan_interior_removal_cov']:.3f} at constant feed); the feed is optimised along them\n")
    if m.get("feed_optimisation_skipped"):
        parts = [lead + "  even removal (default; --constant-feed for a plain plan): the constant feed is written, the "
                 f"feed not optimised: {100 * m['feed_reachable_variance_fraction']:.0f} % of the interior variance "
                 "lies between and along the passes, where a feed along them reaches, the rest across them"]
    elif m.get("constant_feed_kept"):
        parts = [lead + "  even removal (default; --constant-feed for a plain plan): the constant feed is written, the "
                 "feed optimised to " + (f"{target * 1e6:.3g} um" if target else "the target map")
                 + " removed less evenly (W-EVEN-FEED-WORSE)"]
    else:
        parts = [lead + "  even removal (default; --constant-feed for a plain plan): target depth "
                 + (f"{target * 1e6:.3g} um" if target else "from the target map")]
    if m.get("cycle_time_ratio") is not None:
        parts.append(f", cycle time {m['cycle_time_ratio']:.2f}x the constant feed's "
                     f"(allowed {m['cycle_time_allowed_ratio']:g}x)")
    text = "".join(parts) + "\n"
    reached = m.get("target_depth_reached_fraction")
    text += (f"  interior depth {m['interior_removal_mean_m'] * 1e6:.3g} um"
             + (f" ({100 * reached:.0f} % of the target)" if reached is not None else "")
             + (f", feed {m['feed_used_p2_m_per_s'] * 1e3:.0f}..{m['feed_used_max_m_per_s'] * 1e3:.0f} mm/s"
                if "feed_used_p2_m_per_s" in m else "")
             + f", {m['length_ratio']:.2f} L*, lead {m['lead_angle_deg']:.1f} deg")
    if m.get("constant_feed_interior_removal_cov") is not None:
        text += (f"\n  the same passes at constant feed: interior CoV {m['constant_feed_interior_removal_cov']:.3f}, "
                 f"cycle time {m['constant_feed_cycle_time_s']:.1f} s")
    return text


def keep_evener(trajectory, removal, feed, even: dict):
    """The optimised-feed ``trajectory`` and its ``removal``, or the same passes at constant feed
    (``even["_constant"]``, their trajectory and removal) when those remove more evenly on the
    interior, as the simulator finds: then ``feed`` becomes None and ``even["warnings"]``
    says so.  Returns ``(trajectory, removal, feed)``; ``even["_constant"]`` is removed."""
    constant_trajectory, constant_removal = even.pop("_constant")
    optimised = float(removal.metrics["interior_removal_cov"])
    plain = float(constant_removal.metrics["interior_removal_cov"])
    even["optimised_feed_interior_removal_cov"] = optimised
    if not optimised > plain:
        return trajectory, removal, feed
    even["constant_feed_kept"] = True
    message = (
        f"even removal: the optimised feed removes less evenly (interior CoV {optimised:.3f}) than the same passes at "
        f"constant feed ({plain:.3f}) in the simulation, so the constant-feed trajectory is written: what varies "
        "across the passes (the part's curvature or waviness), not the feed along them, bounds the evenness here "
        "(metrics.json's softer_pad_interior_removal_cov says what a softer pad would give) [W-EVEN-FEED-WORSE]")
    even.setdefault("warnings", []).append(message)
    return constant_trajectory, constant_removal, None


def plain_alternative(settings):
    """The plain plan's settings (``constant_feed``, resolved) when the default job chose the
    spacing, the lead and the target itself, so the job may compare the two (:func:`plain_if_evener`);
    None when the job gave any of them, or is not the even-removal default."""
    if not (is_even(settings) and settings.lead_angle == "default" and settings.optimise_spacing is None
            and settings.spacing is None and settings.overlap is None and settings.segment != "auto"
            and settings.planner in RIPPLE_PLANNERS and settings.target_depth is None and settings.target_map is None):
        return None
    return resolve(replace(settings, constant_feed=True, optimise_feed=False))


def plain_run(surface, tool, plain, part=None, progress=None) -> tuple:
    """The plain plan (``plain``: its settings, :func:`plain_alternative`) planned, timed and
    simulated: ``(toolpath, trajectory, removal)``.  ``progress(stage, done, total)`` hears the
    planner's steps, then the simulation's (:data:`PLAIN_SIMULATING`)."""
    from ..simulate import simulate_removal
    from ..trajectory import time_path
    from .job import make_plan

    toolpath = make_plan(surface, plain, tool=tool, part=part, progress=progress)
    trajectory = time_path(toolpath, plain.constraints(), links=plain.links(), lead_angle=plain.lead())
    removal = simulate_removal(trajectory, surface, tool, sample_spacing=plain.sample_spacing,
                               sampling=plain.removal_sampling,
                               progress=None if progress is None else lambda d, n: progress(PLAIN_SIMULATING, d, n))
    return toolpath, trajectory, removal


#: The progress stage of the plain plan's simulation (:func:`plain_run`).
PLAIN_SIMULATING = "simulating the plain plan"


def plain_beside(surface, tool, plain, *, part=None):
    """:func:`plain_run` started now in a forked child process (:class:`swath.core.beside.Beside`,
    with worker processes of its own: the uniform planner's candidate directions), while this
    process goes on (a raster job starts it before its own spacing search, which runs in this
    process alone; otherwise the job simulates its own passes meanwhile, :func:`swath.cli.stages.even_feed_stage`);
    returns a callable that waits for its ``(toolpath, trajectory, removal)``.  The plan is the one
    :func:`plain_run` makes here.  Where no child can be forked the callable plans here.  The
    planners' models shared on ``surface`` are released in this process once the child has started
    (it has its own copy of them), else once the callable has planned.

    The callable's ``share()`` says how much of the plan the child has made (0 to 1, read from a
    value the child writes as the uniform planner's candidate directions come back, so that a job
    waiting for it can say so, :func:`swath.cli.stages.even_feed_stage`; ``None`` where no child
    was forked)."""
    import multiprocessing

    from ..core.beside import Beside, can_fork
    from ..plan.uniform import TRYING_STAGE

    done = multiprocessing.get_context("fork").Value("d", 0.0, lock=False) if can_fork() else None

    def told(stage: str, steps: int, total: int) -> None:       # in the child
        if done is not None and total > 0 and stage.startswith(TRYING_STAGE):
            done.value = PLAN_SHARE * steps / total
        elif done is not None and total > 0 and stage == PLAIN_SIMULATING:
            done.value = PLAN_SHARE + (1.0 - PLAN_SHARE) * steps / total

    if can_fork():
        # both plans route their air moves round the part: its closest-point tree is built once,
        # here, and the child inherits it (else each process builds it, this one in its plan stage)
        surface.build_closest_point_tree()
    beside = Beside(plain_run, surface, tool, plain, part, told, workers=True)
    if beside.forked:
        surface.forget()

    def wait() -> tuple:
        answer = beside.result()
        surface.forget()                    # (planned here: no plan follows)
        return answer

    wait.ready = beside.ready               # type: ignore[attr-defined]
    wait.share = (lambda: done.value) if beside.forked and done is not None else None  # type: ignore[attr-defined]
    return wait


#: The share of the plain plan's time its candidate directions take (the rest: timing and
#: simulating the plan, about 2 s of crs_part_5's 30 s, the simulation counted), for
#: :func:`plain_beside`'s ``share()``.
PLAN_SHARE = 0.9


def plain_if_evener(run: tuple, removal, even: dict, *, feed_follows: bool = False):
    """``run`` (the plain plan's ``(toolpath, trajectory, removal)``, :func:`plain_run`) when it removes
    more evenly on the interior than the default job's ``removal``, else None.  The figures go into
    ``even`` (``plain_interior_removal_cov``, ``plain_cycle_time_s``, ``even_plan_interior_removal_cov``,
    ``plain_plan_kept``), with a warning when the plain plan is kept (``feed_follows``: its feed is
    optimised next, as the job does when the comparison is made at constant feed).

    The least-ripple spacing is worked out on the part's representative curvature
    (:mod:`swath.cli.curved_spacing`); where the curvature varies over the part, or a scan's
    waviness narrows the swath the covering spacing follows, it can lay the passes farther apart
    than covering needs there: the simulation, not the local model, then decides."""
    cov_plain = float(run[2].metrics["interior_removal_cov"])
    cov_even = float(removal.metrics["interior_removal_cov"])
    even.update(plain_interior_removal_cov=cov_plain, plain_cycle_time_s=float(run[1].duration),
                even_plan_interior_removal_cov=cov_even)
    if not cov_plain < cov_even:
        return None
    even["plain_plan_kept"] = True
    warnings: list[str] = []                    # what was said about the even plan's feed no longer applies
    even["warnings"] = warnings
    warnings.append(f"even removal: the plain plan (covering spacing, flat pad, constant feed) removes more evenly on "
                    f"this part (interior CoV {cov_plain:.3f}) than the least-ripple spacing with the lead "
                    f"({cov_even:.3f}) in the simulation, so the plain plan's passes are written"
                    + (" (the feed then optimised along them, kept where the simulation finds it evener)"
                       if feed_follows else "")
                    + ": the spacing worked out on the part's representative curvature does not fit it everywhere "
                    "[W-EVEN-PLAIN-KEPT]")
    return run
