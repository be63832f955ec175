"""Quantities with units at the edges: parsing, SI factors, and clear errors."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st
from wearbench.bench.units import UNITS, QuantityError, format_quantity, parse_quantity

pytestmark = pytest.mark.no_kernels


@pytest.mark.parametrize(
    ("text", "dimension", "si"),
    [
        ("0.6mm", "length", 0.6e-3),
        ("0.6 mm", "length", 0.6e-3),
        ("-5pi rad/s", "angular_speed", -5 * math.pi),
        ("-5 pi rad/s", "angular_speed", -5 * math.pi),
        ("-pi rad/s", "angular_speed", -math.pi),
        ("pi/2 rad", "angle", math.pi / 2),
        ("300 rpm", "angular_speed", 10 * math.pi),
        ("1 Hz", "angular_speed", 2 * math.pi),
        ("-36.84 deg", "angle", math.radians(-36.84)),
        ("206 GPa", "pressure", 206e9),
        ("50 g", "acceleration", 50 * 9.80665),
        ("0.5 g", "mass", 0.5e-3),
        ("1e-15 1/Pa", "wear_coefficient", 1e-15),
        ("7.85e-4 kg*m^2", "inertia", 7.85e-4),
        ("10 kHz", "frequency", 1e4),
        ("100 mV/g", "sensitivity", 0.1 / 9.80665),
    ],
)
def test_parse_known_values(text, dimension, si):
    assert parse_quantity(text, dimension) == pytest.approx(si, rel=1e-12)


def test_bare_number_needs_a_declared_unit():
    with pytest.raises(QuantityError, match="ambiguous"):
        parse_quantity(0.6, "length")
    assert parse_quantity(-5.0, "angular_speed", bare_unit="rad/s") == -5.0
    assert parse_quantity("-5pi", "angular_speed", bare_unit="rad/s") == pytest.approx(-5 * math.pi)


@pytest.mark.parametrize("bad", ["", "mm", "0.6 furlong", "0.6 kg", "1e999 m", "nan m", True])
def test_bad_text_is_refused_with_the_text(bad):
    with pytest.raises(QuantityError) as info:
        parse_quantity(bad, "length")
    assert repr(bad) in str(info.value)


@given(
    dimension=st.sampled_from(sorted(UNITS)),
    value=st.floats(min_value=-1e12, max_value=1e12, allow_nan=False).filter(lambda v: abs(v) > 1e-12),
    data=st.data(),
)
def test_format_then_parse_round_trips(dimension, value, data):
    unit = data.draw(st.sampled_from(sorted(UNITS[dimension])))
    text = format_quantity(value, dimension, unit, digits=17)
    assert parse_quantity(text, dimension) == pytest.approx(value, rel=1e-12)
