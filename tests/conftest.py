"""Shared test fixtures: where the shared real meshes live and the units each is read in."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

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
