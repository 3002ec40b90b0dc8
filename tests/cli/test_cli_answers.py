"""The first answers a user checks: implausible process settings and mistyped options."""

import logging

import pytest

from swath.cli.main import build_parser, main
from swath.cli.settings import PROCESS_RANGES, settings_from_mapping
from swath.errors import InputError

BASE = {"part": "example:plate", "out": "unused"}


@pytest.mark.parametrize("key,value,shown", [
    ("feed", "5m/s", "feed = 5000 mm/s is outside the feed of a sanding robot (1–500 mm/s)"),
    ("feed", "0.5mm/s", "feed = 0.5 mm/s is outside the feed of a sanding robot (1–500 mm/s)"),
    ("force", "0.9kN", "force = 900 N is outside the normal force of a sanding or polishing head (1–500 N)"),
    ("force", "0.5N", "force = 0.5 N is outside"),
    ("pad_radius", "2mm", "pad_radius = 2 mm is outside the radius of a sanding or polishing pad (5–150 mm)"),
    ("pad_radius", "8in", "pad_radius = 203.2 mm is outside"),
])
def test_a_process_setting_outside_what_a_sanding_robot_does_is_refused_naming_the_range(key, value, shown):
    with pytest.raises(InputError, match="check the value and its unit, or add --allow-unusual-process") as exc:
        settings_from_mapping({**BASE, key: value})
    assert shown in str(exc.value)


@pytest.mark.parametrize("key,value,si", [("feed", "1mm/s", 1e-3), ("feed", "500mm/s", 0.5), ("force", "1N", 1.0),
                                          ("force", "500N", 500.0), ("pad_radius", "5mm", 5e-3),
                                          ("pad_radius", "150mm", 0.15)])
def test_the_range_ends_are_accepted(key, value, si):
    assert getattr(settings_from_mapping({**BASE, key: value}), key) == pytest.approx(si, rel=1e-12)


def test_the_escape_plans_an_unusual_process_with_a_warning(caplog):
    with caplog.at_level(logging.WARNING, logger="swath"):
        s = settings_from_mapping({**BASE, "feed": "5m/s", "allow_unusual_process": True})
    assert s.feed == pytest.approx(5.0) and s.allow_unusual_process
    assert "feed = 5000 mm/s is outside the feed of a sanding robot (1–500 mm/s); planning it as asked" in caplog.text


def test_the_spindle_range_is_stated_in_rpm():
    rng = PROCESS_RANGES["spindle_speed"]
    assert rng.text() == "60–20000 rpm"
    assert rng.lo * rng.scale == pytest.approx(60.0) and rng.hi == pytest.approx(20000 * 2 * 3.141592653589793 / 60)


def test_the_cli_refuses_a_feed_of_5_m_per_s_before_any_work(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["-q", "plan", "example:plate", "--feed", "5m/s", "--out", str(out)]) == 2
    assert "feed = 5000 mm/s is outside the feed of a sanding robot (1–500 mm/s)" in capsys.readouterr().err
    assert not out.exists()


def test_the_help_states_the_ranges(capsys):
    with pytest.raises(SystemExit):
        main(["plan", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "within 1–500 mm/s" in text and "within 1–500 N" in text and "within 5–150 mm" in text
    assert "--allow-unusual-process" in text


@pytest.mark.parametrize("argv,typo,near", [
    (["plan", "example:plate", "--feeed", "50mm/s", "--out", "o"], "--feeed", "--feed"),
    (["plan", "--feeed", "50mm/s", "example:plate", "--out", "o"], "--feeed", "--feed"),
    (["plan", "example:plate", "--feed=50mm/s", "--ot", "o"], "--ot", "--out"),
    (["demo", "--pad-radus", "30mm", "--out", "o"], "--pad-radus", "--pad-radius"),
    (["fit", "scan.ply", "--paramterization", "rows", "--out", "o"], "--paramterization", "--parameterization"),
    (["register", "a.ply", "b.ply", "--tabel", "--out", "o"], "--tabel", "--table"),
    (["run", "job.toml", "--overwite"], "--overwite", None),
    (["batch", "sweep.toml", "--workrs", "2"], "--workrs", "--workers"),
    (["calibrate", "trials.csv", "--ot", "o"], "--ot", "--out"),
    (["doe", "--ot", "o"], "--ot", "--out"),
    (["--quiett", "plan", "example:plate"], "--quiett", "--quiet"),
])
def test_a_mistyped_option_names_the_nearest_option_of_its_subcommand(argv, typo, near, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    if near:
        assert f"error: unknown option {typo}; did you mean {near}?" in err
    else:
        assert f"error: unknown option {typo}; swath run --help lists the options" in err
    command = argv[0] if not argv[0].startswith("-") else None
    assert err.startswith(f"usage: swath {command}" if command else "usage: swath")


def test_every_subcommand_option_is_known_and_a_prefix_is_left_to_argparse(capsys):
    parser = build_parser()
    sub = next(a for a in parser._actions if hasattr(a, "choices") and isinstance(a.choices, dict))
    for name, sp in sub.choices.items():
        for option in (o for a in sp._actions for o in a.option_strings if o.startswith("--")):
            from swath.cli.main import _check_option_names

            _check_option_names(parser, [name, option])      # no refusal
    with pytest.raises(SystemExit):
        main(["plan", "example:plate", "--fe", "50mm/s", "--out", "o"])
    assert "ambiguous option: --fe could match --feed, --feed-simulate-check" in capsys.readouterr().err
