"""The area to finish: --faces by id/name/colour/box, keep-outs honoured by the passes and judged
by the simulation, the edge margin."""

from __future__ import annotations

import numpy as np
import pytest

from swath.core.toolpath import Pass, ToolPath
from swath.errors import InputError
from swath.io.part import Part, PartFace
from swath.segment.select import area_metrics, keep_clear, parse_selection, select, work_surface
from swath.surface import Surface


def _plate_part(n: int = 41, size: float = 0.2) -> Part:
    """A flat square plate in z = 0 (normals +z) whose left half (x < 0) is face 1 'left', right half
    face 2 'right' (coloured red)."""
    x = np.linspace(-size / 2, size / 2, n)
    xx, yy = np.meshgrid(x, x, indexing="ij")
    v = np.column_stack([xx.ravel(), yy.ravel(), np.zeros(n * n)])
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    f = np.vstack([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    s = Surface(v, f, name="plate")
    centroid = v[f].mean(axis=1)
    ids = np.where(centroid[:, 0] < 0, 1, 2)
    faces = (PartFace(1, "left", "plane", None, float(s.face_areas[ids == 1].sum())),
             PartFace(2, "right", "plane", "#ff0000", float(s.face_areas[ids == 2].sum())))
    return Part(s, ids, faces)


def test_selection_by_id_name_colour_and_box():
    part = _plate_part()
    left = part.face_ids == 1
    np.testing.assert_array_equal(parse_selection(part, "1"), left)
    np.testing.assert_array_equal(parse_selection(part, "left"), left)
    np.testing.assert_array_equal(parse_selection(part, "#FF0000"), ~left)
    np.testing.assert_array_equal(parse_selection(part, "left,2"), np.ones_like(left))
    box = parse_selection(part, "box:-100mm,-100mm,-1mm,-50mm,100mm,1mm")
    centroid = part.surface.vertices[part.surface.faces].mean(axis=1)
    np.testing.assert_array_equal(box, centroid[:, 0] <= -0.05)
    both = parse_selection(part, "right; box:-0.1,-0.1,-0.001,-0.05,0.1,0.001")
    np.testing.assert_array_equal(both, ~left | (centroid[:, 0] <= -0.05))


@pytest.mark.parametrize("text, message", [
    ("7", "no face 7; its faces are 1..2"),
    ("middle", "face names: left, right"),
    ("#00ff00", "colours: #ff0000"),
    ("box:0,0,0,1,1", "six lengths"),
    ("box:0,0,0,-1,1,1", "maxima must exceed"),
    ("box:1,1,1,2,2,2", "selects no triangle"),
])
def test_bad_selections_are_refused_naming_the_fix(text, message):
    with pytest.raises(InputError, match=message):
        parse_selection(_plate_part(), text)


def test_keep_outs_covering_the_selection_are_refused():
    with pytest.raises(InputError, match="nothing is left"):
        select(_plate_part(), faces="left", keep_out="1")


def test_work_surface_is_the_selection_minus_the_keep_outs():
    part = select(_plate_part(), keep_out="right")
    work = work_surface(part)
    assert work.area == pytest.approx(part.faces[0].area, rel=1e-12)
    assert work.vertices[:, 0].max() <= 1e-12


def test_keep_clear_cuts_passes_where_the_pad_would_reach_a_keep_out():
    part = select(_plate_part(), keep_out="right", keep_out_margin=0.002)
    x = np.linspace(-0.1, 0.1, 201)
    crossing = Pass(np.column_stack([x, np.zeros_like(x), np.zeros_like(x)]), np.tile([0, 0, 1.0], (len(x), 1)))
    far = Pass(np.column_stack([np.full(50, -0.08), np.linspace(-0.05, 0.05, 50), np.zeros(50)]),
               np.tile([0, 0, 1.0], (50, 1)))
    tp = ToolPath(part.surface, (crossing, far), "test")
    out = keep_clear(tp, part, pad_radius=0.02)
    assert len(out.passes) == 2
    kept = out.passes[0].points
    # the pad (20 mm) + margin (2 mm) stays off the keep-out half x >= 0
    assert kept[:, 0].max() < -0.022 + 1e-12
    assert kept[:, 0].max() > -0.022 - 1.5e-3        # cut no farther than the next pass point
    np.testing.assert_array_equal(out.passes[1].points, far.points)
    assert out.metadata["passes_cut"] == 1
    assert out.metadata["keep_out_clearance_m"] == pytest.approx(0.022)


def test_edge_margin_keeps_the_pad_centre_in_from_the_open_edge():
    part = select(_plate_part(), edge_margin=0.01)
    x = np.linspace(-0.1, 0.1, 201)
    tp = ToolPath(part.surface, (Pass(np.column_stack([x, np.zeros_like(x), np.zeros_like(x)]),
                                      np.tile([0, 0, 1.0], (len(x), 1))),), "test")
    kept = keep_clear(tp, part, pad_radius=0.02).passes[0].points
    # the plate's vertices are 5 mm apart: the margin is judged against them
    assert kept[:, 0].min() > -0.09 - 1e-9 and kept[:, 0].max() < 0.09 + 1e-9
    assert kept[:, 0].min() < -0.085


def test_area_metrics_split_removal_between_selection_keep_out_and_the_rest():
    part = select(_plate_part(), faces="left", keep_out="box:0.05,-0.1,-0.001,0.1,0.1,0.001")
    v = part.surface.vertices
    areas = np.full(len(v), 1.0)
    depth = np.where(v[:, 0] < -0.05, 1e-6, 0.0) + np.where(v[:, 0] > 0.075, 2e-6, 0.0)
    m = area_metrics(part, v, areas, depth)
    _, _, tri = part.surface.closest_points(v)
    in_left = part.work_triangles[tri]
    assert m["selected_area_m2"] == in_left.sum()
    assert m["selected_coverage_fraction"] == pytest.approx((in_left & (v[:, 0] < -0.05)).sum() / in_left.sum())
    assert m["keep_out_max_removal_m"] == pytest.approx(2e-6)
    assert m["keep_out_touched_area_m2"] > 0


@pytest.fixture(scope="module")
def tube_step(tmp_path_factory):
    pytest.importorskip("OCP")
    from swath.examples import cad

    shape = cad.tube_with_flange()
    path = tmp_path_factory.mktemp("cad") / "tube.step"
    return cad.write_step(shape, path, names=cad.tube_face_names(shape))


@pytest.mark.slow
def test_keep_out_face_gets_no_removal_while_its_neighbour_is_covered(tube_step):
    """The must-show: tube_outer finished, the flange's top face kept out; the simulation on the
    whole part (every face present) finds zero removal on the flange top and the tube covered
    beyond the pad's clearance band."""
    from swath.cli.job import load_part_info, make_plan
    from swath.cli.settings import settings_from_mapping
    from swath.simulate import simulate_removal
    from swath.trajectory import time_path

    pad = 0.02
    settings = settings_from_mapping({"part": str(tube_step), "out": "unused", "faces": "tube_outer",
                                      "keep_out": "flange_top", "pad_radius": pad, "chordal_tol": 3e-4,
                                      "keep_out_margin": 0.002})
    surface, info = load_part_info(settings)
    part = info["part"]
    toolpath = make_plan(surface, settings, part=part)
    trajectory = time_path(toolpath, settings.constraints(), links=settings.links())
    removal = simulate_removal(trajectory, part.surface, settings.tool(), sample_spacing=3e-3)
    m = area_metrics(part, removal.surface.vertices, removal.surface.vertex_areas, removal.depth)
    assert m["keep_out_area_m2"] == pytest.approx(np.pi * (0.09**2 - 0.05**2), rel=1e-2)
    assert m["keep_out_max_removal_m"] == 0.0
    assert m["keep_out_touched_area_m2"] == 0.0
    # the neighbour: the tube's outer face beyond the clearance band (pad + margin from the flange)
    v = removal.surface.vertices
    _, _, tri = part.surface.closest_points(v)
    tube_outer = next(f.id for f in part.faces if f.name == "tube_outer")
    beyond = (part.face_ids[tri] == tube_outer) & (v[:, 2] > 0.01 + pad + 0.002 + 0.003)
    a = removal.surface.vertex_areas
    assert a[beyond & (removal.depth > 0)].sum() / a[beyond].sum() >= 0.99
