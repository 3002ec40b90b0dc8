"""The cell in the report's 3D view: table, fixtures and collision marks in the part frame."""

import numpy as np

from swath.cell import Body, Box, Cell, Cylinder, Table, parse_pose
from swath.report.cell_view import cell_traces


def test_cell_traces_are_drawn_in_the_part_frame():
    # the part 1 m ahead of the base, turned 90 deg: base x is the part's -y
    cell = Cell(part2base=parse_pose("1,0,-0.2,0,0,90deg"),
                table=Table(top_z=-0.2, centre_xy=(1.0, 0.0), size_xy=(3.0, 3.0), assumed=True),
                fixtures=(Body("fixture clamp", Box((0.1, 0.2, 0.3)), parse_pose("1.5,0,0,0,0,0")),
                          Body("fixture pin", Cylinder(0.01, 0.1), parse_pose("1,0.3,-0.15,0,0,0"))))
    part = np.array([[0, 0, 0], [0.4, 0.3, 0.05]])
    hit = {"point_part_m": [0.1, 0.2, 0.0], "body_a": "tool spindle", "body_b": "fixture clamp", "pass": 3,
           "t_start_s": 12.5}
    table, clamp, pin, marks = cell_traces(cell, [hit], part_vertices=part)
    assert table.name == "table (assumed)"
    z = np.asarray(table.z)
    assert abs(z.max()) < 1e-12                                         # the top at the part's z = 0
    assert np.asarray(table.x).min() >= -0.15 - 1e-12 and np.asarray(table.x).max() <= 0.55 + 1e-12   # cut
    # the clamp's centre, base (1.5, 0, 0): 0.5 m along base x = part -y, 0.2 m above the part origin
    centre = np.mean(np.column_stack([clamp.x, clamp.y, clamp.z]), axis=0)
    np.testing.assert_allclose(centre, [0, -0.5, 0.2], atol=1e-12)
    # box edges turn with the frame: 0.1 m along base x spans part y
    assert abs(np.ptp(clamp.y) - 0.1) < 1e-12
    np.testing.assert_allclose(np.mean(np.column_stack([pin.x, pin.y, pin.z]), axis=0)[:2], [0.3, 0], atol=1e-3)
    np.testing.assert_allclose([marks.x[0], marks.y[0], marks.z[0]], hit["point_part_m"])
    assert "tool spindle hits fixture clamp" in marks.text[0] and "pass 3" in marks.text[0]


def test_report_3d_view_takes_the_cell(tmp_path):
    from swath.examples import example_part
    from swath.report.html import figure_3d

    plate = example_part("plate")
    cell = Cell(fixtures=(Body("fixture far", Box((0.1, 0.1, 0.1)), parse_pose("2,0,0,0,0,0")),))
    far = {"point_part_m": [2.0, 0.0, 0.0], "body_a": "robot link 3", "body_b": "fixture far", "pass": -1,
           "t_start_s": 1.0}
    fig = figure_3d(plate, scene_traces=cell_traces(cell, [far], part_vertices=plate.vertices))
    names = [t.name for t in fig.data]
    assert "fixture far" in names and "collisions" in names
    assert fig.layout.scene.xaxis.range[1] >= 2.0                       # the view takes in the mark
