"""Block sequence quality of one stream: dropped and repeated blocks, counted, never hidden.

The one count every part uses: the recorder feeds blocks in arrival order (a late block counts as
repeated or out of order, and the blocks it skipped as dropped); a session's reader and ``inspect``
feed a file's blocks sorted by sequence (then a repeat is a duplicate kept once).
"""

from __future__ import annotations

__all__ = ["SequenceCheck"]


class SequenceCheck:
    """Running counts of one stream's blocks, samples, dropped blocks (and samples) and repeats."""

    def __init__(self) -> None:
        self.last: int | None = None
        self.block_size = 0
        self.blocks = self.samples = self.dropped = self.dropped_samples = self.repeated = 0

    def check(self, stream: str, sequence: int, samples: int) -> str | None:
        """Count a block of ``samples`` samples numbered ``sequence``; a note when it breaks the sequence."""
        self.blocks += 1
        self.samples += samples
        self.block_size = max(self.block_size, samples)
        note = None
        if self.last is not None:
            gap = sequence - self.last - 1
            if gap > 0:
                self.dropped += gap
                self.dropped_samples += gap * self.block_size
                note = f"{stream}: {gap} block(s) missing before sequence {sequence}"
            elif gap < 0:
                self.repeated += 1
                note = f"{stream}: sequence {sequence} repeated or out of order (after {self.last})"
        self.last = sequence if self.last is None else max(self.last, sequence)
        return note
