"""Can the bench emulators keep up with a 20 kHz accelerometer? Prints one table.

Rows: BenchDevice alone under a manual clock, as device seconds per wall second: the twin (one
model revolution looped, every imperfection on, point sampled) and the shipped test bed's non-twin
truth (a drawn bench's 40-revolution run through the stud-mounted IEPE resonance and the 8th-order
anti-alias filter at 4x oversampling); the serial emulator process over a pty and the CAN emulator on the
virtual bus, each streaming 20 kHz + 1 kHz in real time for DURATION s to a host that counts
blocks and sequence gaps, with the emulator's CPU share (of one core).

    .venv/bin/python -m benchmarks.acquisition.emulator_throughput [DURATION]
"""

from __future__ import annotations

import math
import os
import sys
import time

import can
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.hardware.emulators.can_server import CanEmulator
from wearbench.hardware.emulators.config import EmulatorConfig, emulator_config
from wearbench.hardware.emulators.device import AccelBlock, BenchDevice, ManualClock
from wearbench.hardware.emulators.serial_server import start_serial_emulator
from wearbench.hardware.protocol import can_frames as cf
from wearbench.hardware.protocol import messages as m
from wearbench.hardware.protocol.frames import FrameParser

RATE = 20000.0
W = 2 * math.pi
TABLE = {"signal": "model", "accelerometer": {"noise": "0.05 m/s^2", "bias": "0.1 m/s^2", "drift": "30 ppm",
                                              "resonance": "3 kHz", "damping": 0.08},
         "motor": {"ripple": 0.005}}


def cpu_of(pid: int) -> float:
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def device_alone(bench, table=TABLE, label="BenchDevice, twin (manual clock)", seconds: float = 60.0
                 ) -> tuple[str, str, str, str]:
    cfg = EmulatorConfig.from_table(table, bench=bench)
    clock = ManualClock()
    d = BenchDevice(bench, cfg, clock)
    d.configure_accelerometer(490.0, RATE)
    d.enable()
    d.set_speed(W)
    d.start_stream()
    t0 = time.perf_counter()
    n = 0
    for _ in range(round(seconds / 0.01)):
        clock.advance(0.01)
        n += sum(len(b.samples) for b in d.read() if isinstance(b, AccelBlock))
    wall = time.perf_counter() - t0
    return (label, f"{n / seconds:.0f}", f"{seconds / wall:.0f}x real time", "-")


def serial_stream(bench, duration: float, table=TABLE, label="serial emulator (pty, own process)"
                  ) -> tuple[str, str, str, str]:
    import serial

    proc, port = start_serial_emulator(bench, table)
    try:
        host = serial.Serial(port, timeout=0.05)
        parser = FrameParser()
        for i, cmd in enumerate((m.Enable(), m.SetSpeed(W, 0.0), m.ConfigureAccel(490.0, RATE), m.StartStream(3))):
            host.write(cmd.frame(i))
        c0, t0 = cpu_of(proc.pid), time.monotonic()
        seqs = []
        while time.monotonic() - t0 < duration:
            seqs += [msg.sequence for msg in map(m.decode, parser.feed(host.read(65536)))
                     if isinstance(msg, m.AccelData)]
        cpu = (cpu_of(proc.pid) - c0) / (time.monotonic() - t0)
    finally:
        proc.terminate()
        proc.wait()
    n = len(seqs) * 200
    gaps = (seqs[-1] + 1 - len(seqs)) if seqs else 0
    return (label, f"{n / duration:.0f}", f"{gaps} blocks missing",
            f"{100 * cpu:.0f} %")


def can_stream(bench, duration: float) -> tuple[str, str, str, str]:
    with CanEmulator(bench, "bench-throughput", TABLE) as emu:
        bus = can.Bus(interface="virtual", channel="bench-throughput", fd=True)
        bus.send(cf.encode_frame("StreamControl", {"Command": 2, "Mask": 0, "Range": 490.0, "SampleRate": RATE}))
        bus.send(cf.encode_frame("MotorCommand", {"Command": 1, "Counter": 1, "TargetSpeed": 0, "Acceleration": 0}))
        bus.send(cf.encode_frame("MotorCommand", {"Command": 3, "Counter": 2, "TargetSpeed": W, "Acceleration": 0}))
        bus.send(cf.encode_frame("StreamControl", {"Command": 1, "Mask": 3, "Range": 0, "SampleRate": 0}))
        c0, t0 = time.process_time(), time.monotonic()
        seqs = []
        accel_id = cf.load_dbc().get_message_by_name("AccelBlock").frame_id
        while time.monotonic() - t0 < duration:
            msg = bus.recv(0.05)
            if msg is not None and msg.arbitration_id == accel_id and not msg.is_error_frame:
                seqs.append(cf.decode_frame(msg)[1]["Sequence"])
        cpu = (time.process_time() - c0) / (time.monotonic() - t0)
        bus.shutdown()
        assert emu.sent
    n = len(seqs) * cf.ACCEL_PER_FRAME
    gaps = (seqs[-1] + 1 - len(seqs)) if seqs else 0
    return ("CAN emulator + host decode (virtual bus, one process)", f"{n / duration:.0f}", f"{gaps} frames missing",
            f"{100 * cpu:.0f} %")


def main() -> None:
    duration = float(sys.argv[1]) if len(sys.argv) > 1 else 10.0
    bench = load_bench(shipped_bench("ninebar-testbed"))
    nontwin = emulator_config(bench, "0.3 mm new", 1).to_table()
    rows = [device_alone(bench), device_alone(bench, nontwin, "BenchDevice, non-twin + sensor chain (manual clock)"),
            serial_stream(bench, duration), can_stream(bench, duration),
            serial_stream(bench, duration, nontwin, "serial emulator, non-twin + sensor chain")]
    head = ("emulator", "accel samples/s", "keeping up", "CPU of one core")
    widths = [max(len(r[i]) for r in [head, *rows]) for i in range(4)]
    for r in [head, tuple("-" * w for w in widths), *rows]:
        print("  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)))
    print(f"\n20 kHz accelerometer + 1 kHz encoder, ninebar-testbed at 2 pi rad/s, {duration:g} s per stream row")


if __name__ == "__main__":
    main()
