"""Cycle time of the blade's profile passes under the Amersdorfer & Meurer limits.

    python benchmarks/bench_timing.py [--spacing 0.025] [--feed 0.05]

Passes run round the NACA 0012 profile of the built-in blade (chord 0.4 m, span 0.6 m) at fixed
span, alternating in direction, every ``--spacing`` metres of span; they turn fastest at the
6.3 mm leading-edge radius.  Each row times the same passes with another set of limits.

Columns: the limits; cycle time (s) and its increase over no limits (%); contact and air time
(s); slowest speed within 2 mm of the leading edge (mm/s); largest angular speed |ω| (rad/s, written columns) and
centripetal acceleration v²κ (m/s², κ read at 1 mm) in contact; samples written; wall time (s).
"""

from __future__ import annotations

import argparse

import numpy as np

from common import Measure, print_table


def profile_passes(surface, spacing: float):
    """Passes round the profile at span stations ``spacing`` apart (rows of the structured grid)."""
    from swath.plan import Pass

    ys = np.unique(surface.vertices[:, 1])
    V = surface.vertices.reshape(-1, len(ys), 3)
    N = surface.normals.reshape(-1, len(ys), 3)
    stations = np.arange(spacing / 2, ys[-1], spacing)
    cols = np.unique(np.searchsorted(ys, stations))
    out = [Pass(V[:, j].copy(), N[:, j].copy()) for j in cols]
    return [p if i % 2 == 0 else p.reversed() for i, p in enumerate(out)]


def contact_centripetal(tr) -> float:
    """Largest v²κ over the contact runs (κ at 1 mm scale on the written path), m/s²."""
    from swath.trajectory.geometry import path_curvature, resample_uniform

    c = tr.contact.astype(int)
    d = np.diff(np.concatenate([[0], c, [0]]))
    worst = 0.0
    for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)):
        s, pts, v = resample_uniform(tr.position[a:b], 2e-4, tr.feed[a:b])
        worst = max(worst, float((v**2 * path_curvature(pts, s[1] - s[0], 1e-3)).max()))
    return worst


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--spacing", type=float, default=0.025, help="span between passes, m (default 0.025)")
    ap.add_argument("--feed", type=float, default=0.05, help="feed, m/s (default 0.05)")
    args = ap.parse_args()

    from swath.examples import blade
    from swath.plan import ToolPath
    from swath.trajectory import AngularSpeedLimit, CentripetalLimit, FeedLimit, TangentialAccelLimit, time_path

    surface = blade()
    tp = ToolPath(surface, profile_passes(surface, args.spacing), "profile")
    feed = FeedLimit(args.feed)
    cases = [("none", []), ("a_c 2 m/s²", [CentripetalLimit(2.0)]), ("ω 1 rad/s", [AngularSpeedLimit(1.0)]),
             ("a_t 1 m/s²", [TangentialAccelLimit(1.0)]),
             ("all three", [CentripetalLimit(2.0), AngularSpeedLimit(1.0), TangentialAccelLimit(1.0)])]
    time_path(ToolPath(surface, tp.passes[:1], "warm-up"), [feed])          # import toppra once
    rows = []
    base = None
    for name, extra in cases:
        with Measure() as m:
            tr = time_path(tp, [feed, *extra])
        both = tr.contact[1:] & tr.contact[:-1]
        contact_t = float(np.diff(tr.t)[both].sum())
        base = tr.duration if base is None else base
        w = np.linalg.norm(np.stack([tr.extra[k] for k in ("wx", "wy", "wz")], axis=1), axis=1)
        rows.append(dict(limits=name, cycle_s=tr.duration, more_pct=100 * (tr.duration / base - 1),
                         contact_s=contact_t, air_s=tr.duration - contact_t,
                         v_le_mm_s=1e3 * tr.feed[tr.contact & (tr.position[:, 0] < 2e-3)].min(),
                         w_max=float(w[tr.contact].max()),
                         ac_max=contact_centripetal(tr), samples=len(tr), wall_s=m.seconds))
        print(f"  done {name}", flush=True)
    print()
    print(f"blade (NACA 0012, chord 0.4 m, span 0.6 m): {len(tp.passes)} profile passes, "
          f"{tp.contact_length:.2f} m in contact, feed {1e3 * args.feed:.0f} mm/s, links 0.25 m/s, 1 m/s²")
    print_table(rows, [("limits", "s"), ("cycle_s", ".1f"), ("more_pct", ".1f"), ("contact_s", ".1f"),
                       ("air_s", ".1f"), ("v_le_mm_s", ".2f"), ("w_max", ".2f"), ("ac_max", ".3f"),
                       ("samples", "d"), ("wall_s", ".2f")])


if __name__ == "__main__":
    main()
