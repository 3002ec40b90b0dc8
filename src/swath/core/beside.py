"""Run one function in a forked child process while this process goes on with other work.

Used where a set-up has two independent halves and one of them cannot leave this process (the
uniform planner's heat-method solver lives in C++ and is built here; its width model is plain
arrays and is built beside it).  The child is forked, so it starts at once with everything this
process has loaded, and only the result travels back: pickled, with its large arrays written to
a memory-backed file (``/dev/shm``) that this process maps instead of reading them through a pipe
(a 100 MB width model arrives in milliseconds, not 0.18 s).
"""

from __future__ import annotations

import atexit
import logging
import mmap
import multiprocessing
import os
import pickle
import signal
import sys
import tempfile
from collections.abc import Callable
from typing import Any

from .cpus import usable_cpus

log = logging.getLogger(__name__)

#: Answers whose arrays (pickle-5 out-of-band buffers) add up to at least this many bytes travel
#: through a memory-backed file; smaller ones through the pipe.
FILE_BYTES = 1 << 20
#: Buffers start at multiples of this in the file, so the arrays mapped from it are aligned.
_ALIGN = 64


def can_fork() -> bool:
    """Whether child processes may be forked here: Linux (fork is unsafe on macOS and absent on Windows)."""
    return sys.platform.startswith("linux") and "fork" in multiprocessing.get_all_start_methods()


class Beside:
    """``fn(*args)`` computed in a forked child from now on; :meth:`result` waits for it.

    Where forking is not possible or wanted (``allowed=False``, fewer than 2 usable CPUs, not
    Linux), nothing starts now and :meth:`result` calls ``fn(*args)`` here.  If the child dies
    without answering (killed, out of memory), :meth:`result` also computes it here, so the
    answer is the same either way; an exception ``fn`` raises in the child is raised again here.

    ``fn`` must be deterministic and must not change state this process relies on: the child's
    changes (caches filled, attributes set) stay in the child.

    ``workers=True`` lets the child start worker processes of its own (a multiprocessing child
    that may not is a daemon); such a child still running when this process exits without having
    asked for the result is terminated.
    """

    def __init__(self, fn: Callable[..., Any], *args: Any, allowed: bool = True, workers: bool = False):
        self._fn, self._args = fn, args
        self._process = self._conn = None
        if allowed and usable_cpus() >= 2 and can_fork():
            ctx = multiprocessing.get_context("fork")
            self._conn, child_end = ctx.Pipe(duplex=False)
            self._process = ctx.Process(target=_serve, args=(fn, args, child_end), daemon=not workers)
            self._process.start()
            child_end.close()
            if workers:
                atexit.register(self._stop)

    def _stop(self) -> None:
        """Terminate a child whose result was never asked for (at exit)."""
        if self._process is not None and self._process.is_alive():
            self._process.terminate()
            self._process.join(5.0)
            if self._process.is_alive():                  # a handler that outlived the reset in _serve
                self._process.kill()
                self._process.join(5.0)

    @property
    def forked(self) -> bool:
        """Whether ``fn`` runs in a child process (else :meth:`result` computes it here)."""
        return self._process is not None or getattr(self, "_forked", False)

    def ready(self) -> bool:
        """Whether :meth:`result` would answer without waiting for the child (it has answered or
        ended; True where nothing was forked, :meth:`result` then computing it here)."""
        if hasattr(self, "_answer") or self._process is None:
            return True
        assert self._conn is not None
        return bool(self._conn.poll())

    def result(self) -> Any:
        """The value of ``fn(*args)`` (computed once: later calls return the same object)."""
        if not hasattr(self, "_answer"):
            self._answer = self._wait()
        return self._answer

    def _wait(self) -> Any:
        if self._process is None:
            return self._fn(*self._args)
        process, conn, self._process = self._process, self._conn, None
        self._forked = True
        atexit.unregister(self._stop)
        assert conn is not None
        try:
            kind, value = _received(conn.recv())
        except (EOFError, OSError):
            kind, value = "lost", None
        finally:
            conn.close()
            process.join()
        if kind == "ok":
            return value
        if kind == "raised":
            raise value
        log.warning("a helper process ended without an answer (exit code %s); computing here instead",
                    process.exitcode)
        return self._fn(*self._args)


def _shared_dir() -> str | None:
    """A memory-backed folder for hand-over files, or None (the default temporary folder is then
    used, which may be a disk)."""
    return "/dev/shm" if os.path.isdir("/dev/shm") and os.access("/dev/shm", os.W_OK) else None


def _serve(fn, args, conn) -> None:     # pragma: no cover - runs in the child
    # the parent's SIGTERM handler (the CLI's, which exits cleanly) is not the child's: a child
    # stopped unread must die at once, not hand back an exception through a pipe nobody reads
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        answer = ("ok", fn(*args))
    except BaseException as exc:  # noqa: BLE001 - handed back to the parent as it is
        answer = ("raised", exc)
    try:
        conn.send(_packed(answer))
    except Exception as exc:  # noqa: BLE001 - e.g. an exception that does not pickle
        conn.send(("raised", RuntimeError(f"{type(answer[1]).__name__}: {answer[1]} (in a helper process; "
                                          f"its answer did not pickle: {exc})")))
    finally:
        conn.close()


def _packed(answer: tuple) -> tuple:
    """``answer`` as it goes through the pipe: itself when small, else ``("file", pickle bytes, path,
    [(offset, length), ...])`` with the pickle's out-of-band buffers (the arrays' memory) written to
    the file at ``path`` (a hand-over file the receiver maps and deletes)."""
    buffers: list[pickle.PickleBuffer] = []
    data = pickle.dumps(answer, protocol=5, buffer_callback=buffers.append)
    if sum(b.raw().nbytes for b in buffers) < FILE_BYTES:
        return answer
    try:
        fd, path = tempfile.mkstemp(prefix="swath-beside-", dir=_shared_dir())
    except OSError:
        return answer
    try:
        spans = []
        with os.fdopen(fd, "wb") as f:
            for b in buffers:
                raw = b.raw()
                f.write(b"\0" * (-f.tell() % _ALIGN))
                spans.append((f.tell(), raw.nbytes))
                f.write(raw)
    except OSError:
        # a full or small /dev/shm (containers often have 64 MB): through the pipe after all
        os.unlink(path)
        return answer
    except BaseException:
        os.unlink(path)
        raise
    return ("file", data, path, spans)


def _received(message: tuple) -> tuple:
    """The ``(kind, value)`` answer from what :func:`_packed` sent.  A hand-over file is mapped
    copy-on-write (the arrays are writable, changes stay in this process) and deleted at once."""
    if message[0] != "file":
        return message
    _, data, path, spans = message
    try:
        with open(path, "rb") as f:
            memory = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_COPY)
    finally:
        os.unlink(path)
    view = memoryview(memory)
    return pickle.loads(data, buffers=[view[o:o + n] for o, n in spans])
