"""The docs' generated pages cover what swath really accepts and prints, and the site is wired up.

The command-line and job-key references are generated from the argparse parser and the settings
schema (:mod:`swath.cli.reference`), the warnings page from the code registry, and the "Guides"
section from the files in ``docs/guide/`` (``docs/hooks.py``).
"""

from __future__ import annotations

import argparse
import importlib.util
import re
from pathlib import Path

import pytest
import yaml

from swath.cli.main import build_parser
from swath.cli.reference import cli_markdown, job_keys_markdown
from swath.cli.settings import PLANNER_OPTION_SCHEMA, SCHEMA

REPO = Path(__file__).resolve().parents[2]
DOCS = REPO / "docs"


def _hooks():
    spec = importlib.util.spec_from_file_location("swath_docs_hooks", DOCS / "hooks.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _subparsers(parser):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return action.choices
    return {}


def test_the_cli_reference_names_every_command_and_option():
    parser = build_parser()
    text = cli_markdown(parser)
    subs = _subparsers(parser)
    assert {"plan", "fit", "register", "demo", "run", "calibrate", "doe", "batch"} <= set(subs)
    for name, sub in subs.items():
        section = text[text.index(f"## swath {name}\n"):]
        nxt = section.find("\n## swath ", 1)
        section = section if nxt < 0 else section[:nxt]
        for action in sub._actions:
            if isinstance(action, argparse._HelpAction):
                continue
            for flag in action.option_strings:
                assert f"`{flag}`" in section, f"swath {name}: {flag} missing from the reference"
            if not action.option_strings:
                assert f"*{action.dest.upper()}*" in section
            if action.option_strings and action.default not in (None, False, True, argparse.SUPPRESS):
                assert f"`{action.default}`" in section, f"swath {name} {action.option_strings[0]}: default"


def test_the_reference_follows_a_new_option():
    """Generated, not written: an option added to the parser appears with its default and help."""
    parser = build_parser()
    _subparsers(parser)["plan"].add_argument("--pad-colour", default="grey", help="colour of the pad, for fun")
    assert "| `--pad-colour` *PAD_COLOUR* | `grey` |  |  | colour of the pad, for fun |" in cli_markdown(parser)


def test_the_job_key_reference_names_every_key_with_its_default():
    text = job_keys_markdown()
    for key in [*SCHEMA, *PLANNER_OPTION_SCHEMA]:
        assert f"| `{key}` |" in text, key
    row = next(line for line in text.splitlines() if line.startswith("| `feed` |"))
    assert "`0.05`" in row and "`--feed`" in row and "<= 5" in row
    row = next(line for line in text.splitlines() if line.startswith("| `planner` |"))
    assert all(f"`{p}`" in row for p in ("raster", "uniform", "equidistant"))


def test_guides_are_picked_up_from_the_folder(tmp_path):
    hooks = _hooks()
    (tmp_path / "guide").mkdir()
    (tmp_path / "guide" / "zeta.md").write_text("# Alpha tools\n\ntext\n", encoding="utf-8")
    (tmp_path / "guide" / "beta.md").write_text("no heading\n", encoding="utf-8")
    assert hooks.guide_pages(tmp_path) == [{"Alpha tools": "guide/zeta.md"}, {"Beta": "guide/beta.md"}]
    config = {"docs_dir": str(tmp_path), "nav": [{"Home": "index.md"}, {"Guides": []}]}
    assert hooks.on_config(config)["nav"][1]["Guides"] == hooks.guide_pages(tmp_path)
    (tmp_path / "guide" / "zeta.md").unlink()
    (tmp_path / "guide" / "beta.md").unlink()
    assert hooks.on_config(config)["nav"][1]["Guides"] == []          # a missing page breaks nothing


def test_markers_and_exec_fences_are_rewritten():
    hooks = _hooks()
    page = "# T\n\n```python exec\nprint(1)\n```\n\n```toml exec file=a.toml\nx = 1\n```\n\n<!-- swath:warnings -->\n"
    out = hooks.on_page_markdown(page, None, None, None)
    assert "```python\nprint(1)" in out and "```toml\nx = 1" in out and "exec" not in out
    assert "### W-COVERAGE-LOW {#w-coverage-low}" in out
    with pytest.raises(ValueError, match="unknown generated section"):
        hooks.generated("nothing")


def test_every_page_in_the_nav_exists_and_every_marker_is_known():
    config = yaml.safe_load((REPO / "mkdocs.yml").read_text(encoding="utf-8"))
    pages = []

    def walk(items):
        for item in items:
            if isinstance(item, str):
                pages.append(item)
            elif isinstance(item, dict):
                for value in item.values():
                    walk(value) if isinstance(value, list) else pages.append(value)

    walk(config["nav"])
    assert "reference/cli.md" in pages and "BENCHMARKS.md" in pages
    for page in pages:
        assert (DOCS / page).is_file(), page
    orphans = [str(p.relative_to(DOCS)) for p in DOCS.rglob("*.md")
               if p.parent.name != "guide" and str(p.relative_to(DOCS)) not in pages]
    assert not orphans, f"pages missing from the nav in mkdocs.yml: {orphans}"
    hooks = _hooks()
    for md in DOCS.rglob("*.md"):
        for name in re.findall(r"^<!-- swath:([a-z-]+) -->$", md.read_text(encoding="utf-8"), re.M):
            assert hooks.generated(name).strip(), f"{md.name}: {name}"


def test_docs_images_are_small():
    images = list((DOCS / "img").glob("*.png"))
    assert len(images) >= 5
    for img in images:
        assert img.stat().st_size < 300_000, img.name


def test_the_metrics_documented_are_the_ones_a_job_writes(tmp_path):
    """Every key in the formats page's table of main metrics is in a real job's metrics.json,
    and its name carries a unit swath can read."""
    import json

    from swath.cli.job import run_job
    from swath.cli.settings import settings_from_mapping
    from swath.report.metrics import key_unit

    page = (DOCS / "reference" / "formats.md").read_text(encoding="utf-8")
    table = page[page.index("The main metrics:"):page.index("`settings` holds")]
    keys = [k for row in table.splitlines() if row.startswith("| `")
            for k in re.findall(r"`([a-z0-9_]+)`", row.split("|")[1])]
    assert len(keys) >= 20
    run_job(settings_from_mapping({"part": "example:plate", "out": str(tmp_path / "job"), "point_spacing": "4mm",
                                   "constant_feed": True}))
    metrics = json.loads((tmp_path / "job" / "metrics.json").read_text())["metrics"]
    for key in keys:
        assert key in metrics, key
        assert key == "warnings" or key_unit(key).kind != "unknown", key


def test_equations_are_mathml_built_in_and_the_site_loads_no_script_from_the_network():
    """arithmatex's inline and displayed TeX become MathML at build time (no MathJax, no CDN)."""
    hooks = _hooks()
    page = ('<p>a pad of radius <span class="arithmatex">\\(R\\)</span> and</p>\n'
            '<div class="arithmatex">\\[\nw_i \\approx 2\\sqrt{2 s / \\kappa_i} , \\quad h &gt; 0\n\\]</div>')
    out = hooks.render_math(page)
    assert "arithmatex" not in out and "\\(" not in out and "\\[" not in out
    inline, display = out.split("<math")[1:]
    assert 'display="inline"' in inline and "<mi>R</mi>" in inline
    assert 'display="block"' in display and "<msqrt>" in display and "<mi>&#x003BA;</mi>" in display
    assert "<mo>&#x0003E;</mo>" in display and "&amp;" not in display      # the escaped > read back as >
    with pytest.raises(ValueError, match="cannot render the equation"):
        hooks.mathml("\\frac{1}{", display=False)
    config = yaml.safe_load((REPO / "mkdocs.yml").read_text(encoding="utf-8"))
    scripts = [str(s) for s in config.get("extra_javascript", [])]
    assert not [s for s in scripts if "://" in s], scripts
    math_pages = [p for p in DOCS.rglob("*.md") if "\\(" in p.read_text(encoding="utf-8")]
    assert len(math_pages) >= 3
    for md in math_pages:                # every equation the docs hold converts
        for tex in re.findall(r"\\\((.+?)\\\)|\\\[(.+?)\\\]", md.read_text(encoding="utf-8"), re.S):
            hooks.mathml(tex[0] or tex[1], display=bool(tex[1]))
