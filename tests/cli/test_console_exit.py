"""The ``swath`` command's quick exit (:func:`swath.cli.main.console`): the exit status, the output and
the exit handlers are those of a normal exit."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from pathlib import Path

from conftest import REPO

SCRIPT = """
import atexit, sys, threading, time
atexit.register(lambda: print("exit handler ran", flush=True))
if "--thread" in sys.argv:
    sys.argv.remove("--thread")
    threading.Thread(target=lambda: (time.sleep(0.5), print("thread finished", flush=True))).start()
from swath.cli.main import console
console()
"""


def _run(*argv, cwd):
    env = dict(os.environ, PYTHONPATH=str(REPO / "src") + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run([sys.executable, "-c", SCRIPT, *argv], capture_output=True, text=True, cwd=cwd, env=env,
                          timeout=120)


def test_an_input_error_keeps_its_status_message_and_exit_handlers(tmp_path: Path):
    done = _run("plan", str(tmp_path / "missing.stl"), "--out", str(tmp_path / "out"), cwd=tmp_path)
    assert done.returncode == 2
    assert "swath: error:" in done.stderr and "missing.stl" in done.stderr
    assert done.stdout.strip().endswith("exit handler ran")
    assert not (tmp_path / "out").exists()


def test_a_job_writes_its_files_and_summary_before_the_quick_exit(tmp_path: Path):
    out = tmp_path / "out"
    done = _run("plan", "example:plate", "--constant-feed", "--out", str(out), cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "coverage" in done.stdout and done.stdout.strip().endswith("exit handler ran")
    assert (out / "trajectory.csv").stat().st_size > 0 and (out / "report.html").stat().st_size > 0
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]       # no half-written folder left


def test_a_running_thread_is_waited_for(tmp_path: Path):
    done = _run("plan", str(tmp_path / "missing.stl"), "--out", str(tmp_path / "out"), "--thread", cwd=tmp_path)
    assert done.returncode == 2
    assert "thread finished" in done.stdout and "exit handler ran" in done.stdout


class _Left(Exception):
    pass


def _console_exits(monkeypatch, code: int) -> tuple[str, int]:
    """How :func:`console` leaves after ``main`` returns ``code``: ("quick", status) or ("normal", status)."""
    import importlib

    cli_main = importlib.import_module("swath.cli.main")     # the module (swath.cli.main is also the function)

    def quick(status):
        raise _Left("quick", status)

    monkeypatch.setattr(cli_main, "main", lambda argv=None: code)
    monkeypatch.setattr(os, "_exit", quick)
    ran = []
    monkeypatch.setattr("atexit._run_exitfuncs", lambda: ran.append(True))
    try:
        cli_main.console()
    except _Left as left:
        assert ran == [True]                       # the exit handlers ran first
        return left.args[0], left.args[1]
    except SystemExit as stop:
        assert ran == []                           # left to Python's own exit
        return "normal", stop.code
    raise AssertionError("console() returned")


def test_console_leaves_at_once_unless_a_thread_runs(monkeypatch):
    assert _console_exits(monkeypatch, 3) == ("quick", 3)
    release = threading.Event()
    worker = threading.Thread(target=release.wait)
    worker.start()
    try:
        assert _console_exits(monkeypatch, 3) == ("normal", 3)
    finally:
        release.set()
        worker.join()
