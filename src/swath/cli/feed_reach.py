"""Whether a feed along the passes can even the removal at all, read from the constant feed's removal.

The feed optimisation (:func:`swath.feed.optimise_feed`) sets one speed per few millimetres of every
pass.  Slowing a pass down, or a stretch of it, deepens everything that pass removes there: the
whole pass (the variance *between* passes) and stretches a spacing long along it (the variance
*along* the passes; the band at the interior's edge is such stretches too).  What no feed along
a pass changes is the depth profile *across* it within one pass spacing: the ripple of the summed
pad profiles, set by the spacing, the lead and the curvature.

:func:`feed_reach` splits the interior variance of the constant feed's removal by the law of
total variance (:func:`swath.simulate.evenness.evenness_split` over the whole interior, no band
apart): ``between + along`` is the share a feed can reach, ``within cells`` (one spacing across,
one along) mostly the ripple across the passes, which it cannot (the feed still reaches some of
it: a cell's depth also changes along the pass within one spacing).  When the reachable share is
below :data:`FEED_REACH_MIN` the default job skips the optimisation (a kernel, two to four HiGHS
solves and their timing: 15 s of the 37 s crs_part_5 took) and writes the constant feed, saying so.

Measured with the default job on every built-in and shared part (the reachable share of the
constant feed's removal, and the interior CoV at constant feed and with the optimised feed, as the
simulator finds them; the optimised feed was written only where it is evener):

============================  =========  =================================
part                          reachable  interior CoV: constant, optimised
============================  =========  =================================
example:panel                 0.053      0.0496, 0.0491
snp_part_scan                 0.090      0.294, 0.303
crs_part_5                    0.108      0.127, 0.133
bezier_complex_shape          0.126      0.313, 0.301
example:plate, lead 0         0.137      0.108, 0.126
noether_raw_mesh (plain)      0.157      0.152, 0.140
bezier_dac_cad                0.242      0.066, 0.055
noether_wavy_mesh_with_hole   0.291      0.482, 0.401
example:plate                 0.342      0.081, 0.052
example:hub                   0.396      0.575, 0.452
bezier_dac_scan (plain)       0.421      0.410, 0.340
example:blade                 0.439      0.549, 0.373
============================  =========  =================================

Below 0.115 the feed lost twice and won 1 % once (the panel, where the skip saves 7 s of CPU);
above it, it won 4 % to 36 %, but for the plate with a flat pad (0.137), where it lost.  The share
does not separate the two sides cleanly: the threshold skips where the feed has never been seen to
win by more than 1 %, and a part over it runs the programme as before, the job writing the constant
feed where the simulation finds the optimised one worse (``W-EVEN-FEED-WORSE``).
"""

from __future__ import annotations

import logging
import math

log = logging.getLogger(__name__)

#: The default job optimises the feed only where at least this share of the constant feed's
#: interior removal variance lies between and along the passes (module notes).
FEED_REACH_MIN = 0.115


def feed_reach(removal, trajectory, tool) -> dict:
    """The share of the interior removal variance a feed along the passes can change.

    Parameters
    ----------
    removal : RemovalMap
        The simulated removal of ``trajectory`` (at the constant feed).
    trajectory : Trajectory
        Its passes (labels, in-contact positions).
    tool : Tool
        The pad (its radius sets the interior).

    Returns
    -------
    dict
        ``feed_reachable_variance_fraction`` (between + along the passes, of the interior
        variance) and ``feed_reach_interior_cov`` (the interior CoV it is a share of); empty with
        fewer than two passes or an empty interior (nothing to judge: the feed is optimised).
    """
    from ..simulate.evenness import evenness_split
    from ..simulate.ripple import pass_period

    d = pass_period(trajectory)
    if not (math.isfinite(d) and d > 0):
        return {}
    split = evenness_split(removal, trajectory, tool, spacing=d, band_width=0.0)
    cov = split["interior_cov"]
    reach = split["between_passes_variance_fraction"] + split["along_passes_variance_fraction"]
    if not (math.isfinite(cov) and math.isfinite(reach)):
        return {}
    reach = min(max(float(reach), 0.0), 1.0)
    return {"feed_reachable_variance_fraction": reach, "feed_reach_interior_cov": float(cov)}


def feed_cannot_help(figures: dict, minimum: float = FEED_REACH_MIN) -> bool:
    """Whether :func:`feed_reach`'s ``figures`` say the feed optimisation cannot even the removal
    enough to be worth its time: less than ``minimum`` of the variance within its reach."""
    reach = figures.get("feed_reachable_variance_fraction")
    return reach is not None and reach < minimum
