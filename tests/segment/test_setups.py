"""Closed parts all round: setups that expose every face, and a whole-surface coverage check."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("OCP")

from swath.examples import cad  # noqa: E402
from swath.io.step import load_step  # noqa: E402
from swath.segment.setups import exposure, plan_setups  # noqa: E402


@pytest.fixture(scope="module")
def cad_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("closed")
    cad.write_step(cad.capped_cylinder(), d / "capped_cylinder.step")
    cad.write_step(cad.rounded_box(), d / "rounded_box.step")
    return d


@pytest.mark.parametrize("name, n_faces, n_setups", [("capped_cylinder", 3, 3), ("rounded_box", 26, 4)])
def test_setups_expose_every_face_and_report_their_faces(cad_dir, name, n_faces, n_setups):
    part = load_step(cad_dir / f"{name}.step", chordal_tolerance=3e-4)
    assert part.closed and len(part.faces) == n_faces
    setups = plan_setups(part, overlap=0.02)
    assigned = np.zeros(len(part.face_ids), bool)
    for s in setups:
        assert not (assigned & s.assigned).any()             # each triangle belongs to one setup
        assigned |= s.assigned
        # every assigned triangle faces its setup within 75 degrees
        assert (part.surface.face_normals[s.assigned] @ s.up >= np.cos(np.radians(75)) - 1e-12).all()
        assert set(s.faces) == {int(i) for i in part.face_ids[s.assigned]}
        assert (s.planned >= s.assigned).all() and s.planned.sum() > s.assigned.sum()
    assert assigned.all()
    assert {i for s in setups for i in s.faces} == {f.id for f in part.faces}
    # the fewest: a cylinder's side needs three directions (each sees less than half of it within
    # 75°), and every normal of the rounded box lies within 70.5° of one of four tetrahedral corner
    # directions, while no three candidates expose both its faces and its rounded edges
    assert len(setups) == n_setups
    # no candidate direction alone exposes the part
    assert not any(exposure(part, s.up).all() for s in setups)


@pytest.mark.slow
def test_capped_cylinder_all_round_covers_the_whole_outer_surface(cad_dir, tmp_path):
    from swath.cli.job import run_job
    from swath.cli.settings import settings_from_mapping

    out = tmp_path / "out"
    settings = settings_from_mapping({"part": str(cad_dir / "capped_cylinder.step"), "out": str(out),
                                      "side": "all", "pad_radius": 0.025, "chordal_tol": 3e-4,
                                      "sample_spacing": 3e-3})
    metrics = run_job(settings)
    assert metrics["coverage_fraction"] >= 0.99
    assert metrics["selected_area_m2"] == pytest.approx(2 * np.pi * 0.04 * 0.2 + 2 * np.pi * 0.04**2, rel=2e-3)
    doc = json.loads((out / "metrics.json").read_text())["metrics"]
    assert doc["n_setups"] == len(doc["setups"]) >= 2
    for record in doc["setups"]:
        folder = out / f"setup_{record['setup']}"
        header = (folder / "trajectory.csv").read_text().splitlines()[0]
        assert header.startswith("t,x,y,z,qw,qx,qy,qz,contact")
        t2p = np.array(record["part2table"])
        np.testing.assert_allclose(t2p[:3, :3] @ np.array(record["up"]), [0, 0, 1], atol=1e-12)
        assert record["faces"]
    assert {i for r in doc["setups"] for i in r["faces"]} == {1, 2, 3}
