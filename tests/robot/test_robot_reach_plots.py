"""Reachability map and robot figures."""

import numpy as np
import pytest

from swath.examples import example_part
from swath.robot import Cell, get_robot, reachability_map, run_robot_stage


@pytest.fixture(scope="module")
def plate():
    return example_part("plate")


def test_reachability_map_splits_a_plate_at_the_reach_limit(plate):
    model = get_robot("ur10e")
    # plate spans x in [1.15, 1.55] m from the base at table height: the far part is out of a UR10e's reach
    cell = Cell.from_text("1.15,0,0,0,0,0", "0,0,100mm,0,0,0")
    rm = reachability_map(plate, model, cell, max_vertices=400, n_headings=4)
    assert len(rm.points) == 400
    assert 0.05 < rm.reachable_fraction < 0.95
    # reach falls with distance from the base: the nearest vertices are reachable, the farthest not
    dist = np.linalg.norm((cell.part2base[:3, :3] @ rm.points.T).T + cell.part2base[:3, 3], axis=1)
    order = np.argsort(dist)
    assert rm.reachable[order[:20]].all() and not rm.reachable[order[-20:]].any()
    assert np.all(rm.manipulability[rm.reachable] > 0) and np.all(rm.manipulability[~rm.reachable] == 0)
    assert np.all(np.isnan(rm.joint_limit_margin[~rm.reachable]))
    near = reachability_map(plate, model, Cell.from_text("0.5,-0.15,0,0,0,0", "0,0,100mm,0,0,0"), max_vertices=200,
                            n_headings=4)
    assert near.reachable.all()


def test_robot_figures_render(plate, tmp_path):
    from swath.contact import Tool
    from swath.plan.raster import raster
    from swath.report.robot_plots import (
        joint_plot_figure,
        reachability_figure,
        robot_png_bytes,
        write_robot_plots,
    )
    from swath.trajectory import FeedLimit, time_path

    model = get_robot("ur10e")
    cell = Cell.from_text("0.5,-0.15,0,0,0,0", "0,0,100mm,0,0,0")
    tr = time_path(raster(plate, Tool(pad_radius=0.04, force=20, depression=1e-3), spacing=0.1, point_spacing=5e-3),
                   [FeedLimit(0.1)])
    res = run_robot_stage(tr, robot=model, cell=cell, programs=[])
    fig = joint_plot_figure(res.trajectory.t, res.solution.q, model, branch=res.solution.branch)
    assert len(fig.axes) == 2 and len(fig.axes[0].lines) == 6 + 2
    png = robot_png_bytes(fig)
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    rm = reachability_map(plate, model, cell, max_vertices=100, n_headings=2)
    fig2 = reachability_figure(plate, rm, color_by="joint_limit_margin")
    assert "margin" in fig2.axes[1].get_ylabel()
    paths = write_robot_plots(tmp_path, result=res, surface=plate, reach_map=rm)
    assert set(paths) == {"joints", "reachability", "margins"} and all(p.stat().st_size > 1000 for p in paths.values())
