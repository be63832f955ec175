"""What a session is asked to do and what it reports: :class:`SessionPlan`, :class:`Progress`,
:class:`SessionResult`. Plain records; imports nothing of wearbench."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["Progress", "SessionPlan", "SessionResult"]


@dataclass
class SessionPlan:
    """What to record. ``speed`` is the motor speed (rad/s); stop after ``cycles`` complete crank
    cycles (index pulse to index pulse) or ``duration`` s of recording (device clock), whichever is
    given. A tap session (``taps`` > 0, the tap test) keeps the cranks at rest (``speed`` 0, no
    cycles or duration) and fires ``taps`` taps ``tap_interval`` s apart: half-sine pulses of
    ``tap_width`` s peaking at ``tap_peak`` m/s^2 (None: a quarter of the accelerometer's range)."""

    speed: float
    cycles: float | None = None
    duration: float | None = None
    acceleration: float | None = None  # ramp, rad/s^2 (None: the bench motor's max_acceleration)
    settle: float = 0.5  # s held at speed before recording starts
    speed_tolerance: float = 0.02  # relative: steady when |speed - target| < tol * |target|
    clearances: dict[str, float] = field(default_factory=dict)  # m, as mounted
    wear: dict[str, str] = field(default_factory=dict)  # joint -> label or surfaces file
    operator: str = ""
    cycles_run: float | None = None  # cycles the bench had run before this session (``wearbench track`` reads it)
    silence_timeout: float = 2.0  # s (rig clock) without a block: the device stopped answering
    state_interval: float = 0.05  # s (rig clock) between drive state polls
    max_malformed: int = 100  # malformed frames tolerated before the session stops
    taps: int = 0  # the tap test: taps fired with the cranks at rest
    tap_interval: float = 0.5  # s between taps (the response must die away between them)
    tap_width: float = 2e-4  # s, the tap's half-sine pulse
    tap_peak: float | None = None  # m/s^2, None: a quarter of the accelerometer's range

    def __post_init__(self) -> None:
        if self.taps:
            self._check_taps()
            return
        if (self.cycles is None) == (self.duration is None):
            raise ValueError("a session needs exactly one of cycles or duration")
        if self.speed == 0 or not math.isfinite(self.speed):
            raise ValueError(f"speed = {self.speed!r} rad/s: a session needs the crank turning (finite, non-zero)")
        for name, value, unit in (("cycles", self.cycles, ""), ("duration", self.duration, " s")):
            if value is not None and not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} = {value!r}{unit}: expected a finite number > 0")
        if self.cycles_run is not None and not (math.isfinite(self.cycles_run) and self.cycles_run >= 0):
            raise ValueError(f"cycles_run = {self.cycles_run!r}: expected the cycles the bench had run, a finite "
                             "number >= 0")
        if not (math.isfinite(self.settle) and self.settle >= 0):
            raise ValueError(f"settle = {self.settle!r} s: expected a finite number >= 0")


    def _check_taps(self) -> None:
        if not (isinstance(self.taps, int) and self.taps > 0):
            raise ValueError(f"taps = {self.taps!r}: expected a whole number > 0")
        if self.speed != 0 or self.cycles is not None or self.duration is not None:
            raise ValueError(f"a tap session keeps the cranks at rest: expected speed 0 and no cycles or duration "
                             f"(got speed {self.speed!r}, cycles {self.cycles!r}, duration {self.duration!r})")
        for name, value in (("tap_interval", self.tap_interval), ("tap_width", self.tap_width)):
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} = {value!r} s: expected a finite number > 0")
        if self.tap_peak is not None and not (math.isfinite(self.tap_peak) and self.tap_peak > 0):
            raise ValueError(f"tap_peak = {self.tap_peak!r} m/s^2: expected a finite number > 0")


@dataclass
class Progress:
    """Where a running session is; the recorder hands it to ``on_progress``."""

    cycles: float = 0.0
    elapsed: float = 0.0  # s of recording, device clock
    target: float = 0.0  # cycles or seconds, as planned
    sample_rate: float = 0.0  # Hz, acceleration samples per host second, recent
    dropped: int = 0  # samples lost (sequence gaps x block size)
    phase: str = "start"


@dataclass
class SessionResult:
    """How a session ended and what it recorded, per stream (also the file's "result" record)."""

    path: Path | None
    reason: str  # "completed" or why it stopped
    completed: bool
    cycles: float
    duration: float  # s recorded, device clock
    blocks: dict[str, int]
    samples: dict[str, int]
    dropped_blocks: dict[str, int]
    dropped_samples: dict[str, int]
    repeated_blocks: dict[str, int]
    malformed: int
    events: int
    clipped: int = 0  # acceleration samples at or beyond the range
    writer_cpu: float = 0.0  # s of CPU used by the writer thread
    reader_cpu: float = 0.0  # s of CPU used by the reader threads
