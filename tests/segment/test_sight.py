"""Line of sight for setups: the part's own shadow, checked against trimesh's ray-triangle
intersector, and setups on a channel whose inner faces the normal-angle rule alone calls exposed."""

from __future__ import annotations

import numpy as np
import pytest

from swath.errors import InfeasibleError
from swath.io.part import Part
from swath.segment.select import select
from swath.segment.setups import exposure, plan_setups
from swath.segment.sight import visible
from swath.surface import Surface

VOXEL = 5e-3

#: The four corners of each outward face of a unit voxel, counter-clockwise seen from outside.
_QUADS = {(0, 1): [(1, 0, 0), (1, 1, 0), (1, 1, 1), (1, 0, 1)], (0, -1): [(0, 0, 0), (0, 0, 1), (0, 1, 1), (0, 1, 0)],
          (1, 1): [(0, 1, 0), (0, 1, 1), (1, 1, 1), (1, 1, 0)], (1, -1): [(0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)],
          (2, 1): [(0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)], (2, -1): [(0, 0, 0), (0, 1, 0), (1, 1, 0), (1, 0, 0)]}


def voxel_part(filled: np.ndarray, name: str) -> Part:
    """The closed surface of a union of cubes (``filled`` (nx, ny, nz) bool, VOXEL each), wound outward."""
    filled = np.pad(np.asarray(filled, bool), 1)
    quads = []
    for (axis, sign), corners in _QUADS.items():
        idx = np.argwhere(filled & ~np.roll(filled, -sign, axis=axis)) - 1
        quads.append(idx[:, None, :] + np.array(corners)[None])
    q = np.concatenate(quads)
    points, inverse = np.unique(q.reshape(-1, 3), axis=0, return_inverse=True)
    inverse = inverse.reshape(-1, 4)
    faces = np.vstack([inverse[:, [0, 1, 2]], inverse[:, [0, 2, 3]]])
    part = Part.from_surface(Surface(points * VOXEL, faces, name=name))
    assert part.closed
    return part


def channel() -> Part:
    """A C-channel 100 × 60 × 100 mm (x, y, z): a 20 mm back wall at x < 20 mm and two 20 mm arms
    (z < 20 mm, z > 80 mm); the slot between the arms is open toward +x and ±y."""
    x, _, z = np.meshgrid(np.arange(20), np.arange(12), np.arange(20), indexing="ij")
    return voxel_part((x < 4) | (z < 4) | (z >= 16), "channel")


def _reference_visible(part: Part, direction, which) -> np.ndarray:
    """Visibility by trimesh's ray-triangle intersector: the ray from each centroid (a micrometre off
    the face) along ``direction`` meets no other triangle ahead."""
    import trimesh

    s = part.surface
    mesh = trimesh.Trimesh(s.vertices, s.faces, process=False)
    idx = np.flatnonzero(which)
    origin = mesh.triangles_center[idx] + 1e-7 * s.face_normals[idx]
    d = np.tile(np.asarray(direction, float) / np.linalg.norm(direction), (len(idx), 1))
    location, ray, tri = trimesh.ray.ray_triangle.RayMeshIntersector(mesh).intersects_location(
        origin, d, multiple_hits=True)
    ahead = np.einsum("ij,ij->i", location - origin[ray], d[ray]) > 1e-7
    out = np.zeros(len(s.faces), bool)
    out[idx] = True
    out[idx[ray[ahead & (tri != idx[ray])]]] = False
    return out


@pytest.mark.parametrize("direction", [(0, 0, 1), (1, 0, 1), (-1, 0, 0), (0.3, -0.2, 0.9)])
def test_visibility_agrees_with_ray_casting(direction):
    part = channel()
    everything = np.ones(len(part.face_ids), bool)
    reference = _reference_visible(part, direction, everything)
    np.testing.assert_array_equal(visible(part.surface, direction), reference)
    # a closed solid: only triangles facing against the ray can be the first it meets
    np.testing.assert_array_equal(visible(part.surface, direction, closed=True), reference)


def test_the_floor_of_the_slot_is_hidden_from_above():
    """Seen from +z the lower arm's top inside the slot (z = 20 mm, x > 20 mm, 16 × 12 quads) lies
    under the upper arm: the normal-angle rule calls it exposed, the line of sight does not."""
    part = channel()
    c = part.surface.vertices[part.surface.faces].mean(axis=1)
    floor = np.isclose(c[:, 2], 0.02) & (c[:, 0] > 0.02)
    assert part.surface.face_areas[floor].sum() == pytest.approx(0.08 * 0.06)
    by_angle = exposure(part, (0, 0, 1.0), line_of_sight=False)
    by_sight = exposure(part, (0, 0, 1.0))
    assert by_angle[floor].all() and not by_sight[floor].any()
    # the upper arm's top is seen from above either way
    top = np.isclose(c[:, 2], 0.1)
    assert by_sight[top].all()


def test_setups_with_line_of_sight_see_every_face_they_are_given():
    """On the channel the normal-angle rule alone finds two corner setups, each responsible for
    slot faces the part hides from it; with the line of sight every triangle a setup is given is
    in view from its up direction (checked by ray casting), and every triangle is given to one."""
    part = channel()
    area = part.surface.face_areas
    by_angle = plan_setups(part, line_of_sight=False)
    hidden = sum(area[s.assigned & ~_reference_visible(part, s.up, s.assigned)].sum() for s in by_angle)
    assert len(by_angle) == 2 and hidden > 0.003                   # m²: over 30 cm² would not be reached
    setups = plan_setups(part, overlap=0.01)
    assigned = np.zeros(len(area), bool)
    for s in setups:
        assert not (assigned & s.assigned).any()
        assigned |= s.assigned
        np.testing.assert_array_equal(_reference_visible(part, s.up, s.assigned)[s.assigned], True)
        assert (part.surface.face_normals[s.assigned] @ s.up >= np.cos(np.radians(75)) - 1e-12).all()
        np.testing.assert_array_equal(s.planned & ~exposure(part, s.up), False)
    assert assigned.all()
    assert len(setups) == 3
    # each setup states the area the part hides from it among the faces within its angle, as the
    # ray casting finds it
    for s in setups:
        by_angle = exposure(part, s.up, line_of_sight=False)
        hidden = by_angle & ~_reference_visible(part, s.up, by_angle)
        assert s.hidden == pytest.approx(area[hidden].sum(), rel=1e-12) and s.hidden > 0


def test_a_deep_slot_is_refused_until_kept_out():
    """A 5 mm wide, 40 mm deep slot in a 50 mm cube: its walls, deeper than a slot width, are hidden
    from every direction within 75° of their normals; the refusal names the hidden area and the fix,
    and with the slot kept out (a polygon over it) the setups cover the rest."""
    x, y, z = np.meshgrid(np.arange(10), np.arange(10), np.arange(10), indexing="ij")
    part = voxel_part(~((x == 5) & (y >= 2) & (y < 8) & (z >= 2)), "slotted")
    with pytest.raises(InfeasibleError, match="hidden by the part itself.*--keep-out"):
        plan_setups(part)
    kept = select(part, keep_out="polygon:24mm,9mm 31mm,9mm 31mm,41mm 24mm,41mm")
    setups = plan_setups(kept)
    covered = np.logical_or.reduce([s.assigned for s in setups])
    np.testing.assert_array_equal(covered, kept.work_triangles)
