"""Small closed loops the uniform planner keeps whole (a pocket's level set) are crossed straight:
run as a loop, the tool turns a full circle about its axis and dwells on one spot."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from swath.contact import Tool
from swath.plan.uniform_passes import LOOP_CHORD_EXTENT, _chord_if_small_loop, turn_curvature

TOOL = Tool()
R = TOOL.pad_radius
STEP = 1e-3


def flat_ctx(hole: float = 0.0):
    """The little of a working-mesh context the chord needs: the pad, a plate z = 0 meshed 2 mm apart
    round (0.1, 0.2) (its vertices' tree), with a hole of radius ``hole`` there, and dropping points
    onto it."""
    from scipy.spatial import cKDTree

    spacing = 2e-3
    g = np.arange(-0.1, 0.1 + 1e-9, spacing)
    xy = np.stack(np.meshgrid(0.1 + g, 0.2 + g, indexing="ij"), -1).reshape(-1, 2)
    xy = xy[np.linalg.norm(xy - [0.1, 0.2], axis=1) >= hole]

    def project(points):
        out = np.array(points, float)
        out[:, 2] = 0.0
        return out, np.tile([0.0, 0.0, 1.0], (len(out), 1))
    return SimpleNamespace(tool=TOOL, project=project, work_spacing=spacing,
                           tree=cKDTree(np.column_stack([xy, np.zeros(len(xy))])))


def ellipse(a, b, centre=(0.1, 0.2), n=None):
    n = n or max(16, int(2 * math.pi * max(a, b) / STEP))
    t = np.linspace(0.0, 2 * math.pi, n)
    return np.stack([centre[0] + a * np.cos(t), centre[1] + b * np.sin(t), np.zeros(n)], axis=1)


def test_a_small_loop_becomes_the_straight_pass_across_its_middle():
    loop = ellipse(8e-3, 3e-3)                         # 16 mm x 6 mm, well inside a 38.1 mm radius
    line = _chord_if_small_loop(flat_ctx(), loop, STEP, min_length=0.25 * R)
    assert len(line) >= 3 and np.allclose(line[:, 2], 0.0)
    # straight along the loop's long axis (x), through its middle, as long as the loop
    assert np.ptp(line[:, 1]) < 1e-9 and np.allclose(line[:, 1], 0.2)
    assert line[:, 0].min() == pytest.approx(0.1 - 8e-3, abs=2e-4)
    assert line[:, 0].max() == pytest.approx(0.1 + 8e-3, abs=2e-4)
    # it does not turn the tool (the loop turns it a full circle)
    normals = np.tile([0.0, 0.0, 1.0], (len(line), 1))
    assert turn_curvature(line, normals, R / 8).max() < 1e-6
    assert turn_curvature(loop, np.tile([0.0, 0.0, 1.0], (len(loop), 1)), R / 8).min() > 50.0
    # a pad at any point of it covers the whole loop
    assert np.max(np.linalg.norm(loop[:, None, :2] - line[None, :, :2], axis=2).min(axis=1)) < R


def test_a_tiny_loop_gets_a_pass_of_the_shortest_length_kept():
    line = _chord_if_small_loop(flat_ctx(), ellipse(1.5e-3, 1.5e-3), STEP, min_length=0.25 * R)
    length = float(np.linalg.norm(np.diff(line, axis=0), axis=1).sum())
    assert length == pytest.approx(0.25 * R, rel=0.02)
    assert np.linalg.norm(line.mean(axis=0)[:2] - [0.1, 0.2]) < 1e-4


def test_wide_loops_and_open_pieces_are_kept_as_they_are():
    ctx = flat_ctx()
    wide = ellipse(0.6 * LOOP_CHORD_EXTENT * R, 0.2 * R)        # 1.2 R across: over the limit
    assert _chord_if_small_loop(ctx, wide, STEP, 0.25 * R) is wide
    arc = ellipse(8e-3, 3e-3)[:-10]                            # an open arc of the small loop
    assert _chord_if_small_loop(ctx, arc, STEP, 0.25 * R) is arc


def test_a_loop_round_a_hole_is_kept():
    # a 16 mm x 12 mm loop round a 10 mm hole: its chord would run over the hole
    loop = ellipse(8e-3, 6e-3)
    assert _chord_if_small_loop(flat_ctx(hole=5e-3), loop, STEP, 0.25 * R) is loop
    assert _chord_if_small_loop(flat_ctx(hole=0.0), loop, STEP, 0.25 * R) is not loop


def test_the_scan_with_a_hole_is_planned_without_loops_that_hold_the_tool():
    """noether_wavy_mesh_with_hole at the default job's least-ripple overlap (0.311) and direction
    (150 deg): its last generations were six loops 2-17 mm across; timed at 50 mm/s under 1 rad/s,
    each held the tool at about 2 mm/s for 4 s."""
    from conftest import SHARED_MESH_UNITS, shared_mesh
    from swath.io.mesh import load_mesh
    from swath.plan.uniform import uniform
    from swath.plan.uniform_passes import _is_closed
    from swath.trajectory import AngularSpeedLimit, FeedLimit, time_path

    name = "noether_wavy_mesh_with_hole.ply"
    surface = load_mesh(shared_mesh(name), units=SHARED_MESH_UNITS[name])
    tp = uniform(surface, TOOL, overlap=0.311, direction=math.radians(150.0), workers=1)
    small_loops = [p for p in tp.passes if len(p.points) > 3 and _is_closed(p.points)
                   and np.ptp(p.points, axis=0).max() <= R]
    assert not small_loops
    assert tp.metadata["predicted_coverage_fraction"] > 0.99
    tr = time_path(tp, [FeedLimit(0.05), AngularSpeedLimit(1.0)])
    live = tr.contact & (tr.pass_index >= 0)
    dt = np.diff(tr.t, append=tr.t[-1])
    crawl = live & (tr.feed < 0.005)
    assert dt[crawl].sum() < 0.02 * dt[live].sum()       # under 2 % of the contact time below 5 mm/s
