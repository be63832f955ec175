"""A lab's own recording script, written on top of wearbench (the code the example suite tests).

One run of the test bed at a speed, recorded to MCAP with the wearbench recorder, and the lab's
rules for what a run is worth: a run that ends early is kept and reported with its reason (never
retried or overwritten), and a run is *usable* for the lab's analysis only when it completed, lost
no block, read no garbage, and its index pulse kept coming (the lab cuts cycles at it).

    python lab_recorder.py BENCH.toml --port /dev/ttyACM0 --seconds 60 --out run.mcap
    python lab_recorder.py BENCH.toml --can socketcan:can0 --seconds 60 --out run.mcap
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from wearbench.acquisition.backends import open_rig
from wearbench.acquisition.drivers import ACCELERATION, ENCODER
from wearbench.acquisition.recorder import Recorder
from wearbench.acquisition.session import SessionPlan
from wearbench.acquisition.session_file import Session, blocks, read_session, scan_mcap
from wearbench.bench.load import load_bench
from wearbench.bench.schema import Bench


@dataclass
class RunReport:
    """What the lab's script says about one run."""

    path: Path
    completed: bool
    reason: str
    seconds: float  # recorded, device clock
    samples: int  # acceleration samples in the file
    dropped_blocks: int
    malformed: int
    index_gap: float  # longest stretch without an index pulse, in revolutions
    clock_ratio: float  # accelerometer clock / encoder clock, from the blocks' arrival times

    @property
    def usable(self) -> bool:
        return (self.completed and self.dropped_blocks == 0 and self.malformed == 0
                and self.index_gap < 1.5)


def index_gap(session: Session) -> float:
    """The longest stretch of the recording without an index pulse, in crank revolutions."""
    enc = session.encoder
    turned = np.abs(enc.angle.to_numpy() - enc.angle.iloc[0]) / (2 * math.pi)
    pulses = turned[enc["index"].to_numpy().astype(bool)]
    marks = np.concatenate(([0.0], pulses, [turned[-1]]))
    return float(np.max(np.diff(marks)))


def clock_ratio(path: str | Path) -> float:
    """How fast the accelerometer's sample clock runs against the encoder's (1 + drift): each
    stream's block stamps (at the nominal rate) against the host's arrival times, acceleration over
    encoder. A block arrives some time after it was complete; in each of 16 stretches of the run the
    block that arrived soonest stands for the device clock, and a line through those is its rate."""
    scan = scan_mcap(path)

    def rate(stream: str) -> float:
        got = blocks(scan, stream)
        host = np.array([b.host_time for b in got])
        done = np.array([b.device_time + len(b.samples) / b.sample_rate for b in got])  # block complete
        host, done = host - host[0], done - done[0]
        k = np.polyfit(host, done, 1)[0]
        soonest = [i[np.argmax(done[i] - k * host[i])] for i in np.array_split(np.argsort(host), 16)]
        return float(np.polyfit(host[soonest], done[soonest], 1)[0])

    return rate(ACCELERATION) / rate(ENCODER)


def record_run(bench: Bench, backend: str, options: dict, out: str | Path, *, speed: float, seconds: float,
               operator: str = "lab") -> RunReport:
    """Record ``seconds`` at ``speed`` rad/s into ``out`` and report on the run."""
    rig = open_rig(bench, backend, options)
    plan = SessionPlan(speed=speed, duration=seconds, operator=operator, settle=0.2)
    try:
        result = Recorder(rig, bench, plan, out).run()
    finally:
        rig.close()
    session = read_session(out)
    return RunReport(Path(out), result.completed, result.reason, result.duration, len(session.acceleration),
                     sum(result.dropped_blocks.values()), result.malformed, index_gap(session),
                     clock_ratio(out))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("bench")
    bus = parser.add_mutually_exclusive_group(required=True)
    bus.add_argument("--port", help="serial port of the bench")
    bus.add_argument("--can", help="INTERFACE:CHANNEL of the bench's CAN bus")
    parser.add_argument("--speed", type=float, default=2 * math.pi, help="motor speed, rad/s")
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    bench = load_bench(args.bench)
    if args.port:
        backend, options = "serial", {"port": args.port}
    else:
        interface, _, channel = args.can.partition(":")
        backend, options = "can", {"interface": interface, "channel": channel}
    report = record_run(bench, backend, options, args.out, speed=args.speed, seconds=args.seconds)
    print(f"{report.path}: {'usable' if report.usable else 'NOT usable'}: {report.reason}, "
          f"{report.seconds:.2f} s, {report.samples} samples, {report.dropped_blocks} blocks dropped, "
          f"{report.malformed} malformed, index gap {report.index_gap:.2f} rev")
    return 0 if report.usable else 1


if __name__ == "__main__":
    raise SystemExit(main())
