"""A Ray head node of its own, in a subprocess, for running ``swath big --address`` against.

:class:`LocalRayHead` runs ``ray start --head --block`` on this machine, on the loopback address
and a free port, with its files in a folder of its own (never the default ``/tmp/ray`` another
Ray on the machine may use), and stops it by its process id: it never runs ``ray stop``, which
stops every Ray of the user on the machine.  The tests and ``benchmarks/bench_bigpart.py`` use it
to measure a job on a Ray that is already running, the way a cluster is used.

The head is started with the environment of this process and:

* ``RAY_worker_niceness=0``: its workers run at the priority of the head, as a local Ray of
  ``swath big`` does (Ray's default of 15 steps nicer makes the workers lose every contest for a
  core on a busy machine);
* ``RAY_GRACEFUL_SHUTDOWN_DRAIN_TIMEOUT_S=0``: stopped at once (Ray's default drains the node for
  up to 30 s after the stop signal);
* the authentication settings given (``RAY_AUTH_MODE``, ``RAY_AUTH_TOKEN``): a driver that joins
  it must have the same.
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from ..errors import InputError

#: The line ``ray start`` prints once the head is up.
STARTED = "Ray runtime started"


def free_port(host: str = "127.0.0.1") -> int:
    """A TCP port free on ``host`` now (the system's choice)."""
    with socket.socket() as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


def ray_start_available() -> str | None:
    """None if ``ray start`` can run here, else why not (Ray is not installed)."""
    try:
        import ray.scripts.scripts  # noqa: F401
    except ImportError as exc:
        return f"Ray is not installed ({exc}); pip install 'swath[batch]'"
    return None


class LocalRayHead:
    """A Ray head in a subprocess: ``with LocalRayHead(2) as head: ... head.address ...``.

    Parameters
    ----------
    num_cpus : int
        CPUs the head offers (its workers).
    env : dict, optional
        Variables added to this process's environment for the head (e.g. ``RAY_AUTH_MODE``).
    timeout : float
        Seconds to wait for the head to start, s.

    Attributes
    ----------
    address : str
        ``127.0.0.1:PORT``, the address to give ``swath big --address``.
    """

    def __init__(self, num_cpus: int = 2, *, env: dict | None = None, timeout: float = 120.0):
        self.num_cpus = int(num_cpus)
        self.env = dict(env or {})
        self.timeout = float(timeout)
        self.port = 0
        self.address = ""
        self.process: subprocess.Popen | None = None
        self.folder: Path | None = None

    def start(self) -> LocalRayHead:
        """Start the head and wait until it is up; raises ``RuntimeError`` with its output if it
        does not start (and stops what did)."""
        reason = ray_start_available()
        if reason is not None:
            raise InputError(reason)
        # a short folder: Ray's socket paths under it must stay within the 107 characters allowed
        self.folder = Path(tempfile.mkdtemp(prefix="swr-", dir="/tmp" if os.path.isdir("/tmp") else None))
        self.port = free_port()
        self.address = f"127.0.0.1:{self.port}"
        env = {**os.environ, "RAY_worker_niceness": "0", "RAY_GRACEFUL_SHUTDOWN_DRAIN_TIMEOUT_S": "0",
               "RAY_USAGE_STATS_ENABLED": "0", **self.env}
        cmd = [sys.executable, "-c", "from ray.scripts.scripts import main; main()", "start", "--head", "--block",
               f"--num-cpus={self.num_cpus}", f"--port={self.port}", "--node-ip-address=127.0.0.1",
               "--include-dashboard=false", "--disable-usage-stats",
               f"--temp-dir={self.folder / 'ray'}"]
        log = open(self.folder / "head.log", "wb")
        try:
            self.process = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env,
                                            start_new_session=True)
        finally:
            log.close()
        deadline = time.monotonic() + self.timeout
        while time.monotonic() < deadline:
            if STARTED in self.log():
                return self
            if self.process.poll() is not None:
                break
            time.sleep(0.2)
        code = self.process.poll()
        text = self.log()
        self.stop()
        why = f"stopped with exit code {code}" if code is not None else f"did not start within {self.timeout:.0f} s"
        raise RuntimeError(f"ray start --head {why}:\n{text[-3000:]}")

    def log(self) -> str:
        """What ``ray start`` printed so far."""
        if self.folder is None:
            return ""
        try:
            return (self.folder / "head.log").read_text(errors="replace")
        except OSError:
            return ""

    def stop(self, timeout: float = 30.0) -> None:
        """Stop the head: the stop signal to ``ray start`` (which stops the processes it started),
        then, for any still running after ``timeout`` s, the kill signal to its process group."""
        p = self.process
        if p is None:
            if self.folder is not None:
                shutil.rmtree(self.folder, ignore_errors=True)
                self.folder = None
            return
        if p.poll() is None:
            p.terminate()
            try:
                p.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                pass
        try:
            os.killpg(p.pid, signal.SIGKILL)           # the group is the head's own (a new session)
        except (ProcessLookupError, PermissionError):
            pass
        try:
            p.wait(timeout=10)
        except subprocess.TimeoutExpired:             # pragma: no cover - a process the kernel will not end
            pass
        self.process = None
        if self.folder is not None:
            shutil.rmtree(self.folder, ignore_errors=True)
            self.folder = None

    def __enter__(self) -> LocalRayHead:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
