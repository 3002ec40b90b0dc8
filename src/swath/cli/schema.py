"""One declaration per job setting, and what is derived from it.

Every job setting is one field of :class:`~swath.cli.jobsettings.JobSettings` declared with
:func:`setting`: its SI default, what the value holds (a :class:`Key`: kind, unit hint, range,
choices), the pipeline stage that reads it, its help text and how it appears on the command line
(an :class:`Option`).  From these declarations come

* the job-file schema :data:`swath.cli.settings.SCHEMA` (:func:`schema`), which parses and checks
  every value of a job file or of the command line;
* the options of ``swath plan``, ``swath demo`` and ``swath rework`` (:func:`add_setting_options`);
* the per-stage settings records (:mod:`swath.cli.stage_settings`);
* the command-line and job-file reference (:mod:`swath.cli.reference`).

Adding a setting is a one-place change: one field, e.g. ::

    dust_gap: float | None = setting(None, "length", stage="plan", positive=True, hi=0.1, bare_max=0.1,
                                     hint="mm, e.g. 5mm", help="gap left along dusty edges, e.g. 5mm")

gives the job-file key ``dust_gap``, the option ``--dust-gap`` of ``swath plan`` and its rows in
the reference; list it in the stage's record of :mod:`swath.cli.stage_settings` where that stage
reads it (a test checks every field is in exactly one record).  Choices that a registry holds
(planners, order methods, robots, program formats) are given as that registry, never as a
second list of names.
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

#: The metadata key under which a JobSettings field holds its :class:`Setting`.
META = "swath"

#: The pipeline stages a setting belongs to, in pipeline order: the records of
#: :mod:`swath.cli.stage_settings` and the sections of the job-file reference.
STAGES = {
    "job": "the job: output, memory, the evenness asked for",
    "part": "part and selection (io)",
    "tool": "pad, force and calibration (contact)",
    "plan": "path planning",
    "order": "pass order",
    "feed": "feed and spacing optimisation (even removal)",
    "trajectory": "trajectory timing and links",
    "simulate": "removal and force-control simulation",
    "process": "pad wear and media changes",
    "robot": "robot, cell and programs",
}

#: Titles of the option groups of ``swath plan --help`` (options without a group are listed first).
GROUPS = {
    "part": None,                   # the part options, only on commands that read a part file
    "even": "even removal (the default; Wang §2): spacing, lead and feed (dwell) to a target depth",
    "robot": "robot (kinematics, reachability, programs)",
    "force": "force control and calibration (Jaeger ch. 5, 6)",
    "process": "process: pad, kinematics, wear and media changes",
}

#: A field without a default (``part``, ``out``).
REQUIRED: Any = object()


@dataclass(frozen=True)
class Key:
    """What one settings key holds.

    kind : a quantity kind of :func:`swath.units.parse_quantity`, or ``"bool"``, ``"str"``,
        ``"path"``, ``"table"``, ``"list"``, ``"offset"``, ``"count"`` (a whole number).
    choices : allowed strings (``"str"`` keys).
    lo, hi : allowed range in SI (inclusive), None for open.
    bare_max : a number given without a unit must not exceed this (SI); catches ``feed = 50``.
    hint : the unit the user likely meant, for that message.
    off : the key may be turned off with ``none``/``off``.
    auto : the key may be ``auto`` (None).
    positive : the value must be > 0.
    infinite : the value may be ``inf`` (a TOML float or the text), returned as ``math.inf``.
    """

    kind: str
    choices: tuple = ()
    lo: float | None = None
    hi: float | None = None
    bare_max: float | None = None
    hint: str = ""
    off: bool = False
    auto: bool = False
    positive: bool = False
    infinite: bool = False


@dataclass(frozen=True)
class Option:
    """How a setting appears on the command line of ``swath plan`` (and ``demo``, ``rework``).

    flags : the option strings; empty: ``--name-with-dashes``.
    default : the text argparse passes when the option is not given (parsed like a job-file value,
        so ``"38.1mm"`` must read as the field's SI default); None: nothing is passed.
    action : ``"store"`` (a value), ``"store_true"`` (a flag), ``"store_false"`` (``--no-NAME``
        turns a default-on setting off) or ``"boolean"`` (``--NAME`` / ``--no-NAME``).
    group : an option group of :data:`GROUPS`; ``"part"`` options exist only where a part file is read.
    exclusive : options with the same name here exclude each other.
    choices : argparse refuses a value outside the key's choices (otherwise the settings check does).
    required : the command line must give it (``--out``).
    """

    flags: tuple = ()
    default: Any = None
    action: str = "store"
    group: str | None = None
    exclusive: str | None = None
    choices: bool = False
    required: bool = False


@dataclass(frozen=True)
class Setting:
    """The one declaration of a job setting (a JobSettings field's metadata).

    key : what the value holds; its ``choices`` are ``choices_from()`` when that is given.
    stage : the pipeline stage that reads it (a key of :data:`STAGES`).
    help : what it sets; ``{names}`` is replaced by the names of ``names_from()``.
    option : how it appears on the command line; None: a job-file key only.
    choices_from : a registry the value must be one of (checked with the key).
    names_from : a registry the value is looked up in later (a robot, an order method): shown in the
        help and the reference, checked where it is used.
    """

    key: Key
    stage: str
    help: str = ""
    option: Option | None = None
    choices_from: Callable[[], tuple] | None = None
    names_from: Callable[[], tuple] | None = None

    def resolved_key(self) -> Key:
        """The key with the registry's choices filled in."""
        if self.choices_from is None:
            return self.key
        return dataclasses.replace(self.key, choices=tuple(self.choices_from()))

    def names(self) -> tuple:
        """The names the value is one of (the key's choices or the registry's), () for free values."""
        if self.names_from is not None:
            return tuple(self.names_from())
        return self.resolved_key().choices

    def help_text(self) -> str:
        """The help with the registry's names filled in."""
        if "{names}" in self.help:
            return self.help.replace("{names}", ", ".join(self.names()))
        return self.help


def setting(default, kind: str, *, stage: str, help: str = "", cli: Option | None | bool = True,
            choices: tuple | Callable[[], tuple] = (), names: Callable[[], tuple] | None = None,
            **key: Any) -> Any:
    """A JobSettings field declared once: its default and its :class:`Setting`.

    Parameters
    ----------
    default
        The SI default; :data:`REQUIRED` for none (a dict is copied for every instance).
    kind : str
        What the value is: a quantity kind (``"length"``, ``"speed"``, ...) or ``"bool"``,
        ``"str"``, ``"path"``, ``"list"``, ``"table"``, ``"offset"``, ``"count"`` (see :class:`Key`).
    stage : str
        The pipeline stage that reads it, a key of :data:`STAGES`.
    help : str
        The option's help and the reference text (argparse's ``%%`` for a literal %).
    cli : Option or bool
        How it appears on the command line; True: a plain ``--name VALUE``; False: job files only.
    choices : tuple or callable
        The allowed values, or the registry function that returns them.
    names : callable, optional
        A registry whose names ``{names}`` in ``help`` lists; the stage checks the value.
    **key
        The other fields of :class:`Key` (``positive=True``, ``hi=1.0``, ``hint="mm, e.g. 5mm"``, ...).

    Returns
    -------
    dataclasses.Field
        The field, for a ``JobSettings`` attribute.
    """
    if stage not in STAGES:
        raise ValueError(f"unknown stage {stage!r}; one of {', '.join(STAGES)}")
    option = Option() if cli is True else (cli or None)
    if option is not None and option.group is not None and option.group not in GROUPS:
        raise ValueError(f"unknown option group {option.group!r}")
    spec = Setting(key=Key(kind, choices=choices if isinstance(choices, tuple) else (), **key), stage=stage,
                   help=help, option=option, choices_from=None if isinstance(choices, tuple) else choices,
                   names_from=names)
    metadata = {META: spec}
    if default is REQUIRED:
        return field(metadata=metadata)
    if isinstance(default, dict):
        return field(default_factory=lambda: dict(default), metadata=metadata)
    return field(default=default, metadata=metadata)


def declarations(cls) -> dict[str, Setting]:
    """Field name -> its :class:`Setting`, in declaration order, of every declared field of ``cls``."""
    return {f.name: f.metadata[META] for f in dataclasses.fields(cls) if META in f.metadata}


def default_of(cls, name: str):
    """The SI default of field ``name`` of ``cls`` (:data:`REQUIRED` when it has none)."""
    f = next(f for f in dataclasses.fields(cls) if f.name == name)
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return REQUIRED


def schema(cls) -> dict[str, Key]:
    """Every settings key of ``cls`` -> what it holds, the registries' choices filled in."""
    return {name: spec.resolved_key() for name, spec in declarations(cls).items()}


def flags_of(name: str, option: Option) -> tuple:
    """The option strings of setting ``name``."""
    return option.flags or ("--" + name.replace("_", "-"),)


def add_setting_options(parser: argparse.ArgumentParser, cls, *, with_part_options: bool = True) -> None:
    """Add every setting of ``cls`` that has an :class:`Option` to ``parser``, in declaration order,
    in its option group (``"part"`` options only ``with_part_options``)."""
    groups: dict[str | None, Any] = {None: parser, "part": parser}
    exclusive: dict[tuple, Any] = {}
    for name, spec in declarations(cls).items():
        option = spec.option
        if option is None or (option.group == "part" and not with_part_options):
            continue
        if option.group is not None and option.group not in groups:
            groups[option.group] = parser.add_argument_group(GROUPS[option.group])
        target = groups[option.group]
        if option.exclusive is not None:
            ex = (option.group, option.exclusive)
            if ex not in exclusive:
                exclusive[ex] = target.add_mutually_exclusive_group()
            target = exclusive[ex]
        kw: dict[str, Any] = {"help": spec.help_text()}
        flags = flags_of(name, option)
        if flags[0] != "--" + name.replace("_", "-"):
            kw["dest"] = name
        if option.action == "store":
            if option.choices:
                kw["choices"] = spec.resolved_key().choices
        elif option.action == "boolean":
            kw["action"] = argparse.BooleanOptionalAction
        else:
            kw["action"] = option.action
        if option.default is not None or option.action != "store":
            kw["default"] = option.default
        if option.required:
            kw["required"] = True
        target.add_argument(*flags, **kw)
