"""Run batch jobs as Ray tasks (imported only when a sweep runs on more than one worker).

A local Ray is started for the sweep and shut down after it; an existing cluster is joined (and
left) when an address is given.  At most ``workers`` tasks are in flight, so a cluster can be
shared; each task asks for one CPU.  Rows come back as tasks finish; a task whose worker dies
(out of memory, a crash) gives a failed row instead of stopping the sweep.
"""

from __future__ import annotations

import logging
import os
import re
from pathlib import Path

from ..errors import InputError

log = logging.getLogger(__name__)

#: The logger of Ray's notice that a local cluster runs with token authentication (Ray >= 2.5x).
AUTH_NOTICE_LOGGER = "ray._private.authentication.authentication_token_setup"


def _task(job_id: str, values: dict, base_dir: str) -> dict:
    from .batch import run_batch_job

    logging.basicConfig(level=logging.WARNING, format="swath: %(levelname)s: %(message)s")
    return run_batch_job(job_id, values, base_dir)


def _warm_task() -> int:
    from .batch import warm_up

    warm_up()
    return os.getpid()


def run_on_ray(jobs, base_dir: str, *, workers: int | None, address: str | None):
    """Yield one row per job of ``jobs`` (BatchJob) as each finishes, in finishing order.

    Parameters
    ----------
    jobs : sequence of BatchJob
    base_dir : str
        Folder relative part paths are read from (the sweep file's folder).
    workers : int, optional
        Tasks in flight at once; default every CPU of the local machine (local Ray) or no limit
        (cluster).
    address : str, optional
        Cluster address; None starts a local Ray with ``workers`` CPUs.
    """
    try:
        import ray
    except ImportError:
        raise InputError("running on more than one worker needs Ray (pip install 'swath[batch]'); "
                         "or run serially with --workers 1") from None
    started = False
    if not ray.is_initialized():
        if address:
            # Ship this swath to the cluster's workers, so that they run the driver's version.
            ray.init(address=address, log_to_driver=False, runtime_env={"py_modules": [_package_dir()]})
        else:
            # Warm the workers only when some will run a second job: with one job each, every job
            # pays the same start-up anyway, and the warm-up job would only add its own time.
            n_cpus = workers or os.cpu_count() or 1
            start_local_ray(n_cpus, warm=len(jobs) > n_cpus)
        started = True
    limit = workers or (len(jobs) if address else (os.cpu_count() or 1))
    remote = ray.remote(num_cpus=1, max_retries=0)(_task)
    try:
        queue = list(jobs)
        running: dict = {}
        while queue or running:
            while queue and len(running) < limit:
                job = queue.pop(0)
                running[remote.remote(job.job_id, job.values, base_dir)] = job
            ready, _ = ray.wait(list(running), num_returns=1)
            for ref in ready:
                job = running.pop(ref)
                try:
                    yield ray.get(ref)
                except ray.exceptions.RayError as exc:        # the worker died or could not import swath
                    yield {"job_id": job.job_id, "status": "failed", "error": _error_line(exc), "resumed": False,
                           **_settings_columns(job)}
    finally:
        if started:
            ray.shutdown()


def _package_dir() -> str:
    import swath

    return str(Path(swath.__file__).resolve().parent)


def _error_line(exc: Exception) -> str:
    """One line for a task that Ray could not run: the innermost ``XxxError: ...`` line if any."""
    text = re.sub(r"\x1b\[[0-9;]*m", "", str(exc))
    found = re.findall(r"^(\w+(?:Error|Exception|Exit)\b.*)$", text, flags=re.MULTILINE)
    line = found[-1] if found else next((x for x in text.splitlines() if x.strip()), "")
    return f"{type(exc).__name__}: {line.strip()}"[:300]


def local_ray_options(n_cpus: int) -> dict:
    """``ray.init`` keywords of the local Ray of a sweep: ``n_cpus`` CPUs, no dashboard, worker logs
    kept out of the terminal (see :func:`start_local_ray` for how its workers find swath)."""
    # address "local": a new Ray of our own, even if `ray start` left one running on this machine.
    return {"address": "local", "num_cpus": n_cpus, "include_dashboard": False, "log_to_driver": False,
            "configure_logging": False}


def start_local_ray(n_cpus: int, *, warm: bool = True) -> None:
    """Start the local Ray of a sweep (:func:`local_ray_options`), its workers importing the same swath
    as this process, and (``warm``) run :func:`swath.cli.batch.warm_up` on each of its ``n_cpus``
    workers at once, so that every job's ``job_s`` is its own time and not partly its worker's
    imports.  A warm-up that fails is logged and the sweep goes on: each job then reports its own
    failure.

    The workers inherit ``PYTHONPATH`` from the Ray processes ``ray.init`` starts here, so it is set
    (this swath's folder first) for the time of the call only.  Not through a ``runtime_env``: Ray
    starts the workers of a runtime environment only when the first task arrives, about half a
    second into the sweep, where the plain environment's workers are already running once
    ``ray.init`` returns.
    """
    import ray

    src = str(Path(_package_dir()).parent)
    before = os.environ.get("PYTHONPATH")
    os.environ["PYTHONPATH"] = os.pathsep.join(p for p in (src, before) if p)
    # A new Ray turns token authentication on for a local cluster and says so on the terminal, in
    # the middle of the sweep's progress; authentication stays on, its notice is dropped (a logger
    # that older Rays do not have is harmless to quiet).
    notice = logging.getLogger(AUTH_NOTICE_LOGGER)
    level = notice.level
    notice.setLevel(logging.ERROR)
    try:
        ray.init(**local_ray_options(n_cpus))
    finally:
        notice.setLevel(level)
        if before is None:
            os.environ.pop("PYTHONPATH", None)
        else:
            os.environ["PYTHONPATH"] = before
    if warm:
        warm_workers(n_cpus)


def warm_workers(n: int) -> list[int]:
    """Run the warm-up on ``n`` one-CPU tasks at the same time (so on ``n`` different workers, each
    then kept by Ray for the sweep's tasks); return their process ids ([] if the warm-up failed)."""
    import ray

    remote = ray.remote(num_cpus=1, max_retries=0)(_warm_task)
    try:
        return list(ray.get([remote.remote() for _ in range(n)]))
    except Exception as exc:  # noqa: BLE001 -- the jobs will report it, each in its own row
        log.warning("warming the Ray workers up failed (%s); the jobs go on", _error_line(exc))
        return []


def _settings_columns(job) -> dict:
    from .batch import _plain

    return _plain(job.settings.as_record())
