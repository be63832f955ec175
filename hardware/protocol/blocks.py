"""The device-side data records every transport carries: accelerometer and encoder blocks, motor status.

These are the contract types of ``wearbench.hardware.emulators.device`` (re-exported there); they
live here so the wire codecs can build them without importing the emulators. Imports numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["AccelBlock", "EncoderBlock", "MotorStatus"]


@dataclass(frozen=True, eq=False)
class AccelBlock:
    """Accelerometer samples: block ``sequence`` (per stream, from 0), device ``time`` (s) of the
    first sample, nominal ``sample_rate`` (Hz), ``samples`` (float32, m/s^2)."""

    sequence: int
    time: float
    sample_rate: float
    samples: np.ndarray

    def __eq__(self, other: object) -> bool:
        return (isinstance(other, AccelBlock) and self.sequence == other.sequence
                and self.time == other.time and self.sample_rate == other.sample_rate
                and np.array_equal(self.samples, other.samples))

    @property
    def times(self) -> np.ndarray:
        """Device time of each sample (s), from the nominal rate."""
        return self.time + np.arange(len(self.samples)) / self.sample_rate


@dataclass(frozen=True, eq=False)
class EncoderBlock:
    """Encoder samples: block ``sequence``, device ``time`` (s) of the first sample, ``sample_rate``
    (Hz), ``counts`` (int32, since power-up) and ``index`` (bool, index pulse since the previous sample)."""

    sequence: int
    time: float
    sample_rate: float
    counts: np.ndarray
    index: np.ndarray

    def __eq__(self, other: object) -> bool:
        return (isinstance(other, EncoderBlock) and self.sequence == other.sequence
                and self.time == other.time and self.sample_rate == other.sample_rate
                and np.array_equal(self.counts, other.counts) and np.array_equal(self.index, other.index))

    @property
    def times(self) -> np.ndarray:
        return self.time + np.arange(len(self.counts)) / self.sample_rate


@dataclass(frozen=True)
class MotorStatus:
    """Drive state at device ``time`` (s): ``angle`` (rad, unwrapped crank angle of the encoder
    joint), ``speed`` (rad/s, of that crank), encoder ``counts``, ``index_count`` (index pulses so
    far), ``enabled``, latched ``fault`` (a FaultCode name in lower case, e.g. "stall", or None)."""

    time: float
    angle: float
    speed: float
    counts: int
    index_count: int
    enabled: bool
    fault: str | None = None
