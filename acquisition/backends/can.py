"""The ``can`` backend: the bench's raw CAN (FD) frames through python-can, decoded with cantools.

Any python-can interface works (socketcan, pcan, kvaser, slcan, virtual); frames are those of
``hardware/protocol/wearbench.dbc``. A ``can.Notifier`` thread feeds :class:`BenchFrames`, which
routes replies to the waiting command and blocks and events to the source (python-can's
listener pattern); a second listener, :class:`FrameLog`, keeps every frame received and every
frame the host sends, in the order they happened, which the source hands to the recorder for the
session's ``/can/frames`` channel, and :func:`replay` feeds the received ones back into a fresh decoder. The ``canopen`` backend reuses :class:`BenchFrames`,
:class:`FrameLog` and :class:`CanSource` for the acceleration stream. Options (``[hardware.can]``): ``interface`` (default "virtual"),
``channel`` (default "wearbench"), ``bitrate``, ``data_bitrate``, ``fd`` (default true),
``reply_timeout`` (s, default 1.0), ``log_frames`` (default true: every frame received or sent goes to the
session's ``/can/frames``, about 130 MB per hour at 10 kHz). Imports python-can and the CAN codec only.
"""

from __future__ import annotations

import collections
import heapq
import math
import queue
import threading
import time
from collections.abc import Iterable, Mapping
from typing import Any

import can
import numpy as np
from wearbench.acquisition.backends import fault_name
from wearbench.acquisition.drivers import (
    ACCELERATION,
    ENCODER,
    AccelerationSource,
    Block,
    BusFrame,
    DeviceDisconnected,
    DeviceTimeout,
    DriverError,
    Event,
    MotorDrive,
    MotorState,
    Rig,
    StreamInfo,
)
from wearbench.acquisition.layout import recorded_stream
from wearbench.bench.schema import Bench
from wearbench.hardware.protocol import can_frames as cf
from wearbench.hardware.protocol.messages import ErrorCode
from wearbench.hardware.protocol.taps import TAP_EVENT, tap_message

__all__ = [
    "BUS_OPTIONS",
    "BenchFrames",
    "CanDrive",
    "CanSource",
    "FrameLog",
    "check_bus_options",
    "frame_log",
    "open_bus",
    "open_rig",
    "replay",
]

BUS_OPTIONS = {"interface", "channel", "bitrate", "data_bitrate", "fd", "reply_timeout", "log_frames"}


def open_bus(options: Mapping[str, Any]) -> can.BusABC:
    kwargs = {"interface": options.get("interface", "virtual"), "channel": options.get("channel", "wearbench"),
              "fd": bool(options.get("fd", True))}
    for key in ("bitrate", "data_bitrate"):
        if key in options:
            kwargs[key] = int(options[key])
    if kwargs["interface"] == "virtual":
        kwargs["receive_own_messages"] = False
    try:
        return can.Bus(**kwargs)
    except (can.CanError, OSError, ValueError, ImportError) as exc:
        raise DeviceDisconnected(f"cannot open CAN bus {kwargs}: {exc}") from None


class BenchFrames(can.Listener):
    """Receives the bench frames: replies, the encoder position, blocks and events for the source."""

    def __init__(self, counts_per_rev: int, phase: float = 0.0):
        self.inbox: queue.Queue = queue.Queue()
        self.cond = threading.Condition()
        self.status: dict | None = None  # last MotorStatus signals
        self.status_count = 0
        self.stream_status: dict | None = None
        self.stream_count = 0
        self.counts_per_rev = counts_per_rev
        self.phase = phase  # rad: crank angle at count 0 (the bench's driver phase)
        self.lsb = 0.0
        self.sample_rate = 0.0
        self.encoder_rate = 0.0
        self.counts = 0  # latest encoder count, its device time and index pulses so far
        self.encoder_time: float | None = None
        self.index_count = 0
        self.error: str | None = None

    def on_message_received(self, msg: can.Message) -> None:
        now = time.time()
        if msg.is_error_frame:
            kind = "bus_off" if msg.arbitration_id & 0x040 else "can_error"
            self.inbox.put(Event(kind, f"CAN error frame 0x{msg.arbitration_id:03X}", now))
            return
        try:
            decoded = cf.decode_frame(msg)
        except Exception as exc:  # noqa: BLE001 - wrong length, bad signal values: never kill the notifier
            self.inbox.put(Event("malformed", f"CAN frame 0x{msg.arbitration_id:03X}: {exc}", now))
            return
        if decoded is None:
            return  # not a bench frame (e.g. CANopen traffic on the same bus)
        name, values = decoded
        if name == "AccelBlock":
            if not self.lsb:
                self.inbox.put(Event("malformed", "AccelBlock before the stream was configured", now))
                return
            b = cf.decode_accel_frame(values, self.lsb, self.sample_rate)
            self.inbox.put(Block(ACCELERATION, b.sequence, b.time, b.sample_rate, b.samples, now))
        elif name == "EncoderBlock":
            b = cf.decode_encoder_frame(values, self.encoder_rate or 1000.0)
            with self.cond:
                if len(b.counts):
                    self.counts = int(b.counts[-1])
                    self.encoder_time = b.time + (len(b.counts) - 1) / b.sample_rate
                self.index_count += int(np.count_nonzero(b.index))
            self.inbox.put(Block(ENCODER, b.sequence, b.time, b.sample_rate, b.counts, now, b.index))
        elif name == "Event":
            code = int(values["Code"])
            kind = fault_name(code) or "event"
            self.inbox.put(Event(kind, f"device: {kind} (detail {int(values['Detail'])})", now,
                                 values["TimeMs"] * 1e-3))
        elif name == "TapLatch":
            self.inbox.put(Event(TAP_EVENT, "device: " + tap_message(int(values["Number"]), float(values["Width"]),
                                                                 float(values["Peak"])), now, values["TimeNs"] * 1e-9))
        elif name in ("MotorStatus", "StreamStatus"):
            with self.cond:
                if name == "MotorStatus":
                    self.status, self.status_count = values, self.status_count + 1
                else:
                    self.stream_status, self.stream_count = values, self.stream_count + 1
                self.cond.notify_all()

    def on_error(self, exc: Exception) -> None:
        self.error = f"CAN bus: {exc}"
        self.inbox.put(DeviceDisconnected(self.error))
        with self.cond:
            self.cond.notify_all()

    def wait(self, predicate, timeout: float, what: str):
        with self.cond:
            ok = self.cond.wait_for(lambda: self.error is not None or predicate(), timeout)
        if self.error:
            raise DeviceDisconnected(self.error)
        if not ok:
            raise DeviceTimeout(f"CAN: no {what} within {timeout:g} s")

    def request(self, send, predicate, timeout: float, what: str, retries: int = 2) -> None:
        """``send()`` and wait for ``predicate``; send again (a reply lost while the bus was off)
        up to ``retries`` times. Every bench command is idempotent."""
        for attempt in range(retries + 1):
            send()
            try:
                return self.wait(predicate, timeout, what)
            except DeviceTimeout:
                if attempt == retries:
                    raise
                self.inbox.put(Event("retry", f"CAN: no {what} within {timeout:g} s; sending it again"))

    def angle(self, counts: int | None = None) -> float:
        """Crank angle (rad) at ``counts`` (default: the latest): the driver phase plus the turns counted."""
        return self.phase + (self.counts if counts is None else counts) * 2 * math.pi / self.counts_per_rev

    @classmethod
    def for_bench(cls, bench: Bench) -> BenchFrames:
        """Frames of ``bench``: its encoder's counts per revolution and its driver's phase, so angles
        are crank angles as the model and the serial device give them."""
        return cls(bench.sensor("encoder").counts_per_rev, bench.encoder_driver.phase)


class FrameLog(can.Listener):
    """Every frame on the bus in both directions, as :class:`BusFrame` records in the order they
    happened, until :meth:`drain` hands them out. It listens for received frames and, once
    attached to the bus (:meth:`attach`), records every frame the host sends (commands, SDO requests,
    RPDOs, NMT) after the bus accepted it."""

    def __init__(self) -> None:
        self._frames: collections.deque[BusFrame] = collections.deque()
        self._lock = threading.Lock()  # the notifier thread and the sending threads append

    def _append(self, msg: can.Message, transmitted: bool) -> None:
        with self._lock:  # host time taken under the lock: the log is in host-time order
            now = time.time()
            self._frames.append(BusFrame(
                time=now if transmitted or not msg.timestamp else msg.timestamp,
                arbitration_id=msg.arbitration_id, data=bytes(msg.data), is_extended=msg.is_extended_id,
                is_fd=msg.is_fd, bitrate_switch=msg.bitrate_switch, is_error=msg.is_error_frame,
                is_remote=msg.is_remote_frame, host_time=now, transmitted=transmitted))

    def on_message_received(self, msg: can.Message) -> None:
        self._append(msg, False)

    def attach(self, bus: can.BusABC) -> None:
        """Log every frame sent through ``bus.send`` from now on (python-can has no send listener)."""
        send = bus.send

        def logged_send(msg: can.Message, timeout: float | None = None) -> None:
            send(msg, timeout)
            self._append(msg, True)

        bus.send = logged_send  # type: ignore[method-assign]

    def drain(self) -> list[BusFrame]:
        with self._lock:
            out = list(self._frames)
            self._frames.clear()
        return out


def frame_log(options: Mapping[str, Any]) -> FrameLog | None:
    """A :class:`FrameLog` unless the options say ``log_frames = false``."""
    value = options.get("log_frames", True)
    if isinstance(value, str):
        value = {"true": True, "false": False}.get(value.lower(), value)
    if not isinstance(value, bool):
        raise ValueError(f"log_frames = {value!r}: expected true or false")  # noqa: TRY004 - a user error
    return FrameLog() if value else None


def replay(frames: Iterable[BusFrame], bench: Bench, calibration: Mapping[str, str]) -> list[Block | Event]:
    """What a fresh decoder makes of recorded ``frames``: the blocks and events the source would
    have delivered. ``calibration`` is the session's metadata record of that name (LSB and rates)."""
    decoder = BenchFrames.for_bench(bench)
    lsb = recorded_stream(calibration, ACCELERATION).lsb  # a CAN session records the LSB it decoded with
    if lsb is None:
        raise ValueError("replay: the calibration record holds no acceleration.lsb: not a session of a CAN backend")
    decoder.lsb = lsb
    decoder.sample_rate = float(calibration["acceleration.sample_rate"])
    decoder.encoder_rate = float(calibration["encoder.sample_rate"])
    for f in frames:
        if f.transmitted:
            continue  # the host's own frames: the device never sent them
        decoder.on_message_received(can.Message(
            timestamp=f.time, arbitration_id=f.arbitration_id, data=f.data, is_extended_id=f.is_extended,
            is_fd=f.is_fd, bitrate_switch=f.bitrate_switch, is_error_frame=f.is_error,
            is_remote_frame=f.is_remote, check=False))
    out = []
    while not decoder.inbox.empty():
        item = decoder.inbox.get_nowait()
        if not isinstance(item, Exception):
            out.append(item)
    return out


def _send(bus: can.BusABC, name: str, values: dict) -> None:
    try:
        bus.send(cf.encode_frame(name, values), timeout=0.2)
    except (can.CanError, OSError) as exc:
        raise DeviceDisconnected(f"CAN send {name}: {exc}") from None


class CanSource(AccelerationSource):
    """The accelerometer and encoder streams from AccelBlock/EncoderBlock frames."""

    name = "can-daq"

    def __init__(self, bus: can.BusABC, frames: BenchFrames, bench: Bench, reply_timeout: float,
                 log: FrameLog | None = None):
        self.bus, self.frames, self.reply_timeout, self.log = bus, frames, reply_timeout, log
        acc, enc = bench.sensor("accelerometer"), bench.sensor("encoder")
        self._range, self._rate = acc.range, acc.sample_rate
        frames.encoder_rate = enc.sample_rate
        self._enc = enc

    def _control(self, command: str, **values) -> dict:
        f = self.frames
        count = f.stream_count
        f.request(lambda: _send(self.bus, "StreamControl", {
            "Command": command,  # by its DBC name (the DBC holds the codes)
            "Mask": values.get("Mask", 3), "Range": values.get("Range", 0.0),
            "SampleRate": values.get("SampleRate", 0)}),
            lambda: f.stream_count > count, self.reply_timeout, f"StreamStatus reply to {command}")
        reply = f.stream_status
        if reply["Error"] != ErrorCode.OK:
            raise DriverError(f"CAN bench refused StreamControl {command}: {ErrorCode(reply['Error']).name}")
        return reply

    def configure(self, range_m_s2: float, sample_rate: float) -> None:
        reply = self._control("CONFIGURE", Range=range_m_s2, SampleRate=round(sample_rate))
        self._range, self._rate = float(reply["Range"]), float(reply["SampleRate"])
        self.frames.lsb, self.frames.sample_rate = cf.accel_lsb(self._range), self._rate

    def describe(self) -> tuple[StreamInfo, ...]:
        src = f"CAN {self.bus.channel_info}"
        return (StreamInfo(ACCELERATION, "m/s^2", self._rate, "float32", source=src,
                           extra={"sample_rate": repr(self._rate)}, range=self._range,
                           lsb=cf.accel_lsb(self._range)),
                StreamInfo(ENCODER, "counts", self._enc.sample_rate, "int32", source=src,
                           extra={"counts_per_rev": str(self.frames.counts_per_rev),
                                  "sample_rate": repr(self.frames.encoder_rate)}))

    def start(self) -> None:
        self._control("START")

    def stop(self) -> None:
        self._control("STOP")

    def read(self, timeout: float) -> list[Block | Event | BusFrame]:
        out: list[Block | Event | BusFrame] = []
        try:
            item = self.frames.inbox.get(timeout=timeout)
            while True:
                if isinstance(item, Exception):
                    raise item
                out.append(item)
                item = self.frames.inbox.get_nowait()
        except queue.Empty:
            pass
        if self.log is not None:  # both lists are in host-time order: merge them
            out = list(heapq.merge(out, self.log.drain(), key=lambda item: item.host_time))
        return out


class CanDrive(MotorDrive):
    """The bench drive through MotorCommand/MotorStatus frames; the angle from the encoder blocks."""

    name = "can-drive"

    def __init__(self, bus: can.BusABC, frames: BenchFrames, reply_timeout: float):
        self.bus, self.frames, self.reply_timeout = bus, frames, reply_timeout
        self._counter = 0
        self._lock = threading.Lock()

    def _command(self, command: str, speed: float = 0.0, acceleration: float = 0.0) -> dict:
        return self._acknowledged(command, "MotorCommand", {"Command": command, "TargetSpeed": speed,
                                                             "Acceleration": acceleration})

    def _acknowledged(self, what: str, frame: str, values: dict, retries: int = 2) -> dict:
        """Send ``frame`` with the next command counter; the MotorStatus acknowledging it (sent again
        up to ``retries`` times without one)."""
        f = self.frames
        with self._lock:
            self._counter = (self._counter + 1) & 0xF
            counter, count = self._counter, f.status_count
            f.request(lambda: _send(self.bus, frame, {**values, "Counter": counter}),
                      lambda: f.status_count > count and f.status["AckCounter"] == counter,
                      self.reply_timeout, f"MotorStatus acknowledging {what}", retries)
            status = f.status
        if status["AckError"] != ErrorCode.OK:
            raise DriverError(f"CAN bench refused {what}: {ErrorCode(status['AckError']).name}")
        return status

    def tap(self, after: float = 0.01, width: float = 2e-4, peak: float = 1000.0) -> None:
        # not idempotent (a resent command is a second tap): sent once
        self._acknowledged("TAP", "TapCommand", {"After": after, "Width": width, "Peak": peak}, retries=0)

    def enable(self) -> None:
        if self._command("GET_STATUS")["Fault"]:
            self._command("CLEAR_FAULT")
        self._command("ENABLE")

    def disable(self) -> None:
        self._command("DISABLE")

    def set_speed(self, speed: float, acceleration: float | None = None) -> None:
        self._command("SET_SPEED", float(speed), float(acceleration or 0.0))

    def stop(self, acceleration: float | None = None) -> None:
        if acceleration is None:
            self._command("STOP")
        else:
            self.set_speed(0.0, acceleration)

    def state(self) -> MotorState:
        s = self._command("GET_STATUS")
        f = self.frames
        with f.cond:
            counts, t, index = f.counts, f.encoder_time, f.index_count
        return MotorState(device_time=t if t is not None else 0.0, angle=f.angle(), speed=float(s["Speed"]),
                          counts=counts, index_count=index, enabled=bool(s["Enabled"]),
                          fault=fault_name(int(s["Fault"])), host_time=time.time())


class _Bus:
    """Closes the notifier and the bus once, whichever part is closed first."""

    def __init__(self, bus: can.BusABC, notifier: can.Notifier, extra=None):
        self.bus, self.notifier, self.extra, self.closed = bus, notifier, extra, False

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        if self.extra is not None:
            self.extra()
        self.notifier.stop(timeout=2.0)
        self.bus.shutdown()


def check_bus_options(bench: Bench, options: Mapping[str, Any], allowed: set[str], section: str) -> float:
    """The reply timeout (s) of a ``[hardware.SECTION]`` table, refusing options not in ``allowed``."""
    unknown = set(options) - allowed
    if unknown:
        raise ValueError(f"[hardware.{section}]: unknown option(s) {sorted(unknown)}; expected {sorted(allowed)}")
    return float(options.get("reply_timeout", 1.0))


def open_rig(bench: Bench, options: Mapping[str, Any]) -> Rig:
    reply_timeout = check_bus_options(bench, options, BUS_OPTIONS, "can")
    bus = open_bus(options)
    frames, log = BenchFrames.for_bench(bench), frame_log(options)
    notifier = can.Notifier(bus, [frames, *([log] if log else [])], timeout=0.1)
    if log is not None:
        log.attach(bus)
    closer = _Bus(bus, notifier)
    drive, source = CanDrive(bus, frames, reply_timeout), CanSource(bus, frames, bench, reply_timeout, log)
    drive.close = source.close = closer.close  # type: ignore[method-assign]
    try:
        drive.state()
        source.stop()  # a recorder that died may have left the stream running
    except Exception:
        closer.close()
        raise
    return Rig("can", drive, [source], info={"bus": str(bus.channel_info),
                                             "interface": str(options.get("interface", "virtual"))})
