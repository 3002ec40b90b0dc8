"""The command-line and job-file reference as Markdown, generated from the parser and the schema.

Both derive from the settings' one declaration (:mod:`swath.cli.schema`): the parser's options of
``swath plan`` are built from it, and the job-key tables read it directly, one table per stage.

The docs build (``docs/hooks.py``) puts :func:`cli_markdown` into *Reference → Command line*
and :func:`job_keys_markdown` into *Reference → Job files*, so neither page can drift from the
options ``swath`` really accepts.  ``python -m swath.cli.reference`` prints both.
"""

from __future__ import annotations

import argparse
import math

from .jobsettings import JobSettings
from .main import _DefaultsFormatter, build_parser
from .schema import REQUIRED, STAGES, Key, declarations, default_of
from .settings import ALIASES, PLANNER_OPTION_SCHEMA, SCHEMA


def _cell(text) -> str:
    """Text safe inside a Markdown table cell."""
    return str(text).replace("|", "\\|").replace("\n", " ").replace("%%", "%")


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, tuple[str, argparse.ArgumentParser]]:
    """``name -> (help, subparser)`` of every ``swath`` subcommand, in the parser's order."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {a.dest: a.help or "" for a in action._choices_actions}
            return {name: (helps.get(name, ""), p) for name, p in action.choices.items()}
    return {}


def _default(action: argparse.Action) -> str:
    d = action.default
    if d in (None, False, argparse.SUPPRESS) or isinstance(action, argparse._HelpAction):
        return ""
    if d is True:
        return "on"
    return f"`{d}`"


def option_rows(parser: argparse.ArgumentParser) -> list[tuple[str, str, str, str, str]]:
    """``(option, default, choices, job-file key, help)`` of every argument of ``parser``
    (positional arguments first, ``-h`` left out)."""
    rows = []
    for action in parser._actions:
        if isinstance(action, (argparse._HelpAction, argparse._SubParsersAction)):
            continue
        if action.option_strings:
            name = ", ".join(f"`{s}`" for s in action.option_strings)
            if action.nargs != 0 and not isinstance(action, argparse.BooleanOptionalAction):
                metavar = action.metavar if isinstance(action.metavar, str) else action.dest
                name += f" *{metavar.upper()}*"
        else:
            name = f"*{action.dest.upper()}*"
        choices = ", ".join(f"`{c}`" for c in action.choices) if action.choices else ""
        key = f"`{action.dest}`" if action.dest in SCHEMA else ""
        rows.append((name, _default(action), choices, key, _cell(action.help or "")))
    return rows


def _usage(name: str, parser: argparse.ArgumentParser) -> str:
    usage = parser.format_usage().strip()
    return usage[len("usage: "):] if usage.startswith("usage: ") else usage


def cli_markdown(parser: argparse.ArgumentParser | None = None) -> str:
    """One section per ``swath`` subcommand: what it does, its usage line and a table of its
    options with their defaults, choices and job-file keys."""
    parser = parser or build_parser()
    out = ["## Global options", "", "| option | default | choices | job-file key | what it does |", "|---|---|---|---|---|"]
    out += [f"| {' | '.join(r)} |" for r in option_rows(parser)]
    for name, (helptext, sub) in _subcommands(parser).items():
        sub.formatter_class = _DefaultsFormatter
        out += ["", f"## swath {name}", "", f"{_cell(helptext).capitalize()}.", "", "```text", _usage(name, sub), "```",
                "", "| option | default | choices | job-file key | what it does |", "|---|---|---|---|---|"]
        out += [f"| {' | '.join(r)} |" for r in option_rows(sub)]
    return "\n".join(out) + "\n"


def _describe(spec: Key, names: tuple = ()) -> str:
    """A key's kind, range and choices in words; ``names``: the registry its value is looked up in."""
    parts = [spec.kind]
    if spec.choices:
        parts = ["one of " + ", ".join(f"`{c}`" for c in spec.choices)]
    elif names:
        parts.append("names: " + ", ".join(f"`{c}`" for c in names))
    if spec.lo is not None or spec.hi is not None or spec.positive:
        lo = "> 0" if spec.positive and spec.lo is None else (f">= {spec.lo:g}" if spec.lo is not None else "")
        hi = f"<= {spec.hi:g}" if spec.hi is not None else ""
        parts.append("SI value " + " and ".join(t for t in (lo, hi) if t))
    if spec.off:
        parts.append("`none` turns it off")
    if spec.auto:
        parts.append("or `auto`")
    if spec.infinite:
        parts.append("or `inf`")
    if spec.hint:
        parts.append(f"unit e.g. {spec.hint}")
    return "; ".join(parts)


def _setting_default(name: str) -> str:
    """A setting's SI default as the reference shows it: ``required``, blank for none/empty."""
    d = default_of(JobSettings, name)
    if d is REQUIRED:
        return "required"
    if d is None or d == () or d == {} or d == []:
        return ""
    if isinstance(d, float) and math.isinf(d):
        return "`inf`"
    return f"`{d}`"


def _flags_by_key(parser: argparse.ArgumentParser) -> dict[str, str]:
    """Job-file key -> the ``swath plan`` option that sets it."""
    plan = _subcommands(parser)["plan"][1]
    return {a.dest: a.option_strings[0] if a.option_strings else a.dest.upper()
            for a in plan._actions if a.dest in SCHEMA}


def job_keys_markdown(parser: argparse.ArgumentParser | None = None) -> str:
    """Tables of every job-file key, one per pipeline stage, from the settings' declarations
    (:mod:`swath.cli.jobsettings`): kind, range, default (SI), the ``swath plan`` option, help;
    then the planner options (:data:`~swath.cli.settings.PLANNER_OPTION_SCHEMA`)."""
    flags = _flags_by_key(parser or build_parser())
    settings = declarations(JobSettings)
    out: list[str] = []
    for stage, title in STAGES.items():
        names = [name for name, spec in settings.items() if spec.stage == stage]
        if not names:
            continue
        out += [f"### {title[0].upper()}{title[1:]}", "",
                "| key | value | default (SI) | command-line option | what it sets |", "|---|---|---|---|---|"]
        for name in names:
            spec = settings[name]
            flag = f"`{flags[name]}`" if name in flags else ""
            out.append(f"| `{name}` | {_cell(_describe(SCHEMA[name], spec.names()))} | {_setting_default(name)} "
                       f"| {flag} | {_cell(spec.help_text())} |")
        out.append("")
    out += ["Other spellings accepted: " + ", ".join(f"`{a}` for `{k}`" for a, k in ALIASES.items()) + ".", "",
            "### Planner options (`[planner_options]`)", "",
            "| key | what it holds |", "|---|---|"]
    out += [f"| `{name}` | {_cell(_describe(spec))} |" for name, spec in PLANNER_OPTION_SCHEMA.items()]
    return "\n".join(out) + "\n"


if __name__ == "__main__":          # pragma: no cover - a convenience for reading the reference
    import sys

    sys.stdout.write(cli_markdown() + "\n" + job_keys_markdown())
