"""The serial emulator as a real peer: its own process on a pty, spoken to with pyserial."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import numpy as np
import pytest
import serial
from wearbench.hardware.emulators.serial_server import DISCONNECT_EXIT, start_serial_emulator
from wearbench.hardware.protocol import messages as m
from wearbench.hardware.protocol.frames import FrameParser

pytestmark = pytest.mark.timeout(120)


class Host:
    def __init__(self, port: str):
        self.port = serial.Serial(port, timeout=0.05)
        self.parser = FrameParser()
        self.seq = 0
        self.received: list[tuple[float, m.Message]] = []

    def send(self, msg: m.Message) -> int:
        self.port.write(msg.frame(self.seq))
        self.seq += 1
        return self.seq - 1

    def pump(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            data = self.port.read(65536)
            now = time.monotonic()
            self.received += [(now, m.decode(f)) for f in self.parser.feed(data)]

    def wait_ack(self, seq: int, timeout: float = 5.0) -> tuple[float, m.Ack]:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            for t, msg in self.received:
                if isinstance(msg, m.Ack) and msg.command_sequence == seq:
                    return t, msg
            self.pump(0.02)
        raise AssertionError(f"no ack for command {seq}")

    def of(self, cls):
        return [msg for _, msg in self.received if isinstance(msg, cls)]


@pytest.fixture
def emulator(testbed, tmp_path):
    procs = []

    def start(table, **kw):
        proc, port = start_serial_emulator(testbed, {"signal": "harmonic", **table}, **kw)
        procs.append(proc)
        return proc, Host(port)

    yield start
    for p in procs:
        if p.poll() is None:
            p.terminate()
            p.wait(timeout=10)


def start_streaming(host: Host, speed: float = 6.283) -> None:
    for cmd in (m.Enable(), m.SetSpeed(speed, 0.0), m.ConfigureAccel(490.0, 20000.0), m.StartStream(3)):
        assert host.wait_ack(host.send(cmd))[1].error == m.ErrorCode.OK


def test_session_over_a_pty_matches_what_was_sent(emulator, tmp_path):
    log = tmp_path / "sent.bin"
    proc, host = emulator({}, sent_log=log)
    seq = host.send(m.GetInfo())
    host.wait_ack(seq)
    assert host.of(m.Info)[0].counts_per_rev == 4000
    start_streaming(host)
    host.pump(1.0)
    host.send(m.StopStream())
    host.pump(0.3)
    status_seq = host.send(m.GetStatus())
    host.wait_ack(status_seq)
    status = host.of(m.Status)[-1]
    assert status.flags & 1 and status.speed == pytest.approx(6.283, rel=1e-3) and status.fault == 0
    proc.terminate()
    assert proc.wait(timeout=10) == 0
    acc = host.of(m.AccelData)
    assert len(acc) >= 80 and [a.sequence for a in acc] == list(range(len(acc)))
    assert all(a.fmt == m.SampleFormat.INT16 and a.raw.size == 200 for a in acc)
    sent = FrameParser()
    logged = [m.decode(f) for f in sent.feed(log.read_bytes())]
    assert [x for x in logged if isinstance(x, m.AccelData)] == acc
    assert [x for x in logged if isinstance(x, m.EncoderData)] == host.of(m.EncoderData)
    assert host.parser.stats.crc_errors == 0


def test_refused_and_unknown_commands_are_acknowledged_with_errors(emulator):
    _, host = emulator({})
    assert host.wait_ack(host.send(m.SetSpeed(1.0)))[1].error == m.ErrorCode.NOT_ENABLED
    host.send(m.Enable())
    assert host.wait_ack(host.send(m.SetSpeed(1e4)))[1].error == m.ErrorCode.BAD_VALUE
    host.port.write(m.encode_frame(0x3E, 99, b""))
    assert host.wait_ack(99)[1].error == m.ErrorCode.UNKNOWN_COMMAND
    host.port.write(m.encode_frame(m.MessageType.SET_SPEED, 100, b"\x00"))
    assert host.wait_ack(100)[1].error == m.ErrorCode.BAD_LENGTH


def test_garbage_from_the_host_does_not_stop_the_device(emulator):
    _, host = emulator({})
    host.port.write(bytes(np.random.default_rng(1).integers(0, 256, 5000, dtype=np.uint8)))
    assert host.wait_ack(host.send(m.GetStatus()))[1].error == m.ErrorCode.OK


def test_corrupted_frames_are_caught_by_the_crc(emulator):
    _, host = emulator({"faults": {"corrupt_rate": 0.2}})
    for cmd in (m.Enable(), m.SetSpeed(6.283, 0.0), m.StartStream(3)):
        host.send(cmd)
    host.pump(1.5)
    s = host.parser.stats
    assert s.crc_errors + s.header_errors > 5
    acc = host.of(m.AccelData)
    seqs = [a.sequence for a in acc]
    assert len(acc) > 30 and len(set(seqs)) == len(seqs) and max(seqs) + 1 > len(seqs)


def test_late_replies(emulator):
    _, host = emulator({"faults": {"reply_delay": "0.4 s"}})
    t0 = time.monotonic()
    t, ack = host.wait_ack(host.send(m.GetStatus()))
    assert t - t0 >= 0.4 and ack.error == m.ErrorCode.OK


def test_disconnect_mid_stream(emulator):
    proc, host = emulator({"faults": {"disconnect_after": "0.5 s"}})
    start_streaming(host)
    with pytest.raises(serial.SerialException):
        host.pump(5.0)
    assert proc.wait(timeout=10) == DISCONNECT_EXIT
    assert 30 <= len(host.of(m.AccelData)) <= 70


def test_stall_and_dropped_blocks_reach_the_host(emulator):
    _, host = emulator({"faults": {"stall_at": "0.5 s", "drop_rate": 0.2}, "accel_block": 50})
    start_streaming(host)
    host.pump(1.2)
    ev = host.of(m.Event)
    assert [e.code for e in ev] == [m.FaultCode.STALL]
    host.wait_ack(host.send(m.GetStatus()))
    st = host.of(m.Status)[-1]
    assert st.fault == m.FaultCode.STALL and st.speed == 0
    seqs = [a.sequence for a in host.of(m.AccelData)]
    assert 0.1 < 1 - len(seqs) / (seqs[-1] + 1) < 0.3


@pytest.mark.parametrize("accelerometer", [{}, {"adc_bits": 0}, {"clipping": False}, {"adc_bits": 10}])
def test_wire_samples_equal_the_device_samples_bit_for_bit(testbed, accelerometer):
    from wearbench.hardware.emulators.config import EmulatorConfig
    from wearbench.hardware.emulators.device import AccelBlock, BenchDevice, ManualClock
    from wearbench.hardware.emulators.serial_server import SerialEmulator
    from wearbench.hardware.protocol.frames import Frame

    cfg = EmulatorConfig.from_table({"signal": "harmonic", "accelerometer": {"noise": "30 m/s^2", "bias": "450 m/s^2",
                                                                              **accelerometer}}, bench=testbed)
    clock = ManualClock()
    device = BenchDevice(testbed, cfg, clock)
    device.enable()
    device.set_speed(20.0)
    device.start_stream()
    clock.advance(0.3)
    engine = SerialEmulator(device)
    blocks = [b for b in device.read() if isinstance(b, AccelBlock)]
    assert blocks
    for b in blocks:
        msg = engine.block_message(b)
        wire = m.decode(Frame(msg.TYPE, 0, msg.pack()))
        np.testing.assert_array_equal(wire.samples, b.samples)
        assert wire.time == b.time and wire.sequence == b.sequence


def test_a_bench_changed_in_memory_is_refused(testbed):
    with pytest.raises(ValueError, match=r"emulator\.truth"):
        start_serial_emulator(testbed.with_clearances({"A": 0.5e-3}), {"signal": "none"})


def test_a_bench_whose_masses_changed_in_memory_is_refused(testbed):
    import dataclasses

    heavy = dataclasses.replace(testbed, bodies=tuple(dataclasses.replace(b, mass=2 * b.mass) for b in testbed.bodies))
    with pytest.raises(ValueError, match="changed in memory"):
        start_serial_emulator(heavy, {"signal": "none"})


@pytest.mark.slow
def test_a_drawn_truth_reaches_the_host_over_the_pty(testbed, tmp_path, monkeypatch):
    """The emulator process plays the non-twin truth: the host sees the drawn motor's true speed
    (commanded x speed_scale, 0.2 % off for seed 1) and the model's impacts, not a test pattern."""
    from wearbench.hardware.emulators.config import emulator_config
    from wearbench.model.realisation import draw_realisation

    monkeypatch.setenv("WEARBENCH_CACHE", str(tmp_path / "cache"))
    cfg = emulator_config(testbed, "0.6 mm new", 1, revolutions=2)
    proc, port = start_serial_emulator(testbed, cfg)
    try:
        host = Host(port)
        start_streaming(host, speed=6.2832)
        host.pump(1.0)
        host.wait_ack(host.send(m.GetStatus()))
        status = host.of(m.Status)[-1]
    finally:
        proc.terminate()
        proc.wait(timeout=10)
    scale = draw_realisation(testbed, 1).speed_scale
    assert abs(scale - 1) > 1e-3
    # true speed (with a ripple of ~1e-3 at most): the drawn one, not the commanded
    assert status.speed == pytest.approx(6.2832 * scale, rel=5e-4)
    x = np.concatenate([a.samples for a in host.of(m.AccelData)])
    assert np.abs(x).max() > 5 * np.sqrt(np.mean(x**2))  # impacts stand out of the mechanism's motion


def test_a_temporary_folder_too_long_for_a_socket_is_named(tmp_path):
    """The fork server that starts the emulator listens on a socket in TMPDIR; with a TMPDIR of 120
    bytes the start fails with an error naming the folder and the fix, not multiprocessing's bare one."""
    long_tmp = tmp_path / ("x" * max(1, 120 - len(str(tmp_path))))
    long_tmp.mkdir()
    probe = ("from wearbench.bench.load import load_bench, shipped_bench\n"
             "from wearbench.hardware.emulators.serial_server import start_serial_emulator\n"
             "try:\n    start_serial_emulator(load_bench(shipped_bench('ninebar-testbed')))\n"
             "except RuntimeError as exc:\n    print(exc)\n")
    out = subprocess.run([sys.executable, "-c", probe], env={**os.environ, "TMPDIR": str(long_tmp)},
                         capture_output=True, text=True, timeout=120, check=False)
    assert out.returncode == 0, out.stderr
    assert str(long_tmp) in out.stdout and "set TMPDIR to a shorter folder" in out.stdout, out.stdout
    assert not [p for p in long_tmp.iterdir() if p.name.startswith("wearbench-emu-")]
