"""Job files and flags are checked key by key before any work; every mistake is one line naming the key."""

import re

import pytest

from swath.cli import main
from swath.cli.settings import settings_from_mapping
from swath.errors import InputError

BASE = {"part": "example:plate", "out": "o"}


@pytest.mark.parametrize("key", ["all_pieces", "force_units", "fit", "overwrite"])
def test_a_quoted_boolean_is_refused(key):
    with pytest.raises(InputError, match=f"{key} must be true or false"):
        settings_from_mapping({**BASE, key: "false"})


@pytest.mark.parametrize("values,fragment", [
    ({"planner": ["raster", "uniform"]}, "planner must be text"),
    ({"units": ["mm"]}, "units must be text"),
    ({"feed": 50}, "feed = 50 has no unit"),
    ({"pad_radius": "38.1"}, "pad_radius = 38.1 has no unit"),
    ({"feed": "-5mm/s"}, "feed must be positive"),
    ({"max_accel": "0m/s2"}, "max_accel must be positive"),
    ({"overlap": "150%"}, "overlap = '150%' is out of range: [0, 90] %"),
    ({"force": "1e9N"}, "force = '1e9N' is out of range: at most 10000 N"),
    ({"lead_angle": "60deg"}, "lead_angle = '60deg' is out of range: [-45, 45] deg"),    # in the unit given,
    ({"lead_angle": "1.2rad"}, "lead_angle = '1.2rad' is out of range: [-0.785398, 0.785398] rad"),  # not SI
    ({"lead_angle": 60}, "lead_angle = 60 is out of range: [-45, 45] deg"),              # a bare angle: degrees
    ({"overlap": "10%"}, "the raster planner does not take 'overlap'; planners that do: uniform"),
    ({"planner_options": {"spacing": "abc"}}, "planner_options.spacing"),
    ({"planner_options": {"spcing": "20mm"}}, "the raster planner does not take 'spcing'"),
    ({"planner_options": "x"}, "planner_options must be a table"),
    ({"planner": "uniform", "planner_options": {"work_spacing": 2}}, "planner_options.work_spacing = 2 has no unit"),
    ({"planner": "uniform", "planner_options": {"max_passes": "many"}}, "planner_options.max_passes must be a whole"),
    ({"planner": "uniform", "planner_options": {"workers": 0}}, "planner_options.workers must be a whole number >= 1"),
    ({"planner": "uniform", "planner_options": {"cost": "time"}}, "planner_options.cost cannot be set from a job"),
    ({"planner": "equidistant", "planner_options": {"distance": "exact"}}, "planner_options.distance must be one of"),
    ({"planner_options": {"fill_gaps": "no"}}, "planner_options.fill_gaps must be true or false"),
    ({"colour": "red"}, "unknown job setting 'colour'; known settings"),
    ({"planer": "raster"}, "unknown job setting 'planer'; did you mean 'planner'?"),
    ({"planner": "uniform", "planner_options": {"work_spacng": "2mm"}}, "did you mean 'work_spacing'?"),
])
def test_bad_values_name_their_key(values, fragment):
    with pytest.raises(InputError, match=re.escape(fragment)):
        settings_from_mapping({**BASE, **values})


def test_unit_names_and_case_are_accepted():
    assert settings_from_mapping({**BASE, "units": "MM"}).units == "mm"
    assert settings_from_mapping({**BASE, "units": "inch"}).units == "in"
    assert settings_from_mapping({**BASE, "units": "Millimetres"}).units == "mm"


@pytest.mark.parametrize("text,fragment", [
    ('job = "x"\n', "'job' must be a table"),
    ('part = "example:plate"\nout = "o"\nplanner = ["raster"]\n', "planner must be text"),
    ('part = "example:plate"\nout = "o"\nall_pieces = "false"\n', "all_pieces must be true or false"),
    ('part = "example:plate"\nout = "o"\n[planner_options]\nspcing = "20mm"\n', "does not take 'spcing'"),
])
def test_job_files_fail_with_one_line_and_exit_2(tmp_path, capsys, text, fragment):
    job = tmp_path / "job.toml"
    job.write_text(text)
    assert main(["-q", "run", str(job)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("swath: error:") and fragment in err[0]
    assert not (tmp_path / "o").exists()


def test_a_directory_as_the_job_file_is_refused(tmp_path, capsys):
    assert main(["-q", "run", str(tmp_path)]) == 2
    assert "is a directory" in capsys.readouterr().err


def test_values_are_refused_before_the_part_is_loaded(tmp_path, capsys):
    """A bad limit with a part file that does not exist: the limit is named, not the file."""
    code = main(["-q", "plan", "--constant-feed", str(tmp_path / "missing.stl"), "--max-accel=0", "--out", str(tmp_path / "o")])
    assert code == 2
    assert "max_accel must be positive" in capsys.readouterr().err


def test_a_negative_value_reaches_the_check_instead_of_argparse(tmp_path, capsys):
    assert main(["-q", "plan", "--constant-feed", "example:plate", "--feed", "-5mm/s", "--out", str(tmp_path / "o")]) == 2
    assert "feed must be positive" in capsys.readouterr().err


def test_a_calibration_file_round_trips_into_a_plan(tmp_path):
    """swath calibrate on trials made with a known k_p, then swath plan --calibration plans with it."""
    import json
    import math

    import numpy as np

    from swath.simulate.calibrate import exposure, make_trials

    rng = np.random.default_rng(3)
    force = np.repeat([10.0, 20.0, 30.0], 4)
    rpm = np.tile([6000.0, 10000.0], 6)
    feed = np.tile([0.02, 0.02, 0.05, 0.05], 3)
    k_true = 2.0e-10
    t = make_trials(force=force, spindle_speed=rpm * 2 * math.pi / 60, feed=feed, passes=3, depth=1.0,
                    orbit_radius=2.5e-3)
    depth = k_true * exposure(t) * (1 + 0.03 * rng.standard_normal(len(force)))
    rows = ["trial,grit,force_N,spindle_speed_rpm,orbit_radius_m,pad_radius_m,feed_m_per_s,passes,depth_m"]
    rows += [f"{i + 1},120,{f},{r},0.0025,0.0381,{v},3,{d:.6e}" for i, (f, r, v, d) in enumerate(zip(force, rpm, feed, depth))]
    trials = tmp_path / "trials.csv"
    trials.write_text("\n".join(rows) + "\n")
    assert main(["-q", "calibrate", str(trials), "--out", str(tmp_path / "cal")]) == 0
    cal = json.loads((tmp_path / "cal" / "calibration.json").read_text())
    fitted = json.dumps(cal)
    assert "preston" in fitted
    assert main(["-q", "plan", "--constant-feed", "example:plate", "--spacing", "80mm", "--calibration",
                 str(tmp_path / "cal" / "calibration.json"), "--out", str(tmp_path / "o")]) == 0
    used = json.loads((tmp_path / "o" / "metrics.json").read_text())["metrics"]["preston_coefficient_per_Pa"]
    assert used == pytest.approx(k_true, rel=0.05)


def test_feed_optimisation_runs_through_the_job_and_refuses_a_target_with_constant_feed(tmp_path, capsys):
    import json

    from swath.trajectory import read_csv

    assert main(["-q", "plan", "example:plate", "--constant-feed", "--target-depth", "3um",
                 "--out", str(tmp_path / "x")]) == 2
    assert "--constant-feed runs the feed given" in capsys.readouterr().err
    out = tmp_path / "o"
    assert main(["plan", "example:plate", "--optimise-feed", "--target-depth", "3um", "--out", str(out)]) == 0
    # a line for the kernel, each HiGHS solve and each simulated check (a large part takes a minute)
    err = capsys.readouterr().err
    for line in ("optimising the feed: removal kernel", "optimising the feed: dwell programme, HiGHS solve 1",
                 "optimising the feed: simulated check 1"):
        assert line in err
    assert {"feed_along_passes.png", "depth_vs_target.png", "residual_histogram.png"} <= {p.name for p in out.iterdir()}
    m = json.loads((out / "metrics.json").read_text())["metrics"]
    assert any(k.startswith("feed_") for k in m)
    tr = read_csv(out / "trajectory.csv")
    v = tr.feed[tr.contact]
    assert v.max() <= 0.05 * 1.001 and v.min() < 0.9 * v.max()        # the feed now varies along the passes


def test_join_gap_picks_a_tour_and_refuses_a_fixed_sequence(tmp_path):
    from swath.cli.job import order_method, order_options
    from swath.core import ToolPath

    s = settings_from_mapping({"part": "example:plate", "out": str(tmp_path / "o"), "join_gap": "76mm"})
    assert s.join_gap == pytest.approx(0.076) and s.as_record()["join_gap_m"] == pytest.approx(0.076)
    tp = ToolPath(None, (), "raster", {"order_hint": "snake"})
    assert order_method(tp, s) == "gtsp" and order_options(tp, s)["join_gap"] == pytest.approx(0.076)
    plain = settings_from_mapping({"part": "example:plate", "out": str(tmp_path / "o")})
    assert order_method(tp, plain) == "snake" and order_options(tp, plain) == {}
    with pytest.raises(InputError, match="snake order keeps the planner's sequence"):
        settings_from_mapping({"part": "example:plate", "out": str(tmp_path / "o"), "join_gap": "76mm",
                               "order": "snake"})


def test_spacing_optimisation_is_reachable_from_jobs(tmp_path, capsys):
    import json

    from swath.contact import Tool
    from swath.feed import ripple_spacing

    assert main(["-q", "plan", "example:plate", "--optimise-spacing", "greedy", "--out", str(tmp_path / "x")]) == 2
    assert "add --target-depth" in capsys.readouterr().err
    assert main(["-q", "plan", "example:plate", "--optimise-spacing", "ripple", "--spacing", "40mm",
                 "--out", str(tmp_path / "y")]) == 2
    assert "without --spacing" in capsys.readouterr().err
    assert main(["-q", "plan", "example:plate", "--optimise-spacing", "wavy", "--out", str(tmp_path / "z")]) == 2
    assert "ripple, greedy, joint" in capsys.readouterr().err
    out = tmp_path / "o"
    assert main(["-q", "plan", "example:plate", "--optimise-spacing", "ripple", "--constant-feed",
                 "--out", str(out)]) == 0
    doc = json.loads((out / "metrics.json").read_text())
    assert doc["settings"]["optimise_spacing"] == "ripple"
    assert doc["metrics"]["spacing_m"] == pytest.approx(ripple_spacing(Tool())[0], rel=1e-9)


def test_order_groups_passes_gives_every_pass_its_own_group(tmp_path):
    from swath.cli.job import order_options
    from swath.core import Pass, ToolPath

    pts = [[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]]
    tp = ToolPath(None, tuple(Pass(pts, [[0, 0, 1]] * 2) for _ in range(3)), "raster", {"order_hint": "gtsp"})
    s = settings_from_mapping({"part": "example:plate", "out": str(tmp_path / "o")})     # passes by default
    assert order_options(tp, s)["groups"] == [[0], [1], [2]]
    assert "groups" not in order_options(tp, settings_from_mapping({"part": "example:plate", "out": str(tmp_path / "o"),
                                                                    "order": "gtsp", "order_groups": "regions"}))
    with pytest.raises(InputError, match="order_groups"):
        settings_from_mapping({"part": "example:plate", "out": str(tmp_path / "o"), "order_groups": "cells"})


def test_order_objective_flag_reaches_the_job_settings(tmp_path):
    from swath.cli.main import _settings_from_args, build_parser

    args = build_parser().parse_args(["plan", "example:plate", "--out", str(tmp_path / "o"),
                                      "--order-objective", "length"])
    assert _settings_from_args(args).order_objective == "length"
    args = build_parser().parse_args(["plan", "example:plate", "--out", str(tmp_path / "o")])
    assert _settings_from_args(args).order_objective == "time"
    with pytest.raises(SystemExit):
        build_parser().parse_args(["plan", "example:plate", "--out", "o", "--order-objective", "air"])


def test_removal_sampling_and_feed_check_flags_reach_the_job_settings(tmp_path):
    from swath.cli.main import _settings_from_args, build_parser

    out = str(tmp_path / "o")
    defaults = _settings_from_args(build_parser().parse_args(["plan", "example:plate", "--out", out]))
    assert defaults.removal_sampling == "lattice" and defaults.feed_simulate_check is True
    assert settings_from_mapping({"part": "example:plate", "out": out}).removal_sampling == "lattice"
    chosen = _settings_from_args(build_parser().parse_args(
        ["plan", "example:plate", "--out", out, "--removal-sampling", "mesh", "--no-feed-simulate-check"]))
    assert chosen.removal_sampling == "mesh" and chosen.feed_simulate_check is False
    assert settings_from_mapping({"part": "example:plate", "out": out, "removal_sampling": "mesh"}).removal_sampling \
        == "mesh"
    with pytest.raises(InputError, match="removal_sampling"):
        settings_from_mapping({"part": "example:plate", "out": out, "removal_sampling": "grid"})


def test_planner_options_take_units_and_reach_the_planner():
    """A length planner option given with a unit arrives in metres (it used to reach the planner
    as text and fail deep inside it with a traceback)."""
    from swath.cli.job import planner_arguments

    settings = settings_from_mapping({**BASE, "planner": "uniform",
                                      "planner_options": {"work_spacing": "2.5mm", "max_passes": 40}})
    args = planner_arguments(settings)
    assert args["work_spacing"] == pytest.approx(2.5e-3) and args["max_passes"] == 40
    raster = planner_arguments(settings_from_mapping({**BASE, "planner_options": {"edge_margin": "0.5 cm"}}))
    assert raster["edge_margin"] == pytest.approx(5e-3)
    spread = planner_arguments(settings_from_mapping({**BASE, "planner_options": {"edge_margin": float("inf")}}))
    assert spread["edge_margin"] == float("inf")
