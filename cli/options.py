"""Checks of command-line values at the edge: argparse ``type=`` functions for counts and numbers,
a quantity check.

Every bad value ends as one line naming the option, the value and what was expected, exit 2.
"""

from __future__ import annotations

import argparse
import math

from wearbench.hardware.units import parse_quantity

__all__ = ["nonnegative_int", "nonnegative_number", "positive_int", "positive_number", "positive_quantity"]


def _number(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r}: expected a finite number")
    return value


def _int(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a whole number") from None


def positive_number(text: str) -> float:
    """A finite number > 0."""
    value = _number(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a number > 0")
    return value


def nonnegative_number(text: str) -> float:
    """A finite number >= 0."""
    value = _number(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a number >= 0")
    return value


def positive_int(text: str) -> int:
    """A whole number >= 1."""
    value = _int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a whole number >= 1")
    return value


def nonnegative_int(text: str) -> int:
    """A whole number >= 0."""
    value = _int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a whole number >= 0")
    return value


def positive_quantity(text: str, dimension: str, option: str, *, bare_unit: str | None = None,
                      allow_zero: bool = False) -> float:
    """``text`` parsed as a quantity (SI), finite and > 0 (>= 0 with ``allow_zero``); ValueError naming
    ``option`` otherwise."""
    value = parse_quantity(text, dimension, bare_unit=bare_unit)
    if not math.isfinite(value) or value < 0 or (value == 0 and not allow_zero):
        raise ValueError(f"{option} {text!r}: expected a finite {dimension} {'>=' if allow_zero else '>'} 0")
    return value

