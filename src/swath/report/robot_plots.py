"""Figures of the robot stage: joint positions and speeds against their limits, and the reachability map.

* :func:`joint_plot_figure` — q(t) and q̇(t) (finite differences on the joint rows) of each joint,
  as a fraction of the joint's limits, with the limit lines at ±1 and branch switches marked;
* :func:`reachability_figure` — the part's vertices seen along its principal normal axis, coloured
  by manipulability (or joint-limit margin), unreachable vertices in red.

Both return a ``matplotlib.figure.Figure`` (Agg canvas, no pyplot); :func:`robot_png_bytes`
renders one for embedding, :func:`write_robot_plots` writes both atomically.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .plots import _new_figure, png_bytes, save_png, view_frame

#: File names :func:`write_robot_plots` uses.
ROBOT_PNG_NAMES = {"joints": "robot_joints.png", "reachability": "robot_reachability.png"}


def joint_plot_figure(t, q, model, *, branch=None, title: str | None = None):
    """Joint positions and speeds over time, normalised by the limits.

    Parameters
    ----------
    t : (n,) float
        Sample times, s.
    q : (n, 6) float
        Joint values, rad (rows with NaN are skipped).
    model : RobotModel
        Supplies ``lower``, ``upper`` (rad), ``max_speed`` (rad/s) and ``name``.
    branch : (n,) int, optional
        Branch per sample; switches are marked with vertical lines.
    title : str, optional
    """
    t = np.asarray(t, dtype=float)
    q = np.asarray(q, dtype=float)
    ok = np.all(np.isfinite(q), axis=1)
    t, q = t[ok], q[ok]
    fig = _new_figure(8.0, 6.0)
    ax_q, ax_v = fig.subplots(2, 1, sharex=True)
    mid = 0.5 * (model.upper + model.lower)
    half = 0.5 * (model.upper - model.lower)
    dt = np.diff(t)
    with np.errstate(divide="ignore", invalid="ignore"):
        v = np.where(dt[:, None] > 0, np.diff(q, axis=0) / dt[:, None], 0.0)
    tv = 0.5 * (t[1:] + t[:-1])
    for j in range(q.shape[1]):
        ax_q.plot(t, (q[:, j] - mid[j]) / half[j], lw=1.0, label=f"J{j + 1}")
        ax_v.plot(tv, v[:, j] / model.max_speed[j], lw=0.8, label=f"J{j + 1}")
    for ax in (ax_q, ax_v):
        ax.axhline(1.0, color="k", lw=0.8, ls="--")
        ax.axhline(-1.0, color="k", lw=0.8, ls="--")
        ax.grid(alpha=0.3)
    if branch is not None:
        b = np.asarray(branch)[ok]
        for i in np.flatnonzero(np.diff(b)) + 1:
            for ax in (ax_q, ax_v):
                ax.axvline(t[i], color="r", lw=0.8, alpha=0.6)
    ax_q.set_ylabel("position / limit range\n(±1 = joint limit)")
    ax_v.set_ylabel("speed / speed limit")
    ax_v.set_xlabel("time (s)")
    ax_q.legend(ncol=6, fontsize=8, loc="upper right")
    ax_q.set_title(title or f"{model.name}: joint positions and speeds (finite differences)")
    return fig


def reachability_figure(surface, reach_map, *, color_by: str = "manipulability", title: str | None = None):
    """The reachability map over the part.

    Parameters
    ----------
    surface : Surface
        For the view direction (principal axes).
    reach_map : ReachMap
        From :func:`swath.robot.reachability_map`.
    color_by : str
        ``"manipulability"`` (dimensionless) or ``"joint_limit_margin"`` (shown in degrees).
    """
    frame = view_frame(surface)
    uvw = frame.project(reach_map.points)
    fig = _new_figure(7.0, 5.5)
    ax = fig.subplots()
    ok = reach_map.reachable
    if color_by == "joint_limit_margin":
        values, label = np.degrees(reach_map.joint_limit_margin), "joint-limit margin (deg)"
    else:
        values, label = reach_map.manipulability, "manipulability (Yoshikawa, linear rows / reach)"
    if ok.any():
        sc = ax.scatter(uvw[ok, 0] * 1e3, uvw[ok, 1] * 1e3, c=values[ok], s=8, cmap="viridis")
        fig.colorbar(sc, ax=ax, label=label)
    if (~ok).any():
        ax.scatter(uvw[~ok, 0] * 1e3, uvw[~ok, 1] * 1e3, c="red", s=8, marker="x", label="unreachable")
        ax.legend(loc="upper right")
    ax.set_aspect("equal")
    ax.set_xlabel("u (mm)")
    ax.set_ylabel("v (mm)")
    ax.set_title(title or f"reachable with the tool normal to the surface: {100 * reach_map.reachable_fraction:.1f} %")
    return fig


def robot_png_bytes(fig, *, dpi: int = 110) -> bytes:
    """A robot figure as PNG bytes (for embedding in the HTML report)."""
    return png_bytes(fig, dpi=dpi)


def write_robot_plots(out_dir, *, result=None, surface=None, reach_map=None, dpi: int = 110) -> dict:
    """Write the robot figures whose inputs are given; returns {figure name: path}.

    Parameters
    ----------
    out_dir : path
    result : RobotResult, optional
        Gives the joint plot (re-timed times, joint values, branches).
    surface, reach_map : optional
        Give the reachability map (both needed).
    """
    out = {}
    out_dir = Path(out_dir)
    if result is not None:
        fig = joint_plot_figure(result.trajectory.t, result.solution.q, result.model, branch=result.solution.branch)
        out["joints"] = save_png(fig, out_dir / ROBOT_PNG_NAMES["joints"], dpi=dpi)
    if surface is not None and reach_map is not None:
        fig = reachability_figure(surface, reach_map)
        out["reachability"] = save_png(fig, out_dir / ROBOT_PNG_NAMES["reachability"], dpi=dpi)
    return out
