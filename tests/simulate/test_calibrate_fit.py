"""Preston calibration: recovery of a known coefficient, interval coverage, exponents, the model
against the removal simulator, and the calibration file into a Tool."""

import csv
import json
import math

import numpy as np
import pytest

from swath.contact import Tool
from swath.errors import InputError
from swath.examples import flat_plate
from swath.plan import Pass, ToolPath
from swath.simulate import simulate_removal
from swath.simulate.calibrate import (
    calibrate,
    exposure,
    load_calibration,
    make_trials,
    read_trials,
    write_calibration,
)
from swath.simulate.calibrated import predict_depth, predict_job_depth, tool_with_calibration
from swath.simulate.preston_doe import factorial_design, write_doe
from swath.trajectory import FeedLimit, time_path

K_TRUE = 2.5e-10
RPM = 2 * math.pi / 60


def design(n_rep=1):
    runs = factorial_design({"force_N": [15.0, 20.0, 25.0, 30.0], "spindle_speed_rpm": [1000.0, 2000.0, 3000.0, 4000.0]},
                            replicates=n_rep)
    f = np.array([r["force_N"] for r in runs])
    w = np.array([r["spindle_speed_rpm"] for r in runs]) * RPM
    return f, w


def synthetic(rng, *, noise=0.08, k=K_TRUE, relative=True, orbit=2.5e-3):
    f, w = design()
    t = make_trials(force=f, spindle_speed=w, feed=0.02, passes=3, depth=1.0, orbit_radius=orbit)
    d = k * exposure(t)
    d = d * (1 + noise * rng.standard_normal(len(d))) if relative else d + noise * rng.standard_normal(len(d))
    return make_trials(force=f, spindle_speed=w, feed=0.02, passes=3, depth=d, orbit_radius=orbit)


def test_exposure_closed_forms():
    R, F, w, v = 0.0381, 20.0, 1000.0, 0.05
    p = F / (math.pi * R * R)
    orb = make_trials(force=F, spindle_speed=w, feed=v, passes=2, depth=1.0, orbit_radius=2e-3, pad_radius=R)
    rot = make_trials(force=F, spindle_speed=w, feed=v, passes=2, depth=1.0, orbit_radius=0.0, pad_radius=R)
    assert exposure(orb)[0] == pytest.approx(2 * p * w * 2e-3 * 2 * R / v, rel=1e-12)
    assert exposure(rot)[0] == pytest.approx(2 * p * w * R * R / v, rel=1e-12)


@pytest.mark.parametrize("motion", ["orbital", "rotary"])
def test_exposure_matches_the_removal_simulator_on_a_straight_pass(motion):
    tool = Tool(motion=motion, spindle_speed=1000 * RPM, preston=K_TRUE)
    s = flat_plate()
    feed = 0.05
    tr = time_path(ToolPath(s, [Pass(np.array([[0.0, 0.15, 0], [0.4, 0.15, 0]]), np.array([[0, 0, 1.0]] * 2))], "t"),
                   [FeedLimit(feed)])
    rm = simulate_removal(tr, s, tool, sample_spacing=2e-3)
    v = rm.surface.vertices
    centre = (np.abs(v[:, 0] - 0.2) < 0.05) & (np.abs(v[:, 1] - 0.15) < 1.5e-3)
    t = make_trials(force=tool.force, spindle_speed=tool.spindle_speed, feed=feed, passes=1, depth=1.0,
                    orbit_radius=tool.orbit_radius if motion == "orbital" else 0.0, pad_radius=tool.pad_radius)
    assert np.mean(rm.depth[centre]) == pytest.approx(K_TRUE * exposure(t)[0], rel=0.04)


def test_calibration_recovers_a_known_coefficient_within_5_percent():
    cal = calibrate(synthetic(np.random.default_rng(0)))
    f = cal.fit_for()
    assert f.preston == pytest.approx(K_TRUE, rel=0.05)
    assert f.preston_low < K_TRUE < f.preston_high
    assert f.n_trials == 16 and f.dof == 15
    assert f.residual_std == pytest.approx(0.08, rel=0.4)


@pytest.mark.parametrize("relative", [True, False])
def test_90_percent_interval_covers_the_truth_in_at_least_85_of_100_seeds(relative):
    covered = 0
    for seed in range(100):
        rng = np.random.default_rng(1000 + seed)
        t = synthetic(rng, relative=relative, noise=0.08 if relative else 0.5e-6)
        f = calibrate(t, error_model="relative" if relative else "absolute", confidence=0.9).fit_for()
        covered += f.preston_low <= K_TRUE <= f.preston_high
    assert covered >= 85
    assert covered <= 97        # an interval that always covers would be too wide to be a 90 % interval


def test_exponent_fit_recovers_pressure_and_speed_exponents():
    rng = np.random.default_rng(3)
    f, w = design(n_rep=2)
    a, b = 0.8, 1.3
    orbit = np.where(np.arange(len(f)) % 2 == 0, 2.5e-3, 0.0)          # orbital and rotary pads mixed
    t = make_trials(force=f, spindle_speed=w, feed=0.03, passes=2, depth=1.0, orbit_radius=orbit)
    R = t.pad_radius
    speed_int = np.where(orbit > 0, (w * orbit) ** b * 2 * R / 0.03, 2 * w**b * R ** (b + 1) / ((b + 1) * 0.03))
    d = 1e-9 * 2 * t.pressure**a * speed_int * np.exp(0.03 * rng.standard_normal(len(f)))
    t = make_trials(force=f, spindle_speed=w, feed=0.03, passes=2, depth=d, orbit_radius=orbit)
    fit = calibrate(t, fit_exponents=True).fit_for()
    assert fit.pressure_exponent == pytest.approx(a, abs=0.05)
    assert fit.speed_exponent == pytest.approx(b, abs=0.05)
    assert fit.pressure_exponent_interval[0] < a < fit.pressure_exponent_interval[1]
    assert fit.speed_exponent_interval[0] < b < fit.speed_exponent_interval[1]
    assert fit.preston == pytest.approx(1e-9, rel=0.3)
    dep, lo, hi, plo, phi = fit.predict(t)
    assert np.all((lo < dep) & (dep < hi) & (plo < lo) & (hi < phi))
    assert np.median(np.abs(np.log(dep / d))) < 0.05


def test_exponent_fit_needs_varied_force_and_speed():
    t = make_trials(force=20.0, spindle_speed=np.array([100.0, 200, 300, 400]), feed=0.02, passes=1,
                    depth=np.array([1e-6, 2e-6, 3e-6, 4e-6]), orbit_radius=2e-3)
    with pytest.raises(InputError, match="distinct forces"):
        calibrate(t, fit_exponents=True)


def test_calibration_file_round_trips_into_a_tool_and_a_plan(tmp_path):
    t = synthetic(np.random.default_rng(5))
    hard = make_trials(force=t.force, spindle_speed=t.omega, feed=t.feed, passes=t.passes, depth=t.depth,
                       orbit_radius=t.orbit_radius, hardness=2e8)
    cal = calibrate(hard)
    path = write_calibration(tmp_path / "cal.json", cal)
    data = json.loads(path.read_text())
    assert data["fits"][0]["preston_coefficient_per_pa"] == cal.fit_for().preston
    assert data["fits"][0]["archard_coefficient"] == pytest.approx(cal.fit_for().preston * 2e8)
    back = load_calibration(path)
    assert back.fit_for() == cal.fit_for()
    tool = tool_with_calibration(Tool(), path)
    assert tool.preston == cal.fit_for().preston and tool.force == Tool().force
    # a plan simulated with the calibrated tool removes k_p / k_p,default times more, and the job
    # prediction's interval brackets it
    s = flat_plate()
    tr = time_path(ToolPath(s, [Pass(np.array([[0.1, 0.15, 0], [0.3, 0.15, 0]]), np.array([[0, 0, 1.0]] * 2))], "t"),
                   [FeedLimit(0.05)])
    base = simulate_removal(tr, s, Tool()).metrics["removal_max_m"]
    cald = simulate_removal(tr, s, tool).metrics["removal_max_m"]
    assert cald == pytest.approx(base * tool.preston / Tool().preston, rel=1e-9)
    pred = predict_job_depth(base, calibration=back, preston_used=Tool().preston)
    assert pred.low < cald < pred.high and pred.depth == pytest.approx(cald, rel=1e-9)
    one = predict_depth(back, tool, feed=0.05)
    assert one.pred_low < one.low < one.depth < one.high < one.pred_high


def test_exponent_calibration_linearises_at_the_tool_set_point(tmp_path):
    rng = np.random.default_rng(8)
    f, w = design()
    t0 = make_trials(force=f, spindle_speed=w, feed=0.02, passes=1, depth=1.0, orbit_radius=2.5e-3)
    d = 3e-10 * t0.passes * t0.pressure**0.9 * (w * 2.5e-3) ** 1.1 * 2 * t0.pad_radius / 0.02
    t = make_trials(force=f, spindle_speed=w, feed=0.02, passes=1, depth=d * np.exp(0.01 * rng.standard_normal(16)),
                    orbit_radius=2.5e-3)
    cal = calibrate(t, fit_exponents=True)
    back = load_calibration(write_calibration(tmp_path / "c.json", cal))
    fit = back.fit_for()
    assert not fit.linear
    tool = tool_with_calibration(Tool(force=20.0, spindle_speed=2000 * RPM), back)
    # the linearised k_p reproduces the exponent model's depth at the tool's set point
    pred = predict_depth(back, tool, feed=0.02)
    tt = make_trials(force=20.0, spindle_speed=2000 * RPM, feed=0.02, passes=1, depth=1.0, orbit_radius=2.5e-3)
    assert tool.preston * exposure(tt)[0] == pytest.approx(pred.depth, rel=1e-6)


def test_trials_csv_from_a_doe_template(tmp_path):
    path = write_doe(tmp_path / "trials.csv", {"grit": ["80", "120"], "force_N": [15.0, 30.0],
                                               "spindle_speed_rpm": [2000.0, 4000.0]},
                     fixed={"feed_m_per_s": 0.02, "passes": 3, "orbit_radius_m": 2.5e-3, "pad_radius_m": 0.0381})
    rows = list(csv.DictReader(open(path)))
    assert len(rows) == 8 and rows[0]["depth_m"] == ""
    k = {"80": 4e-10, "120": 2e-10}
    rng = np.random.default_rng(2)
    for r in rows:
        t = make_trials(force=float(r["force_N"]), spindle_speed=float(r["spindle_speed_rpm"]) * RPM, feed=0.02,
                        passes=3, depth=1.0, orbit_radius=2.5e-3)
        r["depth_m"] = repr(float(k[r["grit"]] * exposure(t)[0] * (1 + 0.02 * rng.standard_normal())))
    rows[-1]["depth_m"] = ""                         # one trial not run yet
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    assert len(read_trials(path)) == 7
    cal = calibrate(path)
    assert list(cal.fits) == ["80", "120"]
    for g in ("80", "120"):
        assert cal.fit_for(g).preston == pytest.approx(k[g], rel=0.05)
    with pytest.raises(InputError, match="choose one"):
        cal.fit_for()


def test_trials_csv_without_required_columns_is_refused(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("force_N,depth_m\n20,1e-6\n")
    with pytest.raises(InputError, match="missing spindle_speed_rpm"):
        read_trials(p)
    p.write_text("force_N,spindle_speed_rpm,feed_m_per_s,passes,depth_m\n20,1000,0.02,1,-1e-6\n")
    with pytest.raises(InputError, match="depth_m must be a positive"):
        read_trials(p)
