"""The pad is a material with its own stiffness: the force changes depression, contact width, plan and removal."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import integrate, optimize
from scipy.spatial import cKDTree

from swath.cli.settings import settings_from_mapping
from swath.contact import Tool
from swath.contact.model import local_patch, mesh_contact
from swath.errors import InputError
from swath.plan import get_planner

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shapes import cylinder_patch  # noqa: E402


def test_a_bare_depression_is_at_20_N_and_the_force_presses_the_same_pad_deeper():
    pad = Tool(depression=1e-3)                       # 1 mm at the reference force 20 N
    assert pad.reference_force == 20.0
    k = 20.0 / (1e-3 * math.pi * 0.0381**2)
    for F in (5.0, 10.0, 20.0, 40.0):
        tool = Tool(force=F, depression=1e-3)
        assert tool.k == pytest.approx(k, rel=1e-12)                      # the pad, not the force, sets k
        assert tool.flat_depression == pytest.approx(1e-3 * F / 20.0, rel=1e-12)
    # the same pad stated at another force
    assert Tool(force=10.0, depression=2e-3, reference_force=40.0).flat_depression == pytest.approx(0.5e-3)
    assert Tool(force=10.0).with_force(30.0).flat_depression == pytest.approx(1.5e-3)


@pytest.mark.parametrize("force", [10.0, 20.0, 40.0])
def test_flat_plate_depression_is_proportional_to_the_force_in_both_contact_models(force):
    tool = Tool(force=force)
    patch = local_patch([0.0], [0.0], tool)
    assert patch.sink[0] == pytest.approx(force / (tool.k * math.pi * tool.pad_radius**2), rel=1e-9)
    # the exact force balance on samples of a flat plate (1 mm grid)
    xs = np.arange(-0.06, 0.0601, 1e-3)
    X, Y = np.meshgrid(xs, xs)
    pts = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    nrm = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    areas = np.full(len(pts), 1e-6)
    mc = mesh_contact(pts, nrm, areas, cKDTree(pts), np.array([[0.0, 0.0, 0.0]]), np.array([[0.0, 0.0, -1.0]]), tool)
    # z along tool z (down) is −z_part: the plate lies at z = 0, the pad face sinks s = F / (k A) below it
    assert mc.sink[0] == pytest.approx(force / (tool.k * areas.sum(where=np.hypot(pts[:, 0], pts[:, 1])
                                                                      <= tool.pad_radius)), rel=1e-6)
    assert mc.sink[0] == pytest.approx(1e-3 * force / 20.0, rel=0.02)      # the 1 mm grid's circle area


def _cylinder_sink(tool: Tool, radius: float) -> float:
    """Independent force balance on a cylinder (axis along y): F/k = ∫ (s − x²/2r) · 2·sqrt(R² − x²) dx
    over |x| < sqrt(2 s r)."""
    R = tool.pad_radius

    def volume(s):
        x0 = min(math.sqrt(2 * s * radius), R)
        return integrate.quad(lambda x: (s - x * x / (2 * radius)) * 2 * math.sqrt(R * R - x * x), -x0, x0,
                              epsabs=1e-16, epsrel=1e-12)[0]

    return optimize.brentq(lambda s: volume(s) - tool.force / tool.k, 1e-9, 0.05, xtol=1e-15)


@pytest.mark.parametrize("force", [10.0, 20.0, 40.0])
def test_cylinder_contact_chord_is_2_sqrt_2er_and_grows_with_the_force(force):
    r = 0.1
    tool = Tool(force=force)
    s = _cylinder_sink(tool, r)
    patch = local_patch([1.0 / r], [0.0], tool, n_rays=720)
    assert patch.sink[0] == pytest.approx(s, rel=2e-3)
    chord = 2 * math.sqrt(2 * s * r)
    # across the curved direction (d1, psi = 0) the patch spans the chord; along the axis the pad's diameter
    assert patch.width_across(0.0)[0] == pytest.approx(chord, rel=2e-3)
    assert patch.width_across(math.pi / 2)[0] == pytest.approx(2 * tool.pad_radius, rel=1e-3)
    # and on a mesh of the cylinder (0.14 mm around, 2 mm along) the touching samples span the same chord,
    # to the mesh's quantisation of the pad's circle
    surf = cylinder_patch(r, 0.5, 0.12, n_theta=700, n_len=60)
    v, n = surf.vertices, surf.vertex_normals
    top = np.array([[0.0, 0.0, r]])
    mc = mesh_contact(v, n, surf.vertex_areas, cKDTree(v), top, np.array([[0.0, 0.0, -1.0]]), tool)
    x = v[mc.sample, 0]
    assert x.max() - x.min() == pytest.approx(chord, rel=0.02)


def test_the_chord_follows_the_cube_root_law_while_narrow():
    # a narrow chord on a cylinder: F ≈ k · 2R · (4/3) s sqrt(2 s r), so s ∝ F^(2/3) and the chord ∝ F^(1/3)
    r = 0.02
    w = [local_patch([1.0 / r], [0.0], Tool(force=F), n_rays=720).width_across(0.0)[0] for F in (5.0, 40.0)]
    assert w[1] / w[0] == pytest.approx(8.0 ** (1 / 3), rel=0.03)


def test_a_force_sweep_changes_the_uniform_plan_where_the_contact_width_changes():
    """On a cylinder the swath across the curvature is the chord: more force, wider swaths, fewer
    passes.  On a flat plate the swath is the pad's diameter whatever the force."""
    surf = cylinder_patch(0.1, 0.8, 0.2, n_theta=120, n_len=50)
    counts = {}
    for F in (10.0, 20.0, 40.0):
        tp = get_planner("uniform")(surf, Tool(force=F), direction=0.0)
        counts[F] = len(tp.passes)
    # the curved extent (2 r sin 0.8 = 143 mm) over 90 % of the chord 33, 42, 53 mm: 5, 4, 3 steps
    assert counts[10.0] > counts[20.0] > counts[40.0]
    assert counts == {10.0: 6, 20.0: 5, 40.0: 4}


def test_job_settings_state_the_depression_force_and_refuse_a_pad_pressed_through():
    base = {"part": "example:plate", "out": "/tmp/x"}
    s = settings_from_mapping({**base, "depression": "1mm@10N", "force": "20N"})
    assert s.depression_force == 10.0 and s.tool().flat_depression == pytest.approx(2e-3)
    s = settings_from_mapping({**base, "depression": "1mm", "force": "10N"})
    assert s.tool().flat_depression == pytest.approx(0.5e-3)
    rec = s.as_record()
    assert rec["pad_depression_m"] == pytest.approx(1e-3) and rec["pad_depression_reference_force_N"] == 20.0
    assert rec["depression_on_flat_m"] == pytest.approx(0.5e-3)
    with pytest.raises(InputError, match="through its 2 mm compliant layer"):
        settings_from_mapping({**base, "depression": "1mm@10N", "force": "30N", "pad_thickness": "2mm"})
    with pytest.raises(InputError, match="give it once"):
        settings_from_mapping({**base, "depression": "1mm@10N", "depression_force": "20N"})
    with pytest.raises(InputError, match="spindle_speed"):
        settings_from_mapping({**base, "spindle_speed": 10000})            # a bare number: rpm or Hz?
    assert settings_from_mapping({**base, "spindle_speed": "6000rpm"}).tool().spindle_speed == pytest.approx(
        6000 * 2 * math.pi / 60)
