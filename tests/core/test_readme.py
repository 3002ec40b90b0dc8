"""The README is short, its Quick start is the two commands CI runs, its examples are real, and its
links lead somewhere."""

import argparse
import re
import shlex
from pathlib import Path

from swath.cli.main import build_parser

REPO = Path(__file__).resolve().parents[2]
README = REPO / "README.md"


def _section(text: str, heading: str) -> str:
    start = text.index(f"## {heading}\n")
    end = text.find("\n## ", start + 1)
    return text[start:] if end < 0 else text[start:end]


def test_the_readme_is_short_and_states_no_history():
    text = README.read_text(encoding="utf-8")
    assert len(text.splitlines()) < 120
    assert not re.search(r"\bsession\b", text, re.I)
    assert [h for h in re.findall(r"^## (.+)$", text, re.M)][:2] == ["Quick start", "Using it"]


def test_quick_start_is_the_two_commands():
    quick = _section(README.read_text(encoding="utf-8"), "Quick start")
    blocks = re.findall(r"```bash\n(.*?)```", quick, re.S)
    assert [b.strip() for b in blocks] == ['pip install -e ".[test]" && swath demo --out demo', "python -m pytest"]


def test_using_it_fits_a_screen_and_every_option_exists():
    using = _section(README.read_text(encoding="utf-8"), "Using it")
    assert len(using.splitlines()) <= 45
    parser = build_parser()
    subs = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices
    commands = [line.split("#")[0] for line in re.search(r"```bash\n(.*?)```", using, re.S).group(1).splitlines()]
    assert len(commands) >= 8
    for line in commands:
        words = shlex.split(line)
        assert words[0] == "swath" and words[1] in subs, line
        known = {s for a in subs[words[1]]._actions for s in a.option_strings}
        for w in words[2:]:
            if w.startswith("--"):
                assert w.split("=")[0] in known, f"{line}: {w} is not an option of swath {words[1]}"


def test_the_readme_python_example_runs(capsys):
    code = re.search(r"```python\n(.*?)```", _section(README.read_text(encoding="utf-8"), "Using it"), re.S).group(1)
    exec(compile(code, "README.md", "exec"), {})
    out = capsys.readouterr().out
    m = re.match(r"coverage (\d+\.\d)%, removal CoV (\d\.\d\d)", out)
    assert m and float(m.group(1)) >= 99.5 and float(m.group(2)) < 0.5


def test_the_picture_and_links_exist():
    text = README.read_text(encoding="utf-8")
    targets = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", text)
    assert any(t.endswith(".png") for t in targets)
    assert sum(t.startswith("docs/") for t in targets) >= 10
    for t in targets:
        if not t.startswith("http"):
            assert (REPO / t).exists(), t
