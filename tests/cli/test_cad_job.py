"""A job on a STEP part: what it plans on, what it refuses, and the new keys."""

from __future__ import annotations

import numpy as np
import pytest

from swath.cli.settings import settings_from_mapping
from swath.errors import InputError

pytest.importorskip("OCP")

from swath.cli.job import load_part_info  # noqa: E402
from swath.examples import cad  # noqa: E402


@pytest.fixture(scope="module")
def tube_step(tmp_path_factory):
    shape = cad.tube_with_flange()
    path = tmp_path_factory.mktemp("cad") / "tube.step"
    return cad.write_step(shape, path, names=cad.tube_face_names(shape), colours={1: (0.0, 0.0, 1.0)})


def _settings(part, **values):
    return settings_from_mapping({"part": str(part), "out": "unused", "chordal_tol": "0.3mm", **values})


def test_a_closed_solid_needs_faces_or_a_side(tube_step):
    with pytest.raises(InputError, match="closed solid; pick the area to finish with --faces"):
        load_part_info(_settings(tube_step))


def test_side_keeps_the_faces_facing_it(tube_step):
    surface, info = load_part_info(_settings(tube_step, side="+z"))
    names = {f.name for f in info["part"].faces if f.id in info["metrics"]["selected_faces"]}
    assert names == {"flange_top", "tube_end"}
    assert (surface.face_normals[:, 2] > 0.999).all()


def test_faces_by_colour_and_keep_out_by_box(tube_step):
    surface, info = load_part_info(_settings(tube_step, faces="#0000ff", keep_out="box:0,-0.1,0,0.1,0.1,0.02"))
    part = info["part"]
    assert info["metrics"]["selected_faces"] == [2]                 # the blue flange top
    assert np.allclose(surface.vertices[:, 2], 0.01)
    centroid = surface.vertices[surface.faces].mean(axis=1)
    assert (centroid[:, 0] < 1e-9).all()                            # the box took the x > 0 half out
    assert part.keep_out.any() and part.keep_out_margin == pytest.approx(0.002)


def test_new_keys_parse_with_units():
    s = settings_from_mapping({"part": "p.step", "out": "o", "keep_out_margin": "5mm", "edge_margin": "3mm",
                               "chordal_tol": "0.05mm", "faces": "1,2", "keep_out": "bore", "side": "all"})
    assert (s.keep_out_margin, s.edge_margin, s.chordal_tol) == pytest.approx((5e-3, 3e-3, 5e-5))
    assert s.side == "all"


def test_side_all_refuses_an_open_example(tmp_path):
    from swath.cli.job import run_job

    with pytest.raises(InputError, match="closed part"):
        run_job(settings_from_mapping({"part": "example:plate", "out": str(tmp_path / "o"), "side": "all"}))


def test_regions_on_a_step_part_polygon_and_mask(tube_step, tmp_path):
    """A window drawn across the tube (polygon projected along +x, y-z coordinates) kept out of
    tube_outer, and a closed mask box (mm) selecting the tube's x < 0 half."""
    import trimesh

    window = "polygon[along=+x]:-30mm,100mm 30mm,100mm 30mm,160mm -30mm,160mm"
    surface, info = load_part_info(_settings(tube_step, faces="tube_outer", keep_out=window))
    part = info["part"]
    c = part.surface.vertices[part.surface.faces].mean(axis=1)
    inside = (np.abs(c[:, 1]) < 0.03) & (c[:, 2] > 0.1) & (c[:, 2] < 0.16)
    np.testing.assert_array_equal(part.keep_out, inside)             # every layer the prism crosses
    outer = next(f.id for f in part.faces if f.name == "tube_outer")
    np.testing.assert_array_equal(part.work_triangles, (part.face_ids == outer) & ~inside)
    box = trimesh.creation.box(extents=(200.0, 400.0, 400.0))
    box.apply_translation((-100.0, 0.0, 150.0))
    box.export(tmp_path / "half_mm.stl")
    _, info = load_part_info(_settings(tube_step, faces=f"mask[units=mm]:{tmp_path / 'half_mm.stl'}"))
    part = info["part"]
    # inside the box, or within the default 1 mm of its x = 0 face
    np.testing.assert_array_equal(part.selected, c[:, 0] <= 1e-3)
    assert part.surface.face_areas[part.selected].sum() == pytest.approx(0.5 * part.surface.area, rel=0.02)
