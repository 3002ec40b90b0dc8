"""Short codes for every warning swath can print, with what each means and what to do.

A warning's text ends with its code in brackets, ``... [W-COVERAGE-LOW]``: in the log, in
``metrics.json`` (``warnings``) and in the report, which also shows the entry's advice.  The docs
page *Reference → Warnings* is generated from :data:`CODES`, so every code has a docs entry
(anchor ``#w-coverage-low``), and a test checks that every warning the library can emit resolves
to a code.

A warning gets its code either explicitly (its text holds ``[W-SOME-CODE]``) or from the entry's
``match`` regular expression, searched in the message (both the logging template, e.g.
``"removal sampled at %.2f mm"``, and the formatted text must match).  Adding a warning means
adding one :func:`entry` to :data:`CODES`::

    entry("W-SOME-CODE", r"text the warning holds", "What it means.", "What to do.", "stage"),
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass

#: A code: ``W-`` and upper-case words joined by dashes.
CODE_RE = re.compile(r"\[(W-[A-Z0-9]+(?:-[A-Z0-9]+)*)\]")


@dataclass(frozen=True)
class WarningCode:
    """One warning code.

    code : ``W-...``, upper case.
    match : regular expression searched in the warning's text (``""``: the code is only given
        explicitly, ``[W-...]`` in the text).
    meaning : what the warning says about the plan or input (a sentence or two, Markdown).
    action : what to do about it (Markdown).
    stage : the pipeline stage that emits it (a heading of the docs page).
    """

    code: str
    match: str
    meaning: str
    action: str
    stage: str = "plan"

    @property
    def anchor(self) -> str:
        """The docs page anchor, e.g. ``w-coverage-low``."""
        return self.code.lower()


def entry(code: str, match: str, meaning: str, action: str, stage: str = "plan") -> tuple[str, WarningCode]:
    """A :data:`CODES` item: ``(code, WarningCode(...))``."""
    return code, WarningCode(code, match, meaning, action, stage)


#: Every warning code -> its entry.  Add one line per new warning (see the module docstring).
CODES: dict[str, WarningCode] = dict([
    # --- input: reading parts and scans -------------------------------------------------------
    entry("W-UNITS-SUSPECT", r"the file may not be in",
          "The part's size, read in the given unit, is possible but unusual: it may be in another unit.",
          "Check the size in the message; pass `--units` with the file's real unit.", "input"),
    entry("W-UNITS-FORCED", r"accepted because units were forced",
          "The part's size is outside 5 mm .. 20 m in the given unit, but `--force-units` accepts it.",
          "Make sure the unit is right: every length of the plan scales with it.", "input"),
    entry("W-MESH-NONMANIFOLD", r"edges are shared by more than two faces",
          "Some edges join more than two faces (sheets branching off the surface); swath kept the two faces "
          "that continue the surface and dropped the branches.",
          "Check the dropped area in the message; repair the mesh (e.g. MeshLab *Repair non manifold edges*) "
          "if it matters.", "input"),
    entry("W-MESH-NONORIENTABLE", r"non-orientable piece",
          "Small pieces of the mesh cannot be wound consistently (like a Möbius strip) and were dropped.",
          "Repair the mesh (e.g. MeshLab *Re-orient all faces coherently*) if those pieces are to be finished.",
          "input"),
    entry("W-MESH-COARSE", r"the mesh's facets kink by",
          "The mesh is a coarse tessellation for this pad: neighbouring flat facets kink so much that, over the "
          "pad, they stand off a smooth surface by a fair share of the pad's depression. The contact model "
          "presses the facets as given, so the pressure collects on their edges and the removal streaks along "
          "them whatever the passes, spacing or feed.",
          "Export the CAD finer, with the chord tolerance and angle in the message or less, or give the STEP "
          "file (`--chordal-tol` sets swath's own tessellation).", "input"),
    entry("W-MESH-PIECES", r"pieces: kept the largest|closed solid facing .* form .* pieces",
          "The mesh has several separate pieces; only the largest is planned.",
          "Pass `--all-pieces` to plan every piece, or split the file.", "input"),
    entry("W-SCAN-NAN", r"dropped .* NaN points",
          "The point cloud holds NaN points (no-return pixels of an organised scan); they were dropped.",
          "Nothing, unless many points are missing: then rescan.", "input"),
    entry("W-SCAN-NORMALS", r"normals are zero or not finite",
          "Some normals stored in the scan file are unusable, so all the file's normals are ignored.",
          "Nothing: swath estimates normals itself. Pass `--side` if the tool side is ambiguous.", "input"),
    # --- scan fits and registration ---------------------------------------------------------------
    entry("W-FIT-STRAY", r"dropping .* stray points",
          "A few points lie apart from the scanned surface (specks, fixtures) and are left out of the fit.",
          "Nothing, if they are noise; otherwise crop the scan to the part.", "fit"),
    entry("W-FIT-RESIDUAL", r"points .* lie more than .* from the fitted patch",
          "The smooth B-spline patch does not follow the scan everywhere (stray points, a fold, a sharp "
          "feature).",
          "Look at the residual map in `fit.html`; clean the scan or fit the region on its own.", "fit"),
    entry("W-REGISTER-NOT-CONVERGED", r"ICP did not converge",
          "The registration stopped before the pose settled.",
          "Start from a closer initial pose, use the coarse stage, lower `--trim` for partial overlap or allow "
          "more iterations (`--max-iterations`).", "fit"),
    entry("W-REGISTER-ILL-POSED", r"pose is poorly determined",
          "The surface can nearly slide on itself (a plane, a cylinder): the pose is uncertain along that motion.",
          "Use `--table` (the perimeter fixes the slide) or check the pose against features.", "fit"),
    entry("W-REGISTER-FEW-INLIERS", r"of the CAD points lie within",
          "Fewer than 80 % of the CAD points lie near the scan after registration: the scan covers only part of "
          "the CAD, or the two differ in shape.",
          "Check `residuals.csv`; scan the whole part, or trust the pose only where the residuals are small.", "fit"),
    entry("W-REGISTER-RMS", r"inlier rms .* of the part's size",
          "The registered CAD and scan differ by more than 0.2 % of the part's size: the pose is a compromise "
          "between two different shapes.",
          "Check the residuals; when `--table` and the rigid mode disagree, trust the table answer.", "fit"),
    entry("W-REGISTER-AMBIGUOUS", r"another pose .* fits (almost as well|within)",
          "A second, different pose fits the scan almost as well: the part may be symmetric.",
          "Check the pose in `register.html`; constrain it (`--table`) or give a closer initial pose.", "fit"),
    entry("W-REWORK-UNMEASURED", r"the scan measured only",
          "The rework scan covers less than half of the CAD: the unmeasured rest is taken as nominal.",
          "Check the placement (`--placement`, `--scan-units`) or scan the whole area to finish.", "fit"),
    entry("W-PROCESS-RANGE", r"planning it as asked \(--allow-unusual-process\)",
          "A feed, force, pad radius or spindle speed lies outside what a sanding robot does; with "
          "`--allow-unusual-process` it is planned as asked.",
          "Check the value and its unit; the ranges are in `swath plan --help`.", "input"),
    entry("W-STEP-FACE-SKIPPED", r"could not be tessellated",
          "Open CASCADE could not mesh one face of the CAD file; that face is left out of the part.",
          "Check the face in a CAD tool (a sliver or a broken trim), or lower `--chordal-tol`.", "input"),
    entry("W-SETUPS-COVERAGE", r"the setups together cover",
          "The setups chosen for a closed part (`--side all`) together leave part of its outer surface untouched.",
          "Lower the spacing (or raise the overlap) so each setup reaches its edges, or add a setup.", "plan"),
    entry("W-KEEP-OUT-TOUCHED", r"the pad removes material on the keep-outs",
          "The simulated removal reaches into a keep-out area.",
          "Raise `--keep-out-margin` (the clearance beyond the pad radius), or plan a smaller area.", "simulate"),
    # --- planning and ordering ------------------------------------------------------------------
    entry("W-SPACING-GAP", r"the given spacing .* leaves .* untouched",
          "The spacing you gave is kept (no fill passes are added), and it leaves this share of the part "
          "untouched by the pressed pad.",
          "Lower `--spacing`, leave it out for the full-coverage default, or add fill passes (`fill_gaps = true` "
          "under `[planner_options]`).", "plan"),
    entry("W-RASTER-GAP", r"predicted to stay untouched",
          "The raster's planes and fill passes still leave part of the surface untouched.",
          "Lower `--spacing`, choose another `--direction`, or plan in regions (`--segment auto`).", "plan"),
    entry("W-PIECE-UNPLANNED", r"have no seed and get no passes",
          "The equidistant planner found no seed curve on some pieces of the part; they get no passes.",
          "Plan with `--planner raster` or `uniform`, or plan those pieces on their own.", "plan"),
    entry("W-PATCH-SPLIT", r"the boundary cuts the patch into several regions",
          "The trimmed patch falls apart into several regions in its parameter domain; only the largest is "
          "planned.",
          "Plan on the patch's mesh (`--surface-spacing`) with another planner, or fit each region.", "plan"),
    entry("W-AIR-NEAR-PART", r"closer than half the clearance",
          "Some air moves pass closer to the part than half the clearance: a pass ends in a fold or under an "
          "overhang the tool cannot lift clear of.",
          "Check those moves in the cell (the log gives their ends), or plan another `--direction`.", "plan"),
    # --- trajectory ---------------------------------------------------------------------------------
    entry("W-TOPPRA-MISSING", r"toppra is not installed",
          "Air moves are timed with a trapezoidal profile instead of time-optimally.",
          "`pip install toppra` (a dependency of swath).", "trajectory"),
    entry("W-LINK-TRAPEZOID", r"toppra failed on a link|toppra found no parameterisation|"
                              r"links were timed with the trapezoidal fallback",
          "Some air moves could not be timed by toppra and use a trapezoidal speed profile, which is slower "
          "but within the limits.",
          "Nothing: the cycle time is slightly pessimistic.", "trajectory"),
    entry("W-SLOW-CONTACT", r"hold the tool below half the feed",
          "The speed limits (angular speed, centripetal or tangential acceleration) slow the tool far below "
          "the feed for a share of the contact time; it dwells there and removes more.",
          "Relax the limits (`--max-angular`, `--max-centripetal`, `--max-accel`) or choose another direction.",
          "trajectory"),
    entry("W-AIR-OUTSIDE", r"air moves go .* outside the part's bounding box",
          "Air moves leave the part's bounding box by more than the pad radius plus the clearance.",
          "Check that the cell has room there.", "trajectory"),
    # --- feed optimisation ----------------------------------------------------------------------------
    entry("W-FEED-OVER-TARGET", r"feed optimisation: .* over the",
          "After the feed was optimised and checked in the removal simulation, some points still get more "
          "than the target depth plus the tolerance, even at the fastest feed the limits allow.",
          "Raise the target or the tolerance, or the feed limit; plan the passes farther apart.", "feed"),
    entry("W-TARGET-SHORT", r"the optimised feed removes",
          "The optimised feed removes clearly less than the target depth on average: the tolerance where the "
          "removal is highest (the feed may not slow there) or the slowest allowed feed holds it back; the "
          "message says which, with the slowest feed the plan uses or the shares of the feed nodes held at "
          "their fastest by the tolerance and at the slowest feed.",
          "Lower the target or raise the tolerance, raise the force, plan the passes closer, or run the job "
          "more than once.", "feed"),
    entry("W-TARGET-COV-MISSED", r"--target-cov: the chosen plan reached",
          "The plan --target-cov chose reached the asked interior removal CoV in the search, but the job's final "
          "trajectory (re-timed by the robot stage, or run under force control) removes less evenly.",
          "Ask for a somewhat lower CoV so that the search keeps a margin, or relax the joint limits that re-time the "
          "path.", "feed"),
    entry("W-EVEN-RIDGE", r"even removal: the angular speed limit .* holds the raster's feed",
          "The default job's raster passes turn round a sharp ridge (a blade's leading edge), where the tool's "
          "angular speed limit holds the feed far below the job's, and the pad dwells there and removes more. The "
          "job tried the uniform planner, whose passes run along the ridge, and says which plan it writes.",
          "Raise `--max-angular` to the figure given if the robot can turn the tool that fast, or accept the "
          "ridge's band (docs: Sharp ridges).", "feed"),
    entry("W-EVEN-PLAIN-KEPT", r"even removal: the plain plan .* removes more evenly",
          "The default job compared its even-removal plan (least-ripple spacing, lead, optimised feed) with the "
          "plain plan (covering spacing, flat pad, constant feed) in the removal simulation, and the plain one "
          "removes more evenly on this part: it is written. The least-ripple spacing is worked out on the part's "
          "representative curvature and can be too wide where the curvature differs or waviness narrows the swath.",
          "Nothing to do for this run; `--constant-feed` skips the comparison, `--spacing` or `--planner uniform` "
          "spaces the passes yourself.", "feed"),
    entry("W-EVEN-FEED-WORSE", r"even removal: the (optimised feed removes less evenly|feed could not be optimised)",
          "The default job optimised the feed, but the simulation finds the same passes at constant feed remove "
          "more evenly on the interior (the part's curvature, not the feed, sets the evenness), or the feed "
          "programme found no feed for the default target; the constant-feed trajectory is written.",
          "Nothing to do for this run; a softer pad (`softer_pad_interior_removal_cov`, `W-PAD-TOO-STIFF`) or a smaller one follows the "
          "curvature better. `--constant-feed` skips the feed optimisation.", "feed"),
    entry("W-EVEN-FEED-SKIPPED", r"even removal: the feed is not optimised",
          "Under 11.5 % of the interior removal variance of the passes at constant feed lies between and along the "
          "passes, where a feed along them reaches; the rest is the ripple across them. The default job writes the "
          "constant feed without running the feed programme (it evened nothing on such parts).",
          "Nothing to do for this run; `--target-depth` runs the feed programme all the same. A softer pad or "
          "a closer spacing lowers the ripple across the passes.", "feed"),
    entry("W-TARGET-COV-CANDIDATE", r"--target-cov: candidate .* cannot be planned",
          "One of the candidate plans --target-cov tries could not be planned on this part (for instance no "
          "direction lets the uniform planner lay passes at that overlap); the search goes on without it.",
          "Nothing, if another candidate reaches the target; otherwise try the other planner (--planner raster or "
          "uniform).", "feed"),
    # --- robot ---------------------------------------------------------------------------------------------
    entry("W-ROBOT-UNREACHABLE", r"poses are unreachable for|The programs leave these samples out",
          "Some poses of the trajectory are out of the robot's reach or joint limits, or near a singularity; "
          "the programs leave those samples out, so the robot would move straight across them.",
          "Move the part (`--base`, or `--place` to search a placement) or choose a larger robot.", "robot"),
    entry("W-ROBOT-GAPS", r"The passes are split there with a retract and an approach",
          "Some poses are out of the robot's reach: the passes are split there with a retract, a joint move and an "
          "approach, and the stretches between are not sanded (coverage and removal are computed on what the "
          "robot runs).",
          "Move the part (`--base`, or `--place` to search a placement), choose a larger robot, or split the part "
          "into setups.", "robot"),
    entry("W-ROBOT-SINGULAR", r"comes close to a singularity",
          "The arm's manipulability falls below 0.01 somewhere along the job: small path errors become large joint "
          "speeds there.",
          "Move the part (`--base`, or `--place`) or turn the tool about its axis.", "robot"),
    entry("W-ROBOT-WRIST", r"wrist comes near its singularity",
          "The wrist (joints 4 and 6 nearly aligned) comes within 10 deg of its singularity: joints 4 and 6 may spin "
          "fast.",
          "Move the part or turn the tool about its axis.", "robot"),
    entry("W-ROBOT-JOINT-LIMIT", r"comes within .* deg of its limit",
          "A joint comes within 5 deg of its limit: a small path or calibration error may stop the controller.",
          "Move the part (`--base`, or `--place`) or turn the tool about its axis.", "robot"),
    entry("W-ROBOT-POSITION-ONLY", r"are position only \(--force-program position\)",
          "The vendor programs hold the pad face on the nominal surface and rely on a compliant tool to press "
          "with the planned force.",
          "Use an active contact flange or a spring-mounted tool, or write force-controlled programs "
          "(`--force-program native`).", "robot"),
    entry("W-ROBOT-FLANGE-TCP", r"the TCP is the flange face",
          "No tool was given, so the programs put the flange, not a pad, on the part.",
          "Give the pad face's pose in the flange frame (`--tcp x,y,z,rx,ry,rz`) or a cell file's `[tool]`.",
          "robot"),
    entry("W-ROBOT-FLIP", r"changes configuration .* inside a contact pass",
          "The arm changes configuration (shoulder, elbow or wrist branch) with the pad on the part.",
          "Move the part (`--base`, or `--place`) or choose another robot.", "robot"),
    entry("W-ROBOT-LOW-SWITCH", "",
          "A configuration change in the air sweeps the tool or the arm closer to the part than the job's "
          "clearance, and no lift (a retract away from the part, with a raised via-point) tried kept it clear.",
          "Move the part (`--base`, or `--place`) so that one configuration serves the whole job, or give more "
          "room above the part.", "robot"),
    entry("W-ROBOT-PLACE-CAPPED", "",
          "The placement search (`--place`) ran past its wall-clock safety cap (600 s) and stopped before it had "
          "solved every cell its work budget allows; the search is otherwise counted in work, so only a very slow "
          "or loaded machine gets here, and the placement it chose may differ from the one a quicker machine "
          "chooses.",
          "Run the job again on a quieter machine, or give the placement the metrics record (`robot_x_m`, "
          "`robot_y_m`, `robot_yaw_rad`) as `--base`.", "robot"),
    entry("W-ROBOT-SWITCH-GAP", "",
          "A configuration change came right where the old configuration could not retract from the part, or "
          "an air link of the plan hit the table, a fixture or the robot itself; the end of the pass before the "
          "change (or the air link) was replaced by a retract, a joint move at the clearance and an approach, and "
          "coverage and removal are computed on what the robot runs.",
          "Move the part (`--base`, or `--place`) so that one configuration serves the whole job; keep the air "
          "links clear of fixtures.", "robot"),
    # --- the cell -------------------------------------------------------------------------------------------
    entry("W-CELL-DEFAULT-TOOL", "",
          "No tool was described: a 3-inch random-orbital sander (holder, spindle, 175 mm TCP) is assumed for "
          "the TCP and the collision check.",
          "Describe your tool in a cell file (`[tool]` with `tcp2flange` and `[[tool.body]]`) or give `--tcp`.",
          "robot"),
    entry("W-CELL-NO-TOOL-BODY", "",
          "A TCP was given without a tool body: only the robot's links are checked for collisions.",
          "Describe the tool's body in a cell file (`[[tool.body]]` cylinders or boxes).", "robot"),
    entry("W-CELL-DEFAULT-TABLE", "",
          "No table was described: the part is taken to stand on a table whose top is its lowest point, and the "
          "arm is checked against it.",
          "Describe the real table in a cell file (`[table]`), or `table = false` if there is none.", "robot"),
    entry("W-CELL-COLLISION", "",
          "With `--allow-collisions`: the robot or the tool touches the part, the table, a fixture or itself "
          "somewhere along the job (the report marks where).",
          "Move the part (`part2base`), change the tool body or the fixtures, or plan another direction; "
          "without `--allow-collisions` such a plan writes no program.", "robot"),
    entry("W-WRAP-SPLIT", "",
          "The wrap planner's helix (or a ring) found no outward-facing surface at some angles about the axis "
          "(a slot, a hole or the end of a face the selection leaves out), so the pass is split there and the pad "
          "lifts.", "Check the axis (the positioner's, or `axis=`) and the faces selected; a part that is not "
          "closed about the axis is better planned with another planner.", "plan"),
    entry("W-POSITIONER-ACCEL", "",
          "With a rotary positioner: the axis angle the job asks for changes speed faster than the positioner's "
          "`max_accel` somewhere (the speed itself is kept within `max_speed`); the controller slows there.",
          "Raise `max_accel` if the positioner allows it, or plan a helix of smaller pitch changes (wrap mode "
          "helix rather than rings) so the axis turns steadily.", "robot"),
    # --- simulation, force control, calibration ------------------------------------------------------------
    entry("W-REMOVAL-COARSENED", r"removal sampled at .* instead of",
          "The part is too large for the removal simulation's sample cap at the asked spacing; it is sampled "
          "more coarsely.",
          "Nothing for the plan; for finer removal maps plan regions of the part separately.", "simulate"),
    entry("W-COVERAGE-LOW", r"coverage is .* \(below",
          "Part of the surface is never touched by the pressed pad.",
          "Lower the spacing or raise the overlap, or plan the part in regions (`--segment auto`).",
          "simulate"),
    entry("W-EFFICIENCY-ABOVE-1", r"efficiency .* is above 1",
          "The efficiency η = L\\* / L exceeds 1, which no plan can reach: the lower bound counts area the "
          "passes never cover.",
          "Read it together with `coverage_fraction`.", "simulate"),
    entry("W-HOT-SPOT", r"^hot spot: ",
          "A patch of the part (at least a quarter of the pad's face) is removed more than three times as deep as "
          "the interior's mean; the message gives its area, the deepest removal, where it is, and what the "
          "simulation finds there (the tool slowing while the pad is over it, the surface turning under the pad). "
          "The interior CoV leaves out a pad radius along the edges, so a plan can be even inside and still grind "
          "such a spot at an edge.",
          "Look at the spot in the report's removal map before running. Keep the pad off it (`--keep-out` with a "
          "box round it, or `--edge-margin` at an edge); relax `--max-angular` where the tool slows to turn "
          "at the limit; lower the target depth or use `--constant-feed` where the feed programme slows it. "
          "`hot_spot_*` in `metrics.json` hold the figures.", "simulate"),
    entry("W-PAD-TOO-STIFF", r"is too stiff to follow",
          "The removal is uneven because the pad is too stiff for the surface's curvature or waviness; a "
          "softer pad would remove clearly more evenly (simulated).",
          "Use a softer interface pad (the `--depression` in the message), or plan on a smooth fit of the "
          "scan (`swath fit`).", "simulate"),
    entry("W-FORCE-NO-SURFACE", r"have no surface under the pad",
          "The force simulation found no surface under the pad at some contact samples and assumes the "
          "flat depression there.",
          "Check the part and the trajectory near the edges.", "simulate"),
    entry("W-FORCE-UNSETTLED", r"did not settle within",
          "At the start of a contact run the simulated force did not settle before the hold time ran out.",
          "Lower the approach speed or raise the force loop's gains; check the force trace in the report.",
          "simulate"),
    entry("W-FORCE-NO-CONTACT", r"no contact within .* beyond the nominal sink",
          "The simulated tool found no contact within the search depth: the part is not where the plan "
          "expects it; the pass is skipped.",
          "Register the part (`swath register`) or check `--part-offset`.", "simulate"),
    entry("W-CALIBRATION-NO-TOOL", r"does not state the tool its trials were run with",
          "The calibration file was written before swath recorded the tool of the trials: the job's own tool is "
          "used as it is, unchecked against the trials.",
          "Calibrate again (`swath calibrate`) so the file states the tool.", "simulate"),
    entry("W-CALIBRATION-OUTSIDE", r"lies outside the calibration's|differs from the calibration's trials",
          "The job's spindle speed, orbit or pad radius lies outside what the calibration trials used: removal is "
          "extrapolated by the model there.",
          "Run trials at the job's settings (`swath doe`), or set the job to the calibrated tool.", "simulate"),
    entry("W-CALIBRATION-AGE-IGNORED", r"pad_age_s is ignored",
          "The trials record pad age, but a fit of the pressure and speed exponents does not fit wear too.",
          "Fit with the exponents fixed to have the wear rate fitted.", "simulate"),
    entry("W-CALIBRATION-EXPONENTS", r"calibration exponents",
          "The calibration fits pressure and speed exponents; the removal model is linear and uses a Preston "
          "coefficient exact only at the nominal pressure and speed.",
          "Keep the force and feed near the calibration's nominal values.", "simulate"),
    # --- output, execution -------------------------------------------------------------------------
    entry("W-METRIC-UNIT", r"names without a unit suffix",
          "A metric or setting key lacks a unit suffix (`_m`, `_s`, `_fraction`, ...). This is a bug in swath.",
          "Report it.", "report"),
    entry("W-HELPER-PROCESS", r"a helper process ended without an answer",
          "A helper process swath starts to overlap work ended early (e.g. out of memory); the work is done "
          "in the main process instead.",
          "Nothing; the job is slower. Check the memory if it recurs.", "run"),
    entry("W-RAY-WARMUP", r"warming the Ray workers up failed",
          "`swath batch` could not warm its Ray workers up; the jobs run anyway, the first on each worker "
          "a little slower.",
          "Nothing, unless the jobs then fail: check the Ray cluster.", "run"),
])

#: Docs page of the codes (relative to the docs site root).
DOCS_PAGE = "reference/warnings.md"


def code_for(text: str) -> str | None:
    """The code of a warning ``text`` (explicit ``[W-...]`` first, else the first entry whose
    ``match`` is found), or None."""
    m = CODE_RE.search(text)
    if m:
        return m.group(1)
    for c in CODES.values():
        if c.match and re.search(c.match, text):
            return c.code
    return None


def tagged(text: str) -> str:
    """``text`` ending with its code, ``"... [W-COVERAGE-LOW]"`` (unchanged when it has one
    already or matches no entry)."""
    if CODE_RE.search(text):
        return text
    code = code_for(text)
    return f"{text} [{code}]" if code else text


class WarningCodeFilter(logging.Filter):
    """A handler filter that ends each WARNING record's message with its code."""

    def filter(self, record: logging.LogRecord) -> bool:
        if record.levelno == logging.WARNING and isinstance(record.msg, str) and not CODE_RE.search(record.msg):
            try:
                text = record.getMessage()
            except (TypeError, ValueError):
                return True
            code = code_for(record.msg) or code_for(text)
            if code and f"[{code}]" not in text:
                record.msg, record.args = f"{text} [{code}]", None
        return True


def install_warning_codes(logger: logging.Logger | None = None) -> None:
    """Add :class:`WarningCodeFilter` to the handlers of ``logger`` (default the root logger)."""
    for handler in (logger or logging.getLogger()).handlers:
        if not any(isinstance(f, WarningCodeFilter) for f in handler.filters):
            handler.addFilter(WarningCodeFilter())


def warnings_markdown() -> str:
    """The docs page body: one section per code, grouped by stage."""
    stages = {"input": "Reading parts and scans", "fit": "Scan fits and registration", "plan": "Planning",
              "trajectory": "Timing", "feed": "Feed optimisation", "robot": "Robot", "simulate":
              "Removal, force and calibration", "report": "Output", "run": "Running jobs"}
    lines = []
    for stage in [*stages, *sorted({c.stage for c in CODES.values()} - set(stages))]:
        codes = sorted((c for c in CODES.values() if c.stage == stage), key=lambda c: c.code)
        if not codes:
            continue
        lines += [f"## {stages.get(stage, stage.capitalize())}", ""]
        for c in codes:
            lines += [f"### {c.code} {{#{c.anchor}}}", "", f"**What it means.** {c.meaning}", "",
                      f"**What to do.** {c.action}", ""]
    return "\n".join(lines)
