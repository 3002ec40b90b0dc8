import math

import pytest

from swath.errors import InputError
from swath.units import length_unit_factor, parse_quantity


@pytest.mark.parametrize("text,kind,expected", [
    ("38.1mm", "length", 0.0381), ("3in", "length", 0.0762), ("0.05", "length", 0.05),
    ("20N", "force", 20.0), ("50mm/s", "speed", 0.05), ("3m/min", "speed", 0.05),
    ("90deg", "angle", math.pi / 2), ("2m/s2", "acceleration", 2.0), ("10%", "fraction", 0.1),
    ("4.4MPa/m", "stiffness", 4.4e6), ("6000rpm", "frequency", 100.0), (" 1e-3 m ", "length", 1e-3),
])
def test_parse_quantity_converts_to_si(text, kind, expected):
    assert parse_quantity(text, kind) == pytest.approx(expected)


def test_bare_number_takes_default_unit():
    assert parse_quantity("30", "angle", default_unit="deg") == pytest.approx(math.pi / 6)
    assert parse_quantity(12, "length") == 12.0


@pytest.mark.parametrize("text,kind,fragment", [
    ("38.1 furlongs", "length", "unknown unit 'furlongs'"),
    ("fast", "speed", "expected a speed"),
    ("20mm", "force", "unknown unit 'mm' for a force"),
    ("nan", "length", "expected a length"),
])
def test_parse_quantity_refuses_with_message(text, kind, fragment):
    with pytest.raises(InputError, match=fragment):
        parse_quantity(text, kind)


def test_length_unit_factor():
    assert length_unit_factor("in") == 0.0254
    with pytest.raises(InputError, match="unknown length unit 'ft'"):
        length_unit_factor("ft")
