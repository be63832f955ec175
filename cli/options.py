"""Checks of command-line values at the edge: argparse ``type=`` functions for counts and numbers,
a quantity check, the motor speed, and values per joint (``--clearance A=0.3mm,B=0.3mm``).

Every bad value ends as one line naming the option, the value and what was expected, exit 2.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence

from wearbench.bench.schema import Bench
from wearbench.bench.units import QuantityError, parse_quantity

__all__ = [
    "add_force_argument",
    "check_clearances",
    "check_figure_name",
    "check_motor_speed",
    "check_realisations",
    "check_wear_coefficient",
    "cycle_count",
    "joint_values",
    "motor_speed",
    "nonnegative_int",
    "nonnegative_number",
    "parse_clearances",
    "positive_int",
    "positive_number",
    "positive_quantity",
]


def check_figure_name(path: str, option: str) -> None:
    """Refuse, before any work, a figure name whose suffix matplotlib cannot write (``--figure x.txt``)."""
    from pathlib import Path

    from matplotlib.backend_bases import FigureCanvasBase

    known = FigureCanvasBase.get_supported_filetypes()
    suffix = Path(path).suffix.lstrip(".").lower()
    if suffix not in known:
        raise ValueError(f"{option} {path}: a figure needs one of the suffixes {', '.join(sorted(known))}; got "
                         f"{'.' + suffix if suffix else 'none'}")


def add_force_argument(p: argparse.ArgumentParser, help: str | None = None) -> None:
    """``--force``: the one switch of the output-file policy (``wearbench.bench.output_file``); ``help``
    says what else it allows, where a command has more."""
    p.add_argument("--force", action="store_true",
                   help=help or "replace existing output files (never a recorded session); the old ones stay as "
                   "they were until the new ones are complete")


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


def check_realisations(count: int, option: str = "--realisations") -> int:
    """Realisations per state that identification can use (``validation.ensemble.MIN_REALISATIONS``)."""
    from wearbench.validation.inference.ensemble import MIN_REALISATIONS

    if count < MIN_REALISATIONS:
        raise ValueError(f"{option} {count}: expected at least {MIN_REALISATIONS} realisations per state "
                         "(identification fits each state without one realisation at a time)")
    return count


def add_ensemble_size_arguments(p: argparse.ArgumentParser, cycles_flag: str = "--cycles") -> None:
    """``--realisations`` and ``cycles_flag``: the theory ensembles' size, defaulting to the shipped
    ensembles' (``EnsembleSettings``; not imported here, it would slow every command's start:
    tests/test_cli.py checks the two agree)."""
    p.add_argument("--realisations", type=positive_int, default=64, help="realisations per state (64, as shipped)")
    p.add_argument(cycles_flag, type=positive_int, default=8, help="settled cycles per realisation (8)")


def cycle_count(text: str) -> float:
    """A number of crank cycles: finite and >= 1 (a fraction of a cycle holds no complete cycle)."""
    value = _number(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: expected at least 1 crank cycle")
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




def motor_speed(text: str, option: str = "--speed", *, allow_zero: bool = False, max_speed: float | None = None,
                source: str = "") -> float:
    """A motor speed from the command line (rad/s), the one check every command uses: ``text`` as a
    quantity ('-5pi' or '-5' rad/s, '150rpm', '2Hz'), then :func:`check_motor_speed`."""
    try:
        value = parse_quantity(text, "angular_speed", bare_unit="rad/s")
    except QuantityError as exc:
        raise ValueError(f"{option} {text!r}: {exc}; expected {_expected_speed(allow_zero)}") from None
    return check_motor_speed(value, option, text, allow_zero=allow_zero, max_speed=max_speed, source=source)


def check_motor_speed(value: float, option: str, text: str, *, allow_zero: bool = False,
                      max_speed: float | None = None, source: str = "") -> float:
    """``value`` (rad/s, given as ``text``) finite, not 0 unless ``allow_zero``, and at most ``max_speed``
    (the motor's, from ``source``) in magnitude when given; ValueError naming the option, the value and
    what was expected otherwise."""
    if not math.isfinite(value) or (value == 0 and not allow_zero):
        raise ValueError(f"{option} {text!r}: expected {_expected_speed(allow_zero)}")
    if max_speed is not None and abs(value) > max_speed:
        raise ValueError(f"{option} {text!r}: {value:.4g} rad/s; expected at most the motor's max_speed "
                         f"{max_speed:.4g} rad/s in magnitude{f' ({source})' if source else ''}")
    return value


def _expected_speed(allow_zero: bool) -> str:
    return "a finite motor speed" + ("" if allow_zero else " other than 0") + ", e.g. -5pi (rad/s) or 150rpm"


def joint_values(text: str | None, option: str, joints: Sequence[str], *, every: bool = False) -> dict[str, str]:
    """``"A=0.3mm,B=new"`` -> {joint: value text}, every name one of ``joints``; with ``every``, a bare
    value (``"0.6mm"``) goes to every joint. The one parser of per-joint options."""
    out: dict[str, str] = {}
    if every and text and "=" not in text:
        return dict.fromkeys(joints, text.strip())
    for item in filter(None, (x.strip() for x in (text or "").split(","))):
        key, sep, value = (x.strip() for x in item.partition("="))
        if not sep or not key or not value:
            raise ValueError(f"{option} {text!r}: expected JOINT=VALUE[,JOINT=VALUE...], e.g. A=0.6mm, got {item!r}")
        if key not in joints:
            raise ValueError(f"{option} {text!r}: no clearance joint {key!r}; expected one of {list(joints)}")
        out[key] = value
    return out


def parse_clearances(text: str | None, bench: Bench, option: str = "--clearance", *,
               ideal: bool = False) -> dict[str, float | None]:
    """Radial clearances (m) by joint from ``"0.6mm"`` (every clearance joint) or ``"A=0.6mm,B=0.3mm"``;
    with ``ideal``, ``J=ideal`` makes a joint an ideal pin (None). Empty text: {} (the bench's)."""
    values = joint_values(text, option, [j.name for j in bench.clearance_joints], every=True)
    out: dict[str, float | None] = {}
    for joint, value in values.items():
        if ideal and value.lower() == "ideal":
            out[joint] = None
            continue
        try:
            out[joint] = parse_quantity(value, "length", bare_unit="m")
        except QuantityError as exc:
            raise ValueError(f"{option} {text!r}: {exc}") from None
    check_clearances({j: c for j, c in out.items() if c is not None}, bench, option, text)
    return out


def check_clearances(clearances: dict[str, float], bench: Bench, option: str, text: str) -> None:
    """Radial clearances (m) that fit ``bench``'s bearings (the bench's own rule, 0 < c < bearing
    radius); ValueError naming ``option`` and ``text`` otherwise."""
    try:
        bench.with_clearances(clearances)
    except (ValueError, KeyError) as exc:
        raise ValueError(f"{option} {text!r}: {exc.args[0] if exc.args else exc}") from None


def check_wear_coefficient(value: float, option: str, text: str) -> float:
    """An Archard wear coefficient (1/Pa): finite and >= 0 (0: no wear)."""
    if not (math.isfinite(value) and value >= 0):
        raise ValueError(f"{option} {text!r}: {value:.4g} 1/Pa; expected a wear coefficient >= 0, e.g. 6.6e-14/Pa")
    return value
