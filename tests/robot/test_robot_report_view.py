"""The robot in the report: the arm at a few poses, its reach, the skipped stretches, the margins plot."""

import numpy as np
import pytest

from swath.report.robot_plots import margins_figure, robot_traces
from swath.robot import Cell, run_robot_stage


@pytest.fixture(scope="module")
def far_result(plate_trajectory):
    cell = Cell.from_text("1.0,-0.15,0,0,0,0", "0,0,150mm,0,0,0")
    return run_robot_stage(plate_trajectory, robot="ur10e", cell=cell, programs=[], warn=False)


def test_robot_traces_are_in_the_part_frame(far_result):
    r = far_result
    traces = {t.name.split(":")[0]: t for t in robot_traces(r)}
    arm = traces["ur10e at 3 poses"]
    xyz = np.array([[np.nan if v is None else v for v in getattr(arm, a)] for a in "xyz"]).T
    polylines = np.split(xyz, np.flatnonzero(np.isnan(xyz[:, 0])))
    polylines = [p[np.isfinite(p[:, 0])] for p in polylines if np.isfinite(p[:, 0]).any()]
    assert len(polylines) == 3
    # each starts at the robot base (the base origin seen from the part: x = -1.0 m, y = +0.15 m) ...
    for p in polylines:
        np.testing.assert_allclose(p[0], [-1.0, 0.15, 0.0], atol=1e-12)
    # ... and ends on the TCP of a reached contact sample of the trajectory the robot runs
    tcp = np.array([p[-1] for p in polylines])
    d = np.linalg.norm(r.trajectory.position[None] - tcp[:, None], axis=2).min(axis=1)
    assert d.max() < 1e-9
    # the gaps: exactly the dropped samples of the planned trajectory
    gap = traces["not reached"]
    n_points = sum(v is not None for v in gap.x)
    assert n_points == sum(g.stop - g.start for g in r.gaps) > 0
    # the reach ring: radius reach + TCP offset (1.30 + 0.15 m) about the base axis
    ring = traces["reach (horizontal, TCP)"]
    rad = np.hypot(np.asarray(ring.x) + 1.0, np.asarray(ring.y) - 0.15)
    np.testing.assert_allclose(rad, 1.45, atol=1e-9)


def test_margins_figure_marks_the_minimum(far_result):
    r = far_result
    fig = margins_figure(r.trajectory.t, r.solution.measures, r.trajectory.contact)
    axes = fig.axes
    assert len(axes) == 3
    texts = [t.get_text() for t in axes[0].texts]
    assert texts == [f"min {np.nanmin(r.solution.measures['manipulability']):.3g}"]
    margin_deg = np.degrees(np.nanmin(r.solution.measures["joint_limit_margin_rad"]))
    assert [t.get_text() for t in axes[2].texts] == [f"min {margin_deg:.3g}"]
