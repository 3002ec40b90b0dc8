"""The softer-pad study: the same programme with a more compliant pad, and the warning it gives."""

import json

import numpy as np
import pytest

from swath.cli import main
from swath.contact import Tool
from swath.examples import flat_plate, grid_faces
from swath.io.mesh import save_surface_ply
from swath.plan import raster
from swath.report import plan_warnings
from swath.simulate import simulate_removal
from swath.simulate.compliance import MAX_DEPRESSION_SHARE, softer_pad_study, worth_a_study
from swath.surface import Surface
from swath.trajectory import FeedLimit, time_path

TOOL = Tool()            # 1 mm depression on flat at 20 N


def wavy_plate(amplitude=0.6e-3, wavelength=0.03, size=0.3, spacing=2.5e-3) -> Surface:
    """A square plate whose height is ``amplitude * sin(2 pi x / wavelength) * sin(2 pi y / wavelength)``
    (m): bumps a few pad-widths smaller than the pad, as on the shared scans."""
    n = int(round(size / spacing)) + 1
    x, y = np.meshgrid(np.linspace(0, size, n), np.linspace(0, size, n), indexing="ij")
    z = amplitude * np.sin(2 * np.pi * x / wavelength) * np.sin(2 * np.pi * y / wavelength)
    return Surface(np.column_stack([x.ravel(), y.ravel(), z.ravel()]), grid_faces(n, n), name="wavy plate")


def _job(surface):
    tp = raster(surface, TOOL)
    traj = time_path(tp, FeedLimit(0.05))
    return tp, traj, simulate_removal(traj, surface, TOOL)


def test_on_a_flat_plate_a_softer_pad_presses_the_same():
    """On flat both pads touch with the whole face at F / (pi R²): the same removal, the same CoV."""
    plate = flat_plate()
    _, traj, removal = _job(plate)
    study = softer_pad_study(traj, plate, TOOL, removal)
    assert study["pad_depression_m"] == pytest.approx(1e-3)
    assert study["softer_pad_depression_m"] == pytest.approx(3e-3)
    assert study["softer_pad_removal_cov"] == pytest.approx(removal.metrics["removal_cov"], rel=1e-9)
    assert study["softer_pad_removal_mean_m"] == pytest.approx(removal.metrics["removal_mean_m"], rel=1e-9)


def test_on_a_wavy_plate_a_softer_pad_removes_more_evenly_and_the_job_warns():
    surface = wavy_plate()
    tp, traj, removal = _job(surface)
    assert worth_a_study(removal.metrics)          # the stiff pad rides on the bumps
    study = softer_pad_study(traj, surface, TOOL, removal)
    assert study["softer_pad_removal_cov"] < 0.8 * removal.metrics["removal_cov"]
    # the same force and feed: Preston's removal rate integrated over the patch is the same
    assert study["softer_pad_removal_mean_m"] == pytest.approx(removal.metrics["removal_mean_m"], rel=0.1)
    metrics = dict(removal.metrics, **study)
    warnings = plan_warnings(surface, tp, traj, metrics, 0.05, TOOL.pad_radius)
    said = [w for w in warnings if "too stiff" in w]
    assert study["softer_pad_interior_removal_cov"] < 0.8 * removal.metrics["interior_removal_cov"]
    assert len(said) == 1 and "--depression 3mm" in said[0]
    assert f"interior removal CoV {study['softer_pad_interior_removal_cov']:.2f}" in said[0]
    # without the study's figures nothing is said
    assert not any("too stiff" in w for w in plan_warnings(surface, tp, traj, dict(removal.metrics), 0.05,
                                                           TOOL.pad_radius))


def test_the_softer_pad_is_capped_and_none_when_the_pad_is_already_that_soft():
    plate = flat_plate()
    _, traj, removal = _job(plate)
    soft_already = Tool(depression=0.3 * TOOL.pad_radius)
    assert softer_pad_study(traj, plate, soft_already, removal) is None
    study = softer_pad_study(traj, plate, Tool(depression=4e-3), removal)
    assert study["softer_pad_depression_m"] == pytest.approx(MAX_DEPRESSION_SHARE * TOOL.pad_radius)


def test_worth_a_study_only_above_the_threshold():
    assert worth_a_study({"removal_cov": 0.3})
    assert not worth_a_study({"removal_cov": 0.1})
    assert not worth_a_study({"removal_cov": float("nan")})
    assert not worth_a_study({})
    # the interior decides where the job has it: a plate's thin rim is no pad's doing
    assert not worth_a_study({"removal_cov": 0.225, "interior_removal_cov": 0.052})
    assert worth_a_study({"removal_cov": 0.36, "interior_removal_cov": 0.28})
    assert worth_a_study({"removal_cov": 0.3, "interior_removal_cov": float("nan")})


def test_the_warning_compares_the_interiors_where_both_are_known():
    surface = wavy_plate()
    tp, traj, removal = _job(surface)
    base = {"pad_depression_m": 1e-3, "softer_pad_depression_m": 3e-3}
    # the whole part barely gains (the rim), the interior does: warned, with the interior figures
    m = dict(base, removal_cov=0.36, interior_removal_cov=0.28, softer_pad_removal_cov=0.33,
             softer_pad_interior_removal_cov=0.12)
    said = [w for w in plan_warnings(surface, tp, traj, m, 0.05, TOOL.pad_radius) if "too stiff" in w]
    assert len(said) == 1 and "interior removal CoV 0.28" in said[0] and "interior removal CoV 0.12" in said[0]
    # the interior does not gain: no warning even though the whole part's figure would have given one
    m = dict(m, softer_pad_removal_cov=0.2, softer_pad_interior_removal_cov=0.27)
    assert not any("too stiff" in w for w in plan_warnings(surface, tp, traj, m, 0.05, TOOL.pad_radius))


def test_plan_job_records_the_study_and_warns(tmp_path, capsys):
    part = tmp_path / "wavy.ply"
    save_surface_ply(wavy_plate(), part)
    out = tmp_path / "job"
    assert main(["plan", "--constant-feed", str(part), "--units", "m", "--out", str(out)]) == 0
    m = json.loads((out / "metrics.json").read_text())
    m = m.get("metrics", m)
    assert m["softer_pad_depression_m"] == pytest.approx(3e-3)
    assert m["softer_pad_removal_cov"] < 0.8 * m["removal_cov"]
    assert m["pad_study_s"] > 0
    assert any("too stiff" in w for w in m["warnings"])
