"""Pad wear along a job: media ages, changes between passes, the compensating feed, the programs' stops."""

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from swath.contact import Tool
from swath.errors import InputError
from swath.examples import flat_plate
from swath.plan import Pass, ToolPath
from swath.process import compensate_wear, media_schedule, program_lines, trajectory_with_media
from swath.process.media import change_limit, media_stops
from swath.simulate import simulate_removal
from swath.trajectory import FeedLimit, time_path


def plate_job(n=10, feed=0.05):
    """n straight passes of 0.3 m on the 0.4 × 0.3 m plate, 25 mm apart: 6 s of contact each at 50 mm/s."""
    s = flat_plate()
    ys = 0.03 + 0.025 * np.arange(n)
    ps = [Pass(np.array([[0.05, y, 0.0], [0.35, y, 0.0]]), np.array([[0, 0, 1.0]] * 2)) for y in ys]
    ps = [p if i % 2 == 0 else p.reversed() for i, p in enumerate(ps)]
    return s, time_path(ToolPath(s, ps, "test"), [FeedLimit(feed)])


def test_media_changes_between_passes_before_the_age_would_pass_the_limit():
    _, tr = plate_job()
    sched = media_schedule(tr, 0.0, every=20.0)
    # 6 s passes: three fit in 20 s (18 s), the fourth would end at 24 s: changes before passes 3, 6, 9
    assert sched.changes == 3
    first_on_new = [int(tr.pass_index[np.flatnonzero(tr.pass_index >= 0)[0]])]
    for c in sched.change_index:
        assert not tr.contact[c]                                   # retracted, in the air move
        nxt = np.flatnonzero((np.arange(len(tr)) > c) & (tr.pass_index >= 0))[0]
        first_on_new.append(int(tr.pass_index[nxt]))
    assert first_on_new == [0, 3, 6, 9]
    assert sched.age.max() == pytest.approx(18.0, rel=1e-6)
    assert np.all(np.diff(sched.media) >= 0) and sched.media[-1] == 3
    on3 = tr.pass_index == 3
    assert sched.age[on3].min() == pytest.approx(0.0, abs=1e-9)     # fresh media on pass 3
    assert np.all(sched.factor == 1.0)                               # no wear: the schedule only
    out = trajectory_with_media(tr, sched)
    assert np.array_equal(out.extra["media"], sched.media) and out.metadata["media_changes"] == 3
    assert "media,media_age" in out.to_csv_text().splitlines()[0]


def test_a_removal_loss_sets_the_age_limit():
    lam = 1.0 / 900
    assert change_limit(lam, loss=0.2) == pytest.approx(-math.log(0.8) * 900)
    assert change_limit(lam, every=100.0, loss=0.2) == 100.0
    assert change_limit(0.0) == math.inf
    with pytest.raises(InputError, match="wears"):
        change_limit(0.0, loss=0.2)
    _, tr = plate_job()
    # 20 % in 200.8 s at λ = 1/900 s; 1/90 s: 20 % in 20.1 s, as the 20 s schedule above
    assert media_schedule(tr, 1 / 90, loss=0.2).changes == 3


def test_wear_compensation_restores_the_fresh_removal():
    """A pad losing 1/60 of its cut per second of contact, changed every 30 s: the compensated feed
    removes what the fresh pad does (mean and CoV), the uncompensated one much less."""
    s, tr = plate_job()
    tool = Tool()
    lam = 1.0 / 60
    fresh = simulate_removal(tr, s, tool, sample_spacing=3e-3).metrics
    worn = media_schedule(tr, lam, every=30.0)
    plain = simulate_removal(tr, s, tool, sample_spacing=3e-3, rate_scale=worn.factor).metrics
    comp, sched = compensate_wear(tr, lam, every=30.0)
    fixed = simulate_removal(comp, s, tool, sample_spacing=3e-3, rate_scale=sched.factor).metrics
    assert plain["removal_mean_m"] < 0.9 * fresh["removal_mean_m"]
    assert fixed["removal_mean_m"] == pytest.approx(fresh["removal_mean_m"], rel=0.01)
    assert abs(fixed["removal_cov"] - fresh["removal_cov"]) < 0.01
    # the feed falls by the wear factor: the slowest contact sample runs at exp(−λ a_max) of the feed
    c = comp.contact
    assert comp.feed[c].min() == pytest.approx(0.05 * sched.factor[c].min(), rel=1e-9)
    # A media that removes what E seconds of fresh media would runs T(E) = −ln(1 − λE)/λ: three 6 s passes
    # take 21.4 s, four would take 30.6 s > 30 s, so the ten passes run on media of 3, 3, 3 and 1 passes.
    T = lambda E: -math.log1p(-lam * E) / lam
    assert sched.changes == 3 and sched.age.max() <= 30.0
    added = comp.duration - tr.duration
    assert added == pytest.approx(3 * (T(18.0) - 18.0) + (T(6.0) - 6.0), rel=0.02)


def test_program_statements_for_the_operator():
    assert program_lines("urscript", 2)[1].startswith('  popup("swath: change the abrasive (media change 2)')
    assert program_lines("rapid", 1, "    ")[1:] == ['    TPWrite "swath: change the abrasive (media change 1), then '
                                                     'continue";', "    Stop;"]
    assert program_lines("krl", 3)[-1] == "  HALT"
    with pytest.raises(InputError):
        program_lines("gcode", 1)
    _, tr = plate_job(4)
    tr = trajectory_with_media(tr, media_schedule(tr, 0.0, every=7.0))
    idx = np.arange(0, len(tr), 5)
    stops = media_stops("krl", tr, idx)
    assert sum(len(v) for v in stops.values()) == 2 * 3        # three changes, two lines each


@pytest.mark.slow
def test_a_job_with_a_media_schedule_stops_every_program_for_the_operator(tmp_path):
    # each vendor's program for its own maker's arm (RAPID for ABB, KRL for KUKA, URScript for UR)
    runs = {"ur10e": ("0.5,-0.15,0,0,0,0", "urscript,ros,csv"), "irb4600": ("1.2,-0.15,0,0,0,0", "rapid"),
            "kr120": ("1.6,-0.15,0,0,0,0", "krl")}
    for robot_name, (base, programs) in runs.items():
        out = tmp_path / robot_name
        r = subprocess.run([sys.executable, "-m", "swath.cli", "plan", "--constant-feed", "example:plate", "--spacing", "100mm", "--robot",
                            robot_name, "--base", base, "--program", programs, "--tcp", "0,0,150mm,0,0,0",
                            "--wear-rate", "0.002/s", "--media-change", "10s", "--out", str(out)],
                           capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        assert "without a unit suffix" not in r.stderr          # every new metric names its unit
        m = json.loads((out / "metrics.json").read_text())["metrics"]
        n = m["media_changes"]
        # (the robot's own re-timing and unreachable stretches set how much contact time there is)
        assert n >= 1, (robot_name, n)
        assert len(m["media_change_times_s"]) == n and m["wear_compensation"]
        robot = out / "robot"
        if robot_name == "ur10e":
            assert (robot / "swath_job.script").read_text().count("popup(") == n
            assert (robot / "joint_trajectory.yaml").read_text().count("# media change") == n
            media = np.loadtxt(robot / "joints.csv", delimiter=",", skiprows=1, ndmin=2)[:, -1]
            assert (robot / "joints.csv").read_text().splitlines()[0].endswith(",media")
            assert int(np.sum(np.diff(media) > 0)) == n and media[0] == 0
        elif robot_name == "irb4600":
            rapid = (robot / "SwathJob.mod").read_text()
            assert rapid.count("TPWrite") == n and rapid.count("Stop;") == n
        else:
            assert (robot / "swath_job.src").read_text().count("HALT") == n
        header = (out / "trajectory.csv").read_text().splitlines()[0].split(",")
        assert "media" in header and "media_age" in header
