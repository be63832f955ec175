"""The driver surface every backend implements: a motor drive and an acceleration source.

In the style of python-can's ``BusABC``: two small abstract classes, one module per backend under
``wearbench.acquisition.backends``, chosen by name. What a stream is (name, unit, rate, shape) is
described by :class:`StreamInfo`, separately from the data, which arrives as :class:`Block` objects
carrying a sequence number, the device time of their first sample and the host time of arrival.

This module imports numpy only; it must not import a backend library (pyserial, python-can, ...).
"""

from __future__ import annotations

import abc
import itertools
import math
import threading
import time
from dataclasses import dataclass, field
from typing import Self

import numpy as np

__all__ = [
    "ACCELERATION",
    "ENCODER",
    "AccelerationSource",
    "Block",
    "BusFrame",
    "Clock",
    "DeviceDisconnected",
    "DeviceTimeout",
    "DriverError",
    "Event",
    "MotorDrive",
    "MotorState",
    "RealClock",
    "Rig",
    "StreamInfo",
]

ACCELERATION = "acceleration"  # stream names shared by every backend
ENCODER = "encoder"


class DriverError(RuntimeError):
    """A device refused a command or reported a fault; the message says which device and why."""


class DeviceDisconnected(DriverError):
    """The device went away (cable pulled, port closed, bus off)."""


class DeviceTimeout(DriverError):
    """The device stopped answering within the allowed time."""


@dataclass(frozen=True)
class StreamInfo:
    """What a stream holds: ``describe()`` returns these, data comes separately as blocks.

    ``range`` and ``lsb`` are the ADC's, as the device runs it (an acceleration stream's): the full
    scale (m/s^2; no sample reads beyond it) and the step of one count (m/s^2; None where the device
    does not say: the clip rule then takes range/32768, ``layout.clip_level``). The recorder records
    them once and counts clipped samples with them; the session reader gives them back typed.
    ``extra`` holds the rest a device says of the stream, as text (sensitivity, block size, ...)."""

    name: str  # ACCELERATION or ENCODER
    unit: str  # unit of ``Block.samples``: "m/s^2", "counts"
    sample_rate: float  # Hz, nominal (a block carries the rate it was taken at)
    dtype: str  # numpy dtype of ``Block.samples``: "float32", "int32"
    shape: tuple[int, ...] = ()  # shape of one sample
    source: str = ""  # the device that produces it
    extra: dict[str, str] = field(default_factory=dict)  # counts_per_rev, sensitivity, ...
    range: float | None = None  # m/s^2, full scale (acceleration streams)
    lsb: float | None = None  # m/s^2 per count (acceleration streams; None: not stated)

    def __post_init__(self) -> None:
        typed = sorted({"range", "lsb"} & set(self.extra))
        if typed:
            raise ValueError(f"stream {self.name!r}: extra {typed}: give them as StreamInfo.range and "
                             "StreamInfo.lsb (m/s^2), not as text")
        for what in ("range", "lsb"):
            value = getattr(self, what)
            if value is None:
                continue
            try:
                number = math.nan if isinstance(value, (str, bytes)) else float(value)
            except (TypeError, ValueError):
                number = math.nan
            if not 0 < number < math.inf:
                raise ValueError(f"stream {self.name!r}: {what} = {value!r}: expected a positive number "
                                 "(m/s^2) or None")
            object.__setattr__(self, what, number)


@dataclass
class Block:
    """Consecutive samples of one stream.

    ``device_time`` (s, device clock) is the time of the first sample; sample ``i`` was taken at
    ``device_time + i / sample_rate``. ``host_time`` (s, Unix epoch) is when the host received it.
    ``index`` holds the encoder index pulse per sample (encoder streams only); ``clipped`` the
    acceleration samples at or beyond the accelerometer's range (set by the recorder).
    """

    stream: str
    sequence: int
    device_time: float
    sample_rate: float
    samples: np.ndarray
    host_time: float = 0.0
    index: np.ndarray | None = None
    clipped: int = 0


@dataclass(frozen=True)
class BusFrame:
    """One raw frame as a bus backend received or sent it (python-can's ``Message`` fields that
    matter for replaying it into the decoder); ``time`` is the bus timestamp (s; the host clock
    for a frame the host sent), ``host_time`` the host clock at arrival or sending (s, Unix
    epoch), ``transmitted`` true for a frame the host sent (commands, SDO requests, RPDOs, NMT)."""

    time: float
    arbitration_id: int
    data: bytes
    is_extended: bool = False
    is_fd: bool = False
    bitrate_switch: bool = False
    is_error: bool = False
    is_remote: bool = False
    host_time: float = 0.0
    transmitted: bool = False


@dataclass
class Event:
    """Something worth a line in the session's event log (a fault, a malformed frame, a phase)."""

    kind: str
    message: str
    host_time: float = field(default_factory=time.time)
    device_time: float | None = None


@dataclass(frozen=True)
class MotorState:
    """One reading of the drive: angle (rad, unwrapped) and speed (rad/s) of the encoder's crank,
    encoder counts since power-up, index pulses so far, enabled, latched fault (lower-case name)."""

    device_time: float  # s
    angle: float  # rad
    speed: float  # rad/s
    counts: int
    index_count: int
    enabled: bool
    fault: str | None = None
    host_time: float = 0.0


class Clock(abc.ABC):
    """The time base the recorder waits on: real time, or a simulated bench clock."""

    @abc.abstractmethod
    def now(self) -> float:
        """Seconds on this clock."""

    @abc.abstractmethod
    def sleep(self, seconds: float) -> None:
        """Wait ``seconds`` of this clock."""


class RealClock(Clock):
    def now(self) -> float:
        return time.monotonic()

    def sleep(self, seconds: float) -> None:
        time.sleep(max(0.0, seconds))


class MotorDrive(abc.ABC):
    """A crank motor drive: enable, command a speed (with a ramp), stop, read its state."""

    name: str = "drive"

    @abc.abstractmethod
    def enable(self) -> None:
        """Power the drive (clears a cleared fault); raises DriverError if it refuses."""

    @abc.abstractmethod
    def disable(self) -> None:
        """Remove power; the crank coasts."""

    @abc.abstractmethod
    def set_speed(self, speed: float, acceleration: float | None = None) -> None:
        """Command motor speed ``speed`` (rad/s; driver i turns at ratio_i times it), ramping at
        ``acceleration`` (rad/s^2, None: the drive's)."""

    def stop(self, acceleration: float | None = None) -> None:
        """Ramp to standstill (the drive stays enabled)."""
        self.set_speed(0.0, acceleration)

    def set_profile(self, times: list[float], speeds: list[float], acceleration: float | None = None) -> None:
        """Speed profile: at ``times[i]`` s from now ramp to ``speeds[i]`` rad/s.

        This default times the points on the host (a timer thread per point); backends whose device
        runs profiles itself override it.
        """
        if len(times) != len(speeds) or any(b < a for a, b in itertools.pairwise(times)):
            raise ValueError(f"profile times {list(times)} and speeds {list(speeds)}: expected equal "
                             "lengths and ascending times")
        for t, v in zip(times, speeds):
            timer = threading.Timer(t, self.set_speed, (v, acceleration))
            timer.daemon = True
            timer.start()

    def tap(self, after: float = 0.01, width: float = 2e-4, peak: float = 1000.0) -> None:
        """Fire the tapper on the accelerometer's body ``after`` s from now: a half-sine pulse of ``width`` s peaking
        at ``peak`` m/s^2. The drive latches its trigger on the encoder's clock and reports it as an
        event of kind ``"tap"`` from the sources (hardware/protocol/taps.py names its message)."""
        raise DriverError(f"{self.name}: this drive has no tapper on its touch probe (tap test not supported)")

    @abc.abstractmethod
    def state(self) -> MotorState:
        """The drive's current state (encoder angle, speed, index count, enabled, fault)."""

    def close(self) -> None:
        """Release the connection; the drive is left disabled if it can be."""

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class AccelerationSource(abc.ABC):
    """A device streaming sample blocks (the accelerometer, and the encoder where it rides along)."""

    name: str = "daq"

    @abc.abstractmethod
    def configure(self, range_m_s2: float, sample_rate: float) -> None:
        """Set the measuring range (m/s^2) and sample rate (Hz) before ``start``."""

    @abc.abstractmethod
    def describe(self) -> tuple[StreamInfo, ...]:
        """The streams ``read`` delivers."""

    @abc.abstractmethod
    def start(self) -> None:
        """Start streaming."""

    @abc.abstractmethod
    def stop(self) -> None:
        """Stop streaming."""

    @abc.abstractmethod
    def read(self, timeout: float) -> list[Block | Event | BusFrame]:
        """Blocks (host-timestamped), events and raw bus frames (bus backends) received so far;
        waits at most ``timeout`` s.

        Returns an empty list when nothing came in time; raises DeviceDisconnected when the
        device is gone. The recorder decides when silence means a dead device.
        """

    def close(self) -> None:
        """Release the connection."""

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@dataclass
class Rig:
    """What a backend opens: one drive, the sources, the clock they run on, and a closer."""

    backend: str
    drive: MotorDrive
    sources: list[AccelerationSource]
    clock: Clock = field(default_factory=RealClock)
    info: dict[str, str] = field(default_factory=dict)  # recorded as metadata "hardware"

    def close(self) -> None:
        errors = []
        for part in (*self.sources, self.drive):
            try:
                part.close()
            except Exception as exc:  # noqa: BLE001 - closing must reach every device
                errors.append(f"{part.name}: {exc}")
        if errors:
            raise DriverError("closing the rig: " + "; ".join(errors))
