"""The ``sim`` backend: the hardware emulator's :class:`BenchDevice` in-process.

The device runs on a :class:`SimClock`: real time (``speedup = 1``, the default), faster, or
stepped by the recorder's own waits (``speedup = inf``: as fast as the host can, for tests and
benchmarks). Options (``[hardware.sim]`` or ``--option``): ``speedup``, ``step`` (s of device
time between reads in real-time mode, default 0.02), ``config`` (a JSON file replacing the
bench's ``[emulator]`` table, as for ``wearbench emulate --config``: one object with the table's
keys and values, units in strings, e.g. ``{"truth": {"state": "0.6 mm new", "seed": 3}}``; the
reference is ``hardware/emulators/config.py``). The rig's ``truth`` entry holds the marks of the
device's truth (``hardware/protocol/truth.py``), which a host checks its labels against
(``acquisition/emulated_truth.py``). Imports the emulator; no other backend.
"""

from __future__ import annotations

import json
import math
import threading
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from wearbench.acquisition.backends import fault_name
from wearbench.acquisition.drivers import (
    ACCELERATION,
    ENCODER,
    AccelerationSource,
    Block,
    Clock,
    DeviceDisconnected,
    DriverError,
    Event,
    MotorDrive,
    MotorState,
    Rig,
    StreamInfo,
)
from wearbench.bench.schema import Bench
from wearbench.hardware.emulators.config import EmulatorConfig
from wearbench.hardware.emulators.device import BenchDevice, DeviceError
from wearbench.hardware.protocol.truth import announce

__all__ = ["SimClock", "SimDrive", "SimSource", "blocks_from_device", "open_rig"]


class SimClock(Clock):
    """Device time of the emulated bench.

    With a finite ``speedup`` it runs ``speedup`` times faster than real time. With
    ``speedup = inf`` it is stepped: it moves only when the controlling thread ``sleep``s, so the
    bench runs as fast as the host can while every wait of the recorder still lasts exactly its
    device time. Readers wait for it to move with :meth:`wait_change`.
    """

    def __init__(self, speedup: float = 1.0, start: float = 0.0):
        if not speedup > 0:
            raise ValueError(f"speedup = {speedup}: expected a positive number (inf: as fast as possible)")
        self.speedup = speedup
        self.stepped = not math.isfinite(speedup)
        self._t = start
        self._m0 = time.monotonic()
        self._cond = threading.Condition()
        self._seen: dict[int, tuple[threading.Thread, float]] = {}

    def now(self) -> float:
        if self.stepped:
            return self._t
        return self._t + (time.monotonic() - self._m0) * self.speedup

    def __call__(self) -> float:
        return self.now()

    def sleep(self, seconds: float) -> None:
        if not self.stepped:
            time.sleep(max(0.0, seconds) / self.speedup)
            return
        with self._cond:
            self._t += max(0.0, seconds)
            self._cond.notify_all()
            # lockstep: let every live reader thread catch up before time moves on (1 s at most)
            end = time.monotonic() + 1.0
            while not all(t >= self._t for th, t in self._seen.values() if th.is_alive()):
                if not self._cond.wait(min(0.05, end - time.monotonic())) and time.monotonic() >= end:
                    break

    def seen(self, reader: object, t: float) -> None:
        """``reader`` (in the calling thread) has read everything up to device time ``t``."""
        with self._cond:
            self._seen[id(reader)] = (threading.current_thread(), t)
            self._cond.notify_all()

    def forget(self, reader: object) -> None:
        with self._cond:
            self._seen.pop(id(reader), None)
            self._cond.notify_all()

    def wait_change(self, since: float, timeout: float) -> float:
        """Wait until the clock is past ``since`` (at most ``timeout`` real s); returns now."""
        if not self.stepped:
            time.sleep(min(timeout, max(0.0, since - self.now()) / self.speedup))
            return self.now()
        with self._cond:
            self._cond.wait_for(lambda: self._t > since, timeout)
            return self._t


def _status(s: Any) -> MotorState:
    return MotorState(device_time=float(s.time), angle=float(s.angle), speed=float(s.speed),
                      counts=int(s.counts), index_count=int(s.index_count), enabled=bool(s.enabled),
                      fault=s.fault or None)


def blocks_from_device(items: list, host_time: float) -> list[Block]:
    """The device's AccelBlock/EncoderBlock records as :class:`Block` objects."""
    out = []
    for b in items:
        if hasattr(b, "counts"):
            out.append(Block(ENCODER, int(b.sequence), float(b.time), float(b.sample_rate),
                             np.asarray(b.counts, dtype=np.int32), host_time, np.asarray(b.index, dtype=bool)))
        else:
            out.append(Block(ACCELERATION, int(b.sequence), float(b.time), float(b.sample_rate),
                             np.asarray(b.samples, dtype=np.float32), host_time))
    return out


class SimDrive(MotorDrive):
    name = "sim-drive"

    def __init__(self, device: Any, lock: threading.Lock):
        self.device, self._lock = device, lock

    def _call(self, what: str, *args) -> Any:
        with self._lock:
            try:
                return getattr(self.device, what)(*args)
            except DeviceError as exc:
                raise DriverError(f"sim device refused {what}: {exc}") from None

    def enable(self) -> None:
        if self.device.fault:
            self._call("clear_fault")
        self._call("enable")

    def disable(self) -> None:
        self._call("disable")

    def set_speed(self, speed: float, acceleration: float | None = None) -> None:
        self._call("set_speed", speed, acceleration)

    def stop(self, acceleration: float | None = None) -> None:
        if acceleration is None:
            self._call("stop")
        else:
            self._call("set_speed", 0.0, acceleration)

    def set_profile(self, times: list[float], speeds: list[float], acceleration: float | None = None) -> None:
        self._call("set_profile", list(times), list(speeds), acceleration)

    def tap(self, after: float = 0.01, width: float = 2e-4, peak: float = 1000.0) -> None:
        self._call("tap", after, width, peak)

    def state(self) -> MotorState:
        return _status(self._call("motor_status"))


class SimSource(AccelerationSource):
    name = "sim-daq"

    def __init__(self, device: Any, lock: threading.Lock, clock: SimClock, bench: Bench, *,
                 step: float = 0.02):
        self.device, self._lock, self.clock = device, lock, clock
        self.step = step  # s of device time between reads in real-time mode
        self._seen = clock.now()
        acc, enc = bench.sensor("accelerometer"), bench.sensor("encoder")
        self._rate, self._range = acc.sample_rate, acc.range
        self._enc = enc
        self.closed = False

    def configure(self, range_m_s2: float, sample_rate: float) -> None:
        self._range, self._rate = range_m_s2, sample_rate
        with self._lock:
            try:
                self.device.configure_accelerometer(range_m_s2, sample_rate)
            except DeviceError as exc:
                raise DriverError(f"sim device refused the accelerometer configuration: {exc}") from None

    def describe(self) -> tuple[StreamInfo, ...]:
        return (StreamInfo(ACCELERATION, "m/s^2", self._rate, "float32", source="sim accelerometer",
                           range=self._range),
                StreamInfo(ENCODER, "counts", self._enc.sample_rate, "int32", source="sim encoder",
                           extra={"counts_per_rev": str(self._enc.counts_per_rev)}))

    def start(self) -> None:
        with self._lock:
            self.device.start_stream()
        self.clock.seen(self, self._seen)

    def read(self, timeout: float) -> list[Block | Event]:
        if self.closed:
            raise DeviceDisconnected("sim device closed")
        self._seen = self.clock.wait_change(self._seen + (0.0 if self.clock.stepped else self.step), timeout)
        with self._lock:
            items = self.device.read()
            events = self.device.events()
        self.clock.seen(self, self._seen)
        now = time.time()
        out: list[Block | Event] = blocks_from_device(items, now)
        for e in events:
            out.append(Event(fault_name(int(e.code)) or "event", f"device: {e.message}", now, e.time))
        return out

    def stop(self) -> None:
        with self._lock:
            self.device.stop_stream()
        self.clock.forget(self)

    def close(self) -> None:
        self.closed = True
        self.clock.forget(self)


def _positive(options: Mapping[str, Any], name: str, default: float) -> float:
    raw = options.get(name, default)
    try:
        value = float(raw)
    except (TypeError, ValueError):
        value = math.nan
    if not value > 0:  # inf is allowed (speedup: as fast as the host can)
        raise ValueError(f"[hardware.sim] {name} = {raw!r}: expected a positive number"
                         + (" (inf: as fast as the host can)" if name == "speedup" else " (s of device time)"))
    return value


def open_rig(bench: Bench, options: Mapping[str, Any]) -> Rig:
    """A sim rig: the emulator device on a :class:`SimClock`. ``options['device']`` may pass a ready
    device built on ``options['clock']`` (tests use it to keep a handle on the emulator)."""
    unknown = set(options) - {"speedup", "step", "device", "clock", "config"}
    if unknown:
        raise ValueError(f"[hardware.sim]: unknown option(s) {sorted(unknown)}; expected speedup, step, config")
    speedup, step = (_positive(options, name, default) for name, default in (("speedup", 1.0), ("step", 0.02)))
    clock = options.get("clock") or SimClock(speedup)
    device = options.get("device")
    if device is None:
        config = options.get("config")
        if isinstance(config, str):  # a JSON file replacing the bench's [emulator] table
            try:
                table = json.loads(Path(config).read_text(encoding="utf-8"))
            except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
                raise ValueError(f"[hardware.sim] config = {config!r}: expected a JSON file of the [emulator] "
                                 f"table ({exc})") from None
            config = EmulatorConfig.from_table(table, bench=bench, source=config)
        elif isinstance(config, Mapping):
            config = EmulatorConfig.from_table(config, bench=bench)
        elif config is not None and not isinstance(config, EmulatorConfig):
            raise ValueError(f"[hardware.sim] config = {config!r}: expected the path of a JSON file of the "
                             "[emulator] table (or, from Python, the table itself)")
        device = BenchDevice(bench, config=config, clock=clock)
    lock = threading.Lock()
    source = SimSource(device, lock, clock, bench, step=step)
    return Rig("sim", SimDrive(device, lock), [source], clock,
               info={"device": "wearbench BenchDevice (in-process emulator)", "speedup": repr(speedup),
                     "truth": announce(device.bench.name, device.config.truth.marks(device.bench))})
