"""The taps a session recorded (the tap test): each tapper trigger the drive latched, as a "tap"
event whose device time is the latch (hardware/protocol/taps.py). Imports pandas and the protocol's tap codec."""

from __future__ import annotations

from dataclasses import dataclass

import pandas as pd
from wearbench.hardware.protocol.taps import TAP_EVENT, parse_tap_message

__all__ = ["TAP_EVENT", "RecordedTap", "recorded_taps"]


@dataclass(frozen=True)
class RecordedTap:
    """A tap: its ``number`` on the device, its trigger's ``latch`` (s, the session's clock: device
    time minus the session's origin, as the samples' times), its half-sine ``width`` (s) and ``peak`` (m/s^2)."""

    number: int
    latch: float
    width: float
    peak: float


def recorded_taps(events: pd.DataFrame) -> list[RecordedTap]:
    """The taps among a session's ``events`` (``Session.events``: time, kind, message), in time order."""
    out = []
    for row in events[events["kind"] == TAP_EVENT].itertuples(index=False):
        pulse = parse_tap_message(str(row.message))
        if pulse is not None:
            out.append(RecordedTap(pulse.number, float(row.time), pulse.width, pulse.peak))
    return sorted(out, key=lambda tap: tap.latch)
