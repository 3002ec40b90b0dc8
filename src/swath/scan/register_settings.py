"""Tuning constants of rigid registration (:mod:`swath.scan.register`), in one place."""

from __future__ import annotations

import numpy as np

#: Source points used by the fine ICP; larger inputs are subsampled at random (a surface's points
#: are weighted by their vertex areas).
MAX_POINTS = 20_000
#: Source points used to score coarse start poses.
COARSE_POINTS = 250
#: Target point spacing (fraction of the source size) used to score coarse start poses.
COARSE_SPACING = 0.02
#: Correspondence search radius (fraction of the source size) of the first coarse step.
COARSE_BOUND = 0.25
#: Coarse placement: source points scored, candidate-centre step (in target-thinning spacings),
#: distance clip (same unit), centres scored at once, placements kept for the coarse ICP, and
#: the largest distance-field grid (cells) and number of candidate centres.
PLACE_POINTS = 100
PLACE_STEP = 3.0
PLACE_CLIP = 3.0
PLACE_CHUNK = 512
PLACE_KEEP = 24
MAX_FIELD_CELLS = 4_000_000
MAX_CENTRES = 20_000
#: ICP steps run from every coarse start pose before they are scored.
COARSE_ITERATIONS = 10
#: Best distinct coarse poses refined to convergence (on a table, this many by the surface fit
#: and this many by the surface and perimeter fit).
COARSE_KEEP = 3
#: Fewest source points accepted.
MIN_POINTS = 10
#: Neighbours used to estimate normals of a target given as bare points.
NORMAL_NEIGHBOURS = 16
#: Target perimeter loops shorter than this (vertices) are scan holes, not the part's perimeter.
MIN_LOOP_VERTICES = 10
#: Two poses differing by less than this rotation (rad) and translation (fraction of the source
#: size) are the same pose.
SAME_POSE_ANGLE = np.radians(5.0)
SAME_POSE_SHIFT = 0.02
#: A pose has settled (its trimmed set is frozen) when a step moves points by less than this
#: fraction of the source size, or after FREEZE_AFTER steps.
SETTLE_STEP = 1e-4
FREEZE_AFTER = 20
#: Correspondences whose point-to-plane residual exceeds this many robust standard deviations
#: (1.4826 × median absolute residual of the trimmed set), or GATE_FLOOR × the source size if
#: larger, are dropped too.
GATE_SIGMAS = 3.0
GATE_FLOOR = 1e-4
#: Correspondences are searched within this many times the last trimmed distance (+ the step).
SEARCH_FACTOR = 4.0
#: Residuals are reported for source points within this fraction of the source size of the target.
FAR_FRACTION = 0.1
#: With a surface target, the closest-vertex ICP stops at steps below this fraction of the
#: source size and the exact closest-point ICP takes over.
POLISH_FROM = 1e-5
#: Largest rotation (rad, about the weighted centroid) of one ICP step.
MAX_STEP_ANGLE = 0.3
#: A distinct pose whose score is within this factor of the best makes the answer ambiguous.
AMBIGUOUS_SCORE = 1.15
#: A registration is reported poor when fewer source points than this are inliers, or when the
#: inlier rms exceeds this fraction of the source size (the two differ in shape, or cover
#: different parts).
POOR_INLIERS = 0.8
POOR_RMS = 2e-3
#: Weight of a perimeter point in general rigid registration, and the least length of the
#: target's area-weighted mean normal for its perimeter to be matched (a target seen from one side).
PERIMETER_WEIGHT = 10.0
PERIMETER_VIEW = 0.5
#: Relative eigenvalue of the normal equations below which a motion counts as unconstrained.
DEGENERATE_EIGENVALUE = 1e-10

NO_MATCH = "no correspondences"
_MOTION_NAMES = ("rotation about x", "rotation about y", "rotation about z",
                 "translation along x", "translation along y", "translation along z")
