"""The uniform planner's progress over its candidate directions (:func:`swath.plan.uniform.uniform`
with ``direction="auto"``): how many steps laying and ranking them counts, and how many of those
a pool of workers has done, the layouts still running included."""

from __future__ import annotations

import time

#: Progress steps a layout counts for (directions with the same seed share one), against one for
#: each direction's ranking: the layout (the heat-method generations) is most of the work.  On
#: crs_part_5 a layout took about 9.5 s and a ranking 0.5-1 s: counted as one step each, the
#: rankings' steps all came in the plan's last 2-3 s and the time left measured before them was
#: several times too long.
LAYOUT_STEPS = 9


def _progress_steps(groups: list[list[float]]) -> int:
    """The progress steps of laying and ranking ``groups`` (directions with the same seed):
    :data:`LAYOUT_STEPS` for each layout, one for each direction's ranking, one for the winner."""
    return LAYOUT_STEPS * len(groups) + sum(len(g) for g in groups) + 1


class _PoolProgress:
    """The steps of :func:`_run_pool` done: :data:`LAYOUT_STEPS` per layout back, one per
    direction ranked, and the layouts still running counted by how long they have run against the
    mean time of those back (at most 0.9 of theirs).  Layouts take about the same time, and with
    two workers they come back in pairs: counted only once back, the first of a pair halved the
    rate the time left is read from (crs_part_5's re-plan said "about 52 s left" 11 s before it
    ended).

    ``layouts``: how many layout tasks were submitted (numbered in that order).  The first
    ``n_workers`` start at once and each later one as a task comes back (:func:`_run_pool` queues a
    ranking only when no layout waits).  ``clock()``: seconds."""

    def __init__(self, layouts: int, n_workers: int, clock=time.perf_counter):
        self.layouts, self.clock = layouts, clock
        now = clock()
        self.started = {i: now for i in range(min(n_workers, layouts))}   # layouts running: start times
        self.queued = len(self.started)                     # the next layout to start
        self.took: list[float] = []                         # the layouts back: their times, s
        self.early: set[int] = set()                        # layouts back before they were seen to start
        self.done = self.told = 0

    def back(self, layout: int | None = None, ranked: int = 0) -> int:
        """A task came back (``layout``: its index, else a ranking of ``ranked`` directions): the
        next queued layout starts now.  Returns the steps done, never fewer than said before."""
        now = self.clock()
        if layout is not None:
            if layout in self.started:
                self.took.append(now - self.started.pop(layout))
            else:           # back in the same batch as the task whose worker it took: its time is unknown
                self.early.add(layout)
            self.done += LAYOUT_STEPS
        self.done += ranked
        while self.queued in self.early:
            self.queued += 1
        if self.queued < self.layouts:
            self.started[self.queued] = now
            self.queued += 1
        typical = sum(self.took) / len(self.took) if self.took else 0.0
        running = sum(LAYOUT_STEPS * min(0.9, (now - t) / typical) for t in self.started.values()) \
            if typical > 0 else 0.0
        self.told = max(self.told, int(self.done + running))
        return self.told
