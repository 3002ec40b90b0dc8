"""Hot spots (swath.simulate.hot_spots): a plate's raster run evenly, and with one stretch crawled."""

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from shapes import timed_plate_raster
from swath.report.warncodes import tagged
from swath.report.warnings import plan_warnings
from swath.simulate import simulate_removal
from swath.simulate.hot_spots import HOT_SPOT_FACTOR, HOT_SPOT_MIN_PAD_SHARE, hot_spot_metrics, hot_spot_warnings

SPACING = 0.05
CRAWL = 10.0          # the crawled stretch takes this many times as long


@pytest.fixture(scope="module")
def plate():
    """The plate's raster (passes along x, 50 mm apart), its removal, and the same trajectory with
    the middle pass crawling at a tenth of its speed within 30 mm of the plate's centre in x."""
    surface, tool, trajectory = timed_plate_raster(SPACING)
    centre = 0.5 * (surface.bounds[0] + surface.bounds[1])
    live = trajectory.contact & (trajectory.pass_index >= 0)
    middle = int(np.median(trajectory.pass_index[live]))
    on = live & (trajectory.pass_index == middle) & (np.abs(trajectory.position[:, 0] - centre[0]) <= 0.03)
    dt = np.diff(trajectory.t)
    dt[on[1:] & on[:-1]] *= CRAWL
    crawled = replace(trajectory, t=np.concatenate([[trajectory.t[0]], trajectory.t[0] + np.cumsum(dt)]))
    at = trajectory.position[on].mean(axis=0)
    return surface, tool, trajectory, crawled, at


def test_an_even_raster_has_no_hot_spot(plate):
    surface, tool, trajectory, _, _ = plate
    m = hot_spot_metrics(simulate_removal(trajectory, surface, tool), trajectory, tool)
    assert m["hot_spot_area_m2"] == 0.0
    assert 1.0 < m["hot_spot_depth_ratio"] < HOT_SPOT_FACTOR
    assert m["hot_spot_normal_turn_rad"] < math.radians(0.5)          # a plane
    assert hot_spot_warnings(m, 0.05) == []


def test_a_crawled_stretch_is_found_with_its_speed(plate):
    surface, tool, trajectory, crawled, at = plate
    m = hot_spot_metrics(simulate_removal(crawled, surface, tool), crawled, tool)
    feed = float(np.median(trajectory.feed[trajectory.contact]))
    # the pad dwells ten times as long over the stretch: several times the mean there
    assert 4.0 < m["hot_spot_depth_ratio"] < CRAWL
    # along the crawled stretch, within the pad's reach across it (where a neighbour's swath adds)
    dx, dy = np.abs(np.asarray(m["hot_spot_position_m"])[:2] - at[:2])
    assert dx < 0.03 and dy < tool.pad_radius
    assert not m["hot_spot_at_edge"]
    assert m["hot_spot_slowest_speed_m_per_s"] == pytest.approx(feed / CRAWL, rel=0.1)
    assert m["hot_spot_area_m2"] >= HOT_SPOT_MIN_PAD_SHARE * math.pi * tool.pad_radius**2
    [text] = hot_spot_warnings(m, feed)
    assert text.startswith("hot spot: ")
    assert f"slows to {1e3 * feed / CRAWL:.0f} mm/s" in text and "inside the part" in text
    assert "angular speed limit" not in text                          # slowed, not turning
    assert "turns by" not in text                                     # the plate does not turn
    assert tagged(text).endswith("[W-HOT-SPOT]")


def test_the_job_warns_only_over_a_quarter_pad(plate):
    surface, tool, trajectory, crawled, _ = plate
    m = hot_spot_metrics(simulate_removal(crawled, surface, tool), crawled, tool)
    pad = math.pi * tool.pad_radius**2
    warned = [w for w in plan_warnings(surface, _plan(surface), crawled, m, 0.05, tool.pad_radius)
              if w.startswith("hot spot")]
    assert len(warned) == 1
    assert m["hot_spot_area_over_pad_ratio"] == pytest.approx(m["hot_spot_area_m2"] / pad, rel=1e-12)
    small = dict(m, hot_spot_area_over_pad_ratio=0.9 * HOT_SPOT_MIN_PAD_SHARE)
    assert not [w for w in plan_warnings(surface, _plan(surface), crawled, small, 0.05, tool.pad_radius)
                if w.startswith("hot spot")]


def _plan(surface):
    from swath.core import ToolPath

    return ToolPath(surface, [], "raster", {})


def test_the_removal_map_circles_a_hot_spot_worth_a_warning(plate):
    from swath.report.plots import removal_map_figure

    surface, tool, _, crawled, _ = plate
    removal = simulate_removal(crawled, surface, tool)
    m = hot_spot_metrics(removal, crawled, tool)

    def labels(metrics):
        fig = removal_map_figure(removal, metrics=metrics)
        return [t.get_text() for t in fig.axes[0].texts if t.get_text().startswith("hot spot")]

    assert labels(m) == [f"hot spot {1e6 * m['hot_spot_depth_m']:.3g} µm ({m['hot_spot_depth_ratio']:.0f}x the interior)"]
    assert labels(dict(m, hot_spot_area_over_pad_ratio=0.5 * HOT_SPOT_MIN_PAD_SHARE)) == [] and labels(None) == []


def test_the_report_marks_a_hot_spot_in_its_3d_view(plate, tmp_path):
    from swath.report import write_report

    surface, tool, _, crawled, _ = plate
    removal = simulate_removal(crawled, surface, tool)
    m = dict(removal.metrics, **hot_spot_metrics(removal, crawled, tool))
    label = f"hot spot {1e6 * m['hot_spot_depth_m']:.3g} µm ({m['hot_spot_depth_ratio']:.0f}x)"
    # (the 3D view's figure is JSON in the page: its "µ" is written as it is or escaped, as the encoder chooses)
    written = (label, json.dumps(label)[1:-1])
    html = write_report(tmp_path, surface=surface, trajectory=crawled, removal=removal, metrics=m)["html"]
    assert any(w in html.read_text(encoding="utf-8") for w in written)
    quiet = tmp_path / "quiet"
    quiet.mkdir()
    small = dict(m, hot_spot_area_over_pad_ratio=0.5 * HOT_SPOT_MIN_PAD_SHARE)
    html = write_report(quiet, surface=surface, trajectory=crawled, removal=removal, metrics=small)["html"]
    assert not any(w in html.read_text(encoding="utf-8") for w in written)
