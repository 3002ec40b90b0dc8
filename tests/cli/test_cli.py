"""The swath command line: outputs, TOML jobs, unit suffixes, and refusals that leave nothing behind."""

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from swath.cli import main
from swath.cli.job import load_job_toml, settings_from_mapping
from swath.errors import InputError
from swath.trajectory import CSV_COLUMNS, read_csv


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "swath.cli", *args], capture_output=True, text=True, timeout=300)


def test_plan_writes_trajectory_metrics_and_report(tmp_path):
    out = tmp_path / "out"
    r = run_cli("plan", "--constant-feed", "example:plate", "--spacing", "60mm", "--feed", "80mm/s", "--max-accel", "none",
                "--out", str(out))
    assert r.returncode == 0, r.stderr
    assert "coverage" in r.stdout and "loading part" in r.stderr      # progress on stderr
    assert {p.name for p in out.iterdir()} >= {"trajectory.csv", "metrics.json", "report.html"}
    tr = read_csv(out / "trajectory.csv")
    assert (out / "trajectory.csv").read_text().split("\n", 1)[0].split(",")[:9] == list(CSV_COLUMNS)
    speed = np.linalg.norm(np.diff(tr.position, axis=0), axis=1) / np.diff(tr.t)
    both = tr.contact[1:] & tr.contact[:-1]
    assert np.allclose(speed[both], 0.08, rtol=0.01)
    m = json.loads((out / "metrics.json").read_text())
    assert m["settings"]["spacing_m"] == pytest.approx(0.06)
    assert m["metrics"]["coverage_fraction"] > 0.99
    assert m["metrics"]["contact_length_m"] == pytest.approx(tr.contact_length, rel=1e-6)
    # the summary gives the CoV inside the edge band too, as metrics.json holds it
    inner = m["metrics"]["interior_removal_cov"]
    assert f"removal CoV {m['metrics']['removal_cov']:.3f} ({inner:.3f} a pad radius in from the edges)" in r.stdout


def test_bad_input_exits_2_with_one_line_and_no_output(tmp_path):
    bad = tmp_path / "empty.stl"
    bad.write_bytes(b"")
    out = tmp_path / "out"
    r = run_cli("plan", "--constant-feed", str(bad), "--out", str(out))
    assert r.returncode == 2
    lines = [l for l in r.stderr.splitlines() if l.startswith("swath: error:")]
    assert len(lines) == 1 and "empty" in lines[0]
    assert not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".out")]


def test_failure_keeps_an_existing_output_directory_intact(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("old results")
    assert main(["-q", "plan", "--constant-feed", "example:plate", "--feed=-5mm/s", "--out", str(out)]) == 2
    assert (out / "keep.txt").read_text() == "old results"


@pytest.mark.parametrize("flag,value,fragment", [
    ("--pad-radius", "38.1 furlongs", "unknown unit"),
    ("--force", "20mm", "unknown unit 'mm' for a force"),
    ("--planner", "spiral", "planner must be one of raster, uniform, equidistant, wrap, got 'spiral'"),
    ("--units", "ft", "unknown length unit"),
])
def test_bad_settings_are_refused_by_name(tmp_path, capsys, flag, value, fragment):
    part = "example:plate" if flag != "--units" else str(tmp_path / "x.stl")
    if flag == "--units":
        import trimesh
        trimesh.creation.box([0.1, 0.1, 0.01]).export(part)
    code = main(["plan", "--constant-feed", part, flag, value, "--out", str(tmp_path / "o")])
    assert code == 2
    assert fragment in capsys.readouterr().err


def test_quantities_accept_unit_suffixes():
    s = settings_from_mapping({"part": "example:plate", "out": "o", "pad_radius": "3in", "force": "0.02kN",
                               "feed": "3m/min", "angle": "90", "depression": "0.5mm",
                               "max_centripetal": "2m/s2", "max_angular": "57.29578deg/s"})
    assert s.pad_radius == pytest.approx(0.0762) and s.force == pytest.approx(20.0)
    assert s.feed == pytest.approx(0.05) and s.direction == pytest.approx(math.pi / 2)
    assert s.depression == pytest.approx(5e-4) and s.max_angular == pytest.approx(1.0, rel=1e-6)
    assert settings_from_mapping({"part": "example:plate", "out": "o", "angle": "auto"}).direction is None
    with pytest.raises(InputError, match="unknown job setting 'colour'"):
        settings_from_mapping({"part": "example:plate", "out": "o", "colour": "red"})


def test_default_limits_apply_and_can_be_turned_off():
    base = {"part": "example:plate", "out": "o"}
    s = settings_from_mapping(base)
    assert (s.max_angular, s.max_centripetal, s.max_accel) == (1.0, 2.0, 1.0)
    names = sorted(type(c).__name__ for c in s.constraints())
    assert names == ["AngularSpeedLimit", "CentripetalLimit", "FeedLimit", "TangentialAccelLimit"]
    off = settings_from_mapping({**base, "max_angular": "none", "max_accel": "off", "max_centripetal": "3m/s2"})
    assert off.max_angular is None and off.max_accel is None and off.max_centripetal == pytest.approx(3.0)
    assert sorted(type(c).__name__ for c in off.constraints()) == ["CentripetalLimit", "FeedLimit"]


def test_written_trajectory_honours_the_limits_the_direction_was_chosen_under(tmp_path):
    """The uniform planner ranks directions by the cycle time under the job's own limits, and the
    written trajectory is timed under the same ones: peak in-contact angular speed <= limit + 3 %."""
    out = tmp_path / "o"
    assert main(["-q", "plan", "--constant-feed", "example:panel", "--planner", "uniform", "--max-angular", "0.8rad/s",
                 "--out", str(out)]) == 0
    tr = read_csv(out / "trajectory.csv")
    omega = np.linalg.norm(np.stack([tr.extra["wx"], tr.extra["wy"], tr.extra["wz"]], axis=1), axis=1)
    assert omega[tr.contact].max() <= 0.8 * 1.03
    m = json.loads((out / "metrics.json").read_text())
    assert "AngularSpeedLimit" in m["settings"]["plan"]["direction_rule"]
    assert m["settings"]["max_angular_rad_per_s"] == pytest.approx(0.8)


def test_toml_job_runs_relative_to_its_file(tmp_path):
    job = tmp_path / "job.toml"
    job.write_text('part = "example:plate"\nout = "result"\nspacing = "70mm"\nfeed = "100mm/s"\nangle = "0deg"\n')
    s = load_job_toml(job)
    assert s.out == str(tmp_path / "result") and s.spacing == pytest.approx(0.07)
    assert main(["-q", "run", str(job)]) == 0
    assert (tmp_path / "result" / "report.html").exists()
    bad = tmp_path / "bad.toml"
    bad.write_text("part = [unclosed\n")
    assert main(["-q", "run", str(bad)]) == 2


@pytest.mark.parametrize("planner,extra", [("uniform", ["--direction", "0deg", "--overlap", "10%"]),
                                           ("equidistant", ["--angle", "0deg"])])
def test_every_planner_runs_through_the_cli(tmp_path, planner, extra):
    out = tmp_path / planner
    assert main(["-q", "plan", "--constant-feed", "example:plate", "--planner", planner, *extra, "--out", str(out)]) == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["settings"]["planner"] == planner
    assert m["metrics"]["coverage_fraction"] > 0.995
    # plate 0.4 x 0.3 m: 4 or 5 passes 0.4 m long, whichever planner
    assert 1.5 < m["metrics"]["contact_length_m"] < 2.1


@pytest.mark.parametrize("command", ["plan", "fit", "register", "demo", "run", "calibrate", "doe", "batch"])
def test_every_command_prints_its_help(command, capsys):
    # argparse %-formats help text: a stray % in a help string or a default ("90%") used to crash --help.
    with pytest.raises(SystemExit) as exc:
        main([command, "--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: swath " + command) and "--help" in out


def test_a_pad_larger_than_the_part_suggests_only_what_can_explain_it(tmp_path, capsys):
    """A built-in part has known units, so only the pad is named; a mesh file read in metres that is
    too small for the pad gets no unit suggestion that would make it smaller still (inches)."""
    assert main(["-q", "plan", "--constant-feed", "example:plate", "--out", str(tmp_path / "a"), "--pad-radius", "500mm",
                 "--allow-unusual-process"]) == 2
    err = capsys.readouterr().err
    assert "smaller than the pad (1000.0 mm); choose a smaller --pad-radius" in err
    assert "--units" not in err and "--force-units" not in err
    from swath.examples import example_part
    from swath.io.mesh import save_surface_ply

    mesh = tmp_path / "plate.ply"
    save_surface_ply(example_part("plate"), mesh)        # 0.4 m across, read in metres
    assert main(["-q", "plan", "--constant-feed", str(mesh), "--units", "m", "--out", str(tmp_path / "b"), "--pad-radius", "500mm",
                 "--allow-unusual-process"]) == 2
    err = capsys.readouterr().err
    assert "smaller than the pad" in err and "inches" not in err and "--force-units" in err
    assert "--units in" not in err and "--units" not in err.split("smaller than the pad")[1].split("--force")[0]
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


@pytest.mark.parametrize("argv,fragment", [
    (["plan", "example:plate", "--side", "+q"], "side: expected a tool side such as '+z'"),
    (["plan", "example:plate", "--side", "0,0,0"], "side: the tool side '0,0,0' is a zero vector"),
    (["plan", "example:plate", "--direction", "north"], "direction: expected an angle such as"),
    (["fit", "example:plate"], "swath fit reads the scan from a file"),
    (["fit", "scan.xyz", "--side", "up"], "--side: expected a tool side"),
    (["register", "example:plate", "scan.ply"], "swath register reads the CAD from a file"),
    (["register", "cad.stl", "example:plate"], "swath register reads the scan from a file"),
    (["rework", "example:plate", "after.xyz", "--units", "mm"], "swath rework reads the CAD from a file"),
    (["rework", "cad.stl", "example:plate", "--units", "mm"], "swath rework reads the scan after the run from a file"),
    (["big", "nothere.npz"], "nothere.npz: no such file; check the path"),
    (["plan", "example:plate", "--tool-mass", "2kg"], "--tool-mass applies with --force-control"),
    (["plan", "example:plate", "--tool-tilt", "30deg", "--no-gravity-compensation"],
     "--tool-tilt, --no-gravity-compensation apply with --force-control"),
    (["plan", "example:plate", "--grit", "P120"], "--grit picks a grit from a calibration file"),
    (["plan", "."], "is a directory; give the path of a mesh file"),
    (["plan", "example:plate", "--robot", "ur3e", "--base", "5m,0,0,0,0,0", "--program", "urscript"],
     "none of the"),
])
def test_inputs_that_cannot_apply_are_refused_first(tmp_path, capsys, argv, fragment):
    """Refused before any file is read or written: a tool side that is no direction (it used to
    pass unchecked on an open part), a built-in part given to a command that reads files, options
    that only apply with another (they used to be ignored), a directory given as the part, and a
    robot cell where no pose is reachable (found after planning; still nothing is written)."""
    out = tmp_path / "out"
    assert main(["-q", *argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and fragment in err[0]
    assert not out.exists()


def test_a_partly_unreachable_robot_cell_is_a_job_warning_said_once(tmp_path):
    """Poses no configuration reaches are left out of the robot programs, so the report must say so
    (they used to reach the console only, once for every cell the placement search tried, and
    metrics.json's warnings stayed empty).  The robot and force figures all name their unit (or
    say they are pure numbers), so the job logs no naming complaint."""
    out = tmp_path / "out"
    r = run_cli("plan", "--constant-feed", "example:plate", "--spacing", "100mm", "--robot", "ur3e", "--base", "0.2,-0.15,0,0,0,0",
                "--program", "urscript", "--force-control", "--out", str(out))
    assert r.returncode == 0, r.stderr
    doc = json.loads((out / "metrics.json").read_text())
    m = doc["metrics"]
    assert 0 < m["robot_reachable_fraction"] < 1
    robot = [w for w in m["warnings"] if w.startswith("robot: ") and "unreachable" in w]
    n_bad = round((1 - m["robot_reachable_fraction"]) * m["robot_n_poses"])
    assert len(robot) == 1 and f"{n_bad} of {m['robot_n_poses']} poses are unreachable for ur3e" in robot[0]
    assert r.stderr.count("poses are unreachable") == 1
    assert "without a unit suffix" not in r.stderr
    assert {"robot_min_manipulability", "robot_min_wrist_sin", "force_gain_margin"} <= set(m)
    assert robot[0] in (out / "report.html").read_text()
