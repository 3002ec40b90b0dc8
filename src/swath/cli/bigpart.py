"""``swath big``: a part too big for one process, planned region by region on Ray and stitched.

The part is read once, here, and cut span-wise into regions (:func:`swath.segment.tiles.span_tiles`)
on planes normal to its longest axis.  The passes lie on planes normal to the same axis, laid over
the whole part ``spacing`` apart, and every seam falls halfway between two of them, so no pass
crosses a seam and the passes of two regions sit one spacing apart across it.  Each region's
mesh (the faces it owns and a band of ``2.5`` pad radii each side) is written to its own file in
a work folder; the workers read their region from that path, never the whole part.

On the workers (:mod:`swath.cli.bigpart_work`), each region is planned, timed and optionally
feed-optimised on its own area, then its removal is simulated on the extended mesh from every
trajectory that reaches it, its own and its neighbours'; each removal sample belongs to the one
region whose span range holds it.  So the seam gets the removal of every pass that touches it
(no gap) and counts it once (no double removal).  The regions' trajectories run one after the
other, joined by straight air moves (:func:`swath.trajectory.join.join_trajectories`).

Writes ``trajectory.csv``, ``metrics.json`` and ``regions.csv`` (one row per region: its span
range, faces, passes, stage times and its worker's peak memory) atomically to ``--out``.
"""

from __future__ import annotations

import csv
import io
import logging
import math
import os
import shutil
import tempfile
import time
from contextlib import contextmanager
from dataclasses import fields
from pathlib import Path

import numpy as np

from ..errors import InputError
from .bigpart_work import CloseAside, RayExecutor
from .settings import JobSettings

log = logging.getLogger(__name__)

#: Band of the extended mesh each side of a region, in pad radii: a pad pressed on a neighbour's
#: pass that reaches the region (its centre up to one radius outside) lies wholly on the mesh.
BAND_RADII = 2.5

#: ``--regions auto`` aims at this many faces per region (and at least two regions per worker).
FACES_PER_REGION = 400_000

#: Settings ``swath big`` does not take (it plans raster sections at a constant or optimised feed).
UNSUPPORTED = ("planner", "order", "segment", "direction", "overlap", "join_gap", "fit", "optimise_spacing",
               "target_cov", "robot", "cell", "force_control", "faces", "keep_out", "edge_margin", "target_map",
               "media_change", "media_change_loss", "wear_rate")


def check_settings(settings: JobSettings) -> None:
    """Refuse the settings ``swath big`` does not take, naming them."""
    defaults = {f.name: f.default for f in fields(JobSettings)}
    given = [k for k in UNSUPPORTED if getattr(settings, k) != defaults.get(k)]
    if settings.side == "all":
        given.append("side=all")
    if given:
        raise InputError(f"swath big plans raster sections across the part's long axis and does not take "
                         f"{', '.join(given)}; plan the part with swath plan for those")


def load_arrays(settings: JobSettings) -> tuple[np.ndarray, np.ndarray, str]:
    """``(vertices (n, 3), faces (m, 3), name)`` of the job's part (a mesh file or ``example:NAME``)."""
    part = settings.part
    if part.lower().endswith(".npz"):
        return read_npz_mesh(part, units=settings.units)
    if part.startswith("example:"):
        from ..examples import example_part

        surface = example_part(part.split(":", 1)[1])
    else:
        from ..io.mesh import load_mesh

        surface = load_mesh(part, units=settings.units, side=settings.side, all_pieces=settings.all_pieces,
                            force_units=settings.force_units)
    return np.asarray(surface.vertices), np.asarray(surface.faces), surface.name


def read_npz_mesh(path: str, *, units: str = "m") -> tuple[np.ndarray, np.ndarray, str]:
    """``(vertices (n, 3) m, faces (m, 3) int, name)`` of a NumPy ``.npz`` mesh: arrays ``vertices``
    (in ``units``) and ``faces``, optionally ``name``; read without the checks and repairs of
    :func:`swath.io.mesh.load_mesh` (seconds instead of minutes for millions of faces), so only
    the shapes and index range are checked."""
    from ..units import length_unit_factor

    name = Path(path).stem
    if not Path(path).is_file():
        raise InputError(f"{path}: no such file; check the path")
    try:
        with np.load(path) as data:
            vertices, faces = np.asarray(data["vertices"], float), np.asarray(data["faces"])
            if "name" in data:
                name = str(data["name"])
    except (OSError, ValueError, KeyError) as exc:
        raise InputError(f"{Path(path).name}: not a mesh .npz with 'vertices' and 'faces' arrays ({exc})") from None
    if vertices.ndim != 2 or vertices.shape[1] != 3 or faces.ndim != 2 or faces.shape[1] != 3 or not len(faces) \
            or not np.issubdtype(faces.dtype, np.integer) or faces.min() < 0 or faces.max() >= len(vertices):
        raise InputError(f"{Path(path).name}: expected vertices (n, 3) and integer faces (m, 3) indexing them; got "
                         f"{vertices.shape} and {faces.shape} {faces.dtype}")
    return vertices * length_unit_factor(units), faces, name


def default_spacing(vertices, faces, axis, tool, name: str, heights=None) -> float:
    """The raster rule's spacing (:func:`swath.contact.widths.raster_spacing`) for planes normal to
    ``axis``, read on a slab of the part about its middle (at most 20 pad radii wide), m;
    ``heights`` (m,): the faces' heights along ``axis`` if known (m)."""
    from ..contact.widths import raster_spacing
    from ..segment.tiles import face_heights, submesh
    from ..surface import Surface

    h = face_heights(vertices, faces, axis) if heights is None else heights
    mid, half = 0.5 * (h.min() + h.max()), 10 * tool.pad_radius
    v, f = submesh(vertices, faces, np.abs(h - mid) <= half)
    return float(raster_spacing(Surface(v, f, name=f"{name}_middle"), tool, axis).spacing)


def region_count(regions, n_faces: int, workers: int, n_planes: int) -> int:
    """The number of regions: ``regions`` (int) or, for ``"auto"``, enough for about
    :data:`FACES_PER_REGION` faces each and at least two per worker, at most one per plane."""
    if regions == "auto":
        return max(1, min(n_planes, max(math.ceil(n_faces / FACES_PER_REGION), 2 * workers)))
    try:
        n = int(regions)
    except (TypeError, ValueError):
        raise InputError(f"--regions takes a count or 'auto', got {regions!r}") from None
    if n < 1:
        raise InputError(f"--regions must be at least 1, got {n}")
    return n


def run_big_part(settings: JobSettings, *, regions="auto", workers: int | None = 1, address: str | None = None,
                 executor=None, progress=None, work_dir: str | None = None, use_ray: bool | None = None) -> dict:
    """Plan a big part region by region and write the stitched job to ``settings.out``.

    Parameters
    ----------
    settings : JobSettings
        The job (tool, feed, spacing, removal sampling, feed optimisation, output folder).
    regions : int or "auto"
        Number of span-wise regions (see :func:`region_count`).
    workers : int, optional
        Region tasks at once.  1 (default): in this process (on the cluster, with ``address``);
        more, or None (every CPU of this machine, or of the cluster): on Ray.
    address : str, optional
        A running Ray to run on (``host:port`` of its head, ``ray://host:10001`` or ``auto``);
        None: a local Ray of the job's own, started and shut down here.
    executor : optional
        An executor (:mod:`swath.cli.bigpart_work`) to run the tasks on instead; closed at the end.
    progress : callable, optional
        ``progress(stage, done, total)``.
    work_dir : str, optional
        Folder for the region files (default: a new folder beside the output, removed at the end);
        on a cluster it must be one every worker can read and write.
    use_ray : bool, optional
        Run on Ray even with one worker (True), or never (False); None: on Ray unless ``workers``
        is 1 and there is no ``address``.  A Ray of our own starts while the part is read and split.

    Returns
    -------
    dict
        The metrics written to ``metrics.json`` (keys with units), with ``regions`` (the rows of
        ``regions.csv``), ``tasks`` (the rows of ``tasks.csv``: when each task ran, on which
        worker), ``stitched`` (per region: its owned removal samples ``points``, ``depth``,
        ``area``, ``interior``) and ``trajectory`` (the stitched Trajectory).
    """
    from ..io.atomic import atomic_directory, check_output_dir
    from ..trajectory.join import join_trajectories
    from .bigpart_schedule import idle_figures

    say = progress or (lambda stage, done, total: None)
    check_settings(settings)
    check_output_dir(settings.out, overwrite=settings.overwrite)
    if workers is not None and workers < 1:
        raise InputError(f"--workers must be at least 1, got {workers}")
    on_ray = use_ray if use_ray is not None else not (workers == 1 and not address)
    region_count(regions, 0, 1, 1)                 # a count that is no count is refused before the part is read
    wall0 = time.perf_counter()
    epoch0 = time.time()
    cpu0 = time.process_time()
    folder = None
    starting = None
    closing = None
    try:
        if executor is None and on_ray:
            starting = RayStart(workers, address)
        elif executor is None:
            from .bigpart_work import InlineExecutor

            executor = InlineExecutor()
        with one_blas_thread(starting is not None):   # no BLAS threads while Ray's processes are forked
            if work_dir is None:
                folder = Path(tempfile.mkdtemp(prefix=".swath-regions-", dir=Path(settings.out).resolve().parent))
            else:
                Path(work_dir).mkdir(parents=True, exist_ok=True)
            where = folder if folder is not None else Path(str(work_dir))
            known = workers or (None if address else os.cpu_count() or 1)     # a cluster's size: once joined
            split = split_part(settings, regions, where, known, starting, executor, say)
            executor, tasks = split["executor"], split["tasks"]
            if starting is not None and starting.ready_s is not None:
                split["timings"]["ray_start_s"] = starting.ready_s
        say(f"{len(tasks.tiles)} regions of {split['name']} ({split['n_faces']} faces), {executor.where}", 0, 1)
        joined: dict = {}

        def join_plans():                  # while the last regions are simulated
            t0 = time.perf_counter()
            trajectories = [executor.result(("plan", k)) for k in range(len(tasks.tiles))]
            split["timings"]["results_s"] = time.perf_counter() - t0
            t0 = time.perf_counter()
            joined["trajectory"] = join_trajectories(trajectories, link_speed=settings.links().speed)
            split["timings"]["join_s"] = time.perf_counter() - t0
        tasks.run(when_planned=join_plans)
        if "trajectory" not in joined:     # the last task to finish was a plan
            join_plans()
        executor_workers, executor_where = executor.workers, executor.where
        closing, executor = CloseAside(executor), None     # Ray shuts down while the job is stitched and written
        with atomic_directory(settings.out, overwrite=settings.overwrite) as tmp:
            metrics = stitch(settings, split, tasks, joined["trajectory"], tmp, epoch0=epoch0)
            metrics.update(workers=int(executor_workers), where=executor_where)
            metrics.update(idle_figures(metrics["tasks"], int(executor_workers)))
            finish(settings, metrics, tmp, wall_s=time.perf_counter() - wall0, driver_cpu_s=time.process_time() - cpu0)
        closing.wait()
    finally:
        if closing is not None:
            closing.wait(raise_error=False)          # the job's own error, if any, is the one raised
        elif starting is not None and executor is None:
            try:
                executor = starting.result()         # a Ray that started after the job failed is shut down too
            except Exception:                        # noqa: BLE001 - the job's own error is the one raised
                executor = None
        if executor is not None:
            executor.close()
        if starting is not None:
            starting.release()
        if folder is not None:
            shutil.rmtree(folder, ignore_errors=True)
    say("done", 1, 1)
    return metrics


class RayStart:
    """A :class:`~swath.cli.bigpart_work.RayExecutor` started in a thread of its own: Ray's start is
    mostly waiting for its processes, and this process reads and splits the part meanwhile.

    The thread lives until :meth:`release` (after the executor is closed): Ray's processes are tied
    to the life of the thread that started them (they get a signal when it ends).  Ray's notice
    that it cannot set its SIGTERM handler outside the main thread is dropped; the handler it would
    set (exit, so that the job's folders are removed) is set here, from the main thread.
    """

    def __init__(self, workers: int | None, address: str | None):
        import signal
        import sys
        import threading

        if threading.current_thread() is threading.main_thread() \
                and signal.getsignal(signal.SIGTERM) in (signal.SIG_DFL, None):
            signal.signal(signal.SIGTERM, lambda signum, frame: sys.exit(signum))
        self._args = (workers, address)
        self.started_at = time.perf_counter()
        self.ready_s: float | None = None       # s from the start to Ray up
        self._ready, self._released = threading.Event(), threading.Event()
        self._value: RayExecutor | None = None
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name="swath-ray-start", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        notice = logging.getLogger("ray._private.worker")
        level = notice.level
        notice.setLevel(logging.ERROR)
        try:
            self._value = RayExecutor(*self._args)
        except BaseException as exc:                     # noqa: BLE001 - raised in the main thread by result()
            self._error = exc
        finally:
            notice.setLevel(level)
            self.ready_s = time.perf_counter() - self.started_at
            self._ready.set()
        self._released.wait()

    def done(self) -> bool:
        """Whether Ray is up (or failed to start)."""
        return self._ready.is_set()

    def result(self):
        """The executor, once Ray is up (waits for it); Ray's error if it could not start."""
        self._ready.wait()
        if self._error is not None:
            raise self._error
        return self._value

    def release(self) -> None:
        """Let the thread end (after the executor is closed)."""
        self._released.set()
        self._thread.join(timeout=10)


@contextmanager
def one_blas_thread(active: bool):
    """BLAS on one thread inside the block when ``active``: a process forked while OpenBLAS's
    threads work can hang (its fork handler waits for them), and Ray forks its processes from this
    one while the part is read and split."""
    if not active:
        yield
        return
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:                          # pragma: no cover - threadpoolctl is a dependency
        yield
        return
    with threadpool_limits(limits=1, user_api="blas"):
        yield


def split_part(settings: JobSettings, regions, where: Path, workers, starting, executor, say) -> dict:
    """Read the part, cut it into regions and write each region's file to ``where``, starting each
    region's plan as soon as its file is written once the executor is up (``starting``: a
    :class:`RayStart` of it, waited for at the end; ``workers``: their count, None if only the
    executor knows it).  Returns ``executor``, ``tasks`` (the
    :class:`~swath.cli.bigpart_schedule.RegionTasks`), ``name``, ``n_faces``, ``spacing``,
    ``axis``, ``feed``, ``band`` (m) and ``timings`` (s)."""
    from ..segment.tiles import face_heights, principal_axes, span_tiles, submesh
    from . import stages
    from .bigpart_schedule import RegionTasks, work_order

    tool = stages.job_tool(settings)
    timings: dict = {}
    t0 = time.perf_counter()
    say("loading part", 0, 1)
    vertices, faces, name = load_arrays(settings)
    axis, feed_direction = principal_axes(vertices)
    heights_v = vertices @ axis
    h_faces = face_heights(vertices, faces, axis)
    timings["load_s"] = time.perf_counter() - t0
    spacing = settings.spacing
    if spacing is None:
        t0 = time.perf_counter()
        spacing = default_spacing(vertices, faces, axis, tool, name, heights=h_faces)
        timings["spacing_s"] = time.perf_counter() - t0
    n_planes = max(math.ceil(float(np.ptp(heights_v)) / spacing), 1)
    waited = 0.0
    if executor is None and workers is None and regions == "auto":
        t0 = time.perf_counter()                      # "auto" needs the cluster's size, known once it is joined
        executor = starting.result()
        waited += time.perf_counter() - t0
    n_workers = executor.workers if executor is not None else (workers or 1)
    n_regions = region_count(regions, len(faces), n_workers, n_planes)
    band = BAND_RADII * tool.pad_radius
    tiles = span_tiles(heights_v, spacing, n_regions, band=band)
    t0 = time.perf_counter()
    owned = [int(np.count_nonzero(t.owns(h_faces))) for t in tiles]
    order = work_order(owned)
    axis_l, feed_l = axis.tolist(), feed_direction.tolist()
    all_planes = np.concatenate([t.offsets for t in tiles])
    reach = [reaching(tiles, k) for k in range(n_regions)]
    n_faces = len(faces)

    def new_tasks(executor):
        return RegionTasks(executor, tiles, reach, order, plan_args=(axis_l, feed_l, settings, all_planes),
                           simulate_args=(axis_l, settings), link_speed=settings.links().speed,
                           rows_folder=where, progress=say)
    tasks = None
    for k in order:                                    # the files in the work order: the first can start at once
        v, f = submesh(vertices, faces, tiles[k].reaches(h_faces))
        path = where / f"region{k:04d}.npz"
        np.savez(path, vertices=v, faces=f.astype(np.int32 if len(v) < 2**31 else np.int64), name=name)
        if executor is None and starting.done():
            executor = starting.result()
        if tasks is None and executor is not None and not getattr(executor, "inline", False):
            tasks = new_tasks(executor)               # on Ray: the regions written so far start now
            for j in order[:order.index(k)]:
                tasks.file_ready(j, str(where / f"region{j:04d}.npz"))
        if tasks is not None:
            tasks.file_ready(k, str(path))
            tasks.fill()
    del vertices, faces, heights_v, h_faces            # the workers read their regions from the files
    timings["split_s"] = time.perf_counter() - t0
    if executor is None:
        t0 = time.perf_counter()
        executor = starting.result()
        waited += time.perf_counter() - t0
    if tasks is None:
        tasks = new_tasks(executor)
    for k in order:
        if k not in tasks.paths:
            tasks.file_ready(k, str(where / f"region{k:04d}.npz"))
    timings["ray_wait_s"] = waited
    return {"executor": executor, "tasks": tasks, "name": name, "n_faces": n_faces, "spacing": float(spacing),
            "axis": axis_l, "feed": feed_l, "band": band, "pad_radius": tool.pad_radius, "timings": timings}


def stitch(settings: JobSettings, split: dict, tasks, trajectory, tmp: Path, *, epoch0: float) -> dict:
    """The stitched job's metrics; writes ``trajectory.csv`` (the rows tasks' files after one header,
    or, if a region has an extra column the ones before it lacked, from ``trajectory``, the regions'
    trajectories joined), ``regions.csv`` and ``tasks.csv`` to ``tmp``."""
    from ..trajectory.join import csv_header

    t0 = time.perf_counter()
    planned, simulated = tasks.results("plan"), tasks.results("simulate")
    metrics = stitched_metrics(simulated, split["pad_radius"])
    metrics.update(cycle_time_s=trajectory.duration, contact_length_m=trajectory.contact_length,
                   air_length_m=trajectory.air_length, n_passes=int(sum(r["n_passes"] for r in planned)),
                   n_part_faces=split["n_faces"], n_regions=len(tasks.tiles), spacing_m=split["spacing"],
                   region_band_m=split["band"], long_axis=split["axis"], pass_direction=split["feed"],
                   removal_sample_spacing_m=float(max(r["sample_spacing_m"] for r in simulated)),
                   part_name=split["name"])
    per_worker: dict = {}
    cpu: dict = {}
    for r in tasks.info.values():
        per_worker[r["pid"]] = max(per_worker.get(r["pid"], 0), r["peak_rss_bytes"])
        cpu[r["pid"]] = cpu.get(r["pid"], 0.0) + r["cpu_s"]
    metrics["worker_swath_dirs"] = sorted({r["swath_dir"] for r in tasks.info.values()})
    metrics["worker_peak_rss_bytes"] = sorted(per_worker.values(), reverse=True)
    metrics["max_worker_peak_rss_bytes"] = max(per_worker.values())
    # CPU time of the region tasks: all of it, and the busiest worker's share (their ratio is the
    # speed-up the split allows whatever else the machine runs)
    metrics["regions_cpu_s"] = float(sum(cpu.values()))
    metrics["busiest_worker_cpu_s"] = float(max(cpu.values()))
    rows = region_rows(tasks.tiles, planned, simulated)
    timeline = tasks.timeline(epoch0)
    metrics["stitch_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    names = tuple(trajectory.extra)
    if all(tasks.rows_names[k] == names for k in range(len(tasks.tiles))):
        with open(tmp / "trajectory.csv", "w", encoding="utf-8", newline="") as out:
            out.write(csv_header(names))
            for k in range(len(tasks.tiles)):
                with open(tasks.rows_path(k), encoding="utf-8", newline="") as part:
                    shutil.copyfileobj(part, out, 1 << 20)
        metrics["trajectory_rows_by"] = "regions"
    else:
        log.info("a region's trajectory has extra columns the ones before it lack: trajectory.csv written here")
        trajectory.write_csv(tmp / "trajectory.csv")
        metrics["trajectory_rows_by"] = "driver"
    (tmp / "regions.csv").write_text(rows_csv(rows))
    (tmp / "tasks.csv").write_text(rows_csv(timeline))
    metrics["write_s"] = time.perf_counter() - t0
    metrics.update(split["timings"])
    metrics.update(regions=rows, tasks=timeline, stitched=simulated, trajectory=trajectory)
    return metrics


def finish(settings: JobSettings, metrics: dict, tmp: Path, *, wall_s: float, driver_cpu_s: float) -> None:
    """Write ``metrics.json`` to ``tmp``: the figures of ``metrics`` that are not tables or arrays,
    with the wall time and this process's own CPU time (reading, splitting, stitching, writing; not
    the workers'), both up to here: the figures of the job's serial part."""
    from ..report.metrics import write_metrics_json

    metrics.update(wall_s=wall_s, driver_cpu_s=driver_cpu_s)
    skip = ("regions", "tasks", "stitched", "trajectory")
    write_metrics_json(tmp / "metrics.json", {k: v for k, v in metrics.items() if k not in skip},
                       settings.as_record())


def reaching(tiles, k: int) -> list[int]:
    """Indices of the tiles whose planes lie within tile ``k``'s owned range grown by its band
    (their passes can press on the area it owns), ``k`` itself included."""
    me = tiles[k]
    return [j for j, t in enumerate(tiles) if j == k or bool(me.reaches(t.offsets).any())]


def stitched_metrics(simulated: list, pad_radius: float) -> dict:
    """Removal figures over every region's owned samples (the figures of
    :func:`swath.simulate.removal.plan_metrics` that the depths alone give), keys with units."""
    depth = np.concatenate([r["depth"] for r in simulated])
    area = np.concatenate([r["area"] for r in simulated])
    interior = np.concatenate([r["interior"] for r in simulated])
    total = float(area.sum())

    def cov(mask):
        """(mean, CoV, area) of the samples where ``mask``: each masked copy made once."""
        d, w = depth[mask], area[mask]
        a = float(w.sum())
        if not len(d) or not a > 0:
            return float("nan"), float("nan"), a
        mean = float(np.average(d, weights=w))
        std = float(np.sqrt(np.average((d - mean) ** 2, weights=w)))
        return mean, (std / mean if mean > 0 else float("nan")), a

    mean, removal_cov, covered = cov(depth > 0)
    _, interior_cov, interior_area = cov(interior)
    return {"surface_area_m2": total, "covered_area_m2": covered,
            "coverage_fraction": covered / total if total > 0 else 0.0,
            "removal_mean_m": mean, "removal_cov": removal_cov, "interior_removal_cov": interior_cov,
            "interior_area_m2": interior_area, "removal_max_m": float(depth.max()),
            "n_removal_samples": int(len(depth)), "pad_radius_m": float(pad_radius)}


def region_rows(tiles, planned, simulated) -> list[dict]:
    """One row per region: span range (m), faces, passes, stage times (s), worker peak memory (bytes)."""
    rows = []
    for t, p, s in zip(tiles, planned, simulated):
        rows.append({"region": t.index, "from_m": t.lo, "to_m": t.hi, "n_faces": p["n_faces"],
                     "n_passes": p["n_passes"], "plan_s": p["plan_s"], "trajectory_s": p["trajectory_s"],
                     "feed_s": p["feed_s"], "simulate_s": s["simulate_s"], "cpu_s": p["cpu_s"] + s["cpu_s"],
                     "n_removal_samples": int(len(s["depth"])),
                     "peak_rss_bytes": max(p["peak_rss_bytes"], s["peak_rss_bytes"])})
    return rows


def rows_csv(rows: list[dict]) -> str:
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)
    return buf.getvalue()


def add_arguments(parser) -> None:
    """The options ``swath big`` adds to the plan options: ``--regions``, ``--workers``, ``--address``."""
    parser.add_argument("--regions", default="auto",
                        help="span-wise regions the part is cut into: a count, or auto (about "
                             f"{FACES_PER_REGION // 1000}k faces each, at least two per worker)")
    parser.add_argument("--workers", type=int, default=None,
                        help="regions planned at once; 1 runs them in this process (default: every CPU, on Ray)")
    parser.add_argument("--address", default=None,
                        help="a running Ray to run on (host:port of its head, ray://host:10001 or auto); with "
                             "--workers N, N regions at a time on it; default a local Ray of the job's own")
    parser.add_argument("--work-dir", default=None,
                        help="folder for the region files the workers read (default: a new folder beside --out, "
                             "removed after); on a cluster, one every worker can read")


def run_from_args(args, settings, *, progress=None, quiet: bool = False) -> int:
    """``swath big``: run :func:`run_big_part` from parsed arguments and print a summary."""
    m = run_big_part(settings, regions=args.regions, workers=args.workers, address=args.address,
                     progress=progress, work_dir=args.work_dir)
    if not quiet:
        print(summary(settings, m))
    return 0


def summary(settings, m: dict) -> str:
    """The lines ``swath big`` prints when it is done."""
    gib = m["max_worker_peak_rss_bytes"] / 2**30
    return (f"wrote {Path(settings.out) / 'trajectory.csv'}, metrics.json, regions.csv\n"
            f"  {m['n_regions']} regions {m['where']}, {m['n_part_faces']} faces, wall {m['wall_s']:.1f} s, "
            f"peak memory per worker {gib:.2f} GiB\n"
            f"  passes {m['n_passes']}, contact path {m['contact_length_m']:.1f} m, cycle time {m['cycle_time_s']:.1f} s\n"
            f"  coverage {100 * m['coverage_fraction']:.2f} %, removal CoV {m['removal_cov']:.3f} "
            f"({m['interior_removal_cov']:.3f} a pad radius in from the edges)")
