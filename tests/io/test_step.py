"""STEP/IGES input through OCP: exact normals, face ids, names, colours, units, refusals.

The STEP files are written by the tests themselves (swath.examples.cad), so no file is downloaded.
"""

from __future__ import annotations

import numpy as np
import pytest

from swath.errors import InputError

pytest.importorskip("OCP")

from swath.examples import cad  # noqa: E402
from swath.io.step import load_step  # noqa: E402

LENGTH, RADIUS, WALL, FLANGE_R, FLANGE_T = 0.3, 0.05, 0.005, 0.09, 0.01


@pytest.fixture(scope="module")
def tube_step(tmp_path_factory):
    shape = cad.tube_with_flange()
    names = cad.tube_face_names(shape)
    path = tmp_path_factory.mktemp("cad") / "tube.step"
    cad.write_step(shape, path, names=names, colours={names.index("flange_top"): (0.0, 0.0, 1.0)})
    return path


@pytest.fixture(scope="module")
def tube(tube_step):
    return load_step(tube_step)


def _face(part, name):
    return next(f for f in part.faces if f.name == name)


def _vertices_of(part, face_id):
    return np.unique(part.surface.faces[part.face_ids == face_id])


def test_faces_keep_ids_names_kinds_colours_and_exact_areas(tube):
    kinds = {f.name: f.kind for f in tube.faces}
    assert kinds["tube_outer"] == "cylinder" and kinds["bore"] == "cylinder" and kinds["flange_top"] == "plane"
    assert [f.id for f in tube.faces] == list(range(1, len(tube.faces) + 1))
    assert _face(tube, "flange_top").colour == "#0000ff"
    assert _face(tube, "tube_outer").colour is None
    # areas of the tessellation against the analytic faces (chordal error 0.1 mm: < 0.5 %)
    outer = 2 * np.pi * RADIUS * (LENGTH - FLANGE_T)
    bore = 2 * np.pi * (RADIUS - WALL) * LENGTH
    top = np.pi * (FLANGE_R**2 - RADIUS**2)
    assert _face(tube, "tube_outer").area == pytest.approx(outer, rel=5e-3)
    assert _face(tube, "bore").area == pytest.approx(bore, rel=5e-3)
    assert _face(tube, "flange_top").area == pytest.approx(top, rel=5e-3)
    assert tube.closed                                       # a solid: its faces close up


def test_units_from_the_file_metres_out(tube):
    lo, hi = tube.surface.bounds
    assert hi[2] - lo[2] == pytest.approx(LENGTH, abs=1e-6)
    assert hi[0] - lo[0] == pytest.approx(2 * FLANGE_R, abs=2e-4)


@pytest.mark.parametrize("name, radius, sign", [("tube_outer", RADIUS, 1.0), ("bore", RADIUS - WALL, -1.0)])
def test_normals_within_a_tenth_of_a_degree_of_the_cylinder_and_out_of_the_solid(tube, name, radius, sign):
    v_idx = _vertices_of(tube, _face(tube, name).id)
    v = tube.surface.vertices[v_idx]
    n = tube.surface.normals[v_idx]
    inside = (v[:, 2] > FLANGE_T + 1e-4) & (v[:, 2] < LENGTH - 1e-4)    # off the edges shared with other faces
    assert inside.sum() > 500
    radial = v[inside].copy()
    radial[:, 2] = 0.0
    radial = sign * radial / np.linalg.norm(radial, axis=1, keepdims=True)
    angle = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", n[inside], radial), -1, 1)))
    assert angle.max() < 0.1
    # the tessellation keeps to the chordal tolerance (0.1 mm)
    r = np.hypot(v[:, 0], v[:, 1])
    assert np.abs(r - radius).max() < 1e-4 + 1e-9


def test_plane_normals_and_reversed_faces_point_out(tube):
    v_idx = _vertices_of(tube, _face(tube, "flange_top").id)
    v = tube.surface.vertices[v_idx]
    r = np.hypot(v[:, 0], v[:, 1])
    interior = (r > RADIUS + 1e-4) & (r < FLANGE_R - 1e-4)
    assert interior.sum() > 50
    np.testing.assert_allclose(tube.surface.normals[v_idx][interior], np.tile((0, 0, 1), (interior.sum(), 1)),
                               atol=1e-9)
    # the winding agrees with the exact normals: facets face out of the solid, up or down
    for name, z in (("tube_end", 1.0), ("flange_top", 1.0), ("flange_bottom", -1.0)):
        for f in (f for f in tube.faces if f.name == name):
            fn = tube.surface.face_normals[tube.face_ids == f.id]
            assert (fn[:, 2] * z > 0.999).all()


def test_chordal_tolerance_sets_the_tessellation(tube_step):
    coarse = load_step(tube_step, chordal_tolerance=1e-3, max_edge=None)
    fine = load_step(tube_step, chordal_tolerance=5e-5, max_edge=None)
    for part, tol in ((coarse, 1e-3), (fine, 5e-5)):
        fid = _face(part, "tube_outer").id
        tri = part.surface.faces[part.face_ids == fid]
        mid = part.surface.vertices[tri].mean(axis=1)       # a facet's centre is its farthest point from the cylinder
        gap = RADIUS - np.hypot(mid[:, 0], mid[:, 1])
        assert gap.max() <= tol * 1.05
    assert len(fine.surface.faces) > 2 * len(coarse.surface.faces)


def test_iges_reads_the_same_faces(tmp_path):
    shape = cad.tube_with_flange()
    path = cad.write_iges(shape, tmp_path / "tube.igs")
    part = load_step(path)
    assert sorted(f.kind for f in part.faces) == sorted(["cylinder"] * 3 + ["plane"] * 4)
    assert part.surface.area == pytest.approx(load_step(cad.write_step(shape, tmp_path / "t.step")).surface.area,
                                              rel=1e-3)


def test_closed_box_with_rounded_edges_is_closed_and_outward(tmp_path):
    part = load_step(cad.write_step(cad.rounded_box(), tmp_path / "box.step"))
    assert part.closed
    kinds = {f.kind for f in part.faces}
    assert {"plane", "cylinder"} <= kinds
    v, f = part.surface.vertices, part.surface.faces
    volume = np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]])).sum() / 6
    exact = 0.2 * 0.1 * 0.06 - (4 - np.pi) * 0.01**2 * (0.2 + 0.1 + 0.06) \
        + (4 - np.pi) * 0.01**2 * 3 * 0.01 - (8 - 4 * np.pi / 3) * 0.01**3   # a box with every edge rounded
    assert volume == pytest.approx(exact, rel=2e-3)        # positive: the normals point out of the solid
    assert (np.einsum("ij,ij->i", part.surface.normals[f].mean(axis=1), part.surface.face_normals) > 0.9).all()


def test_refusals_name_the_problem(tmp_path):
    bad = tmp_path / "broken.step"
    bad.write_text("ISO-10303-21;\nthis is not a step file\n")
    with pytest.raises(InputError, match="re-export"):
        load_step(bad)
    with pytest.raises(InputError, match="chordal tolerance"):
        load_step(bad, chordal_tolerance=0.0)
    with pytest.raises(InputError, match="unsupported"):
        load_step(tmp_path / "part.stl")


def test_missing_ocp_names_the_extra(monkeypatch):
    import builtins

    from swath.io import step

    real = builtins.__import__

    def no_ocp(name, *args, **kwargs):
        if name == "OCP" or name.startswith("OCP."):
            raise ImportError("No module named 'OCP'")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_ocp)
    with pytest.raises(InputError, match=r"swath\[cad\]"):
        step.require_ocp()
