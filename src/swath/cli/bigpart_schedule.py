"""When each task of a big part's regions runs: as soon as what it needs is there.

Every region has three tasks (:mod:`swath.cli.bigpart_work`): *plan* (needs the region's file),
*simulate* (needs the plans of every region whose passes reach it: itself and its neighbours) and
*rows* (writes its stretch of ``trajectory.csv``; needs the plans of every region before it in the
trajectory, whose ends fix its time shift and first pass number).  :class:`RegionTasks` keeps at
most ``executor.workers`` tasks running and, whenever one ends, starts the ready task that comes
first in this order: rows (short, and nothing waits on them), then by the region's place in the
work order (a region's plan before its simulation).  There is no barrier between planning and
simulating: region ``k`` is simulated while the regions after it are still being planned.

The work order runs along the span from the end with more faces, so the largest regions start
first and the last tasks to run, which decide how long the workers sit idle at the end, are the
smallest ones (longest processing time first, within the pipeline along the span).
"""

from __future__ import annotations

import logging
from pathlib import Path

from ..trajectory.join import join_offsets
from .bigpart_work import plan_region, simulate_region, write_rows

log = logging.getLogger(__name__)

#: The three tasks of a region, in the order their figures are listed.
KINDS = ("plan", "simulate", "rows")


def work_order(faces_per_region) -> list[int]:
    """Region indices in the order their work starts: along the span from the end whose half of the
    regions has more faces (``faces_per_region`` (n,), the faces each region owns); ties from 0."""
    n = len(faces_per_region)
    first_half, second_half = sum(faces_per_region[: n // 2]), sum(faces_per_region[n - n // 2:])
    return list(range(n))[::-1] if second_half > first_half else list(range(n))


class RegionTasks:
    """The plan, simulate and rows tasks of every region, started on ``executor`` as they get ready.

    Parameters
    ----------
    executor
        :class:`~swath.cli.bigpart_work.InlineExecutor` or
        :class:`~swath.cli.bigpart_work.RayExecutor` (``workers``, ``in_flight``, ``submit``,
        ``handle``, ``next_done``).
    tiles : list of Tile
        The regions, in span order (the order of the joined trajectory).
    reach : list of list of int
        For each region, the regions whose passes reach it (itself included).
    order : list of int
        The work order (:func:`work_order`).
    plan_args, simulate_args : tuple
        The arguments of :func:`~swath.cli.bigpart_work.plan_region` after ``(path, tile)`` and of
        :func:`~swath.cli.bigpart_work.simulate_region` between ``(path, tile)`` and the trajectories.
    link_speed : float
        Speed of the air moves joining the regions' trajectories, m/s.
    rows_folder : Path
        Folder the rows tasks write ``rows{k:04d}.csv`` to (one the workers can write).
    progress : callable, optional
        ``progress(stage, done, total)`` after each task.
    """

    def __init__(self, executor, tiles, reach, order, *, plan_args: tuple, simulate_args: tuple, link_speed: float,
                 rows_folder: Path, progress=None):
        self.executor = executor
        self.tiles, self.reach = tiles, reach
        self.place = {k: i for i, k in enumerate(order)}
        self.plan_args, self.simulate_args = plan_args, simulate_args
        self.link_speed = link_speed
        self.rows_folder = Path(rows_folder)
        self.say = progress or (lambda stage, done, total: None)
        self.paths: dict[int, str] = {}
        self.info: dict[tuple, dict] = {}          # (kind, region) -> the finished task's info
        self.started: set = set()
        self.rows_names: dict[int, tuple] = {}     # extra columns each rows task wrote
        self.total = len(KINDS) * len(tiles)

    # -- what is ready ------------------------------------------------------------------------------

    def file_ready(self, k: int, path: str) -> None:
        """Region ``k``'s file is written at ``path``: its plan can start."""
        self.paths[k] = path

    def _planned(self, regions) -> bool:
        return all(("plan", j) in self.info for j in regions)

    def _ready(self) -> list[tuple]:
        """``(rank, kind, k)`` of the tasks that can start now, not started yet."""
        out = []
        for k, place in self.place.items():
            if ("plan", k) not in self.started and k in self.paths:
                out.append(((1, place, 0), "plan", k))
            if ("simulate", k) not in self.started and self._planned(self.reach[k]):
                out.append(((1, place, 1), "simulate", k))
            if ("rows", k) not in self.started and self._planned(range(k + 1)):
                out.append(((0, place, 2), "rows", k))
        return sorted(out)

    def _args(self, kind: str, k: int) -> tuple:
        tile, path = self.tiles[k], self.paths[k]
        if kind == "plan":
            return (path, tile, *self.plan_args)
        if kind == "simulate":
            handles = [self.executor.handle(("plan", j)) for j in self.reach[k]]
            return (path, tile, *self.simulate_args, *handles)
        ends = [self.info[("plan", j)]["ends"] for j in range(k + 1)]
        shifts, first_pass, _ = join_offsets(ends, link_speed=self.link_speed)
        names = tuple(dict.fromkeys(name for e in ends for name in e.extra))
        self.rows_names[k] = names
        return (self.executor.handle(("plan", k)), str(self.rows_path(k)), shifts[k], first_pass[k], names)

    def rows_path(self, k: int) -> Path:
        """The file region ``k``'s rows task writes."""
        return self.rows_folder / f"rows{k:04d}.csv"

    # -- running ------------------------------------------------------------------------------------

    def fill(self) -> None:
        """Start ready tasks, first in order, until ``executor.workers`` run."""
        while self.executor.in_flight < self.executor.workers:
            ready = self._ready()
            if not ready:
                return
            _, kind, k = ready[0]
            fn = {"plan": plan_region, "simulate": simulate_region, "rows": write_rows}[kind]
            self.started.add((kind, k))
            self.executor.submit((kind, k), fn, self._args(kind, k))

    @property
    def finished(self) -> bool:
        return len(self.info) == self.total

    def run(self, *, when_planned=None) -> None:
        """Start and wait for tasks until every one has finished (every region's file is written);
        ``when_planned()`` (optional) is called once every region's plan has finished, after the
        tasks that could start then have started: the simulations still running, this process can
        use the plans meanwhile."""
        self.fill()
        planned = when_planned is None
        while not self.finished:
            if not self.executor.in_flight:
                raise RuntimeError("region tasks left that can never start")   # pragma: no cover - a bug
            key, info = self.executor.next_done()
            self.info[key] = info
            self.say("planning and simulating regions", len(self.info), self.total)
            self.fill()
            if not planned and self._planned(range(len(self.tiles))):
                planned = True
                when_planned()

    def results(self, kind: str) -> list[dict]:
        """The infos of every region's ``kind`` task, in span order."""
        return [self.info[(kind, k)] for k in range(len(self.tiles))]

    def timeline(self, epoch0: float) -> list[dict]:
        """One row per task: ``task``, ``region``, ``worker`` (process id), ``start_s`` and ``end_s``
        (s after ``epoch0``, seconds since the epoch), ``cpu_s``, in start order."""
        rows = [{"task": kind, "region": k, "worker": i["pid"], "start_s": i["started"] - epoch0,
                 "end_s": i["ended"] - epoch0, "cpu_s": i["cpu_s"]} for (kind, k), i in self.info.items()]
        return sorted(rows, key=lambda r: r["start_s"])


def idle_figures(timeline: list[dict], workers: int) -> dict:
    """How busy the workers were over the region tasks' span (from the first start to the last end),
    s: ``regions_s`` (that span), ``tasks_busy_s`` (the tasks' wall times summed), ``tail_idle_s``
    (summed over ``workers``, the time from each worker's last end to the last end overall, a
    worker that ran nothing counting the whole span: the load imbalance at the end)."""
    if not timeline:
        return {"regions_s": 0.0, "tasks_busy_s": 0.0, "tail_idle_s": 0.0}
    first = min(r["start_s"] for r in timeline)
    last = max(r["end_s"] for r in timeline)
    ends: dict = {}
    for r in timeline:
        ends[r["worker"]] = max(ends.get(r["worker"], first), r["end_s"])
    lasts = sorted(ends.values(), reverse=True)[:workers]
    lasts += [first] * (workers - len(lasts))
    return {"regions_s": last - first, "tasks_busy_s": float(sum(r["end_s"] - r["start_s"] for r in timeline)),
            "tail_idle_s": float(sum(last - e for e in lasts))}
