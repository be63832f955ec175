"""Serial framing of the bench protocol: frame layout, CRCs, and the streaming parser.

A frame on the wire (all integers little-endian; see ``SERIAL.md`` beside this file)::

    offset  size  field
    0       2     sync       0xA5 0x5A
    2       2     length     payload length N, 0 <= N <= MAX_PAYLOAD
    4       1     type       message type (messages.MessageType)
    5       2     sequence   per-direction frame counter, wraps at 65536
    7       1     hcheck     CRC-8 (poly 0x07, init 0) of bytes 2..6
    8       N     payload
    8+N     2     crc        CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) of bytes 2..8+N-1

The header check lets the parser reject a false sync at once instead of waiting for a bogus
length's worth of bytes. This module imports only the standard library.
"""

from __future__ import annotations

import binascii
import struct
from dataclasses import dataclass, field

__all__ = [
    "HEADER_SIZE",
    "MAX_PAYLOAD",
    "SYNC",
    "Frame",
    "FrameParser",
    "ParserStats",
    "crc8",
    "crc16",
    "encode_frame",
]

SYNC = b"\xa5\x5a"
HEADER_SIZE = 8
TRAILER_SIZE = 2
MAX_PAYLOAD = 4096
_HEADER = struct.Struct("<2sHBHB")


def _crc8_table() -> bytes:
    table = bytearray(256)
    for i in range(256):
        c = i
        for _ in range(8):
            c = ((c << 1) ^ 0x07) & 0xFF if c & 0x80 else (c << 1) & 0xFF
        table[i] = c
    return bytes(table)


_CRC8 = _crc8_table()


def crc8(data: bytes) -> int:
    """CRC-8 (poly 0x07, init 0x00, no reflection; check value of b"123456789" is 0xF4)."""
    c = 0
    for b in data:
        c = _CRC8[c ^ b]
    return c


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF; check value of b"123456789" is 0x29B1)."""
    return binascii.crc_hqx(data, 0xFFFF)


@dataclass(frozen=True)
class Frame:
    """One decoded frame: message ``type``, frame ``sequence`` and raw ``payload``."""

    type: int
    sequence: int
    payload: bytes


def encode_frame(type_: int, sequence: int, payload: bytes = b"") -> bytes:
    """The bytes of one frame (``sequence`` is taken modulo 65536)."""
    if not 0 <= type_ <= 0xFF:
        raise ValueError(f"frame type {type_!r}: expected 0..255")
    if len(payload) > MAX_PAYLOAD:
        raise ValueError(f"payload of {len(payload)} bytes: expected at most {MAX_PAYLOAD}")
    head = struct.pack("<HBH", len(payload), type_, sequence & 0xFFFF)
    body = head + bytes([crc8(head)]) + payload
    return SYNC + body + struct.pack("<H", crc16(body))


@dataclass
class ParserStats:
    """What the parser has seen: good frames, rejected headers, CRC failures, bytes thrown away."""

    frames: int = 0
    header_errors: int = 0
    crc_errors: int = 0
    bytes_skipped: int = 0
    bytes_in: int = 0

    def to_dict(self) -> dict[str, int]:
        return dict(self.__dict__)


@dataclass
class FrameParser:
    """Streaming frame parser: ``feed(bytes) -> [Frame]``.

    Never raises on input, never loops without consuming: on a bad header or CRC it skips one byte
    past the sync it tried and searches again, so valid frames after garbage are all recovered.
    Memory is bounded by one maximal frame. Call :meth:`flush` at the end of a stream: it gives up
    on a half-received frame (a false sync whose length ran past the end) and rescans what follows.
    """

    stats: ParserStats = field(default_factory=ParserStats)
    _buf: bytearray = field(default_factory=bytearray, repr=False)

    def feed(self, data: bytes) -> list[Frame]:
        self.stats.bytes_in += len(data)
        self._buf += data
        return self._scan(final=False)

    def flush(self) -> list[Frame]:
        """End of stream: recover frames hidden behind an incomplete false frame; drop the rest."""
        frames = self._scan(final=True)
        self.stats.bytes_skipped += len(self._buf)
        self._buf.clear()
        return frames

    @property
    def pending(self) -> int:
        """Bytes held waiting for the rest of a frame."""
        return len(self._buf)

    def _skip(self, n: int) -> None:
        del self._buf[:n]
        self.stats.bytes_skipped += n

    def _scan(self, final: bool) -> list[Frame]:
        out: list[Frame] = []
        buf = self._buf
        while True:
            start = buf.find(SYNC)
            if start < 0:
                # keep a trailing first sync byte, it may start the next frame
                keep = 1 if buf[-1:] == SYNC[:1] and not final else 0
                self._skip(len(buf) - keep)
                return out
            if start:
                self._skip(start)
            if len(buf) < HEADER_SIZE:
                if final:
                    self._skip(1)
                    continue
                return out
            _, length, type_, seq, check = _HEADER.unpack_from(buf, 0)
            if length > MAX_PAYLOAD or crc8(bytes(buf[2:7])) != check:
                self.stats.header_errors += 1
                self._skip(1)
                continue
            total = HEADER_SIZE + length + TRAILER_SIZE
            if len(buf) < total:
                if final:
                    self.stats.crc_errors += 1
                    self._skip(1)
                    continue
                return out
            (crc,) = struct.unpack_from("<H", buf, HEADER_SIZE + length)
            if crc16(bytes(buf[2:HEADER_SIZE + length])) != crc:
                self.stats.crc_errors += 1
                self._skip(1)
                continue
            out.append(Frame(type_, seq, bytes(buf[HEADER_SIZE:HEADER_SIZE + length])))
            del buf[:total]
            self.stats.frames += 1
