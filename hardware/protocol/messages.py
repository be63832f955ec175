"""Messages of the serial bench protocol: types, error and fault codes, payload codecs.

Every message is a frozen dataclass with ``TYPE`` and ``pack() -> bytes``; :func:`decode` turns a
:class:`~wearbench.hardware.protocol.frames.Frame` into the message (``ProtocolError`` on a payload
that does not match its type). The layouts are specified in ``SERIAL.md``. Imports numpy and
``frames`` only.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field, fields
from enum import IntEnum
from typing import ClassVar

import numpy as np
from wearbench.hardware.protocol.frames import Frame, encode_frame

__all__ = [
    "PROTOCOL_VERSION",
    "AccelData",
    "Ack",
    "ClearFault",
    "ConfigureAccel",
    "Disable",
    "Enable",
    "EncoderData",
    "ErrorCode",
    "Event",
    "FaultCode",
    "GetInfo",
    "GetStatus",
    "Info",
    "Message",
    "MessageType",
    "ProtocolError",
    "SampleFormat",
    "SetProfile",
    "SetSpeed",
    "StartStream",
    "Status",
    "Stop",
    "StopStream",
    "StreamMask",
    "Tap",
    "counts_to_m_s2",
    "decode",
    "encode",
]

PROTOCOL_VERSION = 1


class MessageType(IntEnum):
    """Frame ``type`` byte. 0x01-0x3F host -> device commands, 0x80-0xBF device -> host."""

    GET_INFO = 0x01
    ENABLE = 0x02
    DISABLE = 0x03
    SET_SPEED = 0x04
    SET_PROFILE = 0x05
    STOP = 0x06
    CONFIGURE_ACCEL = 0x07
    START_STREAM = 0x08
    STOP_STREAM = 0x09
    GET_STATUS = 0x0A
    CLEAR_FAULT = 0x0B
    TAP = 0x0C
    ACK = 0x80
    STATUS = 0x81
    INFO = 0x82
    ACCEL_DATA = 0x90
    ENCODER_DATA = 0x91
    EVENT = 0xA0


class ErrorCode(IntEnum):
    """Result of a command, carried by :class:`Ack`."""

    OK = 0
    UNKNOWN_COMMAND = 1
    BAD_LENGTH = 2
    BAD_VALUE = 3          # out of range (speed above max_speed, sample rate not supported, ...)
    NOT_ENABLED = 4        # motion command while the drive is disabled
    FAULT_ACTIVE = 5       # motion command while a fault latches; send CLEAR_FAULT first
    BUSY = 6               # e.g. CONFIGURE_ACCEL while streaming


class FaultCode(IntEnum):
    """Latched device faults and events (:class:`Status`, :class:`Event`)."""

    NONE = 0
    STALL = 1              # motor blocked: speed collapsed while commanded
    OVERSPEED = 2
    OVERRUN = 3            # device-side buffer overflow: blocks dropped
    BUS_OFF = 4            # CAN controller bus-off (CAN transport)
    DISCONNECT = 5         # link going down (sent if the device still can)
    INFO = 0x80            # not a fault: informational event
    TAP = 0x81             # not a fault: a tapper's trigger latched (time: the latch; protocol/taps.py)


class SampleFormat(IntEnum):
    """Sample encoding of :class:`AccelData`."""

    INT16 = 0              # counts, m/s^2 = counts * scale
    INT32 = 1              # counts, m/s^2 = counts * scale
    FLOAT32 = 2            # m/s^2 directly (scale is 1.0)


class StreamMask(IntEnum):
    ACCEL = 1
    ENCODER = 2
    BOTH = 3


class ProtocolError(ValueError):
    """A frame's payload does not match its message type (says type, length and expectation)."""


_NP_FORMAT = {SampleFormat.INT16: "<i2", SampleFormat.INT32: "<i4", SampleFormat.FLOAT32: "<f4"}


def counts_to_m_s2(counts: np.ndarray, scale: float) -> np.ndarray:
    """ADC counts to m/s^2 as float32, the one conversion both the device and the host use.

    ``scale`` is rounded to float32 first (it travels as float32) so both sides get identical bits.
    """
    return (np.asarray(counts, dtype=np.float64) * float(np.float32(scale))).astype(np.float32)


@dataclass(frozen=True)
class Message:
    TYPE: ClassVar[MessageType]
    _FMT: ClassVar[struct.Struct] = struct.Struct("<")

    def pack(self) -> bytes:
        return self._FMT.pack(*(getattr(self, f.name) for f in fields(self)))

    @classmethod
    def unpack(cls, payload: bytes) -> Message:
        if len(payload) != cls._FMT.size:
            raise ProtocolError(f"{cls.TYPE.name}: payload of {len(payload)} bytes, expected {cls._FMT.size}")
        return cls(*cls._FMT.unpack(payload))

    def frame(self, sequence: int) -> bytes:
        return encode_frame(self.TYPE, sequence, self.pack())


# ---- host -> device ---------------------------------------------------------------------------

@dataclass(frozen=True)
class GetInfo(Message):
    TYPE = MessageType.GET_INFO


@dataclass(frozen=True)
class Enable(Message):
    TYPE = MessageType.ENABLE


@dataclass(frozen=True)
class Disable(Message):
    TYPE = MessageType.DISABLE


@dataclass(frozen=True)
class SetSpeed(Message):
    """Ramp the motor to ``speed`` (rad/s) at ``acceleration`` (rad/s^2; 0 = the drive's maximum)."""

    TYPE = MessageType.SET_SPEED
    _FMT = struct.Struct("<ff")
    speed: float
    acceleration: float = 0.0


@dataclass(frozen=True)
class SetProfile(Message):
    """Piecewise speed profile: at ``times[i]`` (s after receipt) ramp to ``speeds[i]`` (rad/s)."""

    TYPE = MessageType.SET_PROFILE
    times: tuple[float, ...]
    speeds: tuple[float, ...]
    acceleration: float = 0.0

    def pack(self) -> bytes:
        if len(self.times) != len(self.speeds):
            raise ValueError("SetProfile: times and speeds differ in length")
        n = len(self.times)
        return struct.pack(f"<fH{2 * n}f", self.acceleration, n,
                           *(v for pair in zip(self.times, self.speeds) for v in pair))

    @classmethod
    def unpack(cls, payload: bytes) -> SetProfile:
        if len(payload) < 6:
            raise ProtocolError(f"SET_PROFILE: payload of {len(payload)} bytes, expected >= 6")
        acc, n = struct.unpack_from("<fH", payload)
        if len(payload) != 6 + 8 * n:
            raise ProtocolError(f"SET_PROFILE: payload of {len(payload)} bytes for {n} points, "
                                f"expected {6 + 8 * n}")
        vals = struct.unpack_from(f"<{2 * n}f", payload, 6)
        return cls(tuple(vals[0::2]), tuple(vals[1::2]), acc)


@dataclass(frozen=True)
class Stop(Message):
    TYPE = MessageType.STOP


@dataclass(frozen=True)
class ConfigureAccel(Message):
    """Accelerometer full-scale ``range`` (m/s^2) and ``sample_rate`` (Hz)."""

    TYPE = MessageType.CONFIGURE_ACCEL
    _FMT = struct.Struct("<ff")
    range: float
    sample_rate: float


@dataclass(frozen=True)
class StartStream(Message):
    TYPE = MessageType.START_STREAM
    _FMT = struct.Struct("<B")
    mask: int = StreamMask.BOTH


@dataclass(frozen=True)
class StopStream(Message):
    TYPE = MessageType.STOP_STREAM


@dataclass(frozen=True)
class GetStatus(Message):
    TYPE = MessageType.GET_STATUS


@dataclass(frozen=True)
class ClearFault(Message):
    TYPE = MessageType.CLEAR_FAULT


# ---- device -> host ---------------------------------------------------------------------------

@dataclass(frozen=True)
class Tap(Message):
    """Fire the tapper ``after`` s from receipt: a half-sine pulse of ``width`` s peaking at ``peak``
    m/s^2 on the slider; its trigger's latch comes back as an EVENT with code TAP."""

    TYPE = MessageType.TAP
    _FMT = struct.Struct("<fff")
    after: float
    width: float
    peak: float


@dataclass(frozen=True)
class Ack(Message):
    """Reply to every command: the command's type and frame sequence, and an :class:`ErrorCode`."""

    TYPE = MessageType.ACK
    _FMT = struct.Struct("<BHB")
    command: int
    command_sequence: int
    error: int = ErrorCode.OK


@dataclass(frozen=True)
class Status(Message):
    """Motor and stream state at device ``time`` (s): crank ``angle`` (rad, unwrapped), ``speed``
    (rad/s), encoder ``counts``, ``index_count``, flags (bit 0 enabled, 1 accel streaming,
    2 encoder streaming), latched ``fault`` (:class:`FaultCode`), accelerometer ``range``/``sample_rate``."""

    TYPE = MessageType.STATUS
    _FMT = struct.Struct("<ddfiIBBff")
    time: float
    angle: float
    speed: float
    counts: int
    index_count: int
    flags: int
    fault: int
    range: float
    sample_rate: float


@dataclass(frozen=True)
class Info(Message):
    """Protocol version, encoder counts per revolution, block sizes, and a free-text device name."""

    TYPE = MessageType.INFO
    protocol: int
    counts_per_rev: int
    accel_block: int
    encoder_block: int
    name: str = ""

    def pack(self) -> bytes:
        return struct.pack("<HIHH", self.protocol, self.counts_per_rev, self.accel_block,
                           self.encoder_block) + self.name.encode()[:200]

    @classmethod
    def unpack(cls, payload: bytes) -> Info:
        if len(payload) < 10:
            raise ProtocolError(f"INFO: payload of {len(payload)} bytes, expected >= 10")
        return cls(*struct.unpack_from("<HIHH", payload), payload[10:].decode("utf-8", "replace"))


@dataclass(frozen=True, eq=False)
class AccelData(Message):
    """A block of accelerometer samples: block ``sequence`` (per stream, u32), device ``time`` (s) of
    the first sample, ``sample_rate`` (Hz, nominal), ``scale`` (m/s^2 per count), ``raw`` samples
    in ``fmt``. ``samples`` gives m/s^2 as float32."""

    TYPE = MessageType.ACCEL_DATA
    sequence: int
    time: float
    sample_rate: float
    scale: float
    fmt: int
    raw: np.ndarray = field(repr=False)
    _HEAD: ClassVar[struct.Struct] = struct.Struct("<IdffBH")

    @property
    def samples(self) -> np.ndarray:
        if self.fmt == SampleFormat.FLOAT32:
            return np.asarray(self.raw, dtype=np.float32)
        return counts_to_m_s2(self.raw, self.scale)

    def pack(self) -> bytes:
        raw = np.asarray(self.raw, dtype=_NP_FORMAT[SampleFormat(self.fmt)])
        return self._HEAD.pack(self.sequence & 0xFFFFFFFF, self.time, self.sample_rate, self.scale,
                               self.fmt, raw.size) + raw.tobytes()

    @classmethod
    def unpack(cls, payload: bytes) -> AccelData:
        h = cls._HEAD.size
        if len(payload) < h:
            raise ProtocolError(f"ACCEL_DATA: payload of {len(payload)} bytes, expected >= {h}")
        seq, t, rate, scale, fmt, n = cls._HEAD.unpack_from(payload)
        if fmt not in _NP_FORMAT:
            raise ProtocolError(f"ACCEL_DATA: sample format {fmt}: expected one of {list(map(int, SampleFormat))}")
        dtype = np.dtype(_NP_FORMAT[SampleFormat(fmt)])
        if len(payload) != h + n * dtype.itemsize:
            raise ProtocolError(f"ACCEL_DATA: payload of {len(payload)} bytes for {n} samples, "
                                f"expected {h + n * dtype.itemsize}")
        return cls(seq, t, rate, scale, fmt, np.frombuffer(payload, dtype, n, h).copy())

    def __eq__(self, other: object) -> bool:
        return (isinstance(other, AccelData) and self.pack() == other.pack())


@dataclass(frozen=True, eq=False)
class EncoderData(Message):
    """A block of encoder samples: block ``sequence``, device ``time`` (s) of the first sample,
    ``sample_rate`` (Hz), ``counts`` (int32) and ``index`` (bool: index pulse since the previous
    sample), the index travelling as a bitmap (bit i of byte i//8)."""

    TYPE = MessageType.ENCODER_DATA
    sequence: int
    time: float
    sample_rate: float
    counts: np.ndarray = field(repr=False)
    index: np.ndarray = field(repr=False)
    _HEAD: ClassVar[struct.Struct] = struct.Struct("<IdfH")

    def pack(self) -> bytes:
        counts = np.asarray(self.counts, dtype="<i4")
        index = np.asarray(self.index, dtype=bool)
        if index.shape != counts.shape:
            raise ValueError("EncoderData: counts and index differ in length")
        return (self._HEAD.pack(self.sequence & 0xFFFFFFFF, self.time, self.sample_rate, counts.size)
                + counts.tobytes() + np.packbits(index, bitorder="little").tobytes())

    @classmethod
    def unpack(cls, payload: bytes) -> EncoderData:
        h = cls._HEAD.size
        if len(payload) < h:
            raise ProtocolError(f"ENCODER_DATA: payload of {len(payload)} bytes, expected >= {h}")
        seq, t, rate, n = cls._HEAD.unpack_from(payload)
        size = h + 4 * n + (n + 7) // 8
        if len(payload) != size:
            raise ProtocolError(f"ENCODER_DATA: payload of {len(payload)} bytes for {n} samples, expected {size}")
        counts = np.frombuffer(payload, "<i4", n, h).astype(np.int32)
        bits = np.frombuffer(payload, np.uint8, (n + 7) // 8, h + 4 * n)
        index = np.unpackbits(bits, count=n, bitorder="little").astype(bool)
        return cls(seq, t, rate, counts, index)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, EncoderData) and self.pack() == other.pack()


@dataclass(frozen=True)
class Event(Message):
    """A fault or event at device ``time`` (s): ``code`` (:class:`FaultCode`) and a message."""

    TYPE = MessageType.EVENT
    time: float
    code: int
    message: str = ""

    def pack(self) -> bytes:
        return struct.pack("<dB", self.time, self.code) + self.message.encode()[:1000]

    @classmethod
    def unpack(cls, payload: bytes) -> Event:
        if len(payload) < 9:
            raise ProtocolError(f"EVENT: payload of {len(payload)} bytes, expected >= 9")
        t, code = struct.unpack_from("<dB", payload)
        return cls(t, code, payload[9:].decode("utf-8", "replace"))


_BY_TYPE: dict[int, type[Message]] = {
    cls.TYPE: cls for cls in (GetInfo, Enable, Disable, SetSpeed, SetProfile, Stop, ConfigureAccel,
                              StartStream, StopStream, GetStatus, ClearFault, Tap, Ack, Status, Info,
                              AccelData, EncoderData, Event)
}


def decode(frame: Frame) -> Message:
    """The message a frame carries; ``ProtocolError`` for an unknown type or a malformed payload."""
    cls = _BY_TYPE.get(frame.type)
    if cls is None:
        raise ProtocolError(f"unknown message type 0x{frame.type:02X}")
    try:
        return cls.unpack(frame.payload)
    except (struct.error, ValueError) as exc:
        if isinstance(exc, ProtocolError):
            raise
        raise ProtocolError(f"{cls.TYPE.name}: {exc}") from None


def encode(message: Message, sequence: int) -> bytes:
    """The frame bytes of ``message`` with frame ``sequence``."""
    return message.frame(sequence)
