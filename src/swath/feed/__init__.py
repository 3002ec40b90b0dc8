"""The ``feed`` stage: dwell (feed-rate) and pass-spacing optimisation to a target depth map.

Between planning and timing: any planner's :class:`~swath.plan.ToolPath` goes in with a target
depth map; a :class:`~swath.trajectory.FeedProfile` comes out for :func:`swath.trajectory.time_path`.

* :mod:`.kernel` — the removal kernel (depth per second of dwell, per dwell node, per surface sample);
* :mod:`.optimise` — :func:`optimise_feed`: match a target (L1 / minimax) or Wang's maximal removal
  without over-grinding, under feed, acceleration, centripetal and angular-speed limits (HiGHS);
* :mod:`.ripple` — the pad's analytic cross-profile and the pass spacing whose summed profiles are flattest;
* :mod:`.spacing` — raster passes at chosen offsets; greedy (pattern search) and joint spacing + feed;
* :mod:`.targets` — target depth maps: uniform, per-vertex from a file, scan excess over a CAD.

Proposed CLI flags / job keys (wired by the CLI, not here): ``--optimise-feed [match|max_removal]``,
``--target-depth 20um`` (uniform, :func:`swath.units.parse_quantity` kind ``length``), ``--target-map FILE``
(CSV ``x,y,z,depth`` in m or PLY with a vertex ``depth``), ``--target-excess-over CAD_FILE`` (scan excess),
``--depth-tolerance 2um``, ``--min-feed 5mm/s``, ``--optimise-spacing ripple|greedy|joint`` (raster only).
The job then calls ``optimise_feed(toolpath, tool, constraints, target=..., tolerance=...,
simulate=lambda traj: simulate_removal(traj, surface, tool))`` and passes ``constraints + [result.profile]``
to :func:`swath.trajectory.time_path`.  ``simulate`` (job key ``feed_simulate_check``, default true; up to
``simulate_rounds`` = 6 rounds) makes the over-removal cap hold as :func:`swath.simulate.simulate_removal` measures it: the feed
stage may not import the simulator, so the job hands it in.
"""

from .kernel import DwellNodes, RemovalKernel, build_kernel, dwell_nodes, interior_mask, trajectory_node_dwell
from .optimise import FeedResult, node_speed_caps, optimise_feed, removal_stats
from .ripple import cross_profile, ripple_cov, ripple_overlap, ripple_spacing
from .spacing import SpacingResult, greedy_offsets, joint_spacing, raster_at_offsets
from .targets import TargetMap, excess_target, read_target_map, uniform_target, write_target_map

__all__ = ["DwellNodes", "FeedResult", "RemovalKernel", "SpacingResult", "TargetMap", "build_kernel", "cross_profile",
           "dwell_nodes", "excess_target", "greedy_offsets", "interior_mask", "joint_spacing", "node_speed_caps",
           "optimise_feed", "raster_at_offsets", "read_target_map", "removal_stats", "ripple_cov", "ripple_overlap",
           "ripple_spacing",
           "trajectory_node_dwell", "uniform_target", "write_target_map"]
