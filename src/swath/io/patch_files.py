"""Patch files with their footprint: patch.json as swath fit writes it."""

from __future__ import annotations

import logging

from ..surface.footprint import Footprint

log = logging.getLogger(__name__)


def save_patch(patch, path, footprint: Footprint | None = None) -> None:
    """Write ``patch`` as JSON (:func:`swath.io.patch.save_patch_json`) with its footprint, atomically."""
    from .patch import save_patch_json

    save_patch_json(patch, path, extra=None if footprint is None else {"footprint": footprint.to_dict()})


def load_patch(path):
    """Read a patch written by :func:`save_patch` (or :func:`swath.io.patch.save_patch_json`):
    ``(BSplinePatch, Footprint or None)``."""
    from .patch import read_patch_document

    patch, data = read_patch_document(path)
    fp = data.get("footprint")
    return patch, (None if fp is None else Footprint.from_dict(fp))
