"""CAN side of the bench protocol: the DBC and EDS files, frame ids, and block <-> frame codecs.

Signals are packed and unpacked by cantools from ``wearbench.dbc`` (no hand-written bit fields);
the CiA 402 drive's object dictionary is ``cia402_drive.eds``. One CAN FD frame carries one block:
up to 24 accelerometer samples (int16 counts, LSB = range/32768) or 12 encoder samples. See
``CAN.md``. Imports cantools, python-can, numpy and ``blocks``.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import can
import cantools
import numpy as np
from wearbench.hardware.protocol.blocks import AccelBlock, EncoderBlock
from wearbench.hardware.protocol.messages import counts_to_m_s2

__all__ = [
    "ACCEL_PER_FRAME",
    "COUNTS_FULL_SCALE",
    "DBC_PATH",
    "EDS_PATH",
    "ENCODER_PER_FRAME",
    "accel_frame",
    "accel_lsb",
    "decode_accel_frame",
    "decode_encoder_frame",
    "decode_frame",
    "encode_frame",
    "encoder_frame",
    "load_dbc",
    "to_counts",
]

DBC_PATH = Path(__file__).with_name("wearbench.dbc")
EDS_PATH = Path(__file__).with_name("cia402_drive.eds")
ACCEL_PER_FRAME = 24
ENCODER_PER_FRAME = 12
COUNTS_FULL_SCALE = 32768  # int16 counts per full-scale range


@lru_cache(maxsize=1)
def load_dbc() -> cantools.database.can.Database:
    """The bench DBC (cached)."""
    return cantools.database.load_file(DBC_PATH)


def accel_lsb(range_m_s2: float) -> float:
    """m/s^2 per int16 count for full scale ``range_m_s2`` (the range as the StreamStatus frame says)."""
    return float(range_m_s2) / COUNTS_FULL_SCALE


def to_counts(samples: np.ndarray, lsb: float) -> np.ndarray:
    """Nearest int16 counts of ``samples`` (m/s^2), saturating at the int16 limits."""
    c = np.rint(np.asarray(samples, dtype=np.float64) / float(np.float32(lsb)))
    return np.clip(c, -32768, 32767).astype(np.int16)


def encode_frame(name: str, values: dict, *, fd: bool = False) -> can.Message:
    """A python-can message for DBC message ``name`` with signal ``values`` (physical units)."""
    msg = load_dbc().get_message_by_name(name)
    return can.Message(arbitration_id=msg.frame_id, data=msg.encode(values, padding=True),
                       is_extended_id=False, is_fd=msg.is_fd, bitrate_switch=msg.is_fd)


def decode_frame(message: can.Message) -> tuple[str, dict] | None:
    """(DBC message name, signal values) of a received frame, or None if the id is not in the DBC.

    Enumerated signals come back as plain numbers (no choice names).
    """
    try:
        msg = load_dbc().get_message_by_frame_id(message.arbitration_id)
    except KeyError:
        return None
    return msg.name, msg.decode(bytes(message.data), decode_choices=False)


def accel_frame(block: AccelBlock, lsb: float) -> can.Message:
    """The AccelBlock CAN FD frame of a block of at most 24 samples."""
    n = len(block.samples)
    if n > ACCEL_PER_FRAME:
        raise ValueError(f"accelerometer block of {n} samples: at most {ACCEL_PER_FRAME} fit one frame")
    counts = np.zeros(ACCEL_PER_FRAME, dtype=np.int64)
    counts[:n] = to_counts(block.samples, lsb)
    values = {"Sequence": block.sequence & 0xFFFFFFFF, "TimeNs": max(0, round(block.time * 1e9)), "Count": n}
    values.update({f"Sample{i:02d}": int(c) for i, c in enumerate(counts)})
    return encode_frame("AccelBlock", values)


def decode_accel_frame(values: dict, lsb: float, sample_rate: float) -> AccelBlock:
    """An :class:`AccelBlock` from decoded AccelBlock signals (see :func:`decode_frame`)."""
    n = min(int(values["Count"]), ACCEL_PER_FRAME)
    counts = np.array([values[f"Sample{i:02d}"] for i in range(n)], dtype=np.int64)
    return AccelBlock(int(values["Sequence"]), values["TimeNs"] / 1e9, float(sample_rate),
                      counts_to_m_s2(counts, lsb))


def encoder_frame(block: EncoderBlock) -> can.Message:
    """The EncoderBlock CAN FD frame of a block of at most 12 samples."""
    n = len(block.counts)
    if n > ENCODER_PER_FRAME:
        raise ValueError(f"encoder block of {n} samples: at most {ENCODER_PER_FRAME} fit one frame")
    bits = int(np.sum(np.asarray(block.index, dtype=np.int64) << np.arange(n)))
    values = {"Sequence": block.sequence & 0xFFFFFFFF, "TimeNs": max(0, round(block.time * 1e9)),
              "Count": n, "IndexBits": bits}
    values.update({f"Counts{i:02d}": int(block.counts[i]) if i < n else 0 for i in range(ENCODER_PER_FRAME)})
    return encode_frame("EncoderBlock", values)


def decode_encoder_frame(values: dict, sample_rate: float) -> EncoderBlock:
    """An :class:`EncoderBlock` from decoded EncoderBlock signals."""
    n = min(int(values["Count"]), ENCODER_PER_FRAME)
    counts = np.array([values[f"Counts{i:02d}"] for i in range(n)], dtype=np.int32)
    index = (int(values["IndexBits"]) >> np.arange(n)) & 1 == 1
    return EncoderBlock(int(values["Sequence"]), values["TimeNs"] / 1e9, float(sample_rate), counts, index)
