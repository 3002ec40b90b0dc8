"""The least-ripple spacing of a job, on the part's own curvature and within the length budget.

``optimise_spacing = "ripple"`` (the even-removal default's spacing) used to take the spacing
that sums the pad's cross-profiles flattest *on a plane* (:func:`swath.feed.ripple_spacing`).
On a curved part the cross-profile itself changes (:mod:`swath.feed.curved_ripple`), and on the
panel, the blade and the scans the simulator then found the plain covering plan evener.

:func:`curved_spacing_plan` plans the passes once at the plane's spacing, reads their
representative curvatures along and across (:func:`swath.feed.curved_ripple.pass_curvatures`),
and re-plans at the spacing whose profiles on that quadric sum flattest
(:func:`swath.feed.curved_ripple.curved_ripple_spacing`, at the job's lead, or in the default job
at the lead of those in :data:`LEAD_CHOICES_DEG` and the job's that ripples least): the raster at
``spacing = choice.spacing``, the uniform planner at ``overlap = choice.overlap``.  On a part
flatter than :data:`FLAT_SAGITTA` over the pad the plane's spacing stays.

The re-plans keep the first plan's raster direction (when the job left it free): the curvature was
read along those passes, and a raster choosing its direction afresh at the new spacing may turn
across the part's strongest curvature, which the spacing was not chosen for.  In the default job
the uniform planner's re-plans keep a direction too: the evenest at constant feed among the first
plan's candidates (:mod:`swath.cli.uniform_direction`); a re-plan is then one layout, not one
per direction.

Either way the contact length is then held within the budget: the plane's ``L* = A / 2R`` and the
quadric's ``w_max / d`` are local estimates, the fill passes and the pass ends add length, and the
panel's plan came out at 1.6 L* for a 1.5 budget.  While the plan's contact length over the
part's coverage bound (:func:`swath.contact.coverage_lower_bound`, the figure ``metrics.json``
states) exceeds the budget (by more than :data:`BUDGET_TOLERANCE`), the spacing widens and the
part is planned again: the uniform planner's by that excess, the raster's to the least spacing
with as few planes as that excess asks (:func:`fewest_planes_spacing`), the one nearest the
least-ripple spacing.  A re-plan that would ask for the very spacing or overlap just planned (the
uniform planner's overlap held at none, or the least-ripple overlap equal to the first plan's) is
not made: it would lay the same passes.  Nor is the uniform planner's re-plan at a least-ripple
overlap that would move the first plan's passes by less than a working-mesh edge
(:data:`KEEP_WITHIN_EDGES`): the first plan is kept.

The uniform planner's re-plan at the least-ripple overlap goes straight to the overlap the budget
would widen it to when the first plan's contact length already says it will be over
(:func:`uniform_replan_overlap`) and its candidate directions came to about the same length
(:data:`DIRECTION_LENGTH_SPREAD`), or the re-plan keeps the first plan's direction: that saves
one whole plan.  The raster measures a spacing it is given on the surface across the passes
(``spacing_on = "surface"``, :mod:`swath.plan.surface_planes`), as the ripple model means it; where
the swath narrows over a good share of the part (:func:`narrow_share`, :data:`NARROW_SHARE`) the
re-plans keep the ripple model's ratio of spacing to width at every step instead
(``spacing_on = "swath"``).
"""

from __future__ import annotations

import logging
import math

import numpy as np

log = logging.getLogger(__name__)

#: Curvatures whose sagitta over the pad, ``R² |κ| / 2``, stays under this (m) leave the plane's
#: spacing: below a tenth of the default pad's 1 mm compression the profile is the plane's.
FLAT_SAGITTA = 1e-4

#: The contact length may exceed the budget by this fraction before the spacing widens: a raster
#: keeps its spacing and leaves the rest to the margins, so its length steps by whole passes (the
#: plate's eight passes at the plane's spacing come to 1.52 L*, seven to 1.33 L*).
BUDGET_TOLERANCE = 0.02

#: The leads (degrees) the default job may choose on a curved part besides the half-pad lead: in a
#: 0.35 m bowl the quadric picks 11° (simulated interior CoV 0.063 against 0.089 at the half-pad
#: lead), on the convex ``bezier_dac_cad`` the flat pad (0.113 against 0.261).
LEAD_CHOICES_DEG = (0.0, 11.0, 15.0)

#: The raster's least-ripple planes follow the local swath width (``spacing_on = "swath"``, unless
#: the job's planner options say where to measure the spacing) when the swath along the levels is
#: narrower than :data:`NARROW_WIDTH` of its median over at least this share of the part's extent
#: across the passes (:func:`narrow_share`); else they lie equally far apart on the surface.  Two
#: tangent arcs of 0.15 m and 0.6 m radius (48 and 76 mm swaths, a third of the extent narrow):
#: interior CoV 0.240 against 0.461 at 1.48 L*.  ``example:hub`` (narrow in one band at its rim,
#: 3 % of the extent): 0.483 at 1.45 L* against 0.452 at 1.53 L*, so it keeps the surface planes.
#: On the panel, ``bezier_dac_cad`` and crs_part_5 the pad touches with its whole face at every
#: sample and both placements give the same planes.
NARROW_SHARE = 0.2

#: A level's swath counts as narrow below this fraction of the part's median width.
NARROW_WIDTH = 0.85

#: Re-plans allowed to bring the contact length within the budget.
BUDGET_ROUNDS = 2

#: The spacing widens by the excess over the budget times this (a little more: the plan's
#: length does not fall quite in proportion, pass ends and fill passes staying).
BUDGET_MARGIN = 1.02


#: The uniform re-plan goes straight to the budget's overlap only when the first plan's candidate
#: directions (those covering enough to be chosen) came to contact lengths within this fraction of
#: each other (:func:`direction_length_spread`): the re-plan chooses its direction afresh, and the
#: prediction holds only if the length does not hinge on which one wins.  snp_part_scan's six lie
#: within 3.2 %, crs_part_5's within 4.8 %; the blade's spread 23 % (6.36 m at 120 degrees, 7.81 m
#: at 0 degrees), and there the re-plan sent straight to overlap 0.267 (1.59 L* predicted) turned to
#: 30 degrees at 1.72 L*; after two budget rounds the interior CoV was 0.542 against 0.373.
DIRECTION_LENGTH_SPREAD = 0.05

#: The uniform planner's first plan is kept, not made again, when the re-plan's passes would lie
#: within this many working-mesh edges of its passes (:func:`replan_shift`): a shift the working
#: mesh on which the passes are laid hardly resolves.  On snp_part_scan the re-plan at overlap
#: 0.302 after the first plan's 0.301 shifts its last (11th) generation by 0.5 mm, under the 3.2 mm
#: edge: the first plan is kept (interior CoV 0.281, cycle time 136.3 s, against 0.294 and 138.2 s
#: re-planned).  crs_part_5's least-ripple overlap 0.289 after 0.301 shifts its 48th generation by
#: about 45 mm, the blade's 0.322 its 13th by about 20 mm: both are planned (crs_part_5 kept at
#: 0.301 chose 0 instead of 30 degrees, and its interior CoV went 0.211 -> 0.287).
KEEP_WITHIN_EDGES = 1.0


def replan_shift(metadata: dict, probed: float, wanted: float, width: float) -> float:
    """How far (m) the passes of a uniform re-plan at overlap ``wanted`` would move from those of
    the first plan at ``probed`` (its ``metadata``) by its last generation: each generation steps
    ``(1 - overlap)`` swath widths ``width`` (m) from the one before, so the last of ``n``
    generations moves ``n |wanted - probed| width`` (the largest ``n`` over a multi-piece part's
    pieces)."""
    generations = max(int(m.get("n_generations", 0)) for m in metadata.get("pieces") or [metadata])
    return generations * abs(wanted - probed) * width


def direction_length_spread(metadata: dict) -> float:
    """How far apart the contact lengths of a uniform plan's candidate directions lie: the longest
    over the shortest, less 1, among those whose predicted coverage would let them be chosen
    (:func:`swath.plan.uniform.coverage_floor`), the largest over the pieces of a multi-piece part.
    0 for a plan with one direction (given, not chosen)."""
    from ..plan.uniform import coverage_floor

    spread = 0.0
    for meta in metadata.get("pieces") or [metadata]:
        rows = meta.get("candidates") or []
        if not rows:
            continue
        floor = coverage_floor(max(r["predicted_coverage_fraction"] for r in rows))
        lengths = [r["length_m"] for r in rows if r["predicted_coverage_fraction"] >= floor]
        spread = max(spread, max(lengths) / min(lengths) - 1.0)
    return spread


def uniform_replan_overlap(ratio: float, probed: float, wanted: float, budget: float) -> tuple[float, float]:
    """The overlap (fraction) the uniform planner's re-plan at the least-ripple overlap ``wanted``
    is made at, and the contact length over the coverage bound it is predicted to have.

    The first plan, at overlap ``probed``, came to ``ratio`` times the coverage bound.  Its passes
    lie ``(1 - overlap)`` local widths apart, so the contact length at ``wanted`` is predicted as
    ``ratio (1 - probed) / (1 - wanted)``.  When that exceeds the budget by more than
    :data:`BUDGET_TOLERANCE`, the re-plan is made at once at the overlap a budget round would widen
    to from that length, ``1 - (1 - wanted) (predicted / budget) BUDGET_MARGIN`` (never below
    none), instead of planning ``wanted`` only to find it too long.  Otherwise ``wanted``.  The
    budget rounds still check the plan made.  (On snp_part_scan the first plan's 4.54 m at
    overlap 0.301 predicted 4.76 m at 0.333, where the plan came to 4.80 m.)

    Parameters
    ----------
    ratio : float
        The first plan's contact length over the coverage bound (NaN: no prediction).
    probed, wanted : float
        The first plan's overlap and the least-ripple overlap, fractions in [0, 1).
    budget : float
        The length budget, times the coverage bound.

    Returns
    -------
    overlap : float
    predicted : float
        The predicted length ratio at ``wanted``.
    """
    predicted = ratio * (1.0 - probed) / (1.0 - wanted)
    if not predicted > budget * (1.0 + BUDGET_TOLERANCE):
        return wanted, predicted
    return max(1.0 - (1.0 - wanted) * predicted / budget * BUDGET_MARGIN, 0.0), predicted


def fewest_planes_spacing(spacing: float, widened: float, extents) -> float:
    """The raster spacing (m) to re-plan at when ``spacing`` made the plan too long: the least
    spacing that cuts each piece with as few planes as ``widened`` does (``ceil(S_k / d)`` planes
    across a piece of extent ``S_k``), nearest the least-ripple ``spacing``; when ``widened`` drops
    no plane, the least spacing that drops one.  ``extents``: the plan's ``plane_extent_m`` (m, per
    piece); without it, ``widened``.

    On the panel the quadric's 49.5 mm gave nine passes across its 403 mm (1.70 L*, budget 1.5):
    15.8 % wider is 57.3 mm and eight passes, which 50.4 mm already gives (1.51 L*, interior CoV
    0.050 at constant feed against 0.080 at 53 mm and 11°).
    """
    if not extents:
        return widened
    s = np.asarray(extents, float)
    now = np.ceil(s / spacing)
    counts = np.maximum(np.ceil(s / widened), 1.0)
    if not (counts < now).any():
        many = now > 1
        if not many.any():
            return widened
        return float(np.min(s[many] / (now[many] - 1.0))) * (1.0 + 1e-6)
    return float(max(np.max(s / counts) * (1.0 + 1e-6), spacing))


def narrow_share(surface, tool, cross, spacing: float) -> float:
    """The share of the part's extent across the passes (planes normal to ``cross``, (3,)) whose
    swath, the median along each level (:func:`swath.plan.surface_planes.level_widths`, over half
    ``spacing`` (m) either side), is narrower than :data:`NARROW_WIDTH` of the median over the part:
    levels a quarter of ``spacing`` apart, each piece's counted."""
    from ..plan.raster import swath_widths_across
    from ..plan.surface_planes import level_widths

    pieces = surface.face_pieces()
    widths = swath_widths_across(surface, tool, np.asarray(cross, float), pieces)
    heights = surface.vertices @ np.asarray(cross, float)
    narrow = total = 0
    for k, faces in enumerate(pieces):
        mine = widths.piece == k
        if not mine.any():
            continue
        h = heights[np.unique(surface.faces[faces])]
        grid = np.linspace(h.min(), h.max(), max(2, int(math.ceil(4 * np.ptp(h) / spacing)) + 1))
        w = level_widths(widths.heights[mine], widths.widths[mine], widths.areas[mine], grid, 0.5 * spacing)
        narrow += int(np.sum(w < NARROW_WIDTH * widths.reference))
        total += len(grid)
    return narrow / total if total else 0.0


def curved_choice(toolpath, surface, tool, leads, budget: float):
    """The lead (one of ``leads``) and the least-ripple spacing on the representative quadric of
    ``toolpath``'s passes, judged by the ripple within ±5 % of the spacing (``robust_cov``), or
    None when the part is flat there (sagitta under :data:`FLAT_SAGITTA`).

    Parameters
    ----------
    toolpath : ToolPath
        A first plan of the part (its passes give the curvatures).
    surface : Surface
    tool : Tool
    leads : sequence of float
        The lead angles to choose from, rad.
    budget : float
        The length budget, times the coverage bound.

    Returns
    -------
    tuple (float, CurvedSpacing) or None
    """
    from ..feed.curved_ripple import curved_ripple_spacing, pass_curvatures, pass_twist

    k_feed, k_cross = pass_curvatures(toolpath, surface)
    k_twist = pass_twist(toolpath, surface)           # passes oblique to the principal directions
    sagitta = 0.5 * tool.pad_radius ** 2 * max(abs(k_feed), abs(k_cross))
    if not sagitta > FLAT_SAGITTA:
        log.info("curvature %.3g, %.3g 1/m: flat over the pad, the plane's spacing stays", k_feed, k_cross)
        return None
    options = [(curved_ripple_spacing(tool, k_feed, k_cross, lead_angle=a, max_length_ratio=budget,
                                      k_twist=k_twist), a) for a in leads]
    choice, lead = min(options, key=lambda o: o[0].robust_cov)
    log.info("curvature %.3g 1/m along, %.3g across the passes: lead %.1f deg, spacing %.1f mm (%.3f of the "
             "%.1f mm swath), cross-profile ripple %.3f (%.3f within 5 %%)", k_feed, k_cross, math.degrees(lead),
             choice.spacing * 1e3, choice.spacing / choice.width, choice.width * 1e3, choice.cov, choice.robust_cov)
    return lead, choice


def uniform_replan_value(toolpath, probed: float, choice, bound: float, budget: float) -> float:
    """The overlap the uniform planner's re-plan is made at, after its first plan ``toolpath`` at
    overlap ``probed`` and the least-ripple ``choice`` (a :class:`swath.feed.curved_ripple.CurvedSpacing`):
    the budget's overlap at once where the first plan predicts the chosen one over ``budget`` and its
    directions agree in length (:func:`uniform_replan_overlap`, :data:`DIRECTION_LENGTH_SPREAD`),
    else the chosen one; ``probed`` itself (no re-plan) where that would move the first plan's
    passes by less than :data:`KEEP_WITHIN_EDGES` working-mesh edges (:func:`replan_shift`).
    ``bound``: the coverage bound, m."""
    first = toolpath.contact_length / bound if bound > 0 else float("nan")
    value, predicted = uniform_replan_overlap(first, probed, choice.overlap, budget)
    spread = direction_length_spread(toolpath.metadata)
    if value != choice.overlap and not spread <= DIRECTION_LENGTH_SPREAD:
        log.info("ripple overlap %.3f predicted at %.2f L*, over the %.2f budget, but the first plan's directions "
                 "spread %.0f %% in length: planned as chosen", choice.overlap, predicted, budget, 100 * spread)
        value = choice.overlap
    if value != choice.overlap:
        log.info("ripple overlap %.3f predicted at %.2f L* (the first plan's %.2f L* at overlap %.3f), over the "
                 "%.2f budget: re-planned at once at overlap %.3f", choice.overlap, predicted, first, probed,
                 budget, value)
    shift = replan_shift(toolpath.metadata, probed, value, choice.width)
    edge = float(toolpath.metadata.get("work_spacing_m", 0.0))
    if value != probed and shift <= KEEP_WITHIN_EDGES * edge:
        log.info("ripple overlap %.3f would move the first plan's passes (overlap %.3f) by %.1f mm, within the "
                 "%.1f mm working-mesh edge: they are kept", value, probed, 1e3 * shift, 1e3 * edge)
        value = probed
    return value


def search_progress(progress, plan: int, most: int, expected_s: float | None = None):
    """The uniform planner's ``progress(stage, done, total)`` for its ``plan``-th plan (from 1) of a
    search that makes at most ``most``: each plan a step of its own, numbered (``"(plan 2, at most
    4)"``), whose percentage and time left are this plan's.  How many plans follow is not known
    while one is made (the re-plan at the least-ripple overlap and the length budget's re-plans
    depend on it); counted as if all four were made, crs_part_5's re-plan said "about 7 min left"
    12 s before it ended.  The working mesh's set-up (:data:`swath.plan.uniform_model.SETUP_STAGE`,
    with its vertex count and time) is said as it comes, by the first plan: the others reuse it.

    A plan of one given direction is one step (:data:`swath.plan.uniform.LAYING_STAGE`) with no
    percentage between its start and its end: ``expected_s``, the time the plan before took to lay
    that direction's passes (s), is said with it as its estimate.  crs_part_5's re-plan in the
    direction that removed the most evenly took 6-8 s, its first plan's 6.8 s."""
    from ..plan.uniform import LAYING_STAGE
    from ..plan.uniform_model import SETUP_STAGE

    label = f" (plan {plan}, at most {most})"
    if expected_s is not None and math.isfinite(expected_s) and expected_s >= 0.5:
        laying = f"{LAYING_STAGE}{label}, about {expected_s:.0f} s as the plan before"
    else:
        laying = LAYING_STAGE + label

    def told(stage: str, done: int, total: int) -> None:
        if stage == LAYING_STAGE:
            progress(laying, done, total)
        elif not stage.startswith(SETUP_STAGE):
            progress(stage + label, done, total)
        elif plan == 1:
            progress(stage, done, total)

    return told


def curved_spacing_plan(surface, tool, planner, settings, arguments: dict, *, choose_lead: bool = False,
                        ridge: bool = False, progress=None):
    """The job's passes at the least-ripple spacing on the part's curvature, within
    ``settings.length_budget`` times the coverage bound (module notes).

    Parameters
    ----------
    surface : Surface
    tool : Tool
    planner : callable
        The raster or the uniform planner.
    settings : JobSettings
        ``planner``, ``length_budget`` and the lead (``settings.lead()``) are read.
    arguments : dict
        The planner's other keyword arguments.
    choose_lead : bool
        On a curved part, also choose the lead among the job's and :data:`LEAD_CHOICES_DEG` (the
        default job, which chose the lead itself): the job then times the passes at
        ``metadata["ripple_lead_rad"]``.
    ridge : bool
        A raster whose direction is left free may turn to the uniform planner where the angular
        speed limit holds its feed round a sharp ridge and the uniform plan removes more evenly
        (:func:`swath.cli.ridge_turn.uniform_if_evener`; the plan's ``metadata["ridge_planner"]``
        then says so).
    progress : callable, optional
        ``progress(stage, done, total)``: hears the uniform planner's steps when a raster turns to
        it round a ridge (the uniform planner's own re-plans hear ``arguments["progress"]``).

    Returns
    -------
    ToolPath
        Its ``metadata`` gains ``ripple_spacing_m`` (the spacing asked, raster), or
        ``ripple_overlap_fraction`` (uniform), ``ripple_model`` (``"plane"`` or ``"curved"``),
        ``ripple_lead_rad`` (the lead the spacing is for) and ``ripple_length_ratio`` (its contact
        length over the coverage bound).
    """
    from ..contact.widths import coverage_lower_bound
    from ..feed import ripple_overlap, ripple_spacing

    lead, budget = settings.lead(), settings.length_budget
    uniform = settings.planner == "uniform"
    # the uniform planner's overlap, or the raster's spacing (m)
    value = (ripple_overlap(tool, lead_angle=lead, max_length_ratio=budget) if uniform
             else ripple_spacing(tool, lead_angle=lead, max_length_ratio=budget)[0])

    most = 2 + BUDGET_ROUNDS                  # the first plan, the re-plan, the budget's re-plans
    plans_made = [0]

    last_layout_s = [None]          # the plan before's time for its (given) direction's passes, s

    def plan(value: float, **extra):
        plans_made[0] += 1
        if uniform:
            told = arguments.get("progress")
            expected = last_layout_s[0] if arguments.get("direction") is not None else None
            numbered = {} if told is None else {"progress": search_progress(told, plans_made[0], most, expected)}
            made = planner(surface, tool, **{**arguments, "overlap": value, **numbered, **extra})
            last_layout_s[0] = made.metadata.get("plan_time_s")
            return made
        # swath's spacing, not the user's: fill passes still close what it leaves (raster's default);
        # the planes follow the local swath width unless the job says where to measure the spacing
        return planner(surface, tool, **{"fill_gaps": True, **arguments, "spacing": value})

    # the default job compares the uniform plan's candidate directions by their removal
    compare = uniform and choose_lead and arguments.get("direction") is None
    candidate_paths: dict = {}
    toolpath = plan(value, **({"candidate_paths": candidate_paths} if compare else {}))
    held = None
    if ridge and not uniform and arguments.get("direction") is None and arguments.get("cross_direction") is None:
        from .ridge_turn import held_share

        held = held_share(toolpath, settings.feed, settings.max_angular)   # the raster's feed round a ridge
    if not uniform and arguments.get("spacing_on") is None:
        share = narrow_share(surface, tool, toolpath.metadata["cross_direction"], value)
        follow = share >= NARROW_SHARE
        log.info("the swath is narrower than %.2f of its median over %.0f %% of the extent across the passes: "
                 "the planes %s", NARROW_WIDTH, 100 * share,
                 "follow the local swath width" if follow else "lie equally far apart on the surface")
        if follow:
            arguments = {**arguments, "spacing_on": "swath"}
    if not uniform and arguments.get("direction") is None and arguments.get("cross_direction") is None:
        # the curvature is read along these passes: the re-plans keep their direction (left free, the
        # raster may turn to where the spacing was not chosen for: the panel's passes turned across its
        # 0.35 m radius, interior CoV 0.238 at 1.37 L* against 0.050 along it at 1.51 L*)
        arguments = {**arguments, "direction": float(toolpath.metadata["angle_rad"])}
    carried: dict = {}
    if compare:
        # the direction of the most even removal, kept by the re-plans
        from .uniform_direction import CARRIED, evenest_direction

        toolpath, angle = evenest_direction(toolpath, candidate_paths, surface, tool, settings,
                                            progress=arguments.get("progress"))
        if angle is not None:
            arguments = {**arguments, "direction": angle}
            last_layout_s[0] = toolpath.metadata.get("plan_time_s")   # the candidate's, laid in a worker
            carried = {k: toolpath.metadata[k] for k in CARRIED}
    model = "plane"
    leads = [lead] + ([math.radians(a) for a in LEAD_CHOICES_DEG if math.radians(a) != lead] if choose_lead else [])
    chosen = curved_choice(toolpath, surface, tool, leads, budget)
    bound = coverage_lower_bound(surface, tool)
    if chosen is not None:
        model = "curved"
        lead, choice = chosen
        if uniform:
            probed, value = value, uniform_replan_value(toolpath, value, choice, bound, budget)
        else:
            value = choice.spacing
        if not (uniform and value == probed):        # the uniform planner at the same overlap: the same plan
            toolpath = plan(value)
    ratio = toolpath.contact_length / bound if bound > 0 else float("nan")
    for _ in range(BUDGET_ROUNDS):
        if not ratio > budget * (1.0 + BUDGET_TOLERANCE):
            break
        widen = ratio / budget * BUDGET_MARGIN
        wider = (max(1.0 - (1.0 - value) * widen, 0.0) if uniform else   # the overlap no lower than none
                 fewest_planes_spacing(value, value * widen, toolpath.metadata.get("plane_extent_m")))
        if wider == value:
            log.info("ripple spacing: %.2f L* over the %.2f budget, and it cannot widen further", ratio, budget)
            break                                  # the same value plans the same passes
        log.info("ripple spacing: %.2f L* over the %.2f budget, %.1f %% wider", ratio, budget, 100 * (widen - 1))
        value = wider
        toolpath = plan(value)
        ratio = toolpath.contact_length / bound
    meta = {"ripple_model": model, "ripple_lead_rad": float(lead), "ripple_length_ratio": float(ratio),
            ("ripple_overlap_fraction" if uniform else "ripple_spacing_m"): float(value), **carried}
    toolpath.metadata.update(meta)
    if held is not None:
        from .ridge_turn import uniform_if_evener

        return uniform_if_evener(toolpath, surface, tool, settings, held, choose_lead=choose_lead, progress=progress)
    return toolpath
