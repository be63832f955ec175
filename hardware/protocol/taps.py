"""The tap test's wire contract: how a tapper's trigger, latched on the drive's clock, is reported.

A tap (an impulse hammer or a solenoid tapper striking the slider carriage, cranks at rest) is
fired by a command (serial ``TAP``, see SERIAL.md; CAN ``MotorCommand`` TAP, see CAN.md); the drive
latches the tapper's trigger edge with its touch probe on the encoder's clock, to ``LATCH_RESOLUTION``,
and reports it as an event (code ``FaultCode.TAP``) whose time is the latch and whose message names
the pulse: :func:`tap_message` writes it, :func:`parse_tap_message` reads it back. Imports only re.
"""

from __future__ import annotations

import re
from typing import NamedTuple

__all__ = ["LATCH_RESOLUTION", "MAX_TAP_WIDTH", "TAP_EVENT", "TapPulse", "parse_tap_message", "tap_message"]

TAP_EVENT = "tap"  # the event kind a latched tap is recorded under (FaultCode.TAP's name, as serial reads it)

LATCH_RESOLUTION = 1e-6  # s: the touch probe's time stamp step (1 us)
MAX_TAP_WIDTH = 5e-3     # s: longest tap pulse a device accepts

_PATTERN = re.compile(r"tap (\d+): trigger latched; half-sine pulse ([0-9.eE+-]+) ms, peak ([0-9.eE+-]+) m/s\^2")


class TapPulse(NamedTuple):
    """One tap as its event names it: its number (from 0), width (s) and peak (m/s^2)."""

    number: int
    width: float
    peak: float


def tap_message(number: int, width: float, peak: float) -> str:
    """The event message of tap ``number`` (from 0): a half-sine force pulse of ``width`` s whose
    acceleration peaks at ``peak`` m/s^2; the event's time is the trigger's latch."""
    return f"tap {int(number)}: trigger latched; half-sine pulse {width * 1e3:.9g} ms, peak {peak:.9g} m/s^2"


def parse_tap_message(message: str) -> TapPulse | None:
    """The :class:`TapPulse` a tap event's message names (None for any other message)."""
    m = _PATTERN.search(message)
    if m is None:
        return None
    return TapPulse(int(m.group(1)), float(m.group(2)) * 1e-3, float(m.group(3)))
