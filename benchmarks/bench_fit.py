"""Accuracy of B-spline fits of simulated point-laser scans (swath issue 3, item 3).

Scans the built-in blade (round its leading edge) and the doubly curved panel with a simulated
point laser — rows 2 mm apart, points 0.5 mm apart along a row, Gaussian noise σ = 0.1 mm along
the normal and a 0.2 mm (per axis) row-to-row positioning offset — fits a patch with
:func:`swath.scan.fit.fit_patch` and compares it with the true surface at every scanned point:

* position: distance from the true point to the fitted surface (RMS, max);
* normals: angle between the fitted and the true normal (mean, 95th percentile, max);
* contact width: the principal curvatures turned into the widest swath of the default pad
  (``local_patch(k1, k2, Tool()).max_width()``), relative error of fitted vs true (mean, 95th
  percentile, max) on a random subsample of 3000 points; the narrowest swath (``min_width``,
  across the most curved direction, where curvature errors show most) is given as well.

The baseline row uses the raw points: local PCA normals (plane fit to the 30 nearest neighbours)
and swath's quadric-fit curvature on the same neighbourhoods.  Targets: 95th-percentile normal
error below 0.5° and contact-width error below 5 %.

Every fit runs in a child process, so each row has its own wall time, CPU time and peak resident
memory (``ru_maxrss`` of the child).  Besides the two parts fitted along their scan rows, the
panel is fitted without rows too (``parameterization="projection"``, as ``swath fit`` does a point
cloud without ``--parameterization rows``), and ``swath fit`` itself (``run_fit``: fit, residuals,
footprint, triangulation, report files) runs on the real scan ``bezier_dac_scan.ply`` (metres):
time, peak memory, rms and largest residual, the warnings it gives, and how many progress calls
it makes.  Targets (issue 11): bezier_dac_scan within 60 s and 2 GiB; 95th-percentile normal error
below 0.5° on the simulated panel.

Run:  python benchmarks/bench_fit.py [--quick] [--seed N] [--scan PATH] [--no-scan]
"""

from __future__ import annotations

import os

# The dense solves here are small (a few hundred to a thousand unknowns); on a shared machine a
# multi-threaded BLAS spends more time contending than computing, so pin it to one thread.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy.spatial import cKDTree  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import SHARED_MESHES  # noqa: E402
from swath.contact import Tool, local_patch  # noqa: E402
from swath.examples.scansim import blade_patch, panel_patch, simulate_laser_scan  # noqa: E402
from swath.scan.fit import fit_patch  # noqa: E402
from swath.surface.curvature import principal_curvatures  # noqa: E402

TARGET_NORMAL_P95_DEG = 0.5
TARGET_WIDTH_ERR = 0.05
TARGET_SCAN_TIME_S = 60.0
TARGET_SCAN_RSS_GIB = 2.0


def pca_normals(points: np.ndarray, k: int = 30, tree=None) -> np.ndarray:
    """Unit normals ``(n, 3)`` from a plane fit to the ``k`` nearest neighbours (sign arbitrary)."""
    tree = tree if tree is not None else cKDTree(points)
    _, idx = tree.query(points, k=k)
    nb = points[idx] - points[idx].mean(axis=1, keepdims=True)
    cov = np.einsum("nki,nkj->nij", nb, nb)
    _, vecs = np.linalg.eigh(cov)
    return vecs[:, :, 0]


def width_errors(k1_true, k2_true, k1, k2, tool):
    """Relative errors of the widest and narrowest swath, ``(n,)`` each."""
    true = local_patch(k1_true, k2_true, tool)
    est = local_patch(k1, k2, tool)
    wmax_t, wmin_t = true.max_width(), true.min_width()
    return (np.abs(est.max_width() - wmax_t) / wmax_t, np.abs(est.min_width() - wmin_t) / wmin_t)


def angle_deg(a: np.ndarray, b: np.ndarray, *, unsigned: bool = False) -> np.ndarray:
    c = np.einsum("ij,ij->i", a, b)
    if unsigned:
        c = np.abs(c)
    return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


def evaluate(name: str, truth, *, row_spacing: float, point_spacing: float, sigma: float,
             row_offset: float, n_width: int, seed: int, method: str = "rows") -> list[dict]:
    """One fit (``method`` "rows", or "projection" without the rows) and, with "rows", the k-NN
    PCA baseline on the same scan: a row of figures each."""
    rng = np.random.default_rng(seed)
    t0 = time.perf_counter()
    scan = simulate_laser_scan(truth, row_spacing=row_spacing, point_spacing=point_spacing, sigma=sigma,
                               row_offset=row_offset, rng=rng)
    t_scan = time.perf_counter() - t0
    tool = Tool()
    sub = rng.choice(len(scan), size=min(n_width, len(scan)), replace=False)
    true_curv = truth.curvature(scan.uv[sub, 0], scan.uv[sub, 1])

    # --- fitted patch ---------------------------------------------------------------------------
    if method == "rows":
        patch, report = fit_patch(scan.points, rows=scan.rows)
    else:
        patch, report = fit_patch(scan.points, parameterization=method)
    u, v, dist = patch.project(scan.true_points)
    ang = angle_deg(patch.normals(u, v), scan.true_normals)
    fc = patch.curvature(u[sub], v[sub])
    wmax_err, wmin_err = width_errors(true_curv.k1, true_curv.k2, fc.k1, fc.k2, tool)
    rows = [dict(part=name, method=f"B-spline ({report.parameterization})", n=len(scan),
                 ctrl=f"{report.n_ctrl[0]}x{report.n_ctrl[1]}", pos_rms=np.sqrt(np.mean(dist**2)),
                 pos_max=dist.max(), ang=ang, wmax=wmax_err, wmin=wmin_err, time=report.time,
                 fit_rms=report.rms, fit_max=report.max_error, warnings=len(report.warnings))]
    if method != "rows":
        rows[0]["scan_time"] = t_scan
        return rows

    # --- baseline: local PCA normals on the raw points -------------------------------------------
    t1 = time.perf_counter()
    tree = cKDTree(scan.points)
    nrm = pca_normals(scan.points, 30, tree)
    nrm *= np.sign(np.einsum("ij,ij->i", nrm, scan.true_normals))[:, None]   # orientation given for free
    ang_b = angle_deg(nrm, scan.true_normals)
    bc = principal_curvatures(scan.points[sub], nrm[sub], neighbours=30, cloud=scan.points, cloud_normals=nrm,
                              tree=tree)
    wmax_b, wmin_b = width_errors(true_curv.k1, true_curv.k2, bc.k1, bc.k2, tool)
    raw = np.abs(np.einsum("ij,ij->i", scan.points - scan.true_points, scan.true_normals))
    rows.append(dict(part=name, method="baseline: k-NN PCA (k=30)", n=len(scan), ctrl="-",
                     pos_rms=np.sqrt(np.mean(raw**2)), pos_max=raw.max(), ang=ang_b, wmax=wmax_b, wmin=wmin_b,
                     time=time.perf_counter() - t1))
    rows[0]["scan_time"] = t_scan
    return rows


def print_table(rows: list[dict]) -> None:
    head = (f"{'part':<6} {'method':<26} {'points':>7} {'ctrl':>6} {'pos RMS':>8} {'pos max':>8} "
            f"{'n° mean':>8} {'n° p95':>7} {'n° max':>7} {'w_max mean/p95/max':>19} {'w_min mean/p95/max':>19} "
            f"{'time':>6}")
    print(head)
    print("-" * len(head))

    def trio(e):
        return f"{100 * e.mean():.1f}/{100 * np.percentile(e, 95):.1f}/{100 * e.max():.1f}%"

    for r in rows:
        print(f"{r['part']:<6} {r['method']:<26} {r['n']:>7d} {r['ctrl']:>6} {r['pos_rms'] * 1e3:>6.3f}mm "
              f"{r['pos_max'] * 1e3:>6.3f}mm {r['ang'].mean():>7.3f}° {np.percentile(r['ang'], 95):>6.3f}° "
              f"{r['ang'].max():>6.2f}° {trio(r['wmax']):>19} {trio(r['wmin']):>19} {r['time']:>5.1f}s")


def _jsonable_rows(rows: list[dict]) -> list[dict]:
    return [{k: (np.asarray(v).tolist() if isinstance(v, np.ndarray) else v) for k, v in r.items()} for r in rows]


def child_simulated(spec: dict) -> list[dict]:
    """In a child process: one simulated scan fitted (see :func:`evaluate`)."""
    truth = blade_patch() if spec["part"] == "blade" else panel_patch()
    return _jsonable_rows(evaluate(spec["part"], truth, row_spacing=spec["rs"], point_spacing=spec["ps"],
                                   sigma=spec["sigma"], row_offset=spec["offset"], n_width=3000, seed=spec["seed"],
                                   method=spec["method"]))


def child_scan(spec: dict) -> dict:
    """In a child process: ``swath fit`` (``run_fit``) on a real scan, as the command line runs it."""
    from swath.cli.fitjob import FitSettings, run_fit

    calls = []
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        doc = run_fit(FitSettings(scan=spec["scan"], out=str(Path(tmp) / "fit"), units=spec["units"]),
                      progress=lambda stage, done, total: calls.append((stage, time.perf_counter() - t0)))
    f = doc["figures"]
    stages = list(dict.fromkeys(c[0] for c in calls))
    return {"rms": f["rms_m"], "max": f["max_error_m"], "p95": f["residual_p95_m"], "all_max": f["residual_max_m"],
            "ctrl": f"{f['n_ctrl_u']}x{f['n_ctrl_v']}", "n": f["n_points"], "warnings": doc["warnings"],
            "calls": len(calls), "stages": len(stages),
            "longest_silence": float(np.max(np.diff([0.0] + [c[1] for c in calls]))), "fit_time": f["fit_time_s"]}


def run_child(kind: str, spec: dict):
    """Run ``child_<kind>(spec)`` in a fresh interpreter: ``(result, wall s, cpu s, peak RSS GiB)``."""
    import os

    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, __file__, "--child", kind, json.dumps(spec)], stdout=subprocess.PIPE,
                            text=True)
    out = proc.stdout.read()
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    if status != 0:
        raise SystemExit(f"child {kind} {spec} failed (status {status})")
    return json.loads(out.strip().splitlines()[-1]), wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 2**20


def print_resources(rows: list[dict]) -> None:
    head = (f"{'case':<34} {'points':>7} {'ctrl':>7} {'wall':>7} {'cpu':>7} {'peak RSS':>9} {'fit rms':>8} "
            f"{'fit max':>8} {'n° p95':>7} {'warnings':>8}")
    print(head)
    print("-" * len(head))
    for r in rows:
        p95 = "-" if r.get("ang") is None else f"{np.percentile(r['ang'], 95):.3f}°"
        print(f"{r['case']:<34} {r['n']:>7d} {r['ctrl']:>7} {r['wall']:>6.1f}s {r['cpu']:>6.1f}s "
              f"{r['rss']:>7.2f}GiB {r['fit_rms'] * 1e3:>6.3f}mm {r['fit_max'] * 1e3:>6.2f}mm {p95:>7} "
              f"{r['warnings']:>8}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="coarser scans (rows 4 mm, points 1 mm)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--scan", default=str(SHARED_MESHES / "bezier_dac_scan.ply"),
                    help="real scan for the swath-fit row (metres; default the shared bezier_dac_scan.ply)")
    ap.add_argument("--no-scan", action="store_true", help="skip the real scan")
    ap.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        kind, spec = args.child[0], json.loads(args.child[1])
        print(json.dumps(child_scan(spec) if kind == "scan" else child_simulated(spec)))
        return 0
    rs, ps = (4e-3, 1e-3) if args.quick else (2e-3, 0.5e-3)
    sigma, offset = 1e-4, 2e-4
    print(f"Simulated point-laser scans: rows {rs * 1e3:g} mm apart, points {ps * 1e3:g} mm apart, "
          f"noise σ = {sigma * 1e3:g} mm along the normal, row offset {offset * 1e3:g} mm per axis, "
          f"seed {args.seed}")
    print("Errors against the true surface at every scanned point; contact widths of the default pad "
          f"({Tool().pad_radius * 1e3:.1f} mm radius, {Tool().flat_depression * 1e3:g} mm depression) on 3000 of them.\n")
    t0 = time.perf_counter()
    rows, resources = [], []
    for part, method in (("blade", "rows"), ("panel", "rows"), ("panel", "projection")):
        spec = dict(part=part, method=method, rs=rs, ps=ps, sigma=sigma, offset=offset, seed=args.seed)
        got, wall, cpu, rss = run_child("simulated", spec)
        for r in got:
            for k in ("ang", "wmax", "wmin"):
                r[k] = np.asarray(r[k])
        rows += got
        resources.append(dict(got[0], case=f"{part} simulated, {method}", wall=wall, cpu=cpu, rss=rss))
    print_table(rows)
    print("\nw_max: widest swath (over feed directions) — on both parts it is the full pad diameter along the "
          "least curved direction, so it rarely moves; w_min: narrowest swath, across the most curved "
          "direction, where curvature errors show.")
    scan_ok = True
    if not args.no_scan:
        if not Path(args.scan).exists():
            print(f"\n{args.scan} not found: the real-scan row is skipped (give --scan PATH)")
        else:
            got, wall, cpu, rss = run_child("scan", dict(scan=args.scan, units="m"))
            resources.append(dict(case=f"swath fit {Path(args.scan).name}", n=got["n"], ctrl=got["ctrl"], wall=wall,
                                  cpu=cpu, rss=rss, fit_rms=got["rms"], fit_max=got["max"], ang=None,
                                  warnings=len(got["warnings"])))
            scan_ok = wall < TARGET_SCAN_TIME_S and rss < TARGET_SCAN_RSS_GIB
            print(f"\nswath fit {Path(args.scan).name}: |residual| p95 {got['p95'] * 1e3:.3g} mm, max over all "
                  f"points {got['all_max'] * 1e3:.3g} mm; {got['calls']} progress calls in {got['stages']} stages, "
                  f"longest silence {got['longest_silence']:.1f} s; warnings: {got['warnings']}")
    print("\nEach case in its own process (wall and CPU time, peak resident memory of that process):")
    print_resources(resources)
    fits = [r for r in rows if r["method"].startswith("B-spline")]
    ok_n = all(np.percentile(r["ang"], 95) < TARGET_NORMAL_P95_DEG for r in fits)
    # the contact-width target (issue 3) is for fits along the scan rows; the projection fit's is shown
    row_fits = [r for r in fits if "(rows)" in r["method"]]
    ok_w = all(max(np.percentile(r["wmax"], 95), np.percentile(r["wmin"], 95)) < TARGET_WIDTH_ERR for r in row_fits)
    print(f"\ntargets (fits): 95th-percentile normal error < {TARGET_NORMAL_P95_DEG}°: {'met' if ok_n else 'MISSED'}; "
          f"95th-percentile contact-width error (w_max and w_min) of the row fits < {100 * TARGET_WIDTH_ERR:g} %: "
          f"{'met' if ok_w else 'MISSED'}; real scan within {TARGET_SCAN_TIME_S:g} s and "
          f"{TARGET_SCAN_RSS_GIB:g} GiB: {'met' if scan_ok else 'MISSED'}")
    print(f"total {time.perf_counter() - t0:.0f} s")
    return 0 if ok_n and ok_w and scan_ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
