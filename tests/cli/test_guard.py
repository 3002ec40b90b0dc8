"""The memory guard counts lattice removal samples exactly (cli.guard.estimate_bytes)."""

import numpy as np
import pytest

from swath.cli.guard import BASE_BYTES, BYTES_PER_FACE, BYTES_PER_SAMPLE, estimate_bytes
from swath.cli.settings import settings_from_mapping
from swath.simulate.removal import MAX_REMOVAL_SAMPLES, samples_for_area
from swath.simulate.samples import count_removal_samples, removal_samples
from swath.surface import Surface


def sliver_plate(size_x=0.4, size_y=0.3, strip=1.5e-3):
    ys = np.arange(0.0, size_y + 1e-12, strip)
    n = len(ys)
    v = np.concatenate([np.stack([np.zeros(n), ys, np.zeros(n)], 1), np.stack([np.full(n, size_x), ys, np.zeros(n)], 1)])
    i = np.arange(n - 1)
    faces = np.concatenate([np.stack([i, n + i, n + i + 1], 1), np.stack([i, n + i + 1, i + 1], 1)])
    return Surface(v, faces, name="slivers")


def settings(tmp_path, **keys):
    return settings_from_mapping({"part": "example:plate", "out": str(tmp_path / "o"), "sample_spacing": "2mm", **keys})


def test_lattice_samples_are_counted_exactly(tmp_path):
    part = sliver_plate()
    est = estimate_bytes(part, settings(tmp_path))                  # the job default: lattice
    made = len(removal_samples(part, 2e-3))
    assert est["removal_samples"] == made == count_removal_samples(part, 2e-3) == 400 * 201
    assert est["bytes"] == pytest.approx(BASE_BYTES + BYTES_PER_FACE * 400 + BYTES_PER_SAMPLE * made)
    # the subdivided mesh is still estimated from the area
    mesh = estimate_bytes(part, settings(tmp_path, removal_sampling="mesh"))
    assert mesh["removal_samples"] == samples_for_area(part.area, 2e-3)


def test_the_count_stops_at_the_simulation_cap(tmp_path, monkeypatch):
    import swath.simulate.removal as removal

    part = sliver_plate()
    monkeypatch.setattr(removal, "MAX_REMOVAL_SAMPLES", 1000)
    assert estimate_bytes(part, settings(tmp_path))["removal_samples"] == 1000
    assert MAX_REMOVAL_SAMPLES > 1000
