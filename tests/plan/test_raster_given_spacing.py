"""A spacing the user gives is honoured: one plane per spacing, no fill passes unless asked for,
and a warning that names the share of the part the passes leave untouched."""

import json
import math
import re

import pytest

from swath.contact import Tool
from swath.examples import flat_plate
from swath.plan.raster import GAP_WARN_SHARE, raster

TOOL = Tool()                     # R = 38.1 mm: a 76.2 mm swath on a flat part
R = TOOL.pad_radius
WIDTH = 0.3                       # the plate's extent across a feed along its long side (direction 0)


@pytest.fixture(scope="module")
def plate():
    return flat_plate()


@pytest.mark.parametrize("spacing", [5.0, 0.2, 0.1])
def test_a_given_spacing_gives_one_pass_per_plane_and_warns_with_the_gap_share(plate, spacing, caplog):
    tp = raster(plate, TOOL, spacing=spacing, direction=0.0)
    n = max(math.ceil(WIDTH / spacing), 1)
    assert len(tp.passes) == n == tp.metadata["n_planes"]
    assert tp.metadata["n_fill_passes"] == 0 and not any(p.kind == "touch_up" for p in tp.passes)
    assert tp.metadata["spacing_m"] == spacing and tp.metadata["spacing_rule"] == "given"
    # planes further apart than the swath: each covers 2R of the width, the rest is bare (to the
    # coverage check's sample step R/8 at each of a swath's two edges)
    gap = tp.metadata["predicted_gap_fraction"]
    assert gap == pytest.approx(1 - n * 2 * R / WIDTH, abs=n * (R / 8) / WIDTH)
    [msg] = tp.metadata["warnings"]
    assert f"leaves {100 * gap:.1f} % of plate untouched" in msg and f"{1e3 * spacing:.4g} mm" in msg
    assert "fill_gaps" in msg and msg in caplog.text


def test_a_given_spacing_within_the_swath_covers_the_plate_without_a_warning(plate, caplog):
    tp = raster(plate, TOOL, spacing=0.06, direction=0.0)
    assert len(tp.passes) == 5 and tp.metadata["n_fill_passes"] == 0
    assert tp.metadata["predicted_gap_fraction"] <= GAP_WARN_SHARE
    assert "warnings" not in tp.metadata and "untouched" not in caplog.text


def test_fill_passes_are_opt_in_with_a_given_spacing(plate):
    tp = raster(plate, TOOL, spacing=0.2, direction=0.0, fill_gaps=True)
    assert tp.metadata["n_fill_passes"] >= 1
    assert len(tp.passes) == tp.metadata["n_planes"] + tp.metadata["n_fill_passes"]
    assert tp.metadata["predicted_gap_fraction"] < 0.01


def test_the_automatic_direction_warns_once_for_the_kept_plan(plate, caplog):
    tp = raster(plate, TOOL, spacing=0.2)
    assert caplog.text.count("untouched") == 1 and tp.metadata["warnings"][0] in caplog.text
    extent = WIDTH if tp.metadata["angle_rad"] == 0.0 else 0.4
    assert len(tp.passes) == math.ceil(extent / 0.2)


def test_swath_plan_with_a_spacing_keeps_it_and_reports_the_gap(tmp_path):
    from swath.cli.main import main

    out = tmp_path / "o"
    assert main(["-q", "plan", "--constant-feed", "example:plate", "--spacing", "200mm", "--direction", "0", "--out", str(out)]) == 0
    m = json.loads((out / "metrics.json").read_text())["metrics"]
    assert m["n_passes"] == 2
    [msg] = [w for w in m["warnings"] if "given spacing 200 mm" in w]
    gap = float(re.search(r"leaves ([0-9.]+) % of plate untouched", msg).group(1)) / 100
    # two 2R swaths across 300 mm; the simulated removal agrees on what stays bare
    assert gap == pytest.approx(1 - 2 * 2 * R / WIDTH, abs=2 * (R / 8) / WIDTH)
    assert 1 - m["coverage_fraction"] == pytest.approx(gap, abs=0.02)
