import pytest

from core import iso
from core.exceptions import ConfigError


def test_21_errors_of_three_linear_axes():
    assert len(iso.TWENTY_ONE) == 21
    assert iso.TWENTY_ONE[:6] == ("EXX", "EYX", "EZX", "EAX", "EBX", "ECX")
    assert iso.TWENTY_ONE[-3:] == ("EC0Y", "EB0Z", "EA0Z")
    assert len(set(iso.TWENTY_ONE)) == 21


@pytest.mark.parametrize(
    "name, axis, direction, kind, unit",
    [
        ("EXX", "X", "X", iso.Kind.POSITIONING, "m"),
        ("EYX", "X", "Y", iso.Kind.STRAIGHTNESS, "m"),
        ("EBX", "X", "B", iso.Kind.ANGULAR, "rad"),
        ("EZZ", "Z", "Z", iso.Kind.POSITIONING, "m"),
        ("EC0Y", "Y", "C", iso.Kind.LOCATION, "rad"),
        ("EX0C", "C", "X", iso.Kind.LOCATION, "m"),
        ("EXC", "C", "X", iso.Kind.RADIAL, "m"),
        ("EZC", "C", "Z", iso.Kind.AXIAL, "m"),
        ("EAC", "C", "A", iso.Kind.TILT, "rad"),
        ("ECC", "C", "C", iso.Kind.POSITIONING, "rad"),
        ("EXA", "A", "X", iso.Kind.AXIAL, "m"),
        ("EAA", "A", "A", iso.Kind.POSITIONING, "rad"),
        ("EZ0A", "A", "Z", iso.Kind.LOCATION, "m"),
    ],
)
def test_symbol_meaning(name, axis, direction, kind, unit):
    s = iso.symbol(name)
    assert (s.axis, s.direction, s.kind, s.unit) == (axis, direction, kind, unit)


def test_rotary_location_errors_of_c_and_a():
    c_loc = {s.name for s in iso.symbols_of_axis("C", location=True)}
    assert c_loc == {"EX0C", "EY0C", "EA0C", "EB0C"}
    a_loc = {s.name for s in iso.symbols_of_axis("A", location=True)}
    assert a_loc == {"EY0A", "EZ0A", "EB0A", "EC0A"}
    assert {s.name for s in iso.symbols_of_axis("C", location=False)} == {
        "EXC", "EYC", "EZC", "EAC", "EBC", "ECC"}


def test_zero_conventions_leave_three_squarenesses():
    lin_loc = {s.name for a in "XYZ" for s in iso.symbols_of_axis(a, location=True)}
    assert set(iso.SQUARENESS) | set(iso.ZERO_BY_CONVENTION) == lin_loc
    assert {"EX0X", "EB0X", "EC0X", "EA0Y"} <= set(iso.ZERO_BY_CONVENTION)


def test_paper_spelling_with_parentheses():
    assert iso.symbol("EC(0X)Y").name == "EC0Y"
    assert iso.symbol("exx").name == "EXX"


@pytest.mark.parametrize("bad", ["EQX", "E", "EXW", ""])
def test_unknown_symbol_is_a_config_error(bad):
    with pytest.raises(ConfigError, match="unknown ISO error symbol"):
        iso.symbol(bad)


def test_unknown_axis():
    with pytest.raises(ConfigError, match="unknown axis 'W'"):
        iso.symbols_of_axis("W")
