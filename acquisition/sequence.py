"""Block sequence quality of one stream: dropped and repeated blocks, counted, never hidden, and
gaps in time between samples.

The one count every part uses: the recorder feeds blocks in arrival order (a late block counts as
repeated or out of order, and the blocks it skipped as dropped); a session's reader and ``inspect``
feed a file's blocks sorted by sequence (then a repeat is a duplicate kept once). The one gap rule
(:func:`gaps`): a time step between consecutive samples longer than 1.5 sample periods.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

__all__ = ["GAP_PERIODS", "SequenceBreak", "SequenceCheck", "gaps"]

GAP_PERIODS = 1.5  # a step between consecutive samples longer than this many sample periods is a gap


def gaps(steps: np.ndarray, sample_rate: float) -> np.ndarray:
    """Which time steps (s) between consecutive samples are gaps (samples dropped): longer than
    :data:`GAP_PERIODS` periods of ``sample_rate`` (Hz)."""
    return np.asarray(steps, dtype=float) > GAP_PERIODS / sample_rate


@dataclass(frozen=True)
class SequenceBreak:
    """A block that breaks its stream's sequence: ``kind`` "drop" (blocks missing before it) or
    "repeat" (repeated or out of order), and a note that says so."""

    kind: Literal["drop", "repeat"]
    note: str


class SequenceCheck:
    """Running counts of one stream's blocks, samples, dropped blocks (and samples) and repeats."""

    def __init__(self) -> None:
        self.last: int | None = None
        self.block_size = 0
        self.blocks = self.samples = self.dropped = self.dropped_samples = self.repeated = 0

    def check(self, stream: str, sequence: int, samples: int) -> SequenceBreak | None:
        """Count a block of ``samples`` samples numbered ``sequence``; the break when it breaks the
        sequence, else None."""
        self.blocks += 1
        self.samples += samples
        self.block_size = max(self.block_size, samples)
        found = None
        if self.last is not None:
            gap = sequence - self.last - 1
            if gap > 0:
                self.dropped += gap
                self.dropped_samples += gap * self.block_size
                found = SequenceBreak("drop", f"{stream}: {gap} block(s) missing before sequence {sequence}")
            elif gap < 0:
                self.repeated += 1
                found = SequenceBreak("repeat", f"{stream}: sequence {sequence} repeated or out of order "
                                                f"(after {self.last})")
        self.last = sequence if self.last is None else max(self.last, sequence)
        return found
