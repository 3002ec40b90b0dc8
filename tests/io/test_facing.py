"""A part whose normals point away from a tool coming from above is found and the fix named."""

import json
import logging

import numpy as np
import pytest

from conftest import SHARED_MESH_UNITS, shared_mesh
from swath.examples import PARTS, example_part, flat_plate
from swath.io.facing import facing_shares, facing_warning
from swath.io.mesh import load_mesh, save_surface_ply
from swath.surface import Surface


def flipped(surface, name):
    return Surface(surface.vertices, surface.faces[:, ::-1], name=name)


def test_a_flat_plate_faces_up_and_its_flipped_copy_down():
    plate = flat_plate()
    assert facing_shares(plate) == pytest.approx((1.0, 0.0, 1.0))
    assert facing_warning(plate) is None
    down = flipped(plate, "plate_down")
    assert facing_shares(down) == pytest.approx((0.0, 1.0, -1.0))
    msg = facing_warning(down)
    assert msg.startswith("plate_down faces away") and "100 % of its area faces down and 0 % up" in msg
    assert "--side +z" in msg and "--side -z" in msg
    assert facing_warning(down, side="-z") is None                  # the user said so
    assert facing_warning(down, up=(0, 0, -1)) is None              # a table upside down


@pytest.mark.parametrize("name", sorted(PARTS))
def test_the_built_in_examples_face_the_tool(name):
    assert facing_warning(example_part(name)) is None


def test_a_part_facing_both_ways_as_much_is_not_flagged():
    # a roof: two planes at ±60 deg from up, one of them flipped: the mean normal is level
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float)
    plate = Surface(v, np.array([[0, 1, 2], [1, 3, 2]]))
    down = Surface(v + [0, 0, -1], np.array([[0, 2, 1], [1, 2, 3]]))
    both = Surface(np.vstack([plate.vertices, down.vertices]), np.vstack([plate.faces, down.faces + 4]))
    assert facing_shares(both) == pytest.approx((0.5, 0.5, 0.0))
    assert facing_warning(both) is None


def test_the_flipped_shared_cad_mesh_warns_on_loading_and_side_fixes_it(tmp_path, caplog):
    name = "bezier_dac_cad.ply"
    cad = load_mesh(shared_mesh(name), units=SHARED_MESH_UNITS[name])
    up, down, mean = facing_shares(cad)
    assert up == pytest.approx(1.0) and down == 0.0 and mean == pytest.approx(0.889, abs=0.005)
    path = tmp_path / "cad_flipped.ply"
    save_surface_ply(flipped(cad, "cad_flipped"), path)
    with caplog.at_level(logging.WARNING, logger="swath.io"):
        bad = load_mesh(path)
    assert facing_shares(bad)[2] == pytest.approx(-mean, abs=1e-6)
    assert "cad_flipped faces away from a tool coming from above" in caplog.text and "--side +z" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="swath.io"):
        good = load_mesh(path, side="+z")
    assert facing_shares(good)[2] == pytest.approx(mean, abs=1e-6) and "faces away" not in caplog.text


def test_swath_plan_names_the_fix_for_a_plate_facing_down(tmp_path):
    from swath.cli.main import main

    path = tmp_path / "plate_down.ply"
    save_surface_ply(flipped(flat_plate(), "plate_down"), path)
    assert main(["-q", "plan", "--constant-feed", str(path), "--out", str(tmp_path / "a")]) == 0
    warnings = json.loads((tmp_path / "a" / "metrics.json").read_text())["metrics"]["warnings"]
    assert warnings[0].startswith("plate_down faces away") and "--side +z" in warnings[0]
    assert main(["-q", "plan", "--constant-feed", str(path), "--side", "+z", "--out", str(tmp_path / "b")]) == 0
    warnings = json.loads((tmp_path / "b" / "metrics.json").read_text())["metrics"]["warnings"]
    assert not any("faces away" in w for w in warnings)
