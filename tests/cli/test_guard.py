"""The memory guard counts lattice removal samples exactly (cli.guard.estimate_bytes)."""

import pytest

from shapes import sliver_plate
from swath.cli.guard import BASE_BYTES, BYTES_PER_FACE, BYTES_PER_SAMPLE, estimate_bytes
from swath.cli.settings import settings_from_mapping
from swath.simulate.removal import MAX_REMOVAL_SAMPLES, samples_for_area
from swath.simulate.samples import count_removal_samples, removal_samples


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
