"""Every way a session can end early leaves a valid, readable MCAP that says why: Ctrl-C and
SIGKILL on a real `wearbench record` process, a disconnecting device, a silent device, malformed
frames, a stalled motor, a full disk, an exception in a reader or in the writer; and dropped or
repeated blocks are counted exactly."""

from __future__ import annotations

import errno
import io
import json
import math
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from wearbench.acquisition.backends import open_rig
from wearbench.acquisition.drivers import ACCELERATION, ENCODER
from wearbench.acquisition.recorder import Recorder
from wearbench.acquisition.session import SessionPlan
from wearbench.acquisition.session_file import read_session, scan_mcap
from wearbench.acquisition.session_writer import SessionWriter
from wearbench.testing import FaultPlan

from .conftest import (
    FAST,
    HARMONIC,
    assert_same_blocks,
    recorded_blocks,
    sent_from_device,
)


def _sim(bench, config=None, **plan):
    rig = open_rig(bench, "sim", {"speedup": math.inf, "config": {**HARMONIC, **(config or {})}})
    return rig, sent_from_device(rig.drive.device), SessionPlan(**{"speed": FAST, "cycles": 20, **plan})


def _run(rig, bench, plan, out, **kwargs):
    try:
        return Recorder(rig, bench, plan, out, **kwargs).run()
    finally:
        rig.close()


def _assert_stopped(path, reason: str):
    """The file is finished, readable, and its events and result record say why it stopped."""
    s = read_session(path)
    assert s.finished, s.problem
    assert reason in s.metadata["result"]["reason"]
    assert s.metadata["result"]["completed"] == "False"
    assert s.events.message.str.contains(reason, regex=False).any()
    return s


def _contiguous(path) -> None:
    for stream, blocks in recorded_blocks(path).items():
        if blocks:
            assert sorted(blocks) == list(range(min(blocks), max(blocks) + 1)), f"{stream}: gap"


# ---- real processes: SIGINT and SIGKILL -------------------------------------------------------


def _start_record(bench, tmp_path, out):
    config = tmp_path / "emulator.json"
    config.write_text(json.dumps(HARMONIC))
    cmd = [sys.executable, "-m", "wearbench.cli", "record", str(bench.path), "--backend", "sim",
           "--option", "speedup=1", "--option", f"config={config}", "--speed", "2pi", "--duration", "60s", "--out", str(out),
           "--operator", "pytest", "--clearance", "A=0.3mm,B=0.31mm", "--wear", "A=new,B=new"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:  # wait until a few chunks of samples are on disk
        # the recorder creates the file before its header reaches the disk: an empty file is not yet a session
        if out.exists() and out.stat().st_size > 0 and len(recorded_blocks(out)[ACCELERATION]) >= 15:
            return proc
        if proc.poll() is not None:
            break
        time.sleep(0.2)
    proc.kill()
    raise AssertionError(f"record did not start: {proc.communicate()}")


def test_sigint_finishes_the_file(bench, tmp_path):
    out = tmp_path / "sigint.mcap"
    proc = _start_record(bench, tmp_path, out)
    proc.send_signal(signal.SIGINT)
    _, stderr = proc.communicate(timeout=30)
    assert proc.returncode == 130, stderr
    s = _assert_stopped(out, "interrupted (SIGINT)")
    assert s.metadata["session"]["operator"] == "pytest"
    assert s.clearances == pytest.approx({"A": 0.3e-3, "B": 0.31e-3})
    assert s.wear_state == {"A": "new", "B": "new"}
    assert len(s.acceleration) >= 15 * 200
    _contiguous(out)
    assert not (tmp_path / "sigint.mcap.ballast").exists()


@pytest.mark.slow
def test_sigkill_leaves_a_recoverable_file(bench, tmp_path):
    out = tmp_path / "killed.mcap"
    proc = _start_record(bench, tmp_path, out)
    proc.kill()
    proc.wait(timeout=10)
    broken = scan_mcap(out)
    assert not broken.finished and broken.chunks >= 2
    partial = read_session(out)  # read_session tolerates the unfinished file
    assert not partial.finished and len(partial.acceleration) >= 15 * 200
    fixed = tmp_path / "fixed.mcap"
    assert not (tmp_path / "killed.mcap.ballast").exists()  # the reserve for a full disk is inside the file
    r = subprocess.run([sys.executable, "-m", "wearbench.cli", "recover", str(out), "--out", str(fixed)],
                       capture_output=True, text=True, timeout=60, check=False)
    assert r.returncode == 0, r.stderr
    assert not (tmp_path / "killed.mcap.ballast").exists()
    s = read_session(fixed)
    assert s.finished and s.bench is not None and s.metadata["session"]["operator"] == "pytest"
    assert len(scan_mcap(fixed).messages) == len(broken.messages) + 1  # + the "recovered" event
    assert recorded_blocks(fixed)[ACCELERATION].keys() == recorded_blocks(out)[ACCELERATION].keys()
    np.testing.assert_array_equal(s.acceleration.acc, partial.acceleration.acc)
    assert (s.events.kind == "recovered").any()
    _contiguous(fixed)


# ---- devices that fail ------------------------------------------------------------------------


def test_serial_disconnect_mid_stream(serial_bench, record_session):
    emulator = serial_bench(table=HARMONIC, faults=FaultPlan(drop_link_at=1.5))
    rec = record_session(emulator, speed=FAST, cycles=100)
    assert "device disconnected" in rec.reason
    _assert_stopped(rec.path, "device disconnected")
    assert_same_blocks(rec.path, emulator.sent(), min_blocks=3)
    # the device's last word before the link went down was read and recorded too
    assert rec.session.events.message.str.contains("link going down").any()


def test_serial_malformed_frames_are_counted(serial_bench, record_session):
    emulator = serial_bench(table=HARMONIC, faults=FaultPlan(corrupt_rate=0.03))
    rec = record_session(emulator, speed=FAST, cycles=20)
    s, result = rec.session, rec.result
    assert s.finished
    assert result.completed, result.reason  # lost replies were asked for again
    assert result.malformed > 0 and (s.events.kind == "malformed").any()
    # corrupted blocks are missing, never garbage: what was recorded is what was sent intact
    assert_same_blocks(rec.path, emulator.sent(), min_blocks=3)
    rec_blocks = recorded_blocks(rec.path)[ACCELERATION]
    assert result.dropped_blocks[ACCELERATION] == max(rec_blocks) - min(rec_blocks) + 1 - len(rec_blocks)
    assert s.quality[ACCELERATION]["dropped"] == result.dropped_blocks[ACCELERATION]


def test_silent_device(bench, tmp_path):
    rig, sent, plan = _sim(bench, silence_timeout=0.5)
    device = rig.drive.device
    read = device.read
    device.read = lambda: read() if device.clock() < 1.5 else []
    out = tmp_path / "silent.mcap"
    result = _run(rig, bench, plan, out)
    assert "device stopped answering" in result.reason
    _assert_stopped(out, "no data for")
    assert_same_blocks(out, sent, min_blocks=2)


def test_stalled_motor(bench, tmp_path):
    rig, sent, plan = _sim(bench, {"faults": {"stall_at": "1.2 s"}})
    out = tmp_path / "stall.mcap"
    result = _run(rig, bench, plan, out)
    assert result.reason == "drive fault: stall"
    s = _assert_stopped(out, "drive fault: stall")
    assert (s.events.kind == "stall").any()
    assert_same_blocks(out, sent, min_blocks=2)


def test_reader_exception(bench, tmp_path):
    rig, sent, plan = _sim(bench)
    device = rig.drive.device
    read = device.read

    def failing():
        if device.clock() > 1.5:
            raise ZeroDivisionError("bug in a driver")
        return read()

    device.read = failing
    out = tmp_path / "reader.mcap"
    result = _run(rig, bench, plan, out)
    assert "reader failed: ZeroDivisionError: bug in a driver" in result.reason
    _assert_stopped(out, "ZeroDivisionError")
    assert_same_blocks(out, sent, min_blocks=2)


def test_writer_exception(bench, tmp_path):
    rig, sent, plan = _sim(bench)
    out = tmp_path / "writer.mcap"
    writer = SessionWriter(out)
    write_block, calls = writer.write_block, []

    def failing(block):
        calls.append(block.sequence)
        if len(calls) == 40:
            raise ValueError("cannot encode")
        write_block(block)

    writer.write_block = failing
    result = _run(rig, bench, plan, out, writer=writer)
    assert "writer failed: ValueError: cannot encode" in result.reason
    s = _assert_stopped(out, "cannot encode")
    assert s.metadata["result"]["lost_items"] == "1"
    # only the block that could not be encoded is missing (a gap, or the end if it was the last)
    rec = recorded_blocks(out)[ACCELERATION]
    gap = sorted(set(range(min(rec), max(rec) + 1)) - set(rec))
    assert calls[39] not in rec and gap in ([], [calls[39]])
    assert s.quality[ACCELERATION]["dropped"] == len(gap)
    for seq, block in rec.items():
        np.testing.assert_array_equal(block.samples, sent[ACCELERATION][seq][2])


class _FullDisk(io.FileIO):
    """A file whose disk fills up once after ``budget`` bytes (part of that write lands)."""

    def __init__(self, path, budget: int):
        super().__init__(path, "wb")
        self.budget, self.failed = budget, False

    def write(self, data) -> int:
        data = bytes(data)
        if not self.failed and self.tell() + len(data) > self.budget:
            self.failed = True
            super().write(data[: len(data) // 2])
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return super().write(data)


def test_full_disk(bench, tmp_path):
    rig, sent, plan = _sim(bench)
    out = tmp_path / "full.mcap"
    raw = _FullDisk(out, budget=140_000)  # the bench and its worn surfaces take the first ~80 kB
    result = _run(rig, bench, plan, out, writer=SessionWriter(raw, chunk_size=16 << 10))
    assert raw.failed and result.reason.startswith("disk full")
    s = _assert_stopped(out, "disk full")
    assert s.metadata["result"]["lost_items"] == "0"
    assert_same_blocks(out, sent, min_blocks=5)  # the chunk that failed was written on the retry


# ---- sequence numbers -------------------------------------------------------------------------


def test_dropped_blocks_are_counted(bench, tmp_path):
    rig, sent, plan = _sim(bench, {"faults": {"drop_rate": 0.05}, "seed": 3})
    out = tmp_path / "drops.mcap"
    result = _run(rig, bench, plan, out)
    assert result.completed
    assert_same_blocks(out, sent)
    rec = recorded_blocks(out)
    s = read_session(out)
    for stream in (ACCELERATION, ENCODER):
        missing = max(rec[stream]) - min(rec[stream]) + 1 - len(rec[stream])
        assert missing > 0
        assert result.dropped_blocks[stream] == missing == s.quality[stream]["dropped"]
    assert (s.events.kind == "drop").sum() >= 1
    assert s.metadata["result"]["acceleration.dropped_blocks"] == str(result.dropped_blocks[ACCELERATION])


def test_repeated_blocks_are_counted(bench, tmp_path):
    rig, sent, plan = _sim(bench)
    device = rig.drive.device
    read, state = device.read, {"done": False}

    def repeating():
        blocks = read()
        acc = [b for b in blocks if not hasattr(b, "counts")]
        if acc and device.clock() > 1.5 and not state["done"]:
            state["done"] = True
            return blocks + [acc[-1]]
        return blocks

    device.read = repeating
    out = tmp_path / "repeat.mcap"
    result = _run(rig, bench, plan, out)
    assert result.completed and result.repeated_blocks[ACCELERATION] == 1
    assert_same_blocks(out, sent)
    s = read_session(out)
    assert s.quality[ACCELERATION]["repeated"] == 1
    assert (s.events.kind == "repeat").sum() == 1
    assert np.all(np.diff(s.acceleration.time) > 0)  # the repeat is reported, not duplicated in the frame


# ---- CAN faults -------------------------------------------------------------------------------


def test_can_bus_off_is_recorded_and_counted(can_bench, record_session):
    emulator = can_bench(table=HARMONIC, faults=FaultPlan(bus_off_at=1.2))
    rec = record_session(emulator, speed=FAST, cycles=20)
    result, s = rec.result, rec.session
    assert result.completed, result.reason
    assert (s.events.kind == "bus_off").sum() >= 2  # the error frame and the bench's Event after it
    assert_same_blocks(rec.path, emulator.sent())
    got = recorded_blocks(rec.path)[ACCELERATION]
    missing = max(got) - min(got) + 1 - len(got)
    assert missing > 0 and result.dropped_blocks[ACCELERATION] == missing


def test_canopen_stall(bench, tmp_path):
    from wearbench.hardware.emulators.can_server import CanEmulator

    channel = f"wearbench-test-stall-{tmp_path.name}"
    out = tmp_path / "stall.mcap"
    with CanEmulator(bench, channel=channel, config={**HARMONIC, "faults": {"stall_at": "1.5 s"}}):
        result = _run(open_rig(bench, "canopen", {"channel": channel}), bench,
                      SessionPlan(speed=FAST, cycles=20), out)
    assert result.reason == "drive fault: stall"
    s = _assert_stopped(out, "drive fault: stall")
    assert (s.events.kind == "stall").any()  # the EMCY


def test_canopen_enable_after_a_stall_resets_the_fault(bench):
    """The host's CiA 402 state machine (canopen's BaseNode402) leaves FAULT through a fault reset."""
    from wearbench.hardware.emulators.can_server import CanEmulator

    channel = "wearbench-test-fault-reset"
    with CanEmulator(bench, channel=channel, config={**HARMONIC, "faults": {"stall_at": "0.5 s"}}):
        rig = open_rig(bench, "canopen", {"channel": channel})
        try:
            drive, source = rig.drive, rig.sources[0]
            accel = bench.sensor("accelerometer")
            source.configure(accel.range, accel.sample_rate)
            drive.enable()
            source.start()
            drive.set_speed(20.0, 200.0)
            deadline = time.monotonic() + 10
            while (s := drive.state()).fault is None and time.monotonic() < deadline:
                source.read(0.01)
            assert s.fault == "stall" and not s.enabled and drive.node.state == "FAULT"
            drive.enable()
            s = drive.state()
            assert s.fault is None and s.enabled and drive.node.state == "OPERATION ENABLED"
            drive.disable()
            assert drive.node.state == "READY TO SWITCH ON"
        finally:
            rig.close()
