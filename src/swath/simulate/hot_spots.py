"""Hot spots: where the simulated removal runs far deeper than over the part's inside, and why.

The interior removal CoV (:func:`swath.simulate.removal.plan_metrics`) leaves out a pad radius along
the open edges, and a CoV says nothing of where the deepest removal is.  A plan can be even inside
and still grind a spot many times deeper near an edge: on bezier_dac_scan the default job's passes
crossed a fold at the scan's rim (the surface turns by about 85 degrees under the pad, 2 mm from the
edge), the angular speed limit held the tool to about 3 mm/s there, and the pad removed 91 um on a
part whose inside loses 4.6 um (70 um once the passes stop short of the fold, :mod:`swath.plan.folds`:
the flat pad still presses on the fold's crest).

:func:`hot_spot_metrics` measures the area removed deeper than :data:`HOT_SPOT_FACTOR` times the
interior's mean depth and, at the deepest sample, the facts a process engineer checks: where it is,
whether it lies within a pad radius of the edge, how slowly the tool moves over it and how far the
surface turns under the pad there.  :func:`hot_spot_warnings` turns them into the job's warning once
the area is at least :data:`HOT_SPOT_MIN_PAD_SHARE` of the pad's.
"""

from __future__ import annotations

import math

import numpy as np

#: Removal deeper than this many times the interior's mean depth counts as a hot spot.
HOT_SPOT_FACTOR = 3.0

#: A hot spot warns once its area is at least this share of the pad's face (pi R^2).  Of the default
#: jobs on the shared and built-in parts (raster and uniform), two parts have such a patch:
#: bezier_dac_scan's fold at its rim (1.8 pads' area over 3x, its deepest 15x) and the hub's rim
#: (0.8 pad, 4.7x); the next, bezier_complex_shape's edge (0.19 pad, 5x) and crs_part_5's (0.11 pad,
#: 4x), are a few passes' slowing at the edge.
HOT_SPOT_MIN_PAD_SHARE = 0.25

#: The slowing counts as the angular speed limit's where the tool turns at least this fraction of it.
AT_LIMIT = 0.9


def hot_spot_metrics(removal, trajectory, tool) -> dict:
    """The hot spot of a simulated plan, for ``metrics.json`` (units in the keys).

    Parameters
    ----------
    removal : RemovalMap
        The simulated removal (``depth`` ``(n,)`` m at ``surface.vertices`` ``(n, 3)`` m).
    trajectory : Trajectory
        The trajectory simulated (TCP ``position`` ``(k, 3)`` m, ``t`` s, ``contact``).
    tool : Tool
        Its ``pad_radius`` (m) sets the interior and the neighbourhood read round the deepest spot.

    Returns
    -------
    dict
        ``hot_spot_reference_m`` (the interior's area-weighted mean depth, or the touched area's on
        a part with no interior), ``hot_spot_area_m2`` (removed deeper than :data:`HOT_SPOT_FACTOR`
        times it), ``hot_spot_area_over_pad_ratio`` (that area over the pad's face, pi R^2: the job
        warns from :data:`HOT_SPOT_MIN_PAD_SHARE`), ``hot_spot_depth_m`` (the deepest removal),
        ``hot_spot_depth_ratio`` (over the reference), ``hot_spot_position_m`` (the deepest sample, part frame), ``hot_spot_at_edge``
        (it lies within a pad radius of the open edge), ``hot_spot_slowest_speed_m_per_s`` (the TCP's
        slowest in-contact speed while the pad is over it, its centre within a pad radius: the 5th
        percentile by time, the pass ends' stops left out), ``hot_spot_angular_speed_rad_per_s`` (the
        tool's angular speed there) and ``hot_spot_angular_limit_rad_per_s`` (the limit the
        trajectory was timed under, NaN if none), ``hot_spot_normal_turn_rad`` (the largest angle
        between the surface normal there and the normals within a pad radius).  Empty when nothing was removed.
    """
    d = np.asarray(removal.depth, float)
    samples = removal.surface
    a = np.asarray(samples.vertex_areas, float)
    if not len(d) or not (d > 0).any():
        return {}
    R = float(tool.pad_radius)
    inner = samples.farther_from_boundary(R)
    base = inner if (inner & (d > 0)).any() else d > 0
    reference = float(np.average(d[base], weights=a[base])) if a[base].sum() > 0 else float(d[base].mean())
    if not reference > 0:
        return {}
    i = int(np.argmax(d))
    p = np.asarray(samples.vertices[i], float)
    area = float(a[d > HOT_SPOT_FACTOR * reference].sum())
    out = {"hot_spot_reference_m": reference, "hot_spot_area_m2": area,
           "hot_spot_area_over_pad_ratio": area / (math.pi * R**2),
           "hot_spot_depth_m": float(d[i]), "hot_spot_depth_ratio": float(d[i] / reference),
           "hot_spot_position_m": [float(x) for x in p], "hot_spot_at_edge": bool(not inner[i])}
    near = np.flatnonzero(np.linalg.norm(samples.vertices - p, axis=1) <= R)
    n = np.asarray(samples.normals, float)
    out["hot_spot_normal_turn_rad"] = float(np.arccos(np.clip(n[near] @ n[i], -1.0, 1.0)).max()) if len(near) else 0.0
    out["hot_spot_slowest_speed_m_per_s"], out["hot_spot_angular_speed_rad_per_s"] = _slowest_speed(trajectory, p, R)
    out["hot_spot_angular_limit_rad_per_s"] = _angular_limit(trajectory)
    return out


def _slowest_speed(trajectory, point: np.ndarray, radius: float) -> tuple[float, float]:
    """The TCP's in-contact speed (m/s) within ``radius`` (m) of ``point`` (the 5th percentile by
    time of the segments whose both ends are in contact there) and the tool's angular speed on that
    segment (rad/s, from the orientations); NaN where no segment is."""
    pos = np.asarray(trajectory.position, float)
    if len(pos) < 2:
        return float("nan"), float("nan")
    inside = trajectory.contact & (np.linalg.norm(pos - point, axis=1) <= radius)
    both = inside[1:] & inside[:-1]
    dt = np.diff(np.asarray(trajectory.t, float))
    both &= dt > 0
    if not both.any():
        return float("nan"), float("nan")
    seg = np.flatnonzero(both)
    v = np.linalg.norm(pos[seg + 1] - pos[seg], axis=1) / dt[seg]
    order = np.argsort(v)
    cdf = np.cumsum(dt[seg][order]) / dt[seg].sum()
    k = order[min(int(np.searchsorted(cdf, 0.05)), len(v) - 1)]
    q = np.asarray(trajectory.quaternion, float)
    turn = 2.0 * np.arccos(np.clip(abs(float(q[seg[k]] @ q[seg[k] + 1])), 0.0, 1.0))   # unit quaternions
    return float(v[k]), float(turn / dt[seg[k]])


def _angular_limit(trajectory) -> float:
    """The angular speed limit (rad/s) the trajectory was timed under, from its metadata (NaN if none)."""
    for c in trajectory.metadata.get("constraints") or []:
        if isinstance(c, dict) and c.get("type") == "AngularSpeedLimit" and c.get("omega_max") is not None:
            return float(c["omega_max"])
    return float("nan")


def worth_warning(metrics: dict) -> bool:
    """Whether the hot spot in ``metrics`` (:func:`hot_spot_metrics`'s keys) is worth the job's
    warning: its area at least :data:`HOT_SPOT_MIN_PAD_SHARE` of the pad's face."""
    share = metrics.get("hot_spot_area_over_pad_ratio")
    return share is not None and bool(share >= HOT_SPOT_MIN_PAD_SHARE)


def warned_position(metrics: dict) -> np.ndarray | None:
    """The deepest spot ``(3,)`` (m, part frame) of the hot spot in ``metrics`` where
    :func:`worth_warning`, for the report's pictures to mark; else None."""
    at = metrics.get("hot_spot_position_m")
    return np.asarray(at, float) if at is not None and worth_warning(metrics) else None


def hot_spot_warnings(metrics: dict, feed: float) -> list[str]:
    """The job's warning about its hot spot (:func:`hot_spot_metrics`'s keys in ``metrics``), where
    :func:`worth_warning`; else none.  ``feed`` m/s."""
    if not worth_warning(metrics):
        return []
    area = float(metrics["hot_spot_area_m2"])
    ref, depth = float(metrics["hot_spot_reference_m"]), float(metrics["hot_spot_depth_m"])
    where = ", ".join(f"{1e3 * x:.0f}" for x in metrics["hot_spot_position_m"])
    edge = "within a pad radius of the edge" if metrics.get("hot_spot_at_edge") else "inside the part"
    turn = math.degrees(float(metrics.get("hot_spot_normal_turn_rad", 0.0)))
    slow, omega, limit = (float("nan") if metrics.get(k) is None else float(metrics[k]) for k in (
        "hot_spot_slowest_speed_m_per_s", "hot_spot_angular_speed_rad_per_s", "hot_spot_angular_limit_rad_per_s"))
    fix, slowed = "keep the pad off it (--keep-out with a box round it, or --edge-margin at an edge)", ""
    if np.isfinite(slow) and slow < 0.5 * feed:
        held = np.isfinite(omega) and np.isfinite(limit) and omega >= AT_LIMIT * limit
        slowed = (f"the tool slows to {1e3 * slow:.0f} mm/s while the pad is over it (the feed {1e3 * feed:.0f} mm/s)"
                  + (f", turning at the angular speed limit {limit:.3g} rad/s" if held else ""))
        fix += ", or relax --max-angular" if held else ", or lower the target depth or use --constant-feed"
    turned = f"the surface turns by {turn:.0f} deg under the pad there" if turn >= 30.0 else ""
    cause = " and ".join(x for x in (slowed, turned) if x)
    cause = f"; {cause}" if cause else ""
    return [f"hot spot: {1e4 * area:.1f} cm2 of the part is removed more than {HOT_SPOT_FACTOR:.0f}x as deep as the "
            f"interior's mean {_um(ref)}, down to {_um(depth)} ({depth / ref:.0f}x) at ({where}) mm, {edge}{cause}; "
            f"check that spot before running: {fix}"]


def _um(x: float) -> str:
    return f"{1e6 * x:.3g} um"
