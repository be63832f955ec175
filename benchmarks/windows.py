"""Five-cycle window validation on non-twin truths: does a window's verdict separate the right
theory from a wrong one, is it calibrated, is the sensor delay found, and what does it cost.

Truths are made as in ``benchmarks/identify.py`` (its helpers, the demo's ``prepare_truth`` and
``record_state``): each session's emulator plays a bench drawn from the bench file's [tolerances]
with its own seed (never an ensemble draw: those use seeds 1..M), through the test bed's sensor chain
(stud-mounted resonance, 8th-order anti-alias filter, noise, 16-bit ADC), recorded through the sim
backend to MCAP. Each truth's accelerometer is also late behind the encoder by its own
``accel_delay``, drawn uniform in [0, --delay-max]; the true sensor delay is that plus the chain's
group delay at 100 Hz (the filters' delay where the CFC 180 windows carry their content).

Prints, for every window of every session against every state's ensemble (default shipped
ensembles when their key matches, else built): the consistent rate against the true state, the
inconsistent rate against each wrong state, the KS test of the true state's window percentiles
against uniform, the fitted-delay error, the scores' separation (which statistic was chosen and
why) and the time to score a 20-cycle session's windows against 4 cached ensembles.

    .venv/bin/python benchmarks/windows.py [--draws 5] [--cycles 20] [--sessions DIR]

``--sessions DIR`` keeps the recorded sessions there and reuses them on the next run.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np


def true_sensor_delay(bench, accel_delay: float) -> float:
    """The truth's accelerometer delay behind the encoder (s): ``accel_delay`` plus the group delay
    of the emulator's sensor chain (mounting resonance and anti-alias filter) at 100 Hz."""
    from scipy import signal as sps
    from wearbench.hardware.emulators.config import emulator_config
    from wearbench.hardware.emulators.sensor import SensorChain

    cfg = emulator_config(bench, bench.states[0], 1)
    acc = bench.sensor("accelerometer")
    chain = SensorChain(cfg.accelerometer, acc.sample_rate, acc.range, np.random.default_rng(0))
    if chain.sos is None:
        return accel_delay
    _, gd = sps.group_delay(sps.sos2tf(chain.sos), w=[100.0], fs=chain.internal_rate)
    return accel_delay + float(gd[0]) / chain.internal_rate


def record_truths(bench, states, args, folder: Path) -> list[tuple[str, Path, float]]:
    """(true state, session path, true sensor delay) of every truth, recorded once into ``folder``."""
    from wearbench.cli.demo import prepare_truth, record_state, slug, truth_revolutions
    from wearbench.model.compute import Task, compute_client, run_tasks, task_key

    folder.mkdir(parents=True, exist_ok=True)
    truths = []
    for k, s in enumerate(states):
        for d in range(args.draws):
            seed = args.seed + 100 * k + d
            delay = float(np.random.default_rng(seed).uniform(0.0, args.delay_max))
            table = {**bench.emulator, "truth": {"accel_delay": f"{delay * 1e3!r} ms"}}
            truths.append((s, seed, table, delay, folder / f"{slug(s.name)}_{seed}.mcap"))
    revolutions = truth_revolutions(args.cycles + 1)
    todo = [t for t in truths if not t[4].exists()]
    if todo:
        with compute_client(workers=args.workers):
            run_tasks([Task(prepare_truth, {"bench": bench, "state": s, "seed": seed, "table": table,
                                            "revolutions": revolutions},
                            task_key("bench-truth", s.name, seed), f"truth {s.name} {seed}")
                       for s, seed, table, _, _ in todo], cache=False, progress="emulator truths")
        for s, seed, table, _, path in todo:
            # one cycle more than analysed: cycles are cut at crank angle 0, the partial ends dropped
            record_state(bench, s, seed, path, backend="sim", cycles=args.cycles + 1, revolutions=revolutions,
                         table=table)
    return [(s.name, path, true_sensor_delay(bench, delay)) for s, _, _, delay, path in truths]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=5, help="truth draws per state (5)")
    ap.add_argument("--cycles", type=int, default=20, help="cycles per session (20)")
    ap.add_argument("--seed", type=int, default=9000, help="first truth seed (9000)")
    ap.add_argument("--delay-max", type=float, default=1e-3, help="largest drawn accel_delay, s (1e-3)")
    ap.add_argument("--sessions", help="folder to keep (and reuse) the recorded sessions")
    ap.add_argument("--workers", type=int, default=None, help="compute workers (default: the machine's cores)")
    ap.add_argument("--record-only", action="store_true", help="record the truths and stop")
    args = ap.parse_args()
    os.environ.setdefault("WEARBENCH_CACHE", tempfile.mkdtemp(prefix="wearbench-windows-"))

    from wearbench.bench.load import load_bench, shipped_bench

    bench = load_bench(shipped_bench("ninebar-testbed"))
    states = bench.states
    folder = Path(args.sessions or tempfile.mkdtemp(prefix="wearbench-windows-sessions-"))
    t0 = time.perf_counter()
    truths = record_truths(bench, states, args, folder)
    print(f"{len(truths)} sessions in {folder} ({time.perf_counter() - t0:.0f} s)")
    if args.record_only:
        return


if __name__ == "__main__":
    main()
