"""Recorder throughput: 20 kHz acceleration + 1 kHz encoder for 10 simulated minutes.

Runs the real recorder (reader thread, writer thread, control loop, MCAP with zstd chunks) on the
``sim`` backend with a stepped clock, so ten bench minutes take far less wall time. The emulator's
own work (generating the signal, motor states) is measured separately, in the thread that calls
it, and subtracted: what is left is what recording costs. The CPU share is that cost divided by
the simulated duration, i.e. the fraction of one core the recorder needs to keep up in real time
(target: under 25 %). Prints a table; exits 1 if any sample was dropped.

``--serial S`` adds a real-time check: S seconds over the serial backend against the emulator in
its own process, where the recorder's share is simply this process's CPU time over the wall time.

    python -m benchmarks.acquisition.record_throughput [--minutes 10] [--rate 20kHz] [--serial 30]
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

from wearbench.acquisition.backends import open_rig
from wearbench.acquisition.recorder import Recorder
from wearbench.acquisition.session import SessionPlan
from wearbench.acquisition.session_file import scan_mcap
from wearbench.bench.load import parse_bench, shipped_bench
from wearbench.bench.units import parse_quantity


def metered(device, names, spent: list[float]) -> None:
    """Add the CPU time of the device's own methods (in the calling thread) to ``spent``."""
    for name in names:
        method = getattr(device, name)

        def timed(*args, _m=method, **kwargs):
            t0 = time.thread_time()
            try:
                return _m(*args, **kwargs)
            finally:
                spent.append(time.thread_time() - t0)

        setattr(device, name, timed)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--rate", default="20kHz", help="accelerometer sample rate")
    ap.add_argument("--serial", type=float, default=0.0, metavar="S",
                    help="also record S seconds in real time over the serial emulator")
    args = ap.parse_args()
    rate = parse_quantity(args.rate, "frequency")
    path = shipped_bench("ninebar-testbed")
    text = path.read_text().replace('sample_rate = "10 kHz"', f'sample_rate = "{rate:g} Hz"')
    bench = parse_bench(text, path)
    assert bench.sensor("accelerometer").sample_rate == rate and bench.sensor("encoder").sample_rate == 1000
    duration = args.minutes * 60.0
    rig = open_rig(bench, "sim", {"speedup": math.inf, "config": {
        "signal": "harmonic", "cache": False, "accelerometer": {"noise": "0.05 m/s^2"}}})
    emulator: list[float] = []
    metered(rig.drive.device, ("read", "events", "motor_status", "set_speed", "enable", "disable", "stop",
                                "start_stream", "stop_stream", "configure_accelerometer"), emulator)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "throughput.mcap"
        wall0, cpu0 = time.perf_counter(), time.process_time()
        try:
            result = Recorder(rig, bench, SessionPlan(speed=2 * math.pi, duration=duration, settle=0.0),
                              out).run()
        finally:
            rig.close()
        wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
        size = out.stat().st_size
        scan = scan_mcap(out)
    emu = sum(emulator)
    recorder = cpu - emu
    drops = sum(result.dropped_samples.values())
    rows = [
        ("simulated duration", f"{result.duration:.1f} s"),
        ("reason", result.reason),
        ("acceleration samples", f"{result.samples['acceleration']:,} ({result.blocks['acceleration']:,} blocks)"),
        ("encoder samples", f"{result.samples['encoder']:,} ({result.blocks['encoder']:,} blocks)"),
        ("dropped samples", f"{drops}"),
        ("repeated blocks", f"{sum(result.repeated_blocks.values())}"),
        ("file", f"{size / 1e6:.1f} MB, {scan.chunks} chunks, finished={scan.finished}"),
        ("wall time", f"{wall:.1f} s ({result.duration / wall:.1f}x real time)"),
        ("process CPU", f"{cpu:.2f} s"),
        ("  emulator (subtracted)", f"{emu:.2f} s"),
        ("  recorder", (f"{recorder:.2f} s (writer thread {result.writer_cpu:.2f} s, reader thread "
                        f"{result.reader_cpu:.2f} s incl. emulator reads)")),
        ("recorder CPU share", f"{100 * recorder / result.duration:.1f} % of one core (target < 25 %)"),
    ]
    width = max(len(k) for k, _ in rows)
    print(f"record_throughput: {rate / 1e3:g} kHz acceleration + 1 kHz encoder, {args.minutes:g} simulated min")
    for k, v in rows:
        print(f"  {k:<{width}}  {v}")
    ok = drops == 0 and result.completed and scan.finished
    if args.serial:
        ok = _serial(bench, args.serial) and ok
    return 0 if ok else 1


def _serial(bench, seconds: float) -> bool:
    from wearbench.hardware.emulators.serial_server import start_serial_emulator

    proc, port = start_serial_emulator(bench, {"signal": "harmonic", "cache": False,
                                               "accelerometer": {"noise": "0.05 m/s^2"}})
    try:
        rig = open_rig(bench, "serial", {"port": port})
        with tempfile.TemporaryDirectory() as tmp:
            wall0, cpu0 = time.perf_counter(), time.process_time()
            try:
                result = Recorder(rig, bench, SessionPlan(speed=2 * math.pi, duration=seconds, settle=0.0),
                                  Path(tmp) / "serial.mcap").run()
            finally:
                rig.close()
            wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    finally:
        proc.terminate()
        proc.wait(timeout=10)
    drops = sum(result.dropped_samples.values())
    print(f"real time over serial (emulator in its own process): {result.duration:.1f} s recorded, "
          f"{result.samples['acceleration']:,} acceleration samples, dropped {drops}, reason {result.reason}; "
          f"recorder process CPU {cpu:.2f} s in {wall:.1f} s wall = {100 * cpu / wall:.1f} % of one core")
    return drops == 0 and result.completed


if __name__ == "__main__":
    sys.exit(main())
