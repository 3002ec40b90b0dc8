"""A job file with regions: a polygon file (relative to the job file, in mm) kept out of a mesh part
in mm, planned, simulated and judged end to end; a bad polygon refused before any output."""

from __future__ import annotations

import json

import pytest

from swath.cli.job import run_job
from swath.cli.settings import load_job_toml
from swath.errors import InputError


def _write_plate_mm(path):
    import trimesh

    from swath.examples.parts import flat_plate

    s = flat_plate(size_x=0.2, size_y=0.15, spacing=5e-3)
    trimesh.Trimesh(s.vertices * 1e3, s.faces, process=False).export(path)


def test_job_file_keep_out_polygon_in_mm_gets_no_removal(tmp_path):
    _write_plate_mm(tmp_path / "plate_mm.stl")
    (tmp_path / "regions").mkdir()
    # a 40 × 30 mm window, corners given in mm (header and comment lines skipped)
    (tmp_path / "regions" / "window.csv").write_text("# keep the label free\nx,y\n80,60\n120,60\n120,90\n80,90\n",
                                                     encoding="utf-8")
    (tmp_path / "job.toml").write_text(
        'part = "plate_mm.stl"\nunits = "mm"\nout = "out"\npad_radius = "15mm"\nsample_spacing = "3mm"\n'
        'keep_out = { polygon = "regions/window.csv", units = "mm" }\n', encoding="utf-8")
    settings = load_job_toml(tmp_path / "job.toml")
    metrics = run_job(settings)
    doc = json.loads((tmp_path / "out" / "metrics.json").read_text())["metrics"]
    # the window's triangles: centres strictly inside 80..120 × 60..90 mm on the 5 mm grid
    assert doc["keep_out_area_m2"] == pytest.approx(0.04 * 0.03, rel=1e-9)
    assert doc["keep_out_max_removal_m"] == 0.0 and doc["keep_out_touched_area_m2"] == 0.0
    assert metrics["keep_out_clearance_m"] == pytest.approx(0.015 + 0.002)
    assert doc["selected_area_m2"] == pytest.approx(0.2 * 0.15 - 0.04 * 0.03, rel=1e-9)
    assert not any("keep-out" in w.lower() for w in doc["warnings"])


def test_a_polygon_crossing_itself_is_refused_before_any_output(tmp_path):
    _write_plate_mm(tmp_path / "plate_mm.stl")
    (tmp_path / "job.toml").write_text(
        'part = "plate_mm.stl"\nunits = "mm"\nout = "out"\n'
        'faces = { polygon = [["0mm", "0mm"], ["100mm", "100mm"], ["100mm", "0mm"], ["0mm", "100mm"]] }\n',
        encoding="utf-8")
    with pytest.raises(InputError, match="crosses itself"):
        run_job(load_job_toml(tmp_path / "job.toml"))
    assert not (tmp_path / "out").exists()
