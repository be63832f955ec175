"""Physical quantities written with units at the edges ("0.6mm", "-5pi rad/s", "300 rpm", "50 g").

Everything inside wearbench is SI; this module is the one place that turns text with a unit into
an SI float and back. It imports nothing from the rest of the package.
"""

from __future__ import annotations

import math
import re

__all__ = ["UNITS", "QuantityError", "format_quantity", "parse_quantity"]

_G0 = 9.80665

# dimension -> {unit spelling: factor to SI}
UNITS: dict[str, dict[str, float]] = {
    "length": {"m": 1.0, "mm": 1e-3, "um": 1e-6, "µm": 1e-6, "cm": 1e-2, "in": 0.0254},
    "mass": {"kg": 1.0, "g": 1e-3},
    "inertia": {"kg*m^2": 1.0, "kg m^2": 1.0, "kg*m2": 1.0, "kgm^2": 1.0, "g*mm^2": 1e-9,
                "kg*mm^2": 1e-6, "kg mm^2": 1e-6},
    "angle": {"rad": 1.0, "deg": math.pi / 180.0, "°": math.pi / 180.0, "rev": 2 * math.pi},
    "angular_speed": {"rad/s": 1.0, "rpm": 2 * math.pi / 60.0, "deg/s": math.pi / 180.0,
                      "rev/s": 2 * math.pi, "Hz": 2 * math.pi},
    "angular_acceleration": {"rad/s^2": 1.0, "rad/s2": 1.0, "rpm/s": 2 * math.pi / 60.0},
    "speed": {"m/s": 1.0, "mm/s": 1e-3},
    "acceleration": {"m/s^2": 1.0, "m/s2": 1.0, "g": _G0, "mm/s^2": 1e-3},
    "pressure": {"Pa": 1.0, "kPa": 1e3, "MPa": 1e6, "GPa": 1e9, "N/m^2": 1.0, "N/mm^2": 1e6},
    "density": {"kg/m^3": 1.0, "kg/m3": 1.0, "g/cm^3": 1e3},
    "frequency": {"Hz": 1.0, "kHz": 1e3, "MHz": 1e6},
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "min": 60.0, "h": 3600.0},
    "force": {"N": 1.0, "kN": 1e3},
    "wear_coefficient": {"1/Pa": 1.0, "m^2/N": 1.0, "mm^3/(N*m)": 1e-9},
    "sensitivity": {"V/g": 1.0 / _G0, "mV/g": 1e-3 / _G0, "V/(m/s^2)": 1.0,
                    "mV/(m/s^2)": 1e-3},
    "current": {"A": 1.0, "mA": 1e-3},
    "voltage": {"V": 1.0, "mV": 1e-3},
    "drift": {"ppm": 1e-6},
}

_NUMBER = r"[-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?"
_PATTERN = re.compile(
    rf"^\s*(?P<sign>[-+])?\s*(?P<num>{_NUMBER[5:]})?\s*\*?\s*(?P<pi>pi|π)?\s*"
    rf"(?:/\s*(?P<div>{_NUMBER[5:]}))?\s*(?P<unit>.*?)\s*$"
)


class QuantityError(ValueError):
    """A quantity's text could not be read: says the text, the dimension and what was expected."""


def _examples(dimension: str) -> str:
    return ", ".join(repr(u) for u in UNITS[dimension])


def parse_quantity(value: str | float, dimension: str, *, bare_unit: str | None = None) -> float:
    """Return ``value`` in SI units of ``dimension``.

    ``value`` is text such as ``"0.6mm"``, ``"-5pi rad/s"``, ``"300 rpm"`` or ``"pi/2 rad"``. A bare
    number is accepted only when ``bare_unit`` names the unit it is taken in; otherwise a bare number
    is ambiguous and raises :class:`QuantityError`.
    """
    if dimension not in UNITS:
        raise KeyError(f"unknown dimension {dimension!r}; known: {sorted(UNITS)}")
    table = UNITS[dimension]
    if isinstance(value, bool):
        raise QuantityError(f"{value!r} is not a quantity; expected a {dimension} such as '1 {next(iter(table))}'")
    if isinstance(value, (int, float)):
        if bare_unit is None:
            raise QuantityError(
                f"{value!r} has no unit; a bare number is ambiguous for a {dimension}, "
                f"write it with one of {_examples(dimension)} (e.g. '{value} {next(iter(table))}')"
            )
        return float(value) * table[bare_unit]
    if not isinstance(value, str):
        raise QuantityError(f"{value!r} is not text; expected a {dimension} such as '1 {next(iter(table))}'")
    match = _PATTERN.match(value)
    if match is None or (match["num"] is None and match["pi"] is None):
        raise QuantityError(f"{value!r} is not a number with a unit; expected a {dimension} "
                            f"such as '1 {next(iter(table))}'")
    number = float(match["num"]) if match["num"] is not None else 1.0
    if match["pi"]:
        number *= math.pi
    if match["div"] is not None:
        number /= float(match["div"])
    if match["sign"] == "-":
        number = -number
    unit = match["unit"]
    if unit == "":
        if bare_unit is None:
            raise QuantityError(f"{value!r} has no unit; write the {dimension} with one of {_examples(dimension)}")
        unit = bare_unit
    factor = table.get(unit)
    if factor is None:
        factor = table.get(unit.replace(" ", ""))
    if factor is None:
        raise QuantityError(f"{value!r}: unit {unit!r} is not a {dimension} unit; expected one of {_examples(dimension)}")
    result = number * factor
    if not math.isfinite(result):
        raise QuantityError(f"{value!r} is not finite")
    return result


def format_quantity(si_value: float, dimension: str, unit: str, digits: int = 4) -> str:
    """Format an SI value in ``unit`` for printing, e.g. ``format_quantity(6e-4, "length", "mm")``."""
    return f"{si_value / UNITS[dimension][unit]:.{digits}g} {unit}"
