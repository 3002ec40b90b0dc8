"""The default job's spacing search is timed as its own stage (``spacing_s``), so ``plan_s`` is the
plan the job keeps and its order."""

from __future__ import annotations

import functools
import json
import time

import pytest

from shapes import bowl
from swath.cli import even_default
from swath.cli.job import make_plan
from swath.cli.main import main
from swath.cli.settings import settings_from_mapping
from swath.contact import Tool
from swath.plan import registry

PAUSE = 0.3


def _slow_raster(monkeypatch, calls: list):
    """The raster planner, each call PAUSE s longer (wall clock), counted in ``calls``."""
    raster = registry.PLANNERS["raster"]

    @functools.wraps(raster)                     # the job reads the planner's options from its signature
    def slow(*args, **kwargs):
        calls.append(kwargs.get("spacing"))
        time.sleep(PAUSE)
        return raster(*args, **kwargs)
    monkeypatch.setitem(registry.PLANNERS, "raster", slow)


def test_the_search_is_timed_apart_from_the_plan_it_keeps(monkeypatch):
    """On a bowl the search plans at the plane's spacing, reads the curvature and plans again at
    the quadric's: every call but the last is the search's, the last one the plan's."""
    calls: list = []
    _slow_raster(monkeypatch, calls)
    settings = even_default.resolve(settings_from_mapping({"part": "example:plate", "out": "unused"}))
    part = bowl(size=0.3, radius=0.35, n=41)
    timings: dict = {}
    t0 = time.perf_counter()
    tp = make_plan(part, settings, tool=Tool(), timings=timings)
    total = time.perf_counter() - t0
    assert tp.metadata["ripple_model"] == "curved" and len(calls) >= 2
    assert timings["spacing_s"] >= (len(calls) - 1) * PAUSE        # the discarded plans are the search's
    assert total - timings["spacing_s"] >= PAUSE                   # the kept plan is not
    assert timings["spacing_s"] < total


def test_without_a_search_there_is_no_spacing_stage(monkeypatch):
    calls: list = []
    _slow_raster(monkeypatch, calls)
    settings = settings_from_mapping({"part": "example:plate", "out": "unused", "spacing": "50mm",
                                      "constant_feed": True})
    timings: dict = {}
    make_plan(bowl(size=0.3, radius=0.35, n=41), settings, tool=Tool(), timings=timings)
    assert calls == [pytest.approx(0.05)] and timings == {}


def test_the_default_job_reports_the_spacing_search_as_a_stage(tmp_path, capsys):
    out = tmp_path / "o"
    job = tmp_path / "job.toml"
    job.write_text(f'part = "example:plate"\nout = "{out.name}"\nsample_spacing = "4mm"\npoint_spacing = "4mm"\n')
    assert main(["run", str(job)]) == 0
    m = json.loads((out / "metrics.json").read_text())["metrics"]
    assert m["spacing_s"] > 0 and m["plan_s"] > 0
    assert "choosing the spacing (ripple)" in capsys.readouterr().err
