"""A lab's own recording script, written on top of wearbench (the code the example suite tests).

One run of the test bed at a speed, recorded to MCAP with the wearbench recorder, and the lab's
rules for what a run is worth: a run that ends early is kept and reported with its reason (never
retried or overwritten), and a run is *usable* for the lab's analysis only when it completed, lost
no block, read no garbage, its index pulse kept coming (the lab cuts cycles at it) and the
accelerometer's clock kept to the encoder's (the lab aligns them by time).

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
from wearbench.acquisition.recorder import Recorder
from wearbench.acquisition.session import SessionPlan
from wearbench.acquisition.session_file import Session, read_session
from wearbench.bench.load import load_bench
from wearbench.bench.schema import Bench

DRIFT_LIMIT = 200e-6  # the lab's limit on the accelerometer's clock drift against the encoder


@dataclass
class RunReport:
    """What the lab's script says about one run."""

    path: Path
    completed: bool
    reason: str
    seconds: float  # of acceleration in the file, device clock
    samples: int  # acceleration samples in the file
    dropped_blocks: int
    malformed: int
    index_gap: float  # longest stretch without an index pulse, in revolutions
    clock_drift: float  # accelerometer clock against the encoder's (fraction, + = fast)

    @property
    def usable(self) -> bool:
        return (self.completed and self.dropped_blocks == 0 and self.malformed == 0
                and self.index_gap < 1.5 and abs(self.clock_drift) < DRIFT_LIMIT)


def index_gap(session: Session) -> float:
    """The longest stretch of the recording without an index pulse, in crank revolutions."""
    enc = session.encoder
    turned = np.abs(enc.angle.to_numpy() - enc.angle.iloc[0]) / (2 * math.pi)
    pulses = turned[enc["index"].to_numpy().astype(bool)]
    marks = np.concatenate(([0.0], pulses, [turned[-1]]))
    return float(np.max(np.diff(marks)))


def clock_drift(session: Session) -> float:
    """How fast the accelerometer's sample clock runs against the encoder's (a fraction, + = fast),
    from the signal itself: the acceleration is periodic in crank angle, so with a drifting sample
    clock (samples stamped at the nominal rate) the phase of its once-per-revolution component
    against the encoder's angle moves by -drift radians per radian turned. Fitted over every whole
    revolution of the run (NaN below three)."""
    enc, acc = session.encoder, session.acceleration
    t = acc.time.to_numpy()
    inside = (t >= enc.time.iloc[0]) & (t <= enc.time.iloc[-1])  # samples the encoder's angle covers
    angle = np.interp(t[inside], enc.time.to_numpy(), enc.angle.to_numpy())
    a = acc.acc.to_numpy()[inside]
    turned = np.abs(angle - angle[0])
    revolution = np.floor(turned / (2 * math.pi)).astype(int)
    whole = revolution < revolution[-1]  # the last revolution is incomplete
    if revolution[-1] < 3:
        return math.nan
    k, a, angle, turned = revolution[whole], a[whole], angle[whole], turned[whole]
    z = np.bincount(k, weights=a * np.cos(angle)) - 1j * np.bincount(k, weights=a * np.sin(angle))
    mid = np.bincount(k, weights=turned) / np.bincount(k)
    return -float(np.polyfit(mid, np.unwrap(np.angle(z)), 1)[0])


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
    acc = session.acceleration
    seconds = float(acc.time.iloc[-1] - acc.time.iloc[0]) if len(acc) else 0.0
    return RunReport(Path(out), result.completed, result.reason, seconds, len(acc),
                     sum(result.dropped_blocks.values()), result.malformed, index_gap(session),
                     clock_drift(session))


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
          f"{report.malformed} malformed, index gap {report.index_gap:.2f} rev, "
          f"clock drift {report.clock_drift * 1e6:.0f} ppm")
    return 0 if report.usable else 1


if __name__ == "__main__":
    raise SystemExit(main())
