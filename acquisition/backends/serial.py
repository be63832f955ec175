"""The ``serial`` backend: an MCU that streams the accelerometer and commands the drive over one
serial port (pyserial), speaking the framed protocol of ``wearbench.hardware.protocol``.

One :class:`SerialLink` owns the port. Whoever needs bytes (the recorder's reader thread, or a
command waiting for its ACK) pumps the port under a lock and routes every frame: replies to the
waiting command, data blocks and device events to the source. Options (``[hardware.serial]``):
``port`` (required; any pyserial URL), ``baudrate`` (default 921600), ``reply_timeout`` (s,
default 1.0), ``retries`` (commands sent again when no ACK comes, default 2). Imports pyserial and the protocol codec only.
"""

from __future__ import annotations

import collections
import threading
import time
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import serial
from wearbench.acquisition.backends import fault_name
from wearbench.acquisition.drivers import (
    ACCELERATION,
    ENCODER,
    AccelerationSource,
    Block,
    DeviceDisconnected,
    DeviceTimeout,
    DriverError,
    Event,
    MotorDrive,
    MotorState,
    Rig,
    StreamInfo,
)
from wearbench.bench.schema import Bench
from wearbench.hardware.protocol import messages as m
from wearbench.hardware.protocol.frames import FrameParser

__all__ = ["SerialDrive", "SerialLink", "SerialSource", "open_rig"]


class SerialLink:
    """The port, the frame parser and the routing of received messages."""

    def __init__(self, port: str, baudrate: int = 921600, reply_timeout: float = 1.0, retries: int = 2):
        try:
            self.ser = serial.serial_for_url(port, baudrate=baudrate, timeout=0.02)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise DeviceDisconnected(f"cannot open serial port {port!r}: {exc}") from None
        self.port, self.reply_timeout, self.retries = port, reply_timeout, retries
        self.parser = FrameParser()
        self._rx = threading.Lock()  # one thread reads the port at a time
        self._tx = threading.Lock()
        self._cond = threading.Condition()
        self._tx_seq = 0
        self._acks: dict[int, m.Ack] = {}
        self._status: m.Status | None = None
        self._status_count = 0
        self._info: m.Info | None = None
        self.inbox: collections.deque = collections.deque()  # AccelData, EncoderData, Event
        self._errors = (0, 0, 0)  # parser header/CRC errors and bytes skipped already reported
        self.closed = False
        self.dead: str | None = None

    # ---- receiving ---------------------------------------------------------------------------

    def pump(self, timeout: float) -> None:
        """Read what the port has (waiting at most about ``timeout`` s) and route the frames."""
        if self.dead:
            raise DeviceDisconnected(self.dead)
        if not self._rx.acquire(timeout=timeout):
            return
        try:
            try:
                self.ser.timeout = max(0.0, timeout)
                data = self.ser.read(max(1, self.ser.in_waiting))
            except (serial.SerialException, OSError, TypeError, AttributeError) as exc:
                self.dead = f"serial port {self.port}: {exc}"
                raise DeviceDisconnected(self.dead) from None
            frames = self.parser.feed(data) if data else []
            with self._cond:
                for frame in frames:
                    self._route(frame)
                s = self.parser.stats
                if (s.header_errors, s.crc_errors, s.bytes_skipped) != self._errors:  # line noise counts too
                    dh, dc = s.header_errors - self._errors[0], s.crc_errors - self._errors[1]
                    ds = s.bytes_skipped - self._errors[2]
                    self._errors = (s.header_errors, s.crc_errors, s.bytes_skipped)
                    self.inbox.append(Event("malformed", f"serial: {dh} bad header(s), {dc} CRC error(s), "
                                            f"{ds} bytes skipped; {s.bytes_skipped} bytes skipped so far"))
                self._cond.notify_all()
        finally:
            self._rx.release()

    def _route(self, frame) -> None:
        try:
            msg = m.decode(frame)
        except m.ProtocolError as exc:
            self.inbox.append(Event("malformed", f"serial: {exc}"))
            return
        if isinstance(msg, m.Ack):
            self._acks[msg.command_sequence] = msg
        elif isinstance(msg, m.Status):
            self._status, self._status_count = msg, self._status_count + 1
        elif isinstance(msg, m.Info):
            self._info = msg
        elif isinstance(msg, (m.AccelData, m.EncoderData, m.Event)):
            self.inbox.append(msg)

    def wait_for(self, predicate: Callable[[], Any], timeout: float, what: str) -> Any:
        """Pump until ``predicate()`` is not None; DeviceTimeout after ``timeout`` s."""
        end = time.monotonic() + timeout
        while True:
            with self._cond:
                value = predicate()
                if value is not None:
                    return value
            left = end - time.monotonic()
            if left <= 0:
                raise DeviceTimeout(f"serial port {self.port}: no {what} within {timeout:g} s")
            if self._rx.locked():
                with self._cond:
                    self._cond.wait(min(left, 0.02))
            else:
                self.pump(min(left, 0.02))

    # ---- commands ----------------------------------------------------------------------------

    def command(self, msg: m.Message) -> m.Ack:
        """Send ``msg`` and wait for its ACK, sending it again (``retries`` times) when no ACK comes
        (a reply lost to a corrupted frame); DriverError when the device refuses it.

        Every command of the protocol is idempotent, so a repeat is harmless.
        """
        for attempt in range(self.retries + 1):
            if self.dead:
                raise DeviceDisconnected(self.dead)
            with self._tx:
                seq = self._tx_seq
                self._tx_seq = (self._tx_seq + 1) & 0xFFFF
                try:
                    self.ser.write(msg.frame(seq))
                except (serial.SerialException, OSError) as exc:
                    self.dead = f"serial port {self.port}: {exc}"
                    raise DeviceDisconnected(self.dead) from None
            try:
                ack = self.wait_for(lambda seq=seq: self._acks.pop(seq, None), self.reply_timeout,
                                    f"ACK to {msg.TYPE.name}")
                break
            except DeviceTimeout:
                if attempt == self.retries:
                    raise
                self.inbox.append(Event("retry", f"serial: no ACK to {msg.TYPE.name} within "
                                        f"{self.reply_timeout:g} s; sending it again"))
        if ack.error != m.ErrorCode.OK:
            raise DriverError(f"serial device refused {msg.TYPE.name}: {m.ErrorCode(ack.error).name}")
        return ack

    def status(self) -> m.Status:
        """The device's STATUS. It comes before its ACK, so it is there when the ACK is; a lost or late
        STATUS is asked for again, as often as a command is sent again (``retries``)."""
        count = self._status_count

        def arrived() -> m.Status | None:
            return self._status if self._status_count > count else None

        wait = 0.0
        for _ in range(self.retries):
            self.command(m.GetStatus())
            try:
                return self.wait_for(arrived, wait, "STATUS")
            except DeviceTimeout:
                self.inbox.append(Event("retry", "serial: no STATUS before its ACK; asking again"))
            wait = self.reply_timeout
        self.command(m.GetStatus())
        return self.wait_for(arrived, wait, "STATUS")

    def info(self) -> m.Info:
        self._info = None
        self.command(m.GetInfo())
        return self.wait_for(lambda: self._info, self.reply_timeout, "INFO")

    def close(self) -> None:
        if not self.closed:
            self.closed = True
            try:
                self.ser.close()
            except (serial.SerialException, OSError):
                pass  # a port that is already gone is closed


class SerialDrive(MotorDrive):
    name = "serial-drive"

    def __init__(self, link: SerialLink):
        self.link = link

    def enable(self) -> None:
        s = self.link.status()
        if s.fault:
            self.link.command(m.ClearFault())
        self.link.command(m.Enable())

    def disable(self) -> None:
        self.link.command(m.Disable())

    def set_speed(self, speed: float, acceleration: float | None = None) -> None:
        self.link.command(m.SetSpeed(float(speed), float(acceleration or 0.0)))

    def stop(self, acceleration: float | None = None) -> None:
        if acceleration is None:
            self.link.command(m.Stop())
        else:
            self.set_speed(0.0, acceleration)

    def tap(self, after: float = 0.01, width: float = 2e-4, peak: float = 1000.0) -> None:
        self.link.command(m.Tap(float(after), float(width), float(peak)))

    def set_profile(self, times: list[float], speeds: list[float], acceleration: float | None = None) -> None:
        self.link.command(m.SetProfile(tuple(times), tuple(speeds), float(acceleration or 0.0)))

    def state(self) -> MotorState:
        s = self.link.status()
        return MotorState(device_time=s.time, angle=s.angle, speed=s.speed, counts=s.counts,
                          index_count=s.index_count, enabled=bool(s.flags & 1), fault=fault_name(s.fault),
                          host_time=time.time())


class SerialSource(AccelerationSource):
    name = "serial-daq"

    def __init__(self, link: SerialLink, bench: Bench, info: m.Info):
        self.link, self.info = link, info
        acc, self._enc = bench.sensor("accelerometer"), bench.sensor("encoder")
        self._range, self._rate = acc.range, acc.sample_rate

    def configure(self, range_m_s2: float, sample_rate: float) -> None:
        self.link.command(m.ConfigureAccel(float(range_m_s2), float(sample_rate)))
        self._range, self._rate = range_m_s2, sample_rate

    def describe(self) -> tuple[StreamInfo, ...]:
        src = f"{self.info.name or 'serial device'} on {self.link.port}"
        return (StreamInfo(ACCELERATION, "m/s^2", self._rate, "float32", source=src,
                           extra={"block": str(self.info.accel_block)}, range=self._range),
                StreamInfo(ENCODER, "counts", self._enc.sample_rate, "int32", source=src,
                           extra={"counts_per_rev": str(self.info.counts_per_rev),
                                  "block": str(self.info.encoder_block)}))

    def start(self) -> None:
        self.link.command(m.StartStream(m.StreamMask.BOTH))

    def stop(self) -> None:
        self.link.command(m.StopStream())

    def read(self, timeout: float) -> list[Block | Event]:
        link = self.link
        if not link.inbox:
            try:
                link.pump(timeout)
            except DeviceDisconnected:
                if not link.inbox:
                    raise  # after what was received before the link died has been delivered
        out: list[Block | Event] = []
        now = time.time()
        while link.inbox:
            msg = link.inbox.popleft()
            if isinstance(msg, m.AccelData):
                out.append(Block(ACCELERATION, msg.sequence, msg.time, msg.sample_rate, msg.samples, now))
            elif isinstance(msg, m.EncoderData):
                out.append(Block(ENCODER, msg.sequence, msg.time, msg.sample_rate,
                                 np.asarray(msg.counts, dtype=np.int32), now, np.asarray(msg.index, dtype=bool)))
            elif isinstance(msg, m.Event):
                kind = fault_name(msg.code) or "event"
                out.append(Event(kind, f"device: {msg.message or kind}", now, msg.time))
            else:
                out.append(msg)  # already an Event (malformed frames)
        return out

    def close(self) -> None:
        self.link.close()


def open_rig(bench: Bench, options: Mapping[str, Any]) -> Rig:
    unknown = set(options) - {"port", "baudrate", "reply_timeout", "retries"}
    if unknown:
        raise ValueError(f"[hardware.serial]: unknown option(s) {sorted(unknown)}; "
                         "expected port, baudrate, reply_timeout, retries")
    if "port" not in options:
        raise ValueError(f"{bench.path or bench.name}: [hardware.serial] port is missing; "
                         "give it in the bench file or with --option port=/dev/ttyACM0")
    link = SerialLink(str(options["port"]), int(options.get("baudrate", 921600)),
                      float(options.get("reply_timeout", 1.0)), int(options.get("retries", 2)))
    try:
        info = link.info()
        if info.protocol == m.PROTOCOL_VERSION:  # a recorder that died may have left it streaming
            link.command(m.StopStream())
            link.inbox.clear()
    except Exception:
        link.close()
        raise
    if info.protocol != m.PROTOCOL_VERSION:
        link.close()
        raise DriverError(f"serial device on {link.port} speaks protocol {info.protocol}, "
                          f"expected {m.PROTOCOL_VERSION}")
    return Rig("serial", SerialDrive(link), [SerialSource(link, bench, info)],
               info={"port": link.port, "device": info.name, "protocol": str(info.protocol),
                     "counts_per_rev": str(info.counts_per_rev)})
