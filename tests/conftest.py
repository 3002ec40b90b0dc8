"""Shared test fixtures: where the shared real meshes live and the units each is read in."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

# The suite runs several test files in one process, one after another, and some of them run Ray in
# that process.  Ray logs an error whose result no one asked for when its reference is dropped,
# which can happen seconds later, in another file's test, and land in the stderr that test reads
# ("Unhandled error ...: The worker died unexpectedly", in a CLI test that expects one line).
# The tests check swath's own messages, so those reports of Ray's are off in the suite.
os.environ.setdefault("RAY_IGNORE_UNHANDLED_ERRORS", "1")

REPO = Path(__file__).resolve().parents[1]
SHARED_MESHES = REPO.parent / "shared" / "meshes"

#: Every shared mesh and the unit it is read in (SOURCES.md; the wavy sheet is unitless, ~10.5
#: across, and read as inches: a 0.27 m panel).
SHARED_MESH_UNITS = {
    "snp_part_scan.ply": "m",
    "noether_raw_mesh.ply": "m",
    "bezier_dac_cad.ply": "m",
    "bezier_dac_scan.ply": "m",
    "noether_wavy_mesh_with_hole.ply": "in",
    "bezier_complex_shape.ply": "m",
    "crs_part_5.stl": "m",
}


def shared_mesh(name: str) -> Path:
    """Path of a shared mesh; skips the test when ../shared/meshes is not beside the repository."""
    path = SHARED_MESHES / name
    if not path.exists():
        pytest.skip(f"shared mesh {path} not found (expected ../shared/meshes beside the repository)")
    return path


@pytest.fixture
def rng():
    """A seeded random generator."""
    return np.random.default_rng(12345)


@pytest.fixture(scope="module")
def plate_trajectory():
    """The built-in plate planned and timed as a job does (raster, 100 mm spacing, with the fill
    passes that close what that spacing leaves: passes near the plate's edges)."""
    from swath.cli.job import JobSettings, load_part_info, make_plan
    from swath.trajectory import time_path

    settings = JobSettings(part="example:plate", out="unused", spacing=0.1, point_spacing=4e-3,
                           planner_options={"fill_gaps": True})
    surface, _ = load_part_info(settings)
    return time_path(make_plan(surface, settings), settings.constraints(), links=settings.links())
