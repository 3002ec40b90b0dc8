"""Full and fractional factorial designs (Jaeger Table 6.1) and factor parsing."""

import itertools

import pytest

from swath.errors import InputError
from swath.simulate.preston_doe import doe_csv_text, factorial_design, parse_factor

TABLE_6_1 = {"grit": ["80", "120", "150", "180"], "force_N": [15.0, 20.0, 25.0, 30.0],
             "spindle_speed_rpm": [1000.0, 2000.0, 3000.0, 4000.0]}


def test_full_factorial_of_table_6_1():
    runs = factorial_design(TABLE_6_1)
    assert len(runs) == 64
    assert len({tuple(r.values()) for r in runs}) == 64
    assert runs[0] == {"grit": "80", "force_N": 15.0, "spindle_speed_rpm": 1000.0}
    assert runs[1]["spindle_speed_rpm"] == 2000.0          # the last factor varies fastest


def test_latin_square_fraction_meets_every_pair_of_levels_once():
    runs = factorial_design(TABLE_6_1, generators={"spindle_speed_rpm": ("grit", "force_N")})
    assert len(runs) == 16
    for a, b in itertools.combinations(TABLE_6_1, 2):
        pairs = {(r[a], r[b]) for r in runs}
        assert len(pairs) == 16


def test_two_level_half_fraction_is_c_equals_ab():
    runs = factorial_design({"A": [-1, 1], "B": [-1, 1], "C": [-1, 1]}, generators={"C": ("A", "B")})
    assert len(runs) == 4
    # level index sum mod 2: C is high exactly when A and B differ, i.e. C = −A·B in ±1 coding
    assert all(r["C"] == -r["A"] * r["B"] for r in runs)


def test_replicates_and_seeded_order():
    a = factorial_design({"force_N": [10.0, 20.0]}, replicates=3, seed=1)
    b = factorial_design({"force_N": [10.0, 20.0]}, replicates=3, seed=1)
    assert a == b and len(a) == 6 and sorted(r["force_N"] for r in a) == [10.0] * 3 + [20.0] * 3


def test_bad_generators_are_refused():
    with pytest.raises(InputError, match="levels"):
        factorial_design({"A": [1, 2], "B": [1, 2, 3], "C": [1, 2]}, generators={"C": ("A", "B")})
    with pytest.raises(InputError, match="not among"):
        factorial_design({"A": [1, 2]}, generators={"Z": ("A",)})


def test_parse_factor_units():
    assert parse_factor("force=10N,20N,0.03kN") == ("force_N", [10.0, 20.0, 30.0])
    col, v = parse_factor("speed=1000rpm,50Hz")
    assert col == "spindle_speed_rpm" and v == pytest.approx([1000.0, 3000.0])
    assert parse_factor("feed=50mm/s,0.1") == ("feed_m_per_s", [0.05, 0.1])
    assert parse_factor("grit=80,120") == ("grit", ["80", "120"])
    assert parse_factor("passes=1,3") == ("passes", [1, 3])
    with pytest.raises(InputError):
        parse_factor("force=10N")
    with pytest.raises(InputError):
        parse_factor("force")


def test_template_columns():
    text = doe_csv_text(factorial_design({"force_N": [10.0, 20.0]}), fixed={"passes": 2})
    lines = text.splitlines()
    assert lines[0] == "trial,force_N,passes,depth_m"
    assert lines[1] == "1,10,2,"


def test_parse_generator():
    from swath.simulate.preston_doe import parse_generator

    assert parse_generator("speed=grit+force") == ("spindle_speed_rpm", ("grit", "force_N"))
    with pytest.raises(InputError):
        parse_generator("speed")
