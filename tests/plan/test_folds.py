"""Folds at the rim (swath.plan.folds): a plate whose edge curls up into a lip, and designed passes."""

import math

import numpy as np
import pytest

from swath.cli.job import JobSettings, make_plan
from swath.core import Pass, ToolPath
from swath.examples.parts import flat_plate, grid_faces
from swath.plan.folds import MIN_PIECE_FRACTION, cut_rim_folds
from swath.surface import Surface

FLAT, LIP_RADIUS, FLANGE = 0.25, 0.004, 0.006      # m


def lipped_plate(step: float = 2e-3, width: float = 0.2) -> Surface:
    """A plate flat for x < 0.25 m whose edge curls up through 90 degrees (radius 4 mm) into a
    6 mm flange, normals +z on the flat and -x on the flange."""
    profile = [(x, 0.0) for x in np.arange(0.0, FLAT, step)]
    profile += [(FLAT + LIP_RADIUS * math.sin(a), LIP_RADIUS * (1 - math.cos(a))) for a in np.linspace(0, math.pi / 2, 10)]
    profile += [(FLAT + LIP_RADIUS, z) for z in np.arange(LIP_RADIUS + step, LIP_RADIUS + FLANGE + 1e-9, step)]
    ys = np.linspace(0.0, width, int(round(width / step)) + 1)
    vertices = np.array([[x, y, z] for x, z in profile for y in ys])
    return Surface(vertices, grid_faces(len(profile), len(ys)), name="lipped plate")


@pytest.fixture(scope="module")
def lip():
    return lipped_plate()


def _plan(surface, **settings):
    return make_plan(surface, JobSettings(part="example:plate", out="unused", spacing=0.05, **settings))


def test_passes_across_the_lip_stop_before_it(lip):
    # across the lip (along x) at the default 1 rad/s: over the 4 mm lip the limit allows 4 mm/s
    plan = _plan(lip, direction=0.0)
    assert plan.metadata["rim_fold_cuts"] == len(plan.passes) >= 4
    # each pass lost the lip (a quarter circle, 6.3 mm; with the normals smoothed over 2 mm, and the
    # flange's first steps, more) and the stub on the flange beyond it, under R/4
    per_pass = plan.metadata["rim_fold_length_m"] / len(plan.passes)
    assert 0.5 * math.pi * LIP_RADIUS <= per_pass <= 0.5 * math.pi * LIP_RADIUS + FLANGE + 2e-3
    for p in plan.passes:
        assert p.points[:, 2].max() < 1e-6 and p.points[:, 0].max() < FLAT          # on the flat only
    # without an angular speed limit nothing crawls and nothing is cut: the passes climb the lip
    free = _plan(lip, direction=0.0, max_angular=None)
    assert "rim_fold_cuts" not in free.metadata
    assert max(p.points[:, 2].max() for p in free.passes) > LIP_RADIUS


def test_passes_along_the_lip_are_not_cut(lip):
    plan = _plan(lip, direction=math.pi / 2)
    assert "rim_fold_cuts" not in plan.metadata


def _pass_with_turn(y: float, at: float = 0.5, *, jitter: bool = False) -> Pass:
    """A pass along x from 0.3 m to 0.995 m at height 0 and ``y`` (m), its normals turning by 90
    degrees about y over ``at``..``at`` + 0.02 m (or, with ``jitter``, by 20 degrees there and back
    every 2 mm)."""
    x = np.arange(0.3, 0.995, 1e-3)
    a = np.clip((x - at) / 0.02, 0.0, 1.0) * math.pi / 2
    if jitter:
        a = np.where((x > at) & (x < at + 0.02), math.radians(20) * (np.round((x - at) / 1e-3) % 2), 0.0)
    normals = np.column_stack([np.sin(a), np.zeros_like(a), np.cos(a)])
    return Pass(np.column_stack([x, np.full_like(x, y), np.zeros_like(x)]), normals, level=0)


def test_only_a_turning_run_at_the_rim_is_cut():
    plate = flat_plate(size_x=1.0, size_y=1.0, spacing=0.02)
    R = 0.0381
    # toward the edge x = 1 m, the turn 10..30 mm before it; hugging the edge y = 0 (5 mm off it)
    ahead, hugging = _pass_with_turn(0.5, at=0.97), _pass_with_turn(0.005)
    # a ridge inside; one crossed 20 mm from the edge y = 0, which lies beside it (the blade's nose
    # near its tip); a scan's noise, turning back and forth, toward the edge
    inside, beside, noisy = _pass_with_turn(0.5), _pass_with_turn(0.02), _pass_with_turn(0.5, at=0.97, jitter=True)
    cut = cut_rim_folds(ToolPath(plate, [ahead, hugging, inside, beside, noisy], "raster", {}), plate, feed=0.05,
                        omega_max=1.0, pad_radius=R)
    assert cut.metadata["rim_fold_cuts"] == 2
    assert cut.metadata["rim_fold_length_m"] == pytest.approx(0.04, abs=4e-3)
    before_edge, hug_first, hug_second, kept_inside, kept_beside, kept_noisy = cut.passes
    # toward the edge only the piece before the turn is left (the 5 mm beyond it is a stub under R/4)
    assert before_edge.points[-1, 0] < 0.97 + 1e-9
    assert hug_first.points[-1, 0] < 0.5 + 1e-9 and hug_second.points[0, 0] > 0.52 - 1e-9
    assert kept_inside is inside and kept_beside is beside and kept_noisy is noisy
    # no limit, or a limit fast enough for the turn at the feed: nothing is cut
    plan = ToolPath(plate, [ahead], "raster", {})
    assert cut_rim_folds(plan, plate, feed=0.05, omega_max=None, pad_radius=R) is plan
    assert cut_rim_folds(plan, plate, feed=0.05, omega_max=10.0, pad_radius=R) is plan
    # a closed part has no rim
    import trimesh

    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.3)
    closed = Surface(ball.vertices, ball.faces, name="ball")
    on_ball = ToolPath(closed, [hugging], "raster", {})
    assert cut_rim_folds(on_ball, closed, feed=0.05, omega_max=1.0, pad_radius=R) is on_ball


def test_stubs_under_a_quarter_pad_radius_are_dropped():
    plate = flat_plate(size_x=1.0, size_y=1.0, spacing=0.02)
    R = 0.0381
    x = np.arange(0.3, 0.49 + 0.5 * MIN_PIECE_FRACTION * R, 1e-3)        # ends half a stub's length past the turn
    a = np.clip((x - 0.47) / 0.02, 0.0, 1.0) * math.pi / 2
    p = Pass(np.column_stack([x, np.full_like(x, 0.005), 0 * x]), np.column_stack([np.sin(a), 0 * a, np.cos(a)]),
             level=0)                                                      # hugging the edge y = 0
    [kept] = cut_rim_folds(ToolPath(plate, [p], "raster", {}), plate, feed=0.05, omega_max=1.0, pad_radius=R).passes
    assert kept.points[-1, 0] < 0.47 + 1e-9
