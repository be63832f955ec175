"""Record a session from a bench into an MCAP file and compare it with what the bench sent.

:func:`record` runs the wearbench recorder on a rig and returns a :class:`RecordedSession` (the
file, the recorder's result, the read session). What a device sent is kept as
``{stream: {sequence: (device time, sample rate, samples, index or None)}}`` (:data:`Sent`), taken
from the serial emulator's byte log (:func:`sent_from_serial_log`), the CAN emulator's blocks
(:func:`sent_from_blocks`) or an in-process device (:func:`sent_from_device`);
:func:`assert_same_blocks` compares a file with it block for block. Imports the acquisition layer
and the serial protocol.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from wearbench.acquisition.drivers import ACCELERATION, ENCODER, Rig
from wearbench.acquisition.recorder import Recorder
from wearbench.acquisition.session import SessionPlan, SessionResult
from wearbench.acquisition.session_file import Session, blocks, read_session, scan_mcap
from wearbench.bench.schema import Bench
from wearbench.hardware.protocol import messages
from wearbench.hardware.protocol.frames import FrameParser

__all__ = ["STREAMS", "RecordedSession", "Sent", "assert_same_blocks", "record", "recorded_blocks",
           "sent_from_blocks", "sent_from_device", "sent_from_serial_log"]

STREAMS = (ACCELERATION, ENCODER)
Sent = dict[str, dict[int, tuple]]


@dataclass
class RecordedSession:
    """A recorded session: ``path`` of the MCAP file, the recorder's ``result`` (why it ended, blocks,
    drops) and the ``session`` read back (:func:`wearbench.acquisition.session_file.read_session`)."""

    path: Path
    result: SessionResult
    session: Session

    @property
    def completed(self) -> bool:
        return self.result.completed

    @property
    def reason(self) -> str:
        return self.result.reason


def record(rig: Rig, bench: Bench, plan: SessionPlan, out: str | Path, *, close: bool = True,
           **recorder: Any) -> RecordedSession:
    """Record ``plan`` from ``rig`` into ``out`` (closing the rig after, unless ``close`` is false)
    and read the file back. A Ctrl-C during the session finishes the file and is raised again as
    ``KeyboardInterrupt`` after it (the recorder turns SIGINT into a clean stop)."""
    try:
        result = Recorder(rig, bench, plan, out, **recorder).run()
    finally:
        if close:
            rig.close()
    if result.reason.startswith("interrupted (SIGINT)"):
        raise KeyboardInterrupt(f"session {out} interrupted; the file was finished")
    return RecordedSession(Path(out), result, read_session(out))


def recorded_blocks(path: str | Path) -> dict[str, dict[int, Any]]:
    """Blocks of a session file by stream and sequence (a repeated sequence keeps the first)."""
    scan = scan_mcap(path)
    out: dict[str, dict[int, Any]] = {ACCELERATION: {}, ENCODER: {}}
    for stream in STREAMS:
        for b in blocks(scan, stream):
            out[stream].setdefault(b.sequence, b)
    return out


def assert_same_blocks(path: str | Path, sent: Sent, *, min_blocks: int = 10) -> dict[str, int]:
    """Every recorded block equals the sent block of the same sequence (device time, rate, samples,
    index), and between the first and last recorded block every sent block was recorded.
    Returns the blocks recorded per stream."""
    rec = recorded_blocks(path)
    counts = {}
    for stream in STREAMS:
        got = rec[stream]
        assert len(got) >= min_blocks, f"{path}: {stream}: only {len(got)} blocks recorded"
        first, last = min(got), max(got)
        expected = [s for s in sent[stream] if first <= s <= last]
        missing = sorted(set(expected) - set(got))
        assert not missing, f"{path}: {stream}: blocks sent and not recorded: {missing[:10]}"
        extra = sorted(set(got) - set(sent[stream]))
        assert not extra, f"{path}: {stream}: blocks recorded that were never sent: {extra[:10]}"
        for seq, b in got.items():
            t, rate, samples, index = sent[stream][seq]
            assert abs(b.device_time - t) <= 1e-9, f"{path}: {stream} block {seq}: device time {b.device_time} != {t}"
            assert abs(b.sample_rate - rate) <= 1e-6 * rate, f"{path}: {stream} block {seq}: sample rate"
            assert b.samples.dtype == np.asarray(samples).dtype, f"{path}: {stream} block {seq}: sample type"
            np.testing.assert_array_equal(b.samples, samples, err_msg=f"{path}: {stream} block {seq}")
            if index is not None:
                np.testing.assert_array_equal(b.index, index, err_msg=f"{path}: {stream} block {seq}: index")
        counts[stream] = len(got)
    return counts


def sent_from_blocks(sent_blocks: Iterable[Any]) -> Sent:
    """:data:`Sent` from device blocks (``AccelBlock``/``EncoderBlock``, e.g. ``CanEmulator.sent``)."""
    sent: Sent = {ACCELERATION: {}, ENCODER: {}}
    for b in sent_blocks:
        if hasattr(b, "counts"):
            sent[ENCODER][b.sequence] = (b.time, b.sample_rate, b.counts, b.index)
        else:
            sent[ACCELERATION][b.sequence] = (b.time, b.sample_rate, b.samples, None)
    return sent


def sent_from_device(device: Any) -> Sent:
    """Wrap an in-process device's ``read`` to log every block it hands out; returns the log."""
    sent: Sent = {ACCELERATION: {}, ENCODER: {}}
    read = device.read

    def logged():
        got = read()
        for stream, table in sent_from_blocks(got).items():
            sent[stream].update(table)
        return got

    device.read = logged
    return sent


def sent_from_serial_log(path: str | Path) -> Sent:
    """:data:`Sent` from the bytes a serial emulator wrote (its ``sent_log``)."""
    parser = FrameParser()
    sent: Sent = {ACCELERATION: {}, ENCODER: {}}
    for frame in parser.feed(Path(path).read_bytes()):
        try:
            msg = messages.decode(frame)
        except messages.ProtocolError:
            continue
        if isinstance(msg, messages.AccelData):
            sent[ACCELERATION][msg.sequence] = (msg.time, msg.sample_rate, msg.samples, None)
        elif isinstance(msg, messages.EncoderData):
            sent[ENCODER][msg.sequence] = (msg.time, msg.sample_rate, msg.counts, msg.index)
    return sent
