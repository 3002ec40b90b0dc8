"""Every tutorial in ``docs/tutorials/`` runs as written.

A tutorial's runnable blocks are fenced ```` ```python exec ````, ```` ```bash exec ```` and
```` ```toml exec file=NAME ```` (the file is written).  They run in order in one temporary folder:
Python blocks in one namespace in this process, shell blocks in ``bash -euo pipefail`` with this
checkout's ``swath`` first on the path.  Any failing command or assertion fails the tutorial.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
TUTORIALS = sorted((REPO / "docs" / "tutorials").glob("*.md"))
BLOCK = re.compile(r"^```(python|bash|toml) exec([^\n]*)\n(.*?)^```\s*$", re.M | re.S)


def blocks(path: Path) -> list[tuple[str, str, str]]:
    """``(language, options, code)`` of every runnable block of a page, in order."""
    return [(m.group(1), m.group(2).strip(), m.group(3)) for m in BLOCK.finditer(path.read_text(encoding="utf-8"))]


def test_every_tutorial_has_runnable_code():
    names = {p.stem for p in TUTORIALS}
    assert {"cad-to-robot", "scan-fit-plan", "even-removal", "calibration", "batch-ray", "python-api"} <= names
    for path in TUTORIALS:
        kinds = [k for k, _, _ in blocks(path)]
        assert kinds, f"{path.name} has no ```python exec / ```bash exec block"


def _env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(REPO / "src"), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    env.setdefault("MPLBACKEND", "Agg")
    return env


@pytest.mark.slow
@pytest.mark.parametrize("path", TUTORIALS, ids=[p.stem for p in TUTORIALS])
def test_tutorial_runs(path, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "__tutorial__"}
    env = _env()
    for i, (kind, options, code) in enumerate(blocks(path)):
        where = f"{path.name}, block {i + 1} ({kind})"
        if kind == "toml":
            name = re.search(r"file=(\S+)", options)
            assert name, f"{where}: a toml exec block needs file=NAME"
            (tmp_path / name.group(1)).write_text(code, encoding="utf-8")
        elif kind == "python":
            exec(compile(code, where, "exec"), namespace)
        else:
            run = subprocess.run(["bash", "-euo", "pipefail", "-c", code], cwd=tmp_path, env=env,
                                 capture_output=True, text=True, timeout=600)
            assert run.returncode == 0, f"{where} exited {run.returncode}:\n{run.stdout[-2000:]}\n{run.stderr[-3000:]}"
