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


def test_a_message_states_a_quantity_in_the_unit_it_was_given_in_or_a_readable_one():
    from swath.units import display_unit

    assert display_unit("60deg", "angle") == ("deg", pytest.approx(math.pi / 180))
    assert display_unit("1.2rad", "angle") == ("rad", 1.0)
    assert display_unit("60", "angle") == ("deg", pytest.approx(math.pi / 180))     # a bare angle is in degrees
    assert display_unit("2m", "length") == ("m", 1.0)
    assert display_unit("0.5", "length") == ("mm", 1e-3)                            # bare: SI read, mm shown
    assert display_unit("3 in", "length") == ("in", 0.0254)
    assert display_unit("150%", "fraction") == ("%", 0.01)
    assert display_unit("50 m/s2", "acceleration") == ("m/s2", 1.0)
    assert display_unit("9", "acceleration") == ("m/s^2", 1.0)
    assert display_unit("5 furlong", "length") == ("mm", 1e-3)                      # not a unit of the kind
