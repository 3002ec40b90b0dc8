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
    assert main(["-q", "plan", "--constant-feed", "example:plate", "--feed", "5m/s", "--out", str(out)]) == 2
    assert "feed = 5000 mm/s is outside the feed of a sanding robot (1–500 mm/s)" in capsys.readouterr().err
    assert not out.exists()


def test_the_help_states_the_ranges(capsys):
    with pytest.raises(SystemExit):
        main(["plan", "--constant-feed", "--help"])
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
        main(["plan", "--constant-feed", "example:plate", "--fe", "50mm/s", "--out", "o"])
    assert "ambiguous option: --fe could match --feed, --feed-simulate-check" in capsys.readouterr().err


# --- cosmetics -------------------------------------------------------------------------------------
def test_the_summary_names_files_without_a_doubled_separator():
    from types import SimpleNamespace

    from swath.cli.main import _in_folder, _summary

    assert _in_folder("out_p1/", "trajectory.csv") == "out_p1/trajectory.csv"
    assert _in_folder("out_p1", "trajectory.csv") == "out_p1/trajectory.csv"
    metrics = dict(n_passes=4, contact_length_m=1.6, air_length_m=0.365, cycle_time_s=16.2, coverage_fraction=1.0,
                   removal_cov=0.2, coverage_lower_bound_m=1.575, efficiency=0.984)
    text = _summary(SimpleNamespace(out="out_p1/"), metrics)
    assert text.startswith("wrote out_p1/trajectory.csv, metrics.json, report.html") and "//" not in text


def test_a_unit_slip_names_inches_in_words():
    from swath.io.checks import check_extent

    # 10.5 units across read in mm is a slip that inches explain (0.267 m)
    with pytest.raises(InputError) as exc:
        check_extent(10.5, "mm", False, "wavy.ply")
    text = str(exc.value)
    assert "read in inches it would be 0.267 m" in text and " in in " not in text and "--units in" in text


def test_the_help_lists_every_built_in_example():
    from swath.examples import PARTS

    parser = build_parser()
    sub = next(a for a in parser._actions if hasattr(a, "choices") and isinstance(a.choices, dict))
    plan_help = " ".join(sub.choices["plan"].format_help().split())
    demo_help = " ".join(sub.choices["demo"].format_help().split())
    assert "hub" in PARTS
    assert f"example:NAME ({', '.join(PARTS)})" in plan_help
    assert ", ".join(f"example:{name}" for name in PARTS) in demo_help


def test_a_scan_fit_warning_has_no_function_name_prefix(caplog):
    import numpy as np

    from swath.examples import flat_plate
    try:
        from swath.scan import fit_patch  # where the scan stage will hold it
    except ImportError:
        from swath.surface.fit import fit_patch

    a = flat_plate(size_x=0.1, size_y=0.1, spacing=5e-3).vertices
    with caplog.at_level(logging.WARNING):
        _, report = fit_patch(np.concatenate([a, [[1.0, 1.0, 1.0], [1.0, 1.0, 1.001]]]))
    assert report.n_dropped == 2
    # (a CLI run earlier in the same process may have installed the filter that appends "[W-...]")
    messages = [r.getMessage().split(" [W-")[0] for r in caplog.records if r.levelno >= logging.WARNING]
    assert any(m == "dropping 2 stray points that lie apart from the patch" for m in messages)
    assert not any(m.startswith("fit_patch") for m in messages)


def test_the_local_ray_keeps_its_token_notice_out_of_the_sweep(monkeypatch, caplog):
    import importlib

    ray = pytest.importorskip("ray")
    from swath.cli import batch_ray

    try:                                               # Rays with token authentication name the logger so
        module = importlib.import_module(batch_ray.AUTH_NOTICE_LOGGER)
    except ImportError:                                # older Rays have no such notice
        module = None
    if module is not None:
        assert module.logger.name == batch_ray.AUTH_NOTICE_LOGGER
    notice = logging.getLogger(batch_ray.AUTH_NOTICE_LOGGER)
    before = notice.level
    seen = {}

    def fake_init(**options):
        seen.update(options)
        notice.warning("Token authentication is enabled for this Ray cluster.")
        notice.error("a real failure is still shown")

    monkeypatch.setattr(ray, "init", fake_init)
    notice.addHandler(caplog.handler)                  # Ray's loggers do not propagate to the root
    try:
        with caplog.at_level(logging.WARNING):
            batch_ray.start_local_ray(2, warm=False)
    finally:
        notice.removeHandler(caplog.handler)
    assert seen["num_cpus"] == 2 and seen["address"] == "local"
    assert "Token authentication" not in caplog.text and "a real failure is still shown" in caplog.text
    assert notice.level == before


# --- air routes: the kept plan only, in the user's unit --------------------------------------------
def _sandwich():
    import numpy as np

    from swath.core import Pass, ToolPath
    from swath.examples import flat_plate
    from swath.surface import Surface

    floor, roof = flat_plate(size_x=0.2, size_y=0.1, spacing=0.01), flat_plate(size_x=0.2, size_y=0.1, spacing=0.01)
    v = np.vstack([floor.vertices, roof.vertices + [0.0, 0.0, 0.02]])
    surface = Surface(v, np.vstack([floor.faces, roof.faces + len(floor.vertices)]), name="sandwich")
    up = np.tile([0.0, 0.0, 1.0], (2, 1))
    passes = [Pass(np.array([[0.05, y, 0.0], [0.15, y, 0.0]]), up) for y in (0.04, 0.06)]
    return ToolPath(surface, passes, "test")


def test_a_blocked_air_route_is_not_a_warning_until_it_is_in_the_kept_plan(caplog):
    import numpy as np

    from swath.order.routing import AirGuard

    tp = _sandwich()
    guard = AirGuard(tp.surface, 0.02)
    up = np.array([0.0, 0.0, 1.0])
    with caplog.at_level(logging.WARNING):
        guard.route(np.array([0.15, 0.04, 0.0]), up, np.array([0.05, 0.06, 0.0]), up)   # a candidate's link
    assert len(guard.near_part) == 1 and not caplog.records


@pytest.mark.parametrize("units,ends", [
    ("mm", "after pass 1: (150.00, 40.00, 0.00) to (50.00, 60.00, 0.00); part coordinates in mm"),
    ("m", "after pass 1: (0.15000, 0.04000, 0.00000) to (0.05000, 0.06000, 0.00000); part coordinates in m"),
    ("inches", "after pass 1: (5.9055, 1.5748, 0.0000) to (1.9685, 2.3622, 0.0000); part coordinates in inches"),
])
def test_the_kept_plans_blocked_air_routes_are_one_warning_in_the_users_unit(units, ends):
    from swath.order import route_links

    tp = route_links(_sandwich(), clearance=0.02, units=units)
    (warning,) = tp.metadata["warnings"]
    assert warning.startswith("1 of 1 air moves pass closer than half the clearance (10 mm)")
    assert ends in warning


# --- the report -------------------------------------------------------------------------------------
@pytest.mark.parametrize("key,value,shown", [
    ("fk_position_error_m", 1.635e-15, "< 1 nm"),          # round-off of a forward-kinematics check
    ("fk_position_error_m", 3.2e-8, "32 nm"),
    ("removal_mean_m", 2.5e-6, "2.5 µm"),
    ("depth_change_m", -3e-10, "> −1 nm"),
    ("fk_angle_error_rad", 2e-12, "< 0.001°"),
    ("direction_rad", 0.5, "28.65°"),
])
def test_small_lengths_and_angles_are_shown_in_units_a_user_reads(key, value, shown):
    from swath.report.metrics import format_value

    assert format_value(key, value) == shown


def test_the_report_summary_shows_the_headline_and_folds_the_rest():
    import re

    from swath.examples import flat_plate
    from swath.report.html import HEADLINE, report_html_text

    metrics = dict(coverage_fraction=0.995, interior_removal_cov=0.134, removal_cov=0.151, cycle_time_s=85.21,
                   contact_length_m=3.341, air_length_m=0.5413, coverage_lower_bound_m=2.944, efficiency=0.8812,
                   n_passes=6, plan_s=27.9, simulate_s=1.6, softer_pad_removal_cov=0.14,
                   ripple_pv_m=1.42e-6, ripple_rms_m=5.3e-7, warnings=["a warning"],
                   evenness_within_cells_variance_fraction=0.484, evenness_along_passes_variance_fraction=0.012,
                   evenness_between_passes_variance_fraction=0.003, evenness_band_variance_fraction=0.501)
    settings = {"part": "example:plate", "plan": {"candidates": [{"direction_deg": float(d), "cost": 100.0 + d}
                                                                 for d in range(0, 180, 30)]}}
    text = report_html_text(surface=flat_plate(spacing=0.02), metrics=metrics, settings=settings)
    summary = text[text.index("<section><h2>Summary</h2>"):text.index("<section><h2>3D view</h2>")]
    headline, folded = summary.split("<details>", 1)
    for label, key, _ in HEADLINE:
        assert label in headline, label
    assert "99.5 %" in headline and "13.4 %" in headline and "85.21 s" in headline and "3.341 m" in headline
    assert re.search(r"L / L\*</td><td class='num'><b>1\.135</b>", headline)            # 3.341 / 2.944
    assert re.search(r"warnings</td><td class='num'><b>1</b>", headline)
    # the mid-spatial ripple across the passes, peak to valley and rms, next to the interior CoV
    assert re.search(r"ripple across the passes</td><td class='num'><b>1\.42 µm</b> \(rms 530 nm\)", headline)
    # and where the interior CoV comes from, as the CLI's line says it
    assert re.search(r"where it comes from</td><td class='num'>across 48 % · along 1 % · between 0 % · band 50 %<",
                     headline)
    # internal timings and the rest are folded, with the settings
    assert "plan_s" not in headline and "plan_s" in folded and "softer_pad_removal_cov" in folded
    assert folded.startswith("<summary>All metrics (18) and settings</summary>") and "example:plate" in folded
    # long values wrap inside their box instead of widening the page
    assert "overflow-wrap:anywhere" in text and "white-space:nowrap}" not in text.replace(
        "table.headline td.num{white-space:nowrap}", "")


def test_the_report_states_the_split_without_a_band_where_a_part_has_no_core_and_nothing_without_a_split():
    from swath.report.html import _split_text

    no_core = dict(evenness_within_cells_variance_fraction=0.69, evenness_along_passes_variance_fraction=0.13,
                   evenness_between_passes_variance_fraction=0.18, evenness_band_variance_fraction=None)
    assert _split_text(no_core) == "across 69 % · along 13 % · between 18 %"        # the hub's
    assert _split_text({**no_core, "evenness_within_cells_variance_fraction": None}) == ""
    assert _split_text({}) == ""


def test_an_option_of_swath_itself_after_the_subcommand_says_where_it_goes(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["plan", "--constant-feed", "example:plate", "--quiet", "--out", "o"])
    assert exc.value.code == 2
    assert "--quiet is an option of swath itself: give it before the subcommand (swath --quiet plan ...)" in \
        capsys.readouterr().err
