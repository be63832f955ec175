"""Fixtures for the acquisition tests: the test-bed bench, emulator configs, and the block-for-block
comparison of a session file with what an emulator sent."""

from __future__ import annotations

import numpy as np
import pytest
from wearbench.acquisition.drivers import ACCELERATION, ENCODER
from wearbench.acquisition.session_file import blocks, scan_mcap
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.hardware.protocol import messages
from wearbench.hardware.protocol.frames import FrameParser

FAST = 62.0  # rad/s: 20 cycles in about 2 s (the motor's limit is 600 rpm)
HARMONIC = {"signal": "harmonic", "cache": False}


@pytest.fixture(scope="session")
def bench():
    return load_bench(shipped_bench("ninebar-testbed"))


def recorded_blocks(path) -> dict[str, dict[int, object]]:
    """Blocks of a session file by stream and sequence (a repeated sequence keeps the first)."""
    scan = scan_mcap(path)
    out: dict[str, dict[int, object]] = {ACCELERATION: {}, ENCODER: {}}
    for stream in (ACCELERATION, ENCODER):
        for b in blocks(scan, stream):
            out[stream].setdefault(b.sequence, b)
    return out


def assert_same_blocks(path, sent: dict[str, dict[int, tuple]], *, min_blocks: int = 10) -> dict[str, int]:
    """Every recorded block equals the sent block of the same sequence (device time, rate, samples,
    index), and between the first and last recorded block every sent block was recorded.

    ``sent[stream][sequence] = (time, sample_rate, samples, index or None)``. Returns blocks per stream.
    """
    rec = recorded_blocks(path)
    counts = {}
    for stream in (ACCELERATION, ENCODER):
        blocks = rec[stream]
        assert len(blocks) >= min_blocks, f"{stream}: only {len(blocks)} blocks recorded"
        first, last = min(blocks), max(blocks)
        expected = [s for s in sent[stream] if first <= s <= last]
        assert sorted(blocks) == expected, f"{stream}: recorded sequences differ from those sent"
        for seq, b in blocks.items():
            t, rate, samples, index = sent[stream][seq]
            assert b.device_time == pytest.approx(t, abs=1e-9), f"{stream} block {seq}: device time"
            assert b.sample_rate == pytest.approx(rate, rel=1e-6)
            assert b.samples.dtype == np.asarray(samples).dtype
            np.testing.assert_array_equal(b.samples, samples, err_msg=f"{stream} block {seq}")
            if index is not None:
                np.testing.assert_array_equal(b.index, index)
        counts[stream] = len(blocks)
    return counts


def sent_from_device(device) -> dict:
    """Wrap ``device.read`` to log every block it hands out."""
    sent = {ACCELERATION: {}, ENCODER: {}}
    read = device.read

    def logged():
        blocks = read()
        for b in blocks:
            if hasattr(b, "counts"):
                sent[ENCODER][b.sequence] = (b.time, b.sample_rate, b.counts, b.index)
            else:
                sent[ACCELERATION][b.sequence] = (b.time, b.sample_rate, b.samples, None)
        return blocks

    device.read = logged
    return sent


def sent_from_serial_log(path) -> dict:
    parser = FrameParser()
    sent = {ACCELERATION: {}, ENCODER: {}}
    for frame in parser.feed(path.read_bytes()):
        msg = messages.decode(frame)
        if isinstance(msg, messages.AccelData):
            sent[ACCELERATION][msg.sequence] = (msg.time, msg.sample_rate, msg.samples, None)
        elif isinstance(msg, messages.EncoderData):
            sent[ENCODER][msg.sequence] = (msg.time, msg.sample_rate, msg.counts, msg.index)
    return sent


def sent_from_can(emulator) -> dict:
    sent = {ACCELERATION: {}, ENCODER: {}}
    for b in emulator.sent:
        if hasattr(b, "counts"):
            sent[ENCODER][b.sequence] = (b.time, b.sample_rate, b.counts, b.index)
        else:
            sent[ACCELERATION][b.sequence] = (b.time, b.sample_rate, b.samples, None)
    return sent
