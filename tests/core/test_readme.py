"""The README's Python example runs as written and says what it should."""

import re
from pathlib import Path

README = Path(__file__).resolve().parents[2] / "README.md"


def test_the_readme_python_example_runs(capsys):
    text = README.read_text(encoding="utf-8")
    section = text[text.index("### Python"):]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    exec(compile(code, "README.md", "exec"), {})
    out = capsys.readouterr().out
    m = re.match(r"coverage (\d+\.\d)%, removal CoV (\d\.\d\d)", out)
    assert m and float(m.group(1)) >= 99.5 and float(m.group(2)) < 0.5
