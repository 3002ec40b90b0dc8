"""Write outputs so that nothing half-written is ever left behind, and nothing of the user's is lost.

Files are written to a temporary sibling and renamed into place; an output directory is built as
a temporary sibling and renamed into place only when every file in it is complete.  An existing
directory is replaced only when swath wrote it (it holds the :data:`MARKER` file) or the caller
says ``overwrite``; :func:`check_output_dir` says so before any work starts.  Written files and
folders get the permissions the user's umask gives, not the 0600 of a temporary file.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from pathlib import Path

from ..errors import InputError

#: The file that marks a directory as swath's output (so a later run may replace it).
MARKER = ".swath-output"


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def check_output_dir(path, *, overwrite: bool = False) -> Path:
    """Refuse an output directory that a run could not safely replace; returns it resolved.

    Refused: an existing file; the current working directory or a folder that contains it; an
    existing non-empty directory without swath's :data:`MARKER` unless ``overwrite``.  Call it
    before any computing, so a refusal costs nothing.
    """
    path = Path(path).expanduser()
    full = path.resolve()
    if full.exists() and not full.is_dir():
        raise InputError(f"output path {path} exists and is not a directory; choose another --out")
    cwd = Path.cwd().resolve()
    if full == cwd or full in cwd.parents:
        raise InputError(f"output directory {path} is the current folder or contains it; swath replaces its output "
                         "folder whole, so give a new folder, e.g. --out out")
    if full.is_dir() and any(full.iterdir()) and not (full / MARKER).exists() and not overwrite:
        raise InputError(f"output directory {path} already holds files that swath did not write; choose a new "
                         "folder, or pass --overwrite to replace it")
    return full


@contextlib.contextmanager
def atomic_file(path, mode: str = "w", **kwargs):
    """Open a temporary file beside ``path`` for writing; rename it to ``path`` on success.

    On an exception the temporary file is removed and ``path`` is untouched.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    try:
        with os.fdopen(fd, mode, **kwargs) as fh:
            yield fh
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def write_text_atomic(path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    with atomic_file(path, "w", encoding="utf-8", newline="") as fh:
        fh.write(text)


@contextlib.contextmanager
def atomic_directory(path, *, overwrite: bool = False):
    """Yield a temporary directory that becomes ``path`` only if the block finishes.

    An existing ``path`` is replaced at the end (its old contents survive any failure) when it is
    an earlier swath output (it holds :data:`MARKER`), is empty, or ``overwrite`` is true; anything
    else is refused up front (:func:`check_output_dir`).  The new directory gets the marker.  On
    an exception — a signal turned into one included — the temporary directory is deleted.
    """
    path = check_output_dir(path, overwrite=overwrite)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent))
    try:
        yield tmp
        (tmp / MARKER).write_text("written by swath; a later swath run may replace this folder\n", encoding="utf-8")
        mask = _umask()
        os.chmod(tmp, 0o777 & ~mask)
        for root, dirs, files in os.walk(tmp):
            for name in dirs:
                os.chmod(os.path.join(root, name), 0o777 & ~mask)
            for name in files:
                os.chmod(os.path.join(root, name), 0o666 & ~mask)
        if path.exists():
            old = path.with_name(f".{path.name}.old")
            shutil.rmtree(old, ignore_errors=True)
            os.replace(path, old)
            os.replace(tmp, path)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, path)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
