"""Curvature-based resampling of scan rows (Jaeger §3.2.3): the distribution function, where the
resampled points fall, and a fit of resampled rows."""

import numpy as np
import pytest

from swath.errors import InputError
from swath.examples.scansim import blade_patch, simulate_laser_scan
from swath.scan import fit_patch, resample_rows, row_distribution


def test_row_distribution_is_jaegers_function():
    s = np.linspace(0.0, 2.0, 200001)
    # κ² = K on [0, a) and 0 beyond: R(s) = q min(s, a)/a + (1 - q) s/L
    a, q, L = 0.5, 0.6, 2.0
    R = row_distribution(s, np.where(s < a, 10.0, 0.0), q)
    np.testing.assert_allclose(R, q * np.minimum(s, a) / a + (1 - q) * s / L, atol=1e-4)
    np.testing.assert_allclose(row_distribution(s, np.zeros_like(s), q), s / L)     # straight: even steps
    np.testing.assert_allclose(row_distribution(s, np.full_like(s, 3.0), q), s / L)  # even bend: even steps


def line_and_arc(n_rows=4, step=0.5e-3, line=0.1, radius=0.02, sweep=np.pi / 2):
    """Rows that run straight for ``line`` m, then bend round a circle of ``radius`` by ``sweep``;
    rows 5 mm apart along z.  Returns (points, rows)."""
    s = np.arange(0.0, line + radius * sweep, step)
    on_arc = s > line
    t = (s - line) / radius
    x = np.where(on_arc, line + radius * np.sin(t), s)
    y = np.where(on_arc, radius * (1 - np.cos(t)), 0.0)
    pts = [np.stack([x, y, np.full_like(s, 5e-3 * r)], axis=1) for r in range(n_rows)]
    return np.concatenate(pts), np.repeat(np.arange(n_rows), len(s))


def test_resampled_points_stay_on_the_row_and_crowd_into_the_bend():
    P, R = line_and_arc()
    line, radius, sweep = 0.1, 0.02, np.pi / 2
    q = 0.5
    new, rows = resample_rows(P, R, q=q, window=7)
    assert len(new) == len(P) and np.array_equal(np.unique(rows), np.unique(R))
    # on the curve: the straight part (y = 0) or the circle about (line, radius)
    on_line = new[:, 0] <= line
    err = np.where(on_line, np.abs(new[:, 1]),
                   np.abs(np.hypot(new[:, 0] - line, new[:, 1] - radius) - radius))
    # within 10 µm (a tenth of a laser's noise): a local quadratic over 3 mm cannot follow the jump
    # in curvature where the line meets the arc exactly
    assert err.max() < 1e-5 and np.median(err) < 1e-7
    # R(s) at the start of the bend is (1 - q) line / L: the share of samples left on the line
    length = line + radius * sweep
    share = on_line.mean()
    assert share == pytest.approx((1 - q) * line / length, abs=0.02)
    assert share < 0.5 * line / length + 0.02 < line / length          # evenly spaced would leave 76 %


def test_resample_rows_refuses_bad_input():
    P, R = line_and_arc()
    with pytest.raises(InputError, match="q in"):
        resample_rows(P, R, q=1.0)
    with pytest.raises(InputError, match=r"\(n, 3\) points"):
        resample_rows(P[:, :2], R)


def test_a_fit_of_resampled_rows_of_a_point_laser_scan_meets_the_normal_target():
    """The blade scanned round its leading edge (σ 0.1 mm, 0.2 mm row offsets), rows resampled,
    then skinned: the normals agree with the analytic blade within 0.5 deg at the 95th percentile."""
    rng = np.random.default_rng(7)
    truth = blade_patch(span=0.12)
    scan = simulate_laser_scan(truth, row_spacing=3e-3, point_spacing=0.75e-3, sigma=1e-4, row_offset=2e-4,
                               rng=rng)
    P, R = resample_rows(scan.points, scan.rows)
    patch, report = fit_patch(P, rows=R)
    u, v, dist = patch.project(scan.true_points)
    ang = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", patch.normals(u, v), scan.true_normals), -1, 1)))
    assert np.percentile(ang, 95) < 0.5
    assert np.sqrt(np.mean(dist**2)) < 1e-4
