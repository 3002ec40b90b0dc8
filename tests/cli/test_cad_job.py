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
