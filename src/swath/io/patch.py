"""Patch files: a :class:`~swath.surface.bspline.BSplinePatch` as JSON (``patch.json`` of ``swath fit``).

The document is :meth:`BSplinePatch.to_dict` (lengths in metres) plus any extra top-level keys
the writer adds (``swath fit`` adds the scan footprint); readers ignore keys they do not know.
Files are written atomically.
"""

from __future__ import annotations

import json
from pathlib import Path

from ..errors import InputError
from ..surface.bspline import BSplinePatch
from .atomic import write_text_atomic


def save_patch_json(patch: BSplinePatch, path, *, extra: dict | None = None) -> None:
    """Write ``patch`` as JSON to ``path`` atomically (a temporary file renamed into place).

    Parameters
    ----------
    patch : BSplinePatch
        The patch (lengths in m).
    path : str or Path
        The file to write.
    extra : dict, optional
        JSON-ready top-level keys added to the document (they must not clash with the patch's own).
    """
    doc = patch.to_dict()
    if extra:
        clash = sorted(set(extra) & set(doc))
        if clash:
            raise InputError(f"extra keys {clash} clash with the patch's own keys; rename them")
        doc.update(extra)
    write_text_atomic(path, json.dumps(doc) + "\n")


def read_patch_document(path) -> tuple[BSplinePatch, dict]:
    """Read a patch file: the patch and the whole JSON document (for extra keys).

    Raises
    ------
    InputError
        When the file is missing, is not JSON, or does not describe a valid patch; the message
        names the file.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"patch file {path} not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read patch file {path}: {exc}") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"{path} is not valid JSON (line {exc.lineno}, column {exc.colno}: {exc.msg}); "
                         "expected a patch written by swath fit") from None
    try:
        return BSplinePatch.from_dict(data), data
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None


def load_patch_json(path) -> BSplinePatch:
    """Read a patch written by :func:`save_patch_json` (see :func:`read_patch_document` for the errors)."""
    return read_patch_document(path)[0]
