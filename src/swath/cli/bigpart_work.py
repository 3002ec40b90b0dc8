"""The work of one region of a big part, and where it runs (this process, or Ray).

Three tasks per region (:mod:`swath.cli.bigpart_schedule` runs them as soon as what they need is
there):

* :func:`plan_region` reads the region's mesh from its file, slices its passes on the whole part's
  planes, routes and times them and (with ``optimise_feed``) optimises the feed on the owned area;
  its result is the region's trajectory.
* :func:`simulate_region` reads the same file and simulates the removal on the extended mesh (the
  owned area and a band each side) of every trajectory whose passes reach it, its own and its
  neighbours'; it returns the depth at the samples the region owns.
* :func:`write_rows` writes the region's stretch of the joined ``trajectory.csv`` to a file, once
  the regions before it are timed (their ends give its time shift and first pass number).

Each task returns ``(result, info)``: the result (a trajectory, or None) stays where it was made
and goes to the tasks that need it (on Ray, through the object store, not through this process);
the info (a small dict, and the owned removal samples) comes back here.  Every info holds its
worker's peak resident memory (``ru_maxrss``), process id, CPU time and start and end times, so the
peak per worker and the timeline of the run can be reported.  :class:`InlineExecutor` runs the
tasks one at a time in this process; :class:`RayExecutor` runs them as one-CPU Ray tasks on a local
Ray or a cluster.
"""

from __future__ import annotations

import logging
import os
import resource
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ..errors import InputError

log = logging.getLogger(__name__)

#: The environment variable of Ray's worker niceness (its raylet reads it when it starts).
WORKER_NICENESS = "RAY_worker_niceness"

#: The folder of the swath package this process imported (a task's info names it: on a cluster,
#: the workers' copy of the driver's swath).
SWATH_DIR = str(Path(__file__).resolve().parents[1])


def peak_rss_bytes() -> int:
    """This process's peak resident memory so far, bytes (``ru_maxrss``: KiB on Linux, bytes on macOS)."""
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(rss if sys.platform == "darwin" else rss * 1024)


def load_region(path: str, *, owned_only: bool, tile, axis):
    """The region's Surface from its ``.npz`` file (``vertices``, ``faces``, ``name``): the extended
    mesh, or with ``owned_only`` the faces whose centroid ``tile`` owns."""
    from ..segment.tiles import face_heights, submesh
    from ..surface import Surface

    if not os.path.exists(path):
        import socket

        raise InputError(f"region file {path} is not on {socket.gethostname()}, where a worker looked for it: on a "
                         f"cluster of several machines, give --work-dir a folder every node mounts at the same path")
    with np.load(path) as data:
        vertices, faces, name = data["vertices"], data["faces"], str(data["name"])
    if owned_only:
        vertices, faces = submesh(vertices, faces, tile.owns(face_heights(vertices, faces, axis)))
    return Surface(vertices, faces, name=f"{name}_region{tile.index}")


def plan_region(path: str, tile, axis, feed_direction, settings, offsets=None) -> tuple:
    """Plan, time and (``settings.optimise_feed``) feed-optimise one region (see the module notes).

    With ``optimise_feed``, the feed is optimised on the region's extended mesh over the passes of
    its own planes and of the whole part's planes ``offsets`` (p,) (m) within the band less a pad
    radius (the neighbours' passes nearest the seam), matching the target everywhere a pad radius
    in from the extended mesh's edge: the owned area and most of the band.  Only the region's own
    passes are kept, with their optimised feed.  The seam is thus optimised by both regions over
    nearly the same passes (an overlapping split), instead of by neither.

    Returns
    -------
    trajectory : Trajectory
        The region's own passes, timed.
    info : dict
        ``ends`` (:class:`swath.trajectory.join.Ends` of the trajectory), ``n_passes``, ``n_faces``
        (owned), ``feed_metrics`` (dict), ``plan_s``, ``trajectory_s``, ``feed_s``, ``load_s``,
        ``cpu_s`` (the task's CPU time, all its threads), ``peak_rss_bytes``, ``pid``, ``swath_dir``
        (the folder of the swath the worker imported), ``started``
        and ``ended`` (s since the epoch).
    """
    from ..order import route_links
    from ..plan.sections import section_passes
    from ..trajectory import time_path
    from ..trajectory.constraints import FeedProfile
    from ..trajectory.join import Ends
    from . import stages

    cpu0, started = time.process_time(), time.time()
    t0 = time.perf_counter()
    owned = load_region(path, owned_only=True, tile=tile, axis=axis)
    out: dict = {"load_s": time.perf_counter() - t0, "n_faces": len(owned.faces)}
    tool = stages.job_tool(settings)
    t0 = time.perf_counter()

    def plan(surface, planes, levels):
        toolpath = section_passes(surface, axis=axis, offsets=planes, levels=levels, feed=feed_direction,
                                  point_spacing=settings.point_spacing, min_pass_length=settings.pad_radius)
        return route_links(toolpath, clearance=settings.clearance, pad_radius=settings.pad_radius,
                           units=settings.units)

    toolpath = plan(owned, tile.offsets, tile.levels)
    out["plan_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    trajectory = time_path(toolpath, settings.constraints(), links=settings.links(), lead_angle=settings.lead())
    out["trajectory_s"] = time.perf_counter() - t0
    out["feed_s"], out["feed_metrics"] = 0.0, {}
    if settings.optimise_feed:
        t0 = time.perf_counter()
        extended = load_region(path, owned_only=False, tile=tile, axis=axis)
        all_planes = np.asarray(tile.offsets if offsets is None else offsets, float)
        reach = tile.band - tool.pad_radius
        near = (all_planes >= tile.lo - reach) & (all_planes < tile.hi + reach)
        wide = plan(extended, all_planes[near], np.flatnonzero(near))
        wide_trajectory = time_path(wide, settings.constraints(), links=settings.links(), lead_angle=settings.lead())
        _, result, out["feed_metrics"] = stages.feed_stage(wide, tool, settings, wide_trajectory, extended)
        own_levels = {int(v) for v in tile.levels}
        mine = [i for i, p in enumerate(wide.passes) if p.level in own_levels]
        profile = FeedProfile(tuple(result.profile.speeds[i] for i in mine))
        own = route_links(wide.replace(passes=tuple(wide.passes[i] for i in mine)),
                          clearance=settings.clearance, pad_radius=settings.pad_radius, units=settings.units)
        trajectory = time_path(own, settings.constraints() + [profile], links=settings.links(),
                               lead_angle=settings.lead())
        out["feed_s"] = time.perf_counter() - t0
    out.update(ends=Ends.of(trajectory), n_passes=len(toolpath.passes), contact_length_m=toolpath.contact_length,
               cpu_s=time.process_time() - cpu0, peak_rss_bytes=peak_rss_bytes(), pid=os.getpid(), swath_dir=SWATH_DIR,
               started=started, ended=time.time())
    return trajectory, out


def simulate_region(path: str, tile, axis, settings, *trajectories) -> tuple[None, dict]:
    """Simulate the removal of ``trajectories`` (those reaching the region, in any order) on the
    region's extended mesh and keep the samples it owns.

    Returns
    -------
    None
        (nothing for other tasks)
    info : dict
        ``points`` (k, 3) float32 and ``depth``, ``area`` (k,) float (m, m²) of the owned samples,
        ``interior`` (k,) bool (more than a pad radius from the part's open boundary: the band
        keeps the region's own cut edges farther than that from every owned sample),
        ``sample_spacing_m``, ``simulate_s``, ``load_s``, ``cpu_s``, ``peak_rss_bytes``, ``pid``, ``swath_dir``,
        ``started``, ``ended``.
    """
    from ..simulate import simulate_removal
    from ..trajectory.join import join_trajectories
    from . import stages

    cpu0, started = time.process_time(), time.time()
    t0 = time.perf_counter()
    surface = load_region(path, owned_only=False, tile=tile, axis=axis)
    load_s = time.perf_counter() - t0
    tool = stages.job_tool(settings)
    t0 = time.perf_counter()
    joined = join_trajectories(trajectories, link_speed=settings.links().speed)
    removal = simulate_removal(joined, surface, tool, sample_spacing=settings.sample_spacing,
                               sampling=settings.removal_sampling)
    samples = removal.surface
    owned = tile.owns(np.asarray(samples.vertices) @ np.asarray(axis, float))
    interior = samples.farther_from_boundary(tool.pad_radius)
    return None, {"points": np.asarray(samples.vertices[owned], np.float32), "depth": removal.depth[owned],
            "area": np.asarray(samples.vertex_areas)[owned], "interior": interior[owned],
            "sample_spacing_m": removal.metrics["removal_sample_spacing_m"],
            "simulate_s": time.perf_counter() - t0, "load_s": load_s, "cpu_s": time.process_time() - cpu0,
            "peak_rss_bytes": peak_rss_bytes(), "pid": os.getpid(), "swath_dir": SWATH_DIR, "started": started,
            "ended": time.time()}


def write_rows(trajectory, path: str, shift: float, first_pass: int, names) -> tuple[None, dict]:
    """Write ``trajectory``'s stretch of the joined ``trajectory.csv`` (rows only, see
    :func:`swath.trajectory.join.csv_rows`) to ``path``; returns ``(None, info)`` with ``rows_s``,
    ``bytes``, ``cpu_s``, ``peak_rss_bytes``, ``pid``, ``swath_dir``, ``started``, ``ended``."""
    from ..trajectory.join import csv_rows

    cpu0, started = time.process_time(), time.time()
    t0 = time.perf_counter()
    text = csv_rows(trajectory, shift=shift, first_pass=first_pass, names=names)
    with open(path, "w", encoding="utf-8", newline="") as fh:
        fh.write(text)
    return None, {"rows_s": time.perf_counter() - t0, "bytes": len(text), "cpu_s": time.process_time() - cpu0,
                  "peak_rss_bytes": peak_rss_bytes(), "pid": os.getpid(), "swath_dir": SWATH_DIR, "started": started,
            "ended": time.time()}


def warm_worker() -> int:
    """Import what the region tasks use (a worker's first task would otherwise); returns the process id."""
    from ..order import route_links  # noqa: F401
    from ..plan.sections import section_passes  # noqa: F401
    from ..simulate import simulate_removal  # noqa: F401
    from ..trajectory import time_path  # noqa: F401
    from ..trajectory.join import csv_rows, join_trajectories  # noqa: F401
    from . import stages  # noqa: F401

    return os.getpid()


class InlineExecutor:
    """Runs the region tasks one at a time in this process, each when it is submitted."""

    workers = 1
    where = "in this process"
    inline = True

    def __init__(self):
        self._results: dict = {}
        self._done: list = []

    @property
    def in_flight(self) -> int:
        return len(self._done)

    def submit(self, key, fn, args) -> None:
        """Run ``fn(*args)`` (``(result, info)``) now; :meth:`next_done` hands out its info."""
        result, info = fn(*args)
        self._results[key] = result
        self._done.append((key, info))

    def handle(self, key):
        """The result of task ``key``, to pass to another task."""
        return self._results[key]

    def result(self, key):
        """The result of the finished task ``key``."""
        return self._results[key]

    def next_done(self) -> tuple:
        """``(key, info)`` of a finished task not handed out yet."""
        return self._done.pop(0)

    def close(self) -> None:
        self._results.clear()


class RayExecutor:
    """Runs the region tasks as one-CPU Ray tasks.

    Without an ``address`` a local Ray with ``workers`` CPUs is started (its workers import this
    swath) and shut down by :meth:`close`; with one (``ray://host:10001``, ``auto``) the cluster is
    joined and this swath shipped to its workers.  The region files must then lie on a folder the
    workers can read (see :mod:`swath.cli.bigpart`).  A task's result stays in Ray's object store
    and goes from there to the tasks given its :meth:`handle`; only its info comes to this process.
    """

    def __init__(self, workers: int | None, address: str | None = None):
        try:
            import ray
        except ImportError:
            raise InputError("planning a big part on Ray needs Ray (pip install 'swath[batch]'); or run it in this "
                             "process with --workers 1") from None
        from .batch_ray import start_local_ray

        self._ray = ray
        self.started = False
        self._remotes: dict = {}
        self._results: dict = {}
        self._running: dict = {}
        if not ray.is_initialized():
            if address:
                join_cluster(address)
            else:
                # Ray starts its workers 15 steps nicer than itself by default; here they do all the
                # work, so they run at this process's priority (on a busy machine a niceness of 15
                # made the same regions 5-6 times slower than in this process).
                before = os.environ.get(WORKER_NICENESS)
                os.environ[WORKER_NICENESS] = "0"
                try:
                    with without_ray_extras():
                        start_local_ray(workers or os.cpu_count() or 1, warm=False)
                finally:
                    if before is None:
                        os.environ.pop(WORKER_NICENESS, None)
                    else:
                        os.environ[WORKER_NICENESS] = before
            self.started = True
        self.workers = workers or max(int(ray.cluster_resources().get("CPU", 1)), 1)
        self.where = (f"on the Ray at {address}, {self.workers} at a time" if address
                      else f"on a local Ray with {self.workers} workers")
        # One warm-up per worker, now: Ray starts a worker when a task comes for it (on a cluster, with
        # this swath unpacked for it), and the warm-up's imports then happen while this process still
        # reads and splits the part, instead of in the first region's task.
        warm = ray.remote(num_cpus=1, max_retries=0)(warm_worker)
        self._warm = [warm.remote() for _ in range(self.workers)]

    @property
    def in_flight(self) -> int:
        return len(self._running)

    def submit(self, key, fn, args) -> None:
        """Start ``fn(*args)`` as a Ray task (arguments that are :meth:`handle` s are resolved there)."""
        remote = self._remotes.get(fn)
        if remote is None:
            remote = self._remotes[fn] = self._ray.remote(num_cpus=1, max_retries=0, num_returns=2)(fn)
        result_ref, info_ref = remote.remote(*args)
        self._results[key] = result_ref
        self._running[info_ref] = key

    def handle(self, key):
        return self._results[key]

    def result(self, key):
        return self._get(self._results[key])

    def next_done(self) -> tuple:
        """``(key, info)`` of the next task to finish (waits for one); a task's error is raised here."""
        ready, _ = self._ray.wait(list(self._running), num_returns=1)
        key = self._running.pop(ready[0])
        return key, self._get(ready[0])

    def _get(self, ref):
        try:
            return self._ray.get(ref)
        except self._ray.exceptions.RayTaskError as exc:        # the task raised: raise its error here
            raise exc.as_instanceof_cause() from None

    def close(self) -> None:
        """Drop the results and leave Ray: shut a local Ray of our own down, or disconnect from a cluster."""
        self._results.clear()
        self._running.clear()
        self._warm.clear()
        if self.started:
            stop_monitor(self._ray)
            self._ray.shutdown()
            self.started = False


class CloseAside:
    """``executor.close()`` in a thread of its own, started at once, and :meth:`wait` for it.

    Once every task has finished, Ray is no longer needed: its shutdown (0.35-0.45 s on 2 cores,
    mostly waiting for its processes to end) then runs while this process stitches and writes
    the job, instead of after.  What the tasks sent back stays readable during and after the
    shutdown (Ray keeps an object fetched into this process mapped while it is referenced).
    """

    def __init__(self, executor):
        import threading

        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._close, args=(executor,), name="swath-ray-close", daemon=True)
        self._thread.start()

    def _close(self, executor) -> None:
        try:
            executor.close()
        except BaseException as exc:                      # noqa: BLE001 - raised by wait()
            self._error = exc

    def wait(self, *, raise_error: bool = True) -> None:
        """Wait until the executor is closed; raise the error its close raised (once), if asked."""
        self._thread.join()
        if raise_error and self._error is not None:
            error, self._error = self._error, None
            raise error


#: What a local Ray of the job's own starts without (methods of Ray's node that start them): the
#: dashboard's API server (``ray.init`` waits for it before the raylet starts), the autoscaler
#: monitor (a fixed local node has nothing to scale) and the log monitor (the workers' output is
#: not shown: ``log_to_driver=False``).
RAY_EXTRAS = ("start_api_server", "start_monitor", "start_log_monitor")


@contextmanager
def without_ray_extras():
    """Inside the block, a local Ray started in this process starts none of :data:`RAY_EXTRAS`.

    On 2 cores they took 1.3 s of CPU while the job read and split the part, and the API server's
    start (0.8 s) lay on the way to the first task: ``ray.init`` took 1.7-1.8 s without them
    against 3.8-4.0 s with them (under a load average of 3).  What the tasks need (the GCS, the
    raylet and its agents, the workers) starts as before.  These methods are Ray's own, not its
    public interface: on a Ray whose node lacks any of them nothing is changed.
    """
    try:
        from ray._private.node import Node
    except ImportError:                              # pragma: no cover - a Ray laid out otherwise
        yield
        return
    saved = {name: Node.__dict__[name] for name in RAY_EXTRAS if callable(Node.__dict__.get(name))}
    if len(saved) < len(RAY_EXTRAS):                 # pragma: no cover - a Ray laid out otherwise
        yield
        return
    for name in saved:
        setattr(Node, name, _not_started)
    try:
        yield
    finally:
        for name, method in saved.items():
            setattr(Node, name, method)


def _not_started(self, *args, **kwargs) -> None:
    """Stands for a method of :data:`RAY_EXTRAS` while a local Ray starts: starts nothing."""
    return None


def join_cluster(address: str) -> None:
    """Connect this process to the running Ray at ``address``, this swath shipped to its workers
    (Ray's ``py_modules``: each worker imports the driver's swath, whatever the cluster has
    installed); raises :class:`~swath.errors.InputError` naming the fix if it cannot."""
    import ray

    from .batch_ray import _package_dir

    knock(address)
    packaging = logging.getLogger("ray._private.runtime_env.packaging")   # "pushing file package ..."
    level = packaging.level
    packaging.setLevel(logging.WARNING)
    try:
        ray.init(address=address, log_to_driver=False, runtime_env={"py_modules": [_package_dir()]})
    except ConnectionError as exc:
        raise InputError(cluster_error(address, exc)) from None
    finally:
        packaging.setLevel(level)


def knock(address: str, timeout: float = 3.0) -> None:
    """Refuse a ``host:port`` address nothing listens at, at once (Ray itself tries for 40 s or
    more before it gives up); other forms (``auto``, ``ray://...``) are left to Ray."""
    import socket

    host, sep, port = address.rpartition(":")
    if not sep or "://" in address or not port.isdigit():
        return
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=timeout).close()
    except OSError as exc:
        raise InputError(cluster_error(address, exc)) from None


def cluster_error(address: str, exc: BaseException) -> str:
    """The message for a Ray at ``address`` that could not be joined (``exc``: Ray's error)."""
    text, seen = [], set()
    e: BaseException | None = exc
    while e is not None and id(e) not in seen:
        seen.add(id(e))
        text.append(f"{type(e).__name__}: {e}")
        e = e.__cause__ or e.__context__
    chain = "\n".join(text)
    if "AuthToken" in chain or "AuthenticationError" in chain:
        return (f"the Ray at {address} asks for an authentication token that this process did not send: run with "
                "RAY_AUTH_MODE=token and the cluster's token in ~/.ray/auth_token, RAY_AUTH_TOKEN_PATH or "
                "RAY_AUTH_TOKEN (Ray sends its token to an address given explicitly only when told to)")
    return (f"no Ray answered at {address}: check the address (host:port of the head's GCS, ray://host:10001 for "
            f"Ray Client, or auto for the Ray started on this machine), or start one with ray start --head "
            f"({text[-1][:200]})")


def stop_monitor(ray) -> None:
    """Stop the autoscaler monitor of the local Ray this process started, before ``ray.shutdown``.

    ``ray.shutdown`` stops its processes one after the other, the monitor after the GCS; the monitor
    then spends its whole second of grace trying to tell the stopped GCS that it was stopped, which
    is most of the shutdown's time (1.4 s, against 0.2 s with the monitor stopped first on 2 cores).
    Ray keeps its processes in a private table; if that is not there, this does nothing."""
    try:
        monitors = list(ray._private.worker._global_node.all_processes.get("monitor", []))
    except AttributeError:
        return
    for info in monitors:
        process = getattr(info, "process", None)
        if process is not None and process.poll() is None:
            process.kill()
            try:
                process.wait(timeout=5)
            except Exception:                         # noqa: BLE001 - ray.shutdown deals with it
                pass
