"""Does Jaeger's curvature-based resampling of scan rows help the fit?  Plain fit against resampled rows.

    python benchmarks/bench_scan_resample.py

Simulated point-laser scans (``swath.examples.scansim``: σ 0.1 mm along the normal, 0.2 mm row
offsets per axis, seed 1) of a 120 mm span of the blade (rows round its leading edge) at 4 mm / 1 mm
and 2 mm / 0.5 mm, and of a 250 × 200 mm doubly curved panel at 4 mm / 1 mm.  Each is fitted as
measured and after :func:`swath.scan.resample_rows` with several curvature weights ``q`` and
regression windows, and after thinning the measured points to half by the same distribution
(keeping measured points, so no smoothing bias).  Prints the 95th-percentile angle (degrees)
between the fitted and the analytic normal at every scanned point.  About a minute on 2 vCPUs.
"""

from __future__ import annotations

import numpy as np

from swath.examples.scansim import blade_patch, panel_patch, simulate_laser_scan
from swath.scan import fit_patch, resample_rows
from swath.scan.resample import local_quadratic, row_distribution


def thin_measured(points, rows, q: float, *, window: int = 21, keep: float = 0.5):
    """Keep ``keep`` of each row's measured points, chosen at equal steps of Jaeger's R(s)."""
    out_p, out_r = [], []
    for rid in np.unique(rows):
        P = points[rows == rid]
        seg = np.maximum(np.linalg.norm(np.diff(P, axis=0), axis=1), 1e-12)
        s = np.concatenate([[0.0], np.cumsum(seg)])
        _, d1, d2 = local_quadratic(s, P, s, window)
        kappa = np.linalg.norm(np.cross(d1, d2), axis=1) / np.maximum(np.linalg.norm(d1, axis=1), 1e-12) ** 3
        R = row_distribution(s, kappa, q)
        idx = np.unique(np.searchsorted(R, np.linspace(0, 1, int(keep * len(P)))).clip(0, len(P) - 1))
        out_p.append(P[idx])
        out_r.append(np.full(len(idx), rid))
    return np.concatenate(out_p), np.concatenate(out_r)


def normal_error_95(points, rows, scan) -> float:
    """95th-percentile angle (deg) between the fit's and the true normals at the scanned points."""
    patch, _ = fit_patch(points, rows=rows)
    u, v, _ = patch.project(scan.true_points)
    cos = np.einsum("ij,ij->i", patch.normals(u, v), scan.true_normals)
    return float(np.percentile(np.degrees(np.arccos(np.clip(cos, -1, 1))), 95))


def main() -> None:
    cases = [("blade", blade_patch(span=0.12), 4e-3, 1e-3), ("blade", blade_patch(span=0.12), 2e-3, 0.5e-3),
             ("panel", panel_patch(size_x=0.25, size_y=0.2), 4e-3, 1e-3)]
    variants = [("q 0.5, window 11 (default)", {"q": 0.5}), ("q 0.2", {"q": 0.2}),
                ("q 0.5, window 21", {"q": 0.5, "window": 21}), ("q 0 (smoothing only)", {"q": 0.0})]
    header = ["part", "rows/points mm", "points", "plain"] + [v[0] for v in variants] + ["thinned to 50 %"]
    print(" | ".join(header))
    for name, truth, row_spacing, point_spacing in cases:
        scan = simulate_laser_scan(truth, row_spacing=row_spacing, point_spacing=point_spacing, sigma=1e-4,
                                   row_offset=2e-4, rng=np.random.default_rng(1))
        row = [name, f"{row_spacing * 1e3:g}/{point_spacing * 1e3:g}", str(len(scan.points)),
               f"{normal_error_95(scan.points, scan.rows, scan):.3f}"]
        for _, kwargs in variants:
            row.append(f"{normal_error_95(*resample_rows(scan.points, scan.rows, **kwargs), scan):.3f}")
        row.append(f"{normal_error_95(*thin_measured(scan.points, scan.rows, 0.5), scan):.3f}")
        print(" | ".join(row), flush=True)


if __name__ == "__main__":
    main()
