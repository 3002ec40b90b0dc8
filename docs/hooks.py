"""mkdocs hooks: generated reference sections and the automatic "Guides" navigation.

* ``Guides`` in ``mkdocs.yml`` is filled with every ``docs/guide/*.md`` (sorted by their first
  heading), so a new guide page needs no nav edit and a missing one breaks nothing.
* A page line ``<!-- swath:NAME -->`` is replaced by generated Markdown:
  ``cli`` (every ``swath`` option, from the argparse parser), ``job-keys`` (every job-file key,
  from ``SCHEMA``), ``warnings`` (every warning code), ``metric-units`` (the unit suffixes of
  ``metrics.json`` keys).
* A fence written `````python exec`` / `````bash exec`` (run by ``tests/docs/test_tutorials.py``)
  is shown as a plain ``python`` / ``bash`` block.
* Equations (``\\(...\\)`` inline, ``\\[...\\]`` displayed, kept whole by ``pymdownx.arithmatex``)
  are turned into MathML when the site is built (``latex2mathml``), which browsers show natively:
  the site needs no script and no network to show them.
"""

from __future__ import annotations

import html
import re
from pathlib import Path

DOCS = Path(__file__).resolve().parent
_MARKER = re.compile(r"^<!-- swath:([a-z-]+) -->$", re.M)
#: What ``pymdownx.arithmatex`` (generic mode) leaves of an equation: inline ``\\(...\\)`` in a
#: span, displayed ``\\[...\\]`` in a div; the TeX inside is HTML-escaped.
_MATH = re.compile(r'<(span|div) class="arithmatex">\s*\\([(\[])(.*?)\\[)\]]\s*</\1>', re.S)
_EXEC_FENCE = re.compile(r"^(\s*```+\s*)(python|bash|toml|text)\s+exec\b[^\n]*$", re.M)


def _title(path: Path) -> str:
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("# "):
            return line[2:].strip()
    return path.stem.replace("-", " ").capitalize()


def guide_pages(docs: Path = DOCS) -> list[dict[str, str]]:
    """``[{title: "guide/x.md"}, ...]`` of every guide page, sorted by title."""
    pages = sorted((docs / "guide").glob("*.md"), key=lambda p: _title(p).lower())
    return [{_title(p): f"guide/{p.name}"} for p in pages]


def on_config(config, **kwargs):
    nav = config.get("nav") or []
    for item in nav:
        if isinstance(item, dict) and "Guides" in item:
            item["Guides"] = guide_pages(Path(config["docs_dir"]))
    return config


def generated(name: str) -> str:
    """The Markdown a ``<!-- swath:NAME -->`` marker stands for."""
    if name == "cli":
        from swath.cli.reference import cli_markdown

        return cli_markdown()
    if name == "job-keys":
        from swath.cli.reference import job_keys_markdown

        return job_keys_markdown()
    if name == "warnings":
        from swath.report.warncodes import warnings_markdown

        return warnings_markdown()
    if name == "metric-units":
        from swath.report.metrics import unit_suffix_markdown

        return unit_suffix_markdown()
    raise ValueError(f"unknown generated section <!-- swath:{name} -->")


def on_page_markdown(markdown, page, config, files, **kwargs):
    markdown = _EXEC_FENCE.sub(lambda m: m.group(1) + m.group(2), markdown)
    return _MARKER.sub(lambda m: generated(m.group(1)), markdown)


def mathml(tex: str, *, display: bool) -> str:
    """``tex`` (LaTeX math, no delimiters) as a MathML ``<math>`` element; a displayed equation
    gets ``display="block"``.  Raises ``ValueError`` naming the equation when it cannot be read."""
    from latex2mathml.converter import convert

    try:
        return convert(tex.strip(), display="block" if display else "inline")
    except Exception as exc:                # latex2mathml raises its own errors for unknown commands
        raise ValueError(f"cannot render the equation {tex.strip()!r} as MathML: {exc}") from exc


def render_math(page_html: str) -> str:
    """Every arithmatex equation in ``page_html`` replaced by its MathML."""

    def one(m: re.Match) -> str:
        display = m.group(2) == "["
        return mathml(html.unescape(m.group(3)), display=display)

    return _MATH.sub(one, page_html)


def on_page_content(page_html, page, config, files, **kwargs):
    return render_math(page_html)
