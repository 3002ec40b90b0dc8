"""One declaration per job setting: the job-file schema, the options of swath plan/demo/rework, the
reference and the per-stage records all derive from JobSettings' field declarations, and cannot drift."""

from __future__ import annotations

import argparse
import dataclasses
import typing

import pytest

from swath.cli.jobsettings import JobSettings
from swath.cli.main import _settings_from_args, build_parser
from swath.cli.reference import cli_markdown, job_keys_markdown
from swath.cli.schema import (
    GROUPS,
    REQUIRED,
    STAGES,
    Option,
    add_setting_options,
    declarations,
    default_of,
    schema,
    setting,
)
from swath.cli.settings import SCHEMA, parse_value, settings_from_mapping
from swath.cli.stage_settings import STAGE_RECORDS, PlanSettings, ProcessSettings, TrajectorySettings, stage_records

#: Options of these commands that are not job settings (the command's own inputs).
COMMAND_OWN = {"rework": {"cad", "scan", "scan_units", "placement", "excess_radius", "min_excess"}}


def _subparsers(parser):
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices


def test_every_field_is_declared_once_and_the_schema_is_derived_from_it():
    fields = [f.name for f in dataclasses.fields(JobSettings)]
    settings = declarations(JobSettings)
    assert list(settings) == fields                      # every field carries exactly one declaration
    assert list(SCHEMA) == fields and SCHEMA == schema(JobSettings)
    assert len(fields) >= 70
    for name, spec in settings.items():
        assert spec.stage in STAGES, name
        assert spec.help_text().strip(), f"{name} has no help"
        assert spec.option is None or spec.option.group in (None, *GROUPS), name


def test_every_option_is_a_key_and_every_declared_option_is_on_the_command_line():
    subs = _subparsers(build_parser())
    declared = {name: spec for name, spec in declarations(JobSettings).items() if spec.option is not None}
    for command in ("plan", "demo", "rework"):
        dests = {a.dest for a in subs[command]._actions if not isinstance(a, argparse._HelpAction)}
        assert dests - set(SCHEMA) - COMMAND_OWN.get(command, set()) == set(), command
    plan = {a.dest: a for a in subs["plan"]._actions}
    assert set(declared) <= set(plan)
    for name, spec in declared.items():
        action = plan[name]
        assert action.help == spec.help_text(), name
        assert action.option_strings[0] == (spec.option.flags or ("--" + name.replace("_", "-"),))[0], name
    # only the settings without an option are job-file keys alone (besides the positional PART)
    assert {n for n in SCHEMA if n not in plan} == {"sample_spacing", "planner_options", "target_floor",
                                                   "robot_strict", "depression_force"}


def test_the_command_line_defaults_are_the_dataclass_defaults():
    """What `swath plan PART --out DIR` builds is JobSettings(part=PART, out=DIR): every default an
    option passes reads back as the field's SI default."""
    args = build_parser().parse_args(["plan", "example:plate", "--out", "somewhere"])
    assert _settings_from_args(args) == JobSettings(part="example:plate", out="somewhere")
    for name, spec in declarations(JobSettings).items():
        option, default = spec.option, default_of(JobSettings, name)
        if option is None or default is REQUIRED:
            continue
        if option.action == "store" and option.default is not None:
            assert parse_value(name, option.default, SCHEMA[name]) == pytest.approx(default), name
        elif option.action == "store_true":
            assert default is False, name
        elif option.action in ("store_false", "boolean"):
            assert default is True, name


def test_the_references_list_every_key_and_option_with_the_dataclass_default():
    keys = job_keys_markdown()
    for name in SCHEMA:
        row = next((line for line in keys.splitlines() if line.startswith(f"| `{name}` |")), None)
        assert row is not None, name
        default = default_of(JobSettings, name)
        cell = row.split(" | ")[2]
        if default is REQUIRED:
            assert cell == "required", name
        elif default not in (None, (), {}):
            assert cell == f"`{default}`", name
    for stage, title in STAGES.items():
        assert f"### {title[0].upper()}{title[1:]}\n" in keys
    cli = cli_markdown()
    for name, spec in declarations(JobSettings).items():
        if spec.option is not None:
            assert f"| `{name}` |" in cli, name          # the job-file key column of its option


def test_choices_come_from_their_registries(monkeypatch):
    from swath.order import ORDER_METHODS
    from swath.plan import PLANNERS
    from swath.robot.programs import FORCE_PROGRAMS, PROGRAM_FILES
    from swath.scan.fit import PARAMETERIZATIONS
    from swath.simulate.removal import SAMPLINGS

    assert SCHEMA["planner"].choices == tuple(PLANNERS)
    assert SCHEMA["parameterization"].choices == tuple(PARAMETERIZATIONS)
    assert SCHEMA["removal_sampling"].choices == tuple(SAMPLINGS)
    assert SCHEMA["force_program"].choices == tuple(FORCE_PROGRAMS)
    settings = declarations(JobSettings)
    assert settings["order"].names() == tuple(ORDER_METHODS)
    assert f"robot programs to write: {', '.join(PROGRAM_FILES)} (" in settings["programs"].help_text()
    assert "robot model: ur3e, ur5e, ur10e, ur16e, irb4600, kr120, or a URDF file" in settings["robot"].help_text()
    # a planner added to the registry is a choice at once: nothing names the planners a second time
    monkeypatch.setitem(PLANNERS, "spiral", PLANNERS["raster"])
    assert "spiral" in schema(JobSettings)["planner"].choices
    assert parse_value("planner", "spiral", schema(JobSettings)["planner"]) == "spiral"
    with pytest.raises(Exception, match="planner must be one of raster, uniform, equidistant, wrap, spiral, got .helix."):
        parse_value("planner", "helix", schema(JobSettings)["planner"])


def test_a_new_setting_is_one_declaration():
    """A field declared with setting() is a job-file key, a command-line option with its help and
    default, and a reference row, with nothing else written."""

    @dataclasses.dataclass(frozen=True, kw_only=True)
    class Extended(JobSettings):
        dust_gap: float | None = setting(None, "length", stage="plan", positive=True, hi=0.1, bare_max=0.1,
                                         hint="mm, e.g. 5mm", cli=Option(default="5mm", group="even"),
                                         help="gap left along dusty edges")

    assert schema(Extended)["dust_gap"].hint == "mm, e.g. 5mm"
    parser = argparse.ArgumentParser()
    add_setting_options(parser, Extended)
    action = next(a for a in parser._actions if a.dest == "dust_gap")
    assert action.option_strings == ["--dust-gap"] and action.default == "5mm"
    assert action.help == "gap left along dusty edges"
    group = next(g for g in parser._action_groups if action in g._group_actions)
    assert group.title == GROUPS["even"]
    assert parser.parse_args(["--dust-gap", "3mm", "--out", "x"]).dust_gap == "3mm"
    with pytest.raises(ValueError, match="unknown stage"):
        setting(None, "length", stage="polish")


def test_every_field_is_in_its_stage_record_with_the_same_type():
    hints = typing.get_type_hints(JobSettings)
    seen: dict[str, str] = {}
    for stage, record in STAGE_RECORDS.items():
        assert record.STAGE == stage
        record_hints = typing.get_type_hints(record)
        for f in dataclasses.fields(record):
            assert f.name not in seen, f"{f.name} is in the {seen.get(f.name)} and the {stage} records"
            seen[f.name] = stage
            assert declarations(JobSettings)[f.name].stage == stage, f.name
            assert record_hints[f.name] == hints[f.name], f.name
    assert list(STAGE_RECORDS) == list(STAGES)
    missing = {n: s.stage for n, s in declarations(JobSettings).items() if n not in seen}
    assert not missing, f"add these fields to their stage records in swath.cli.stage_settings: {missing}"


def test_stage_records_hold_the_job_values():
    settings = settings_from_mapping({"part": "example:plate", "out": "x", "feed": "80mm/s", "max_angular": "none",
                                      "spacing": "30mm", "wear_rate": "0.002/s", "media_change": "300s",
                                      "planner_options": {"min_pass_length": "10mm"}})
    records = stage_records(settings)
    assert set(records) == set(STAGES)
    plan = PlanSettings.of(settings)
    assert plan.spacing == pytest.approx(0.03) and plan.planner == "raster"
    assert plan.planner_options == {"min_pass_length": "10mm"}
    process = records["process"]
    assert isinstance(process, ProcessSettings) and process.media_change == pytest.approx(300.0)
    assert ProcessSettings.of(process) is process
    with pytest.raises(dataclasses.FrozenInstanceError):
        process.wear_rate = 0.0                           # type: ignore[misc]
    trajectory = TrajectorySettings.of(settings)
    kinds = [type(c).__name__ for c in trajectory.constraints()]
    assert kinds == ["FeedLimit", "CentripetalLimit", "TangentialAccelLimit"]   # the angular limit is off
    assert trajectory.constraints()[0].speed == pytest.approx(0.08)
    assert [type(c).__name__ for c in settings.constraints()] == kinds
    assert settings.links().clearance == trajectory.links().clearance == pytest.approx(0.02)


def test_the_ranges_the_help_states_are_the_ones_checked():
    """--feed, --force and --pad-radius state the plausible range that PROCESS_RANGES refuses outside,
    and --allow-unusual-process repeats all three."""
    from swath.cli.settings import PROCESS_RANGES

    settings = declarations(JobSettings)
    for key in ("feed", "force", "pad_radius"):
        text = PROCESS_RANGES[key].text()
        assert f"within {text}" in settings[key].help_text(), key
        assert text in settings["allow_unusual_process"].help_text(), key


def test_the_defaults_the_help_states_are_the_dataclass_defaults():
    """A help text that states a number as the default ("(default 2m/s2; ...") states the field's
    SI default: the two are written apart, and this keeps them equal."""
    import re

    checked = []
    for name, spec in declarations(JobSettings).items():
        default = default_of(JobSettings, name)
        if default is None or default is REQUIRED or name == "pad_radius":
            continue                                  # an automatic default: the help says how it is chosen
        for m in re.finditer(r"\(default:? ([0-9.][^\s;,):]*)", spec.help_text()):
            assert parse_value(name, m.group(1), SCHEMA[name]) == pytest.approx(default), (name, m.group(0))
            checked.append(name)
    assert {"max_centripetal", "max_angular", "max_accel", "keep_out_margin", "chordal_tol", "length_budget",
            "cycle_time_factor", "pad_damping"} <= set(checked)
    # the pad radius's help names the pad: "(default: 3-inch pad)", 3 in across
    assert "(default: 3-inch pad)" in declarations(JobSettings)["pad_radius"].help_text()
    assert default_of(JobSettings, "pad_radius") == pytest.approx(3 * 0.0254 / 2)
