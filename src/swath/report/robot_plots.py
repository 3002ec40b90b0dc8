"""Figures of the robot stage: joint positions and speeds against their limits, and the reachability map.

* :func:`joint_plot_figure` — q(t) and q̇(t) (finite differences on the joint rows) of each joint,
  as a fraction of the joint's limits, with the limit lines at ±1 and branch switches marked;
* :func:`reachability_figure` — the part's vertices seen along its principal normal axis, coloured
  by manipulability (or joint-limit margin), unreachable vertices in red;
* :func:`margins_figure` — manipulability, wrist sine and joint-limit margin along the job, with the
  robot stage's warning thresholds and the contact passes shaded;
* :func:`robot_traces` — plotly traces for the report's 3D view, in the part frame: the arm's links
  at a few poses, the base, the reach envelope and keep-out cylinder at the part's lowest height, and
  the stretches the robot skips (unreachable) in red.

Both return a ``matplotlib.figure.Figure`` (Agg canvas, no pyplot); :func:`robot_png_bytes`
renders one for embedding, :func:`write_robot_plots` writes both atomically.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .plots import _new_figure, png_bytes, save_png, view_frame

#: File names :func:`write_robot_plots` uses.
ROBOT_PNG_NAMES = {"joints": "robot_joints.png", "reachability": "robot_reachability.png",
                   "margins": "robot_margins.png"}


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
    if result is not None:
        fig = margins_figure(result.trajectory.t, result.solution.measures, result.trajectory.contact,
                             title=f"{result.model.name}: distance from singularities and joint limits along the job")
        out["margins"] = save_png(fig, out_dir / ROBOT_PNG_NAMES["margins"], dpi=dpi)
    if surface is not None and reach_map is not None:
        fig = reachability_figure(surface, reach_map)
        out["reachability"] = save_png(fig, out_dir / ROBOT_PNG_NAMES["reachability"], dpi=dpi)
    return out


def margins_figure(t, measures, contact=None, *, title: str | None = None):
    """Manipulability, wrist sine and joint-limit margin along the job.

    Parameters
    ----------
    t : (n,) float
        Sample times, s.
    measures : dict of (n,) float
        ``manipulability`` (dimensionless), ``wrist`` (|sin| of the wrist angle) and
        ``joint_limit_margin_rad`` (rad; shown in degrees), NaN where unreachable
        (:attr:`swath.robot.JointSolution.measures`).
    contact : (n,) bool, optional
        Contact samples, shaded.
    title : str, optional
    """
    from ..robot.stage import WARN_JOINT_LIMIT_MARGIN, WARN_MANIPULABILITY, WARN_WRIST_SIN

    t = np.asarray(t, dtype=float)
    fig = _new_figure(8.0, 6.5)
    axes = fig.subplots(3, 1, sharex=True)
    rows = [("manipulability", np.asarray(measures["manipulability"], float), WARN_MANIPULABILITY,
             "manipulability\n(Yoshikawa, / reach)"),
            ("wrist", np.asarray(measures["wrist"], float), WARN_WRIST_SIN, "wrist |sin|"),
            ("joint_limit_margin", np.degrees(np.asarray(measures["joint_limit_margin_rad"], float)),
             np.degrees(WARN_JOINT_LIMIT_MARGIN), "joint-limit\nmargin (deg)")]
    c = np.zeros(len(t), bool) if contact is None else np.asarray(contact, bool)
    starts = np.flatnonzero(np.diff(np.r_[0, c.astype(int)]) == 1)
    stops = np.flatnonzero(np.diff(np.r_[c.astype(int), 0]) == -1)
    for ax, (name, v, limit, label) in zip(axes, rows):
        finite = np.isfinite(v)
        ax.plot(t[finite], v[finite], lw=0.9, color="tab:blue")
        ax.axhline(limit, color="tab:red", lw=0.9, ls="--", label=f"warning below {limit:.3g}")
        for a, b in zip(starts, stops):
            ax.axvspan(t[a], t[b], color="0.9", lw=0)
        if finite.any():
            i = int(np.nanargmin(np.where(finite, v, np.inf)))
            ax.plot([t[i]], [v[i]], "o", ms=4, color="tab:red")
            ax.annotate(f"min {v[i]:.3g}", (t[i], v[i]), textcoords="offset points", xytext=(5, 5), fontsize=8)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time (s); grey: in contact")
    axes[0].set_title(title or "distance from singularities and joint limits along the job")
    return fig


def robot_traces(result, *, n_poses: int = 3, keep_out: float | None = None) -> list:
    """Plotly traces of the robot for the report's 3D view, in the part frame (m).

    Parameters
    ----------
    result : RobotResult
        Its cell places the robot; its solution gives the poses drawn (first, middle and last reached
        contact samples when ``n_poses`` is 3); its gaps give the unreached stretches.
    n_poses : int
        Arm poses drawn as link polylines (base → joints → flange → TCP).
    keep_out : float, optional
        Keep-out radius drawn, m (default: the placement's, when searched).

    Returns
    -------
    list of plotly traces
    """
    import plotly.graph_objects as go

    model, cell, sol = result.model, result.cell, result.solution
    base2part = cell.base2part                  # maps base-frame points into the part frame
    if getattr(cell, "positioner", None) is not None:
        n_poses = 1                             # the part turns: the cell's part2base is the first pose's

    def to_part(p_base):
        p = np.atleast_2d(p_base)
        return p @ base2part[:3, :3].T + base2part[:3, 3]

    traces = []
    traj = result.trajectory
    ok = np.flatnonzero(sol.reachable & np.asarray(traj.contact, bool))
    if not len(ok):
        ok = np.flatnonzero(sol.reachable)
    if len(ok):
        pick = ok[np.linspace(0, len(ok) - 1, max(n_poses, 1)).astype(int)]
        frames = model.chain.frames(sol.q[pick])
        xs, ys, zs = [], [], []
        for k, f in enumerate(frames):
            pts = np.concatenate([[np.zeros(3)], f[:, :3, 3], [(f[-1] @ cell.tcp2flange)[:3, 3]]])
            pts = to_part(pts)
            xs += list(pts[:, 0]) + [None]
            ys += list(pts[:, 1]) + [None]
            zs += list(pts[:, 2]) + [None]
        traces.append(go.Scatter3d(x=xs, y=ys, z=zs, mode="lines+markers", name=f"{model.name} at {len(pick)} poses",
                                   line=dict(width=7, color="rgb(240,150,30)"),
                                   marker=dict(size=3, color="rgb(90,90,90)"), hoverinfo="skip"))
    # base axis, reach envelope and keep-out at the part's lowest height
    z_low = float(np.min(traj.position @ cell.part2base[:3, :3].T[:, 2] + cell.part2base[2, 3]))
    ang = np.linspace(0, 2 * np.pi, 73)
    rings = [(model.reach + float(np.linalg.norm(cell.tcp2flange[:3, 3])), "reach (horizontal, TCP)",
              "rgb(240,150,30)", "dash")]
    if keep_out is None and result.placement is not None:
        keep_out = result.placement.keep_out
    if keep_out:
        rings.append((keep_out, "keep-out cylinder", "rgb(200,40,40)", "solid"))
    for r, name, color, dash in rings:
        ring = to_part(np.c_[r * np.cos(ang), r * np.sin(ang), np.full(len(ang), z_low)])
        traces.append(go.Scatter3d(x=ring[:, 0], y=ring[:, 1], z=ring[:, 2], mode="lines", name=name,
                                   line=dict(width=3, color=color, dash=dash), hoverinfo="skip"))
    axis = to_part(np.array([[0, 0, min(z_low, 0.0)], [0, 0, 0.0]]))
    traces.append(go.Scatter3d(x=axis[:, 0], y=axis[:, 1], z=axis[:, 2], mode="lines+markers", name="robot base",
                               line=dict(width=10, color="rgb(60,60,60)"), marker=dict(size=6, symbol="square"),
                               hoverinfo="skip"))
    if result.gaps:
        xs, ys, zs = [], [], []
        for g in result.gaps:
            xs += list(g.path[:, 0]) + [None]
            ys += list(g.path[:, 1]) + [None]
            zs += list(g.path[:, 2]) + [None]
        total = sum(g.contact_length for g in result.gaps)
        traces.append(go.Scatter3d(x=xs, y=ys, z=zs, mode="lines", line=dict(width=6, color="rgb(220,0,0)"),
                                   name=f"not reached: {len(result.gaps)} gap(s), {1e3 * total:.0f} mm",
                                   hoverinfo="name"))
    return traces
