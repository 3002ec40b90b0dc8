"""Every warning the library can emit has a code and a docs entry (:mod:`swath.report.warncodes`).

The warnings are found in the source: the text of every ``log.warning(...)`` call, every string
put into a ``warnings`` list (``metadata["warnings"]``, the lists returned by ``*_warnings``
functions), followed through a local variable where the call passes one.  Each must resolve to
exactly one code, and each code must be used somewhere.
"""

from __future__ import annotations

import ast
import io
import logging
import re
from pathlib import Path

import pytest

from swath.report.warncodes import CODE_RE, CODES, WarningCodeFilter, code_for, tagged, warnings_markdown

SRC = Path(__file__).resolve().parents[2] / "src" / "swath"
LOGGERS = {"log", "logger", "_log", "LOG"}


def _skeleton(node, names: dict) -> str | None:
    """The text of a string expression with every computed part as ``{}`` (None: not a string)."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value
    if isinstance(node, ast.JoinedStr):
        return "".join(v.value if isinstance(v, ast.Constant) else "{}" for v in node.values)
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Add):
        a, b = _skeleton(node.left, names), _skeleton(node.right, names)
        if a is None and b is None:
            return None
        return (a if a is not None else "{}") + (b if b is not None else "{}")
    if isinstance(node, ast.Name) and node.id in names:
        return names[node.id]
    return None


#: Local lists that collect a job's warnings (their appends are warnings wherever they are made).
WARNING_LISTS = ("warnings",)


def _setdefault_of_warnings(node) -> bool:
    """Whether ``node`` is ``something.setdefault("warnings", ...)`` (a job's warning list made on first use)."""
    return (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "setdefault"
            and bool(node.args) and isinstance(node.args[0], ast.Constant) and node.args[0].value in WARNING_LISTS)


def _warning_texts() -> list[tuple[str, str]]:
    """``(where, text)`` of every warning in the library's source."""
    found = []
    for path in sorted(SRC.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        rel = path.relative_to(SRC.parent)
        for fn in [n for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))]:
            names: dict[str, str] = {}
            every: dict[str, list[str]] = {}        # a name given different messages on different branches
            for node in ast.walk(fn):
                if isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name):
                    text = _skeleton(node.value, {})
                    if text is not None:
                        names[node.targets[0].id] = text
                        every.setdefault(node.targets[0].id, []).append(text)
            lists_of_warnings = fn.name.endswith("warnings")
            for node in ast.walk(fn):
                where = f"{rel}:{getattr(node, 'lineno', 0)}"
                if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "warning"
                        and isinstance(node.func.value, ast.Name) and node.func.value.id in LOGGERS and node.args):
                    text = _skeleton(node.args[0], names)
                    message = node.args[0]
                    if text is not None and re.fullmatch(r"[\w ]*:?\s*%s", text) and len(node.args) > 1:
                        message = node.args[1]                      # "%s" passes a message on
                        text = _skeleton(message, names)
                    if isinstance(message, ast.Name) and len(every.get(message.id, [])) > 1:
                        found += [(where, alt) for alt in every[message.id]]
                    elif text is not None:
                        found.append((where, text))
                elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) \
                        and node.func.attr == "append" and node.args and (lists_of_warnings or (
                            isinstance(node.func.value, ast.Name) and node.func.value.id in WARNING_LISTS)
                            or _setdefault_of_warnings(node.func.value)):
                    text = _skeleton(node.args[0], names)
                    if text is not None:
                        found.append((where, text))
                elif lists_of_warnings and isinstance(node, ast.Return) and isinstance(node.value, ast.List):
                    found += [(where, t) for t in (_skeleton(e, names) for e in node.value.elts) if t is not None]
                elif isinstance(node, ast.Assign) and any(
                        isinstance(t, ast.Subscript) and isinstance(t.slice, ast.Constant) and t.slice.value == "warnings"
                        for t in node.targets) and isinstance(node.value, ast.List):
                    found += [(where, t) for t in (_skeleton(e, names) for e in node.value.elts if
                                                   not isinstance(e, ast.Starred)) if t is not None]
    return found


WARNINGS = _warning_texts()


def test_the_scan_finds_the_warnings_it_should():
    """The collector sees the known kinds: a logged template, a job warning list, a metadata list."""
    texts = [t for _, t in WARNINGS]
    assert len(texts) >= 30
    assert any(t.startswith("removal sampled at %.2f mm instead of") for t in texts)        # log template
    assert any(t.startswith("coverage is {} % (below") for t in texts)                      # plan_warnings
    assert any("closer than half the clearance" in t and t.startswith("{} of {} air moves") for t in texts)
    assert any(t.startswith("raster: {} % of {} is predicted") for t in texts)               # via a variable


@pytest.mark.parametrize("where,text", WARNINGS, ids=[w for w, _ in WARNINGS])
def test_every_warning_has_exactly_one_code(where, text):
    explicit = CODE_RE.findall(text)
    matched = [c.code for c in CODES.values() if c.match and re.search(c.match, text)]
    codes = explicit or matched
    assert len(codes) == 1, f"{where}: {text[:90]!r} resolves to {codes or 'no code'}; add an entry to " \
                            "swath.report.warncodes.CODES"
    assert codes[0] in CODES, f"{where}: {codes[0]} is not in swath.report.warncodes.CODES"


def test_every_code_is_used_and_documented():
    texts = [t for _, t in WARNINGS]
    page = warnings_markdown()
    for c in CODES.values():
        assert re.fullmatch(r"W-[A-Z0-9]+(-[A-Z0-9]+)*", c.code) and c.meaning.strip() and c.action.strip()
        assert f"### {c.code} {{#{c.anchor}}}" in page
        assert any(code_for(t) == c.code for t in texts), f"{c.code} matches no warning in the source"


def test_tagging_a_message_and_a_log_record():
    msg = "coverage is 98.50 % (below 99 %): 1.50 % of the part is never touched; lower the spacing"
    assert tagged(msg) == msg + " [W-COVERAGE-LOW]" and tagged(tagged(msg)) == msg + " [W-COVERAGE-LOW]"
    assert tagged("nothing known") == "nothing known"
    stream = io.StringIO()
    handler = logging.StreamHandler(stream)
    handler.addFilter(WarningCodeFilter())
    logger = logging.getLogger("swath.test_warning_codes")
    logger.addHandler(handler)
    try:
        logger.warning("removal sampled at %.2f mm instead of %.2f mm: %d samples exceed the %d cap", 2.5, 2, 3, 4)
        logger.warning("%s", tagged(msg))
        logger.info("removal sampled at %.2f mm instead of", 1.0)
    finally:
        logger.removeHandler(handler)
    assert stream.getvalue().splitlines() == [
        "removal sampled at 2.50 mm instead of 2.00 mm: 3 samples exceed the 4 cap [W-REMOVAL-COARSENED]",
        msg + " [W-COVERAGE-LOW]"]
