"""The pipeline's layering (DESIGN.md "Layers", pyproject's import-linter contract) is enforced."""

import ast
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SRC = REPO / "src" / "swath"
# the lint-imports of the Python running the tests first (a venv that is not activated), then PATH's
_BESIDE = Path(sys.executable).parent / "lint-imports"
LINT = str(_BESIDE) if _BESIDE.exists() else shutil.which("lint-imports")

pytestmark = pytest.mark.skipif(LINT is None, reason='import-linter is not installed (pip install -e ".[test]")')


def lint(src_root: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(src_root)}
    # the contract is read from pyproject.toml in the working directory (every import-linter 2.x)
    return subprocess.run([LINT], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=300)


def test_the_layers_contract_is_kept():
    r = lint(REPO / "src")
    assert r.returncode == 0, r.stdout[-3000:]
    assert "1 kept, 0 broken" in r.stdout


def test_an_upward_import_breaks_the_contract(tmp_path):
    shutil.copytree(SRC, tmp_path / "swath", ignore=shutil.ignore_patterns("__pycache__"))
    wrong = tmp_path / "swath" / "plan" / "raster.py"
    wrong.write_text(wrong.read_text() + "\nfrom ..trajectory import time_path  # a planner reaching up\n")
    r = lint(tmp_path)
    assert r.returncode != 0
    assert "swath.plan is not allowed to import swath.trajectory" in r.stdout


def _stage(module: str) -> str:
    parts = module.split(".")
    return ".".join(parts[:2])


def test_no_stage_imports_another_stages_private_names():
    offenders = []
    for path in SRC.rglob("*.py"):
        rel = path.relative_to(SRC.parent).with_suffix("")
        module = ".".join(rel.parts[:-1] if rel.name == "__init__" else rel.parts)
        package = module if rel.name == "__init__" else module.rsplit(".", 1)[0]
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, ast.ImportFrom) or node.module is None and node.level == 0:
                continue
            if node.level:
                base = package.split(".")
                base = base[:len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module
            if not target.startswith("swath") or _stage(target) == _stage(module):
                continue
            offenders += [f"{module} imports {target}.{a.name}" for a in node.names if a.name.startswith("_")
                          and not a.name.startswith("__")]
    assert not offenders, "\n".join(offenders)


def test_the_library_does_not_print():
    r = subprocess.run([sys.executable, "-m", "ruff", "check", "--select", "T20", str(SRC), "--exclude", "cli"],
                       capture_output=True, text=True, cwd=REPO)
    if "No module named ruff" in r.stderr:
        pytest.skip('ruff is not installed (pip install -e ".[test]")')
    assert r.returncode == 0, r.stdout
