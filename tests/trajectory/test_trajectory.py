"""Trajectory timing, orientation and the trajectory.csv contract (FORMATS.md)."""

import numpy as np
import pytest

from swath.errors import InputError
from swath.examples import blade, flat_plate
from swath.plan import Pass, ToolPath
from swath.trajectory import CSV_COLUMNS, FeedLimit, LinkSettings, read_csv, time_path


def straight_passes(ys, x0=0.05, x1=0.35):
    ps = [Pass(np.array([[x0, y, 0.0], [x1, y, 0.0]]), np.array([[0, 0, 1.0], [0, 0, 1.0]])) for y in ys]
    return [p if i % 2 == 0 else p.reversed() for i, p in enumerate(ps)]


def test_constant_feed_orientation_and_sampling_limits():
    s = flat_plate()
    tr = time_path(ToolPath(s, straight_passes([0.05, 0.12]), "test"), [FeedLimit(0.05)])
    c = tr.contact
    both = c[1:] & c[:-1]
    step = np.linalg.norm(np.diff(tr.position, axis=0), axis=1)
    dt = np.diff(tr.t)
    assert step[both].max() <= 2e-3 and dt[both].max() <= 0.02
    assert np.allclose(step[both] / dt[both], 0.05)
    # tool z into the part (−normal), x along the feed, y = z × x
    z, x = tr.tool_z(), tr.tool_x()
    assert np.allclose(z[c], [0, 0, -1], atol=1e-9)
    first = tr.pass_index == 0
    second = tr.pass_index == 1
    assert np.allclose(x[first], [1, 0, 0], atol=1e-9) and np.allclose(x[second], [-1, 0, 0], atol=1e-9)
    assert np.allclose(np.linalg.norm(tr.quaternion, axis=1), 1.0)
    # contact length is the sum of the passes; cycle time = contact time + link time
    assert tr.contact_length == pytest.approx(0.6, rel=1e-9)
    assert tr.duration > 0.6 / 0.05
    # starts and ends above the part, not in contact
    assert not c[0] and not c[-1]
    assert tr.position[0, 2] == pytest.approx(0.02) and tr.position[-1, 2] == pytest.approx(0.02)


def test_air_moves_keep_clear_of_the_part():
    b = blade()
    # put pass points on the surface: project
    p, _, f = b.closest_points(np.array([[0.2, 0.1, 0.05], [0.2, 0.2, 0.05], [0.1, 0.3, -0.05], [0.1, 0.4, -0.05]]))
    n = b.interpolate_normals(p, f)
    passes = [Pass(p[:2], n[:2]), Pass(p[2:], n[2:])]  # upper surface, then lower surface: must go round
    tr = time_path(ToolPath(b, passes, "test"), links=LinkSettings(clearance=0.02))
    air = ~tr.contact
    _, dist, _ = b.closest_points(tr.position[air])
    away = dist > 1e-6
    # away from the pass ends (approach/retract), the tool stays at least half the clearance off
    mid = air.copy()
    mid[air] = dist >= 0.0099
    assert mid.sum() > 0.5 * air.sum()
    assert dist[away].min() >= 0  # sanity
    lifted = tr.position[air][dist > 0.0199]
    assert len(lifted) > 10
    # nowhere does the path dip into the part between lift-off and touch-down
    inner = np.flatnonzero(air)[5:-5]
    _, d_inner, _ = b.closest_points(tr.position[inner])
    assert d_inner.min() > 1e-3


def test_csv_round_trip_and_header(tmp_path):
    s = flat_plate()
    tr = time_path(ToolPath(s, straight_passes([0.1]), "test"))
    path = tmp_path / "trajectory.csv"
    tr.write_csv(path)
    header = path.read_text().splitlines()[0].split(",")
    assert tuple(header[:9]) == CSV_COLUMNS and header[9:] == ["feed", "pass", "wx", "wy", "wz"]
    back = read_csv(path)
    assert np.allclose(back.t, tr.t, atol=1e-6)
    assert np.allclose(back.position, tr.position, atol=1e-7)
    assert np.array_equal(back.contact, tr.contact)
    assert not list(tmp_path.glob("*.part"))


def test_time_path_refuses_empty_and_bad_feed():
    s = flat_plate()
    with pytest.raises(InputError, match="no passes"):
        time_path(ToolPath(s, [], "test"))
    with pytest.raises(InputError, match="feed must be a positive"):
        FeedLimit(-1.0)


def test_densifies_sparse_passes_onto_the_surface():
    b = blade()
    # two points far apart on the upper surface: densified samples must lie on the surface
    p, _, f = b.closest_points(np.array([[0.05, 0.3, 0.05], [0.35, 0.3, 0.05]]))
    tr = time_path(ToolPath(b, [Pass(p, b.interpolate_normals(p, f))], "test"))
    _, d, _ = b.closest_points(tr.position[tr.contact])
    assert d.max() < 1e-4
