"""Right answers on parts users meet daily: plates with holes, several pieces, far from the origin.

Coverage is checked three ways: the planner's own prediction, swath's removal simulation, and an
independent count (every surface point within a pad radius, in the tangent plane, of an in-contact
sample of the written trajectory counts as touched: on these flat parts the pressed pad is the
whole disc).
"""

import numpy as np
import pytest
from scipy.spatial import cKDTree

import swath
from swath.examples import flat_plate
from swath.surface import Surface

TOOL = swath.Tool()
R = TOOL.pad_radius


def plate_with_holes(holes, size=(0.3, 0.3), spacing=4e-3):
    s0 = flat_plate(size_x=size[0], size_y=size[1], spacing=spacing)
    c = s0.vertices[s0.faces].mean(axis=1)
    keep = np.ones(len(c), bool)
    for x, y, r in holes:
        keep &= np.hypot(c[:, 0] - x, c[:, 1] - y) > r
    return Surface(s0.vertices, s0.faces[keep], name="plate with holes")


def pieces(n: int, gap: float = 0.05, tilt_deg: float = 20.0):
    """``n`` plates 0.25 x 0.2 m side by side, ``gap`` apart, each tilted a little more about x."""
    vs, fs, off = [], [], 0
    for k in range(n):
        p = flat_plate(size_x=0.25, size_y=0.2, spacing=5e-3)
        a = np.radians(tilt_deg * k)
        rot = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
        v = p.vertices @ rot.T + [k * (0.25 + gap), 0.0, 0.0]
        vs.append(v)
        fs.append(p.faces + off)
        off += len(v)
    return Surface(np.vstack(vs), np.vstack(fs), name=f"{n} pieces")


def run(surface, planner, **options):
    tp = swath.order_toolpath(swath.PLANNERS[planner](surface, TOOL, **options))
    tr = swath.time_path(tp, [swath.FeedLimit(0.05)])
    return tp, tr, swath.simulate_removal(tr, surface, TOOL).metrics


def independent_coverage(surface, tr) -> float:
    fine = surface.subdivided(3e-3)
    d = cKDTree(tr.position[tr.contact]).query(fine.vertices)[0]
    return float(fine.vertex_areas[d <= R * (1 + 1e-3)].sum() / fine.area)


PARTS = {
    "one hole": lambda: plate_with_holes([(0.15, 0.15, 0.04)]),
    "two holes": lambda: plate_with_holes([(0.09, 0.15, 0.03), (0.21, 0.12, 0.045)], size=(0.32, 0.26)),
    "two pieces": lambda: pieces(2),
    "three pieces": lambda: pieces(3, gap=0.08, tilt_deg=15.0),
}


@pytest.mark.parametrize("part", sorted(PARTS))
def test_raster_covers_every_piece_and_hole_and_predicts_it(part):
    s = PARTS[part]()
    tp, tr, m = run(s, "raster")
    assert m["coverage_fraction"] >= 0.99
    assert independent_coverage(s, tr) >= 0.99
    predicted = 1.0 - tp.metadata["predicted_gap_fraction"]
    assert abs(predicted - m["coverage_fraction"]) <= 0.01
    assert m["efficiency"] <= 1.0
    assert set(tp.regions.tolist()) == set(range(len(s.face_pieces())))      # every piece has passes


@pytest.mark.parametrize("part", ["one hole", "two pieces"])
def test_uniform_covers_every_piece_and_hole(part):
    s = PARTS[part]()
    tp, tr, m = run(s, "uniform", direction=0.0)
    assert m["coverage_fraction"] >= 0.99
    assert independent_coverage(s, tr) >= 0.99
    assert abs(tp.metadata["predicted_coverage_fraction"] - m["coverage_fraction"]) <= 0.01
    assert m["efficiency"] <= 1.0
    assert set(tp.regions.tolist()) == set(range(len(s.face_pieces())))


def test_efficiency_never_passes_one_when_area_is_left():
    """A plan that leaves half the part untouched is not 'more than efficient'."""
    s = flat_plate(size_x=0.4, size_y=0.3, spacing=5e-3)
    tp = swath.order_toolpath(swath.raster(s, TOOL, spacing=0.2, direction=0.0, fill_gaps=False))
    m = swath.simulate_removal(swath.time_path(tp, [swath.FeedLimit(0.05)]), s, TOOL).metrics
    assert m["coverage_fraction"] < 0.8
    assert m["efficiency"] <= 1.0 and m["coverage_lower_bound_m"] > m["covered_lower_bound_m"]


@pytest.mark.parametrize("planner", ["raster", "uniform"])
def test_the_same_part_a_kilometre_away_gives_the_same_figures(planner):
    s0 = plate_with_holes([(0.15, 0.15, 0.04)], spacing=5e-3)
    s1 = Surface(s0.vertices + [1000.0, -1000.0, 1000.0], s0.faces, name="far")
    options = {"direction": 0.0}
    _, _, m0 = run(s0, planner, **options)
    _, _, m1 = run(s1, planner, **options)
    for key in ("coverage_fraction", "efficiency"):         # 0.01 percentage point
        assert m1[key] == pytest.approx(m0[key], abs=1e-4), key
    assert m1["removal_cov"] == pytest.approx(m0["removal_cov"], rel=2e-3)
    assert m1["contact_length_m"] == pytest.approx(m0["contact_length_m"], rel=1e-6)


def test_a_strip_is_run_along_its_length():
    s = flat_plate(size_x=0.3, size_y=0.02, spacing=2e-3)
    tp = swath.raster(s, TOOL)
    assert len(tp.passes) == 1
    assert abs(tp.metadata["feed_direction"][0]) == pytest.approx(1.0, abs=1e-6)


def test_piece_faces_and_owners_are_taken_once_for_every_piece():
    """The faces, face normals and vertex owners of each piece are gathered once per surface (the
    candidate directions and the fill passes share them), in one memo entry however many pieces
    there are, read-only, and equal to gathering them anew."""
    from swath.contact.widths import _MEMO
    from swath.plan.raster import piece_faces, piece_of_vertex

    surface = pieces(20, gap=0.02)
    parts = surface.face_pieces()
    assert len(parts) == 20
    for k in range(len(parts)):
        faces, normals = piece_faces(surface, parts, k)
        np.testing.assert_array_equal(faces, surface.faces[parts[k]])
        np.testing.assert_array_equal(normals, surface.face_normals[parts[k]])
        assert not faces.flags.writeable and not normals.flags.writeable
        assert piece_faces(surface, parts, k)[0] is faces
    owner = piece_of_vertex(surface, parts)
    for k in range(len(parts)):
        assert (owner[surface.faces[parts[k]]] == k).all()
    assert not owner.flags.writeable
    assert sum(key[0] == "piece_faces" for key in _MEMO[surface]) == 1
