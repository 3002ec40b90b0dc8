"""``swath batch sweep.toml``: run a grid of finishing jobs and collect their figures in one table.

Sweep file
----------
A sweep file is a job TOML (the keys of ``swath run``, quantities with units) plus a ``[grid]``
table of lists.  The jobs are the cartesian product of the grid lists, each laid over the base
settings; the first grid key varies slowest::

    out = "sweep-out"              # sweep folder (relative to this file); one sub-folder per job
    pad_radius = "38.1mm"          # base settings: every key of a job file except out
    point_spacing = "2mm"
    feed = "50mm/s"

    [grid]                         # one list per varied key (any job key except out)
    part = ["example:plate", "example:panel", "parts/crs_part_5.stl"]
    planner = ["raster", "uniform"]
    force = ["10N", "20N"]

The base settings may also sit in a ``[job]`` table (as in a job file); ``out`` may be given
there or at the top level.  A key may not be both a base setting and a grid key.  Relative part
paths are read from the sweep file's folder.

Each job gets a deterministic, readable id: its index in the product (zero-padded) and its grid
values, e.g. ``0007-panel-raster-f20N`` (parts by file stem, planners and motions by name, other
keys by a short prefix: ``r`` pad radius, ``f`` force, ``v`` feed, ``s`` spacing, ``a`` angle,
...).  Job ``ID`` writes its usual output (``trajectory.csv``, ``metrics.json``, ``report.html``)
to ``OUT/ID/``; the sweep writes ``OUT/results.csv`` (and ``OUT/results.parquet`` when pyarrow is
installed), one row per job sorted by id: ``job_id``, ``status`` (``ok`` or ``failed``),
``error`` (the failure in one line), ``resumed``, the settings (units in the column names) and
the main metrics (:data:`METRIC_COLUMNS`; ``job_s`` and ``job_cpu_s`` are the job's wall and CPU
time).  A job that failed with an unexpected exception (not an input error) leaves its traceback
in ``OUT/errors/ID.txt``.  A failed job writes no folder (job outputs are atomic).

The whole sweep is validated before any job starts: a bad key or value is refused naming the key
and the first job it breaks.  With resume (the default) a job whose folder already holds a
``metrics.json`` written with the same settings is not run again; its row is read back.

Running
-------
``--workers 1`` runs the jobs one after another in this process (Ray is not imported).  More
workers run them as Ray tasks: on a local Ray started for the sweep (``--workers`` CPUs, default
all), or on an existing cluster when ``--address`` or ``RAY_ADDRESS`` is given.  When a local Ray's
workers will run more than one job each, they first run a small job each (:func:`warm_up`), so that
every job's ``job_s`` is its own time and not its worker's imports.  On a cluster
this process's swath package is shipped to the workers (Ray ``py_modules``), so they run the
same code; its dependencies must be installed on every node, and the part files and ``out``
must be on a file system every node sees.

    swath batch sweep.toml [--workers N] [--address ADDR] [--resume | --no-resume] [-q]

Progress goes to stderr, a line per finished job.  Exit status: 0 every job ok, 1 some failed
(the table is written all the same), 2 the sweep was refused (nothing ran), 130 interrupted
(finished jobs keep their folders; run again to resume).
"""

from __future__ import annotations

import argparse
import csv
import io
import itertools
import json
import logging
import numbers
import os
import re
import sys
import time
import traceback
from dataclasses import dataclass
from pathlib import Path, PurePath
from typing import Any

from ..errors import InputError, SwathError

log = logging.getLogger(__name__)

#: Metric columns of the results table, in order (empty for a failed job).
METRIC_COLUMNS = (
    "n_passes", "coverage_fraction", "effective_coverage_fraction", "removal_cov", "interior_removal_cov", "removal_mean_m",
    "removal_p5_m", "removal_p95_m", "removal_max_m", "hot_spot_area_m2", "contact_length_m", "air_length_m", "cycle_time_s",
    "coverage_lower_bound_m", "efficiency", "load_s", "plan_s", "trajectory_s", "simulate_s", "job_s", "job_cpu_s",
)
#: Short prefixes of grid values in job ids (other keys use their own name).
_ID_PREFIX = {"pad_radius": "r", "force": "f", "feed": "v", "spacing": "s", "angle": "a", "direction": "a",
              "depression": "d", "stiffness": "k", "point_spacing": "ps", "clearance": "c", "overlap": "o",
              "sample_spacing": "ss", "surface_spacing": "fs", "max_centripetal": "ac", "max_angular": "w",
              "max_accel": "at", "units": "u", "side": "side", "planner_options": ""}
_BARE_IDS = {"part", "planner", "motion", "parameterization"}


@dataclass(frozen=True)
class BatchJob:
    """One job of a sweep: its id, its text settings (as in a job file) and the validated record."""

    job_id: str
    values: dict
    settings: Any             # swath.cli.settings.JobSettings


@dataclass(frozen=True)
class Sweep:
    """A validated sweep: the output folder, the grid keys and the jobs in product order."""

    out: Path
    base_dir: Path
    grid_keys: tuple
    jobs: tuple


#: Relative planning work per planner (uniform plans six candidate directions and times each one).
PLANNER_WORK = {"uniform": 3.0}


def expected_job_work(job: BatchJob, base_dir) -> float:
    """A rough, unitless guess of a job's run time, for scheduling only (never for results): the
    planner's weight (:data:`PLANNER_WORK`, 1 for planners not listed) times the part file's size in
    MB plus one (built-in ``example:`` parts count as empty files).  The sweep runs longest first."""
    part = str(job.values.get("part", ""))
    size_mb = 0.0
    if not part.startswith("example:"):
        path = Path(part) if Path(part).is_absolute() else Path(base_dir) / part
        try:
            size_mb = path.stat().st_size / 1e6
        except OSError:          # a missing file fails in its own job, with its own message
            size_mb = 0.0
    return PLANNER_WORK.get(str(job.values.get("planner", "")), 1.0) * (1.0 + size_mb)


def load_sweep(path) -> Sweep:
    """Read and validate a sweep file (see the module docstring); refuses bad input with InputError."""
    from .settings import read_toml

    path = Path(path)
    data = read_toml(path, "sweep file")
    try:
        return sweep_from_mapping(data, base_dir=path.resolve().parent)
    except InputError as exc:
        raise InputError(f"{path.name}: {exc}") from None


def sweep_from_mapping(data: dict, *, base_dir: Path) -> Sweep:
    """Expand a parsed sweep table into jobs and validate every job's settings.

    Parameters
    ----------
    data : dict
        The sweep as parsed TOML: base job keys (top level or ``job``), ``out`` and ``grid``.
    base_dir : Path
        Folder that relative ``out`` and part paths are read from.
    """
    from .job import settings_from_mapping

    data = dict(data)
    grid = data.pop("grid", {})
    if not isinstance(grid, dict):
        raise InputError("[grid] must be a table of lists, e.g. planner = [\"raster\", \"uniform\"]")
    base = dict(data.pop("job")) if isinstance(data.get("job"), dict) else {}
    for key, value in data.items():
        if _norm(key) in {_norm(k) for k in base}:
            raise InputError(f"{key!r} is set both at the top level and in [job]; keep one")
        base[key] = value
    out = base.pop("out", None)
    if not isinstance(out, str) or not out:
        raise InputError("a sweep needs 'out', the folder that receives one sub-folder per job and results.csv")
    out_dir = Path(out) if Path(out).is_absolute() else base_dir / out
    for key, values in grid.items():
        if key == "out":
            raise InputError("'out' cannot be a grid key: every job writes to OUT/JOB_ID")
        if _norm(key) in {_norm(k) for k in base}:
            raise InputError(f"{key!r} is both a base setting and a grid key; keep one")
        if not isinstance(values, list) or not values:
            raise InputError(f"grid key {key!r} must be a non-empty list, e.g. {key} = [..., ...]; got {values!r}")
    keys = tuple(grid)
    combos = list(itertools.product(*(grid[k] for k in keys)))
    width = max(4, len(str(len(combos) - 1)))
    jobs = []
    for index, combo in enumerate(combos):
        varied = dict(zip(keys, combo))
        job_id = make_job_id(index, varied, width=width)
        values = {**base, **varied, "out": str(out_dir / job_id)}
        try:
            settings = settings_from_mapping(values, base_dir=base_dir)
        except InputError as exc:
            key = _offending_key(values, base_dir)
            where = f"{key} = {values[key]!r}: " if key and repr(key) not in str(exc) else ""
            raise InputError(f"job {job_id}: {where}{exc}") from None
        if settings.part.startswith("example:"):
            from ..examples import PARTS

            if settings.part.split(":", 1)[1] not in PARTS:
                raise InputError(f"job {job_id}: part = {settings.part!r} is not a built-in part; choose one of "
                                 + ", ".join(f"example:{name}" for name in PARTS))
        jobs.append(BatchJob(job_id, values, settings))
    return Sweep(out=out_dir, base_dir=base_dir, grid_keys=keys, jobs=tuple(jobs))


def _norm(key: str) -> str:
    return key.replace("-", "_")


def _offending_key(values: dict, base_dir: Path) -> str | None:
    """The first key whose value alone is refused (to name it in the message), if there is one."""
    from .job import settings_from_mapping

    for key, value in values.items():
        if key in ("part", "out"):
            continue
        try:
            settings_from_mapping({"part": "example:plate", "out": "out", key: value}, base_dir=base_dir)
        except InputError:
            return key
    return None


def make_job_id(index: int, varied: dict, *, width: int = 4) -> str:
    """A readable, file-name-safe job id: ``{index:0{width}d}`` then each grid value, ``-``-joined.

    >>> make_job_id(7, {"part": "example:panel", "planner": "raster", "force": "20N"})
    '0007-panel-raster-f20N'
    """
    words = [f"{index:0{width}d}"]
    for key, value in varied.items():
        name = key.replace("-", "_")
        if isinstance(value, dict):
            text = "_".join(f"{k}{v}" for k, v in value.items())
        elif name == "part":
            text = str(value).split(":", 1)[1] if str(value).startswith("example:") else PurePath(str(value)).stem
        else:
            text = str(value)
        if name not in _BARE_IDS:
            text = _ID_PREFIX.get(name, name) + text
        text = re.sub(r"[^A-Za-z0-9.+]+", "_", text.replace("/", "p")).strip("_.")
        words.append(text[:40])
    return "-".join(words)


def run_sweep(sweep: Sweep, *, workers: int | None = None, address: str | None = None, resume: bool = True,
              progress=None) -> list[dict]:
    """Run every job of ``sweep``; write ``results.csv`` (and Parquet); return the rows sorted by id.

    Parameters
    ----------
    sweep : Sweep
        From :func:`load_sweep` or :func:`sweep_from_mapping`.
    workers : int, optional
        1: serial, in this process, without Ray.  More: that many Ray tasks at a time (a local
        Ray with that many CPUs unless ``address`` is given).  Default: every CPU of the local
        machine, or every free slot of the cluster.
    address : str, optional
        Ray cluster address (``ray://host:10001`` or ``host:6379``); default ``RAY_ADDRESS`` if
        set, else a local Ray.  Ignored with ``workers=1``.
    resume : bool
        Skip jobs whose folder holds a ``metrics.json`` with the same settings (default True).
    progress : callable, optional
        ``progress(done: int, total: int, row: dict)`` after each job (resumed ones included).
    """
    if workers is not None and workers < 1:
        raise InputError(f"workers must be at least 1, got {workers}")
    say = progress or (lambda done, total, row: None)
    total = len(sweep.jobs)
    rows, todo = [], []
    for job in sweep.jobs:
        row = _finished_row(job) if resume else None
        if row is None:
            todo.append(job)
        else:
            rows.append(row)
            say(len(rows), total, row)
    if todo:
        if workers == 1:
            for job in todo:
                rows.append(run_batch_job(job.job_id, job.values, str(sweep.base_dir)))
                say(len(rows), total, rows[-1])
        else:
            from .batch_ray import run_on_ray

            # Longest first (LPT): the last jobs to start are short, so workers finish together.
            todo.sort(key=lambda job: expected_job_work(job, sweep.base_dir), reverse=True)
            for row in run_on_ray(todo, str(sweep.base_dir), workers=workers,
                                  address=address or os.environ.get("RAY_ADDRESS") or None):
                rows.append(row)
                say(len(rows), total, row)
    rows.sort(key=lambda r: r["job_id"])
    write_results(sweep, rows)
    return rows


def run_batch_job(job_id: str, values: dict, base_dir: str) -> dict:
    """Run one job and return its table row; never raises for a failure of the job itself."""
    from .job import run_job, settings_from_mapping

    t0, cpu0 = time.perf_counter(), time.process_time()
    settings = None
    try:
        settings = settings_from_mapping(values, base_dir=Path(base_dir))
        metrics = run_job(settings)
        row = _row(job_id, settings, metrics, status="ok")
    except Exception as exc:  # noqa: BLE001 -- a failed job is reported in its row; the sweep goes on
        first = (str(exc).strip().splitlines() or [""])[0]
        row = _row(job_id, settings, {}, status="failed", error=f"{type(exc).__name__}: {first}")
        if not isinstance(exc, SwathError):
            row["_traceback"] = traceback.format_exc()
    row["job_s"] = time.perf_counter() - t0
    row["job_cpu_s"] = time.process_time() - cpu0
    return row


#: The job :func:`warm_up` runs: a built-in part under a coarse raster, every stage and the report.
WARM_UP_JOB = {"part": "example:plate", "planner": "raster", "point_spacing": "5mm"}


def warm_up() -> float:
    """Run one small job in a scratch folder, so that this process has imported everything a job
    uses and loaded the compiled kernels from numba's cache; return its wall time in s.

    A batch worker's first job would otherwise pay that (about 1.4 s on 2 vCPUs) inside its own
    ``job_s``, so the same job would read slower on a fresh worker than on a busy one.  Raises
    :class:`~swath.errors.SwathError` if the job fails (the installation is broken: every job would).
    """
    import tempfile

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="swath-warm-") as tmp:
        row = run_batch_job("warm-up", {**WARM_UP_JOB, "out": str(Path(tmp) / "job")}, tmp)
    if row["status"] != "ok":
        raise SwathError(f"the warm-up job failed, so every job would: {row['error']}")
    return time.perf_counter() - t0


def _row(job_id: str, settings, metrics: dict, *, status: str, error: str = "", resumed: bool = False) -> dict:
    row = {"job_id": job_id, "status": status, "error": error, "resumed": resumed}
    if settings is not None:
        row.update(_plain(settings.as_record()))
    for key in METRIC_COLUMNS:
        value = metrics.get(key)
        if isinstance(value, numbers.Integral) and not isinstance(value, bool):
            value = int(value)
        elif isinstance(value, numbers.Real):
            value = float(value)
        row[key] = value
    return row


def _plain(record: dict) -> dict:
    """A settings record as JSON-comparable values (what metrics.json stores)."""
    return json.loads(json.dumps(record, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o)))


def _finished_row(job: BatchJob) -> dict | None:
    """The row of a job finished earlier with the same settings, or None if it must run."""
    path = Path(job.settings.out) / "metrics.json"
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    stored = doc.get("settings", {}) if isinstance(doc, dict) else {}
    wanted = _plain(job.settings.as_record())
    if any(stored.get(k) != v for k, v in wanted.items()):
        log.info("%s: settings changed since its metrics.json was written; running it again", job.job_id)
        return None
    row = _row(job.job_id, job.settings, doc.get("metrics", {}), status="ok", resumed=True)
    row["job_s"] = row["job_cpu_s"] = None
    return row


def write_results(sweep: Sweep, rows: list[dict]) -> Path:
    """Write ``results.csv`` (and ``results.parquet`` with pyarrow) into ``sweep.out`` atomically,
    and each failed job's traceback to ``errors/ID.txt``; returns the CSV path."""
    from ..io.atomic import atomic_file, write_text_atomic

    columns = ["job_id", "status", "error", "resumed"]
    for row in rows:
        columns += [k for k in row if k not in columns and k not in METRIC_COLUMNS and not k.startswith("_")]
    columns += list(METRIC_COLUMNS)
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(columns)
    for row in rows:
        writer.writerow([_cell(row.get(k)) for k in columns])
    out_csv = sweep.out / "results.csv"
    write_text_atomic(out_csv, buf.getvalue())
    for row in rows:
        trace = sweep.out / "errors" / f"{row['job_id']}.txt"
        if row.get("_traceback"):
            write_text_atomic(trace, row["_traceback"])
        elif trace.exists():                      # from an earlier run of a job that is fine now
            trace.unlink()
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return out_csv
    table = pa.Table.from_pylist([{k: _parquet_cell(row.get(k)) for k in columns} for row in rows])
    with atomic_file(sweep.out / "results.parquet", "wb") as fh:
        pq.write_table(table, fh)
    return out_csv


def _cell(value) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, (dict, list)):
        return json.dumps(value, sort_keys=True)
    return str(value)


def _parquet_cell(value):
    return json.dumps(value, sort_keys=True) if isinstance(value, (dict, list)) else value


# ---- command line ---------------------------------------------------------------------------


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The ``swath batch`` arguments (for the main CLI's sub-parser)."""
    parser.add_argument("sweep", help="sweep file (TOML): base job settings plus a [grid] of lists")
    parser.add_argument("--workers", type=int, default=None,
                        help="jobs at a time; 1 runs them in this process without Ray "
                             "(default: every CPU of the local Ray, or the whole cluster)")
    parser.add_argument("--address", default=None,
                        help="Ray cluster to run on, e.g. ray://head:10001 (default RAY_ADDRESS, else a local Ray)")
    parser.add_argument("--resume", action=argparse.BooleanOptionalAction, default=True,
                        help="skip jobs whose folder already holds their metrics.json (default on)")


def run_from_args(args, *, quiet: bool = False) -> int:
    """Run ``swath batch`` from parsed arguments: 0 all jobs ok, 1 some failed, 2 bad input."""
    try:
        if args.workers is not None and args.workers < 1:
            raise InputError(f"--workers must be at least 1, got {args.workers}")
        if args.workers == 1 and args.address:
            raise InputError("--workers 1 runs the jobs in this process; drop --address, or ask for more workers")
        sweep = load_sweep(args.sweep)
        bar = _ProgressBar(quiet=quiet)
        if not quiet:
            where = ("serially in this process" if args.workers == 1 else
                     f"on Ray at {args.address or os.environ.get('RAY_ADDRESS')}"
                     if args.address or os.environ.get("RAY_ADDRESS") else
                     f"on a local Ray with {args.workers or os.cpu_count()} workers")
            print(f"swath batch: {len(sweep.jobs)} jobs {where} -> {sweep.out}", file=sys.stderr, flush=True)
        rows = run_sweep(sweep, workers=args.workers, address=args.address, resume=args.resume, progress=bar)
    except SwathError as exc:
        print(f"swath: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("swath batch: interrupted; finished jobs keep their folders: run again to resume", file=sys.stderr)
        return 130
    failed = [r for r in rows if r["status"] != "ok"]
    if not quiet:
        resumed = sum(bool(r["resumed"]) for r in rows)
        print(f"wrote {sweep.out / 'results.csv'}: {len(rows) - len(failed)} ok ({resumed} from earlier runs), "
              f"{len(failed)} failed in {time.perf_counter() - bar.t0:.1f} s", file=sys.stderr)
    return 1 if failed else 0


class _ProgressBar:
    """One line on stderr per finished job, led by a bar: ``[####------]  4/10  ok  0003-... 2.1 s``."""

    def __init__(self, *, quiet: bool, width: int = 24):
        self.quiet, self.width, self.t0 = quiet, width, time.perf_counter()

    def __call__(self, done: int, total: int, row: dict) -> None:
        if self.quiet:
            return
        filled = round(self.width * done / max(total, 1))
        took = "earlier run" if row.get("resumed") else f"{row.get('job_s') or 0.0:.1f} s"
        status = row["status"] + (f": {row['error']}" if row["error"] else "")
        print(f"[{'#' * filled}{'-' * (self.width - filled)}] {done:>{len(str(total))}}/{total} "
              f"[{time.perf_counter() - self.t0:7.1f} s] {row['job_id']} ({took}) {status}", file=sys.stderr, flush=True)


def main(argv=None) -> int:
    """``python -m swath.cli.batch sweep.toml ...`` (the same as ``swath batch``)."""
    parser = argparse.ArgumentParser(prog="swath batch", description="Run a sweep of finishing jobs.")
    parser.add_argument("-q", "--quiet", action="store_true", help="only errors")
    add_arguments(parser)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.ERROR if args.quiet else logging.WARNING,
                        format="swath: %(levelname)s: %(message)s")
    return run_from_args(args, quiet=args.quiet)


if __name__ == "__main__":
    sys.exit(main())
