"""One tool record from doe through calibrate to plan, and the loop closed on simulated trials."""

import csv
import json
import math

import numpy as np
import pytest

from swath.cli.settings import settings_from_mapping
from swath.cli.stages import job_tool
from swath.contact import Tool
from swath.errors import InputError
from swath.simulate.calibrate import (
    calibrate,
    load_calibration,
    read_trials,
    write_calibration,
)
from swath.simulate.calibrated import calibrated_tool, predict_depth
from swath.simulate.preston_doe import parse_factor, write_doe
from swath.simulate.trials import fill_trials, hold_back, trial_depth, trial_tool

K_P0 = 2.0e-10            # 1/Pa, the fresh media the simulated shop runs
WEAR = 1.0 / 900.0        # 1/s: the media loses 28 % of its cut in 300 s


def _doe(path, tool, ages=("0s", "300s", "600s", "900s"), replicates=1):
    factors = dict([parse_factor("force=10N,20N,30N"), parse_factor("feed_m_per_s=0.02,0.05"),
                    parse_factor("pad_age=" + ",".join(ages))])
    return write_doe(path, factors, fixed={"passes": 3}, tool=tool, replicates=replicates)


def test_the_readme_doe_template_is_one_calibrate_reads_and_plan_runs_on(tmp_path):
    """Before: the template had no spindle_speed_rpm (calibrate refused it), calibrate took the
    trials for a rotary pad and plan ran orbital: 0.31 µm per pass predicted against 2.1 fitted."""
    factors = dict([parse_factor("force=10N,20N,30N"), parse_factor("feed_m_per_s=0.02,0.05")])
    path = write_doe(tmp_path / "trials.csv", factors, fixed={"passes": 3})
    rows = list(csv.DictReader(open(path)))
    assert {r["spindle_speed_rpm"] for r in rows} == {"10000"} and {r["orbit_radius_m"] for r in rows} == {"0.0025"}
    # fill in 2.1 µm per pass at every run (a constant: the fit is then exact up to the model)
    default = Tool()
    for r in rows:
        t = trial_tool(force=float(r["force_N"]), spindle_speed_rpm=10000, orbit_radius=0.0025, pad_radius=0.0381,
                       preston=1.0)
        r["depth_m"] = str(predict_depth_exposure(t, float(r["feed_m_per_s"])) * 3 * 1e-10)
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    cal = calibrate(path)
    assert cal.metadata["tool"]["motion"] == "orbital"
    assert cal.metadata["tool"]["spindle_speed_rpm"] == [10000.0]
    assert cal.fit_for().preston == pytest.approx(1e-10, rel=1e-9)
    write_calibration(tmp_path / "cal.json", cal)
    settings = settings_from_mapping({"part": "example:plate", "out": str(tmp_path / "o"), "force": "10N",
                                      "feed": "20mm/s", "calibration": str(tmp_path / "cal.json")})
    tool = job_tool(settings)
    assert (tool.motion, tool.orbit_radius, tool.spindle_speed) == ("orbital", 2.5e-3, default.spindle_speed)
    per_pass = predict_depth(cal, tool, feed=0.02, passes=1).depth
    fitted = float(next(r["depth_m"] for r in rows if r["force_N"] == "10" and r["feed_m_per_s"] == "0.02")) / 3
    assert per_pass == pytest.approx(fitted, rel=1e-9)


def predict_depth_exposure(tool, feed):
    """Centre-line depth per pass per unit k_p of an orbital pad on flat (Preston, uniform pressure)."""
    return tool.force / tool.pad_area * tool.spindle_speed * tool.orbit_radius * 2 * tool.pad_radius / feed


def test_doe_refuses_to_replace_a_file_of_measurements(tmp_path):
    path = tmp_path / "trials.csv"
    path.write_text("trial,force_N,depth_m\n1,10,2.1e-6\n")
    with pytest.raises(InputError, match="exists and may hold measurements.*--overwrite"):
        _doe(path, Tool())
    assert path.read_text() == "trial,force_N,depth_m\n1,10,2.1e-6\n"
    _doe(tmp_path / "other.csv", Tool())
    write_doe(path, dict([parse_factor("force=10N,20N")]), tool=Tool(), overwrite=True)
    assert "2.1e-6" not in path.read_text()


def test_plan_refuses_a_calibration_measured_in_another_motion(tmp_path):
    path = _doe(tmp_path / "t.csv", Tool(motion="rotary"), ages=("0s", "100s"))
    filled = fill_trials(path, tmp_path / "f.csv", preston=K_P0, sample_spacing=3e-3)
    cal = calibrate(filled)
    assert cal.metadata["tool"]["motion"] == "rotary" and cal.metadata["tool"]["orbit_radius_m"] == []
    with pytest.raises(InputError, match="measured with a rotary pad and the job runs it orbital"):
        calibrated_tool(Tool(), cal, motion="orbital")
    tool = calibrated_tool(Tool(), cal)                # motion not given: the calibration's
    assert tool.motion == "rotary" and tool.preston == pytest.approx(K_P0, rel=0.02)
    # an older file that does not state its tool is used as before, with a warning
    old = json.loads(json.dumps({**cal.metadata}))
    old.pop("tool")
    assert calibrated_tool(Tool(), type(cal)(cal.fits, old)).motion == "orbital"


@pytest.mark.slow
@pytest.mark.parametrize("motion", ["orbital", "rotary"])
def test_closed_loop_on_simulated_trials_recovers_preston_and_wear(tmp_path, motion):
    """doe → trials run in swath's simulator at a known k_p0 and wear rate, 8 % scatter → calibrate
    on 54 of 72 trials (3 forces × 2 feeds × 4 pad ages × 3 replicates) → the job's tool (plan
    --calibration) predicts the 18 held-back trials' depth per pass within 5 % of the simulator's
    noise-free depth, and the wear rate within 10 %."""
    template = _doe(tmp_path / "trials.csv", Tool(motion=motion), replicates=3)
    filled = fill_trials(template, tmp_path / "filled.csv", preston=K_P0, wear_rate=WEAR, noise=0.08, seed=7,
                         sample_spacing=3e-3)
    rows = list(csv.DictReader(open(filled)))
    fitted, held = hold_back(rows)
    assert (len(fitted), len(held)) == (54, 18)
    with open(tmp_path / "fit.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(fitted)
    cal = calibrate(tmp_path / "fit.csv")
    fit = cal.fit_for()
    assert fit.error_model == "wear"
    assert fit.wear_rate == pytest.approx(WEAR, rel=0.10)
    assert fit.wear_rate_interval[1] - fit.wear_rate_interval[0] < 0.3 * WEAR
    write_calibration(tmp_path / "cal.json", cal)
    assert load_calibration(tmp_path / "cal.json").fit_for().wear_rate == pytest.approx(fit.wear_rate)
    settings = settings_from_mapping({"part": "example:plate", "out": str(tmp_path / "o"),
                                      "calibration": str(tmp_path / "cal.json")})
    tool = job_tool(settings)
    assert tool.motion == motion and tool.wear_rate == pytest.approx(fit.wear_rate)
    errors = []
    for r in held:
        truth_tool = trial_tool(force=float(r["force_N"]), spindle_speed_rpm=10000,
                                orbit_radius=float(r["orbit_radius_m"]), pad_radius=0.0381, preston=K_P0,
                                wear_rate=WEAR)
        errors.append(trial_depth(tool, r, sample_spacing=3e-3) / trial_depth(truth_tool, r, sample_spacing=3e-3) - 1)
    assert np.max(np.abs(errors)) < 0.05, errors
    assert math.isfinite(read_trials(filled).pad_age.sum())


def test_make_plan_plans_with_the_tool_it_is_given():
    """run_job builds the job's tool once (with the calibration) and make_plan plans with it: a
    smaller pad given to make_plan lays more raster passes than the settings' own pad would."""
    from swath.cli.job import make_plan
    from swath.examples import flat_plate

    settings = settings_from_mapping({"part": "example:plate", "out": "/tmp/unused"})
    plate = flat_plate()
    own = make_plan(plate, settings)
    small = make_plan(plate, settings, tool=Tool(pad_radius=0.02))
    assert len(small.passes) > len(own.passes)


def test_swath_doe_refuses_an_existing_out_and_writes_the_tool_columns(tmp_path):
    import subprocess
    import sys

    out = tmp_path / "trials.csv"
    cmd = [sys.executable, "-m", "swath.cli", "doe", "--factor", "force=10N,20N,30N", "--factor",
           "feed_m_per_s=0.02,0.05", "--fixed", "passes=3", "--out", str(out)]
    assert subprocess.run(cmd, capture_output=True, text=True).returncode == 0
    header = out.read_text().splitlines()[0].split(",")
    assert {"spindle_speed_rpm", "orbit_radius_m", "pad_radius_m", "pad_age_s"} <= set(header)
    out.write_text(out.read_text().replace(",,", ",2.1e-6,", 1))
    measured = out.read_text()
    r = subprocess.run(cmd, capture_output=True, text=True)
    assert r.returncode != 0 and "--overwrite" in r.stderr and out.read_text() == measured
    assert subprocess.run(cmd + ["--overwrite"], capture_output=True, text=True).returncode == 0
    assert out.read_text() != measured
