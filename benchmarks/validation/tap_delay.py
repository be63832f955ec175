"""The sensor delay with a tap-tested statement: issue 26's delay mark measured through the tap test.

The truths are ``benchmarks/validation/windows.py``'s (same seeds, states, accel_delay drawn uniform in
[0, --delay-max], with --sensor-paths each truth's own drawn mount). For each truth a tap session is
recorded on the same emulated bench (the sim backend, cranks at rest, --taps taps: what
``wearbench taptest`` records) and ``validation.tap_test`` measures the latency from it; the bench's
``[sensor.chain]`` statement with that latency is then given to every window of the truth's session.
The true delay of a window is read from the emulator's side only: accel_delay plus the group delay of
that truth's own chain as it runs it (its mount, drawn or stud, and its anti-alias filter; averaged
over 1-100 Hz) plus its sample clock's drift at the window's middle.

Prints per truth the tap test's latency against the latency the windows need (the true delay less
the statement's filters), and over all windows the fitted delay's error with the tap-tested
statement, with the latency copied from the truth's accel_delay (the old benchmark's way), and from
the signal alone: the fraction within 0.2 ms (the mark: >= 0.90), the error's p5/p50/p95 and how often the fitted
residual sits at its bound or the statement is flagged (``windows.delay_rates``).

    .venv/bin/python -m benchmarks.validation.tap_delay [--draws 5] [--seed 31000] [--sensor-paths] [--sessions DIR] [--taps 10]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from wearbench.compute.options import QUIET

from benchmarks.validation.windows import (
    chain_delay,
    delay_rates,
    record_truths,
    tap_latencies,
    truth_specs,
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=5, help="truth draws per state (5)")
    ap.add_argument("--cycles", type=int, default=20, help="cycles per session (20)")
    ap.add_argument("--seed", type=int, default=31000, help="first truth seed (31000)")
    ap.add_argument("--delay-max", type=float, default=1e-3, help="largest drawn accel_delay, s (1e-3)")
    ap.add_argument("--sensor-paths", action="store_true", help="draw each truth's sensor path (as windows.py)")
    ap.add_argument("--sessions", help="folder to keep (and reuse) the recorded sessions")
    ap.add_argument("--taps", type=int, default=10, help="taps per tap session (10)")
    ap.add_argument("--workers", type=int, default=None, help="compute workers (default: the machine's cores)")
    ap.add_argument("--alpha", type=float, default=0.05, help="false-alarm rate of the verdict (0.05)")
    args = ap.parse_args()
    os.environ.setdefault("WEARBENCH_CACHE", tempfile.mkdtemp(prefix="wearbench-tap-delay-"))

    from wearbench.bench.load import load_bench, shipped_bench
    from wearbench.validation.comparison.windows import WindowOptions
    from wearbench.validation.inference.ensemble import EnsembleSettings, build_ensembles
    from wearbench.validation.measurement.chain_delay import stated_delay

    bench = load_bench(shipped_bench("ninebar-testbed"))
    folder = Path(args.sessions or tempfile.mkdtemp(prefix="wearbench-tap-delay-sessions-"))
    t0 = time.perf_counter()
    truths = record_truths(bench, bench.states, args, folder)
    specs = truth_specs(bench, bench.states, args, folder)
    c0 = time.process_time()
    tapped = tap_latencies(bench, specs, folder, args.taps)
    c_tap = (time.process_time() - c0) / len(specs)
    print(f"{len(truths)} sessions and their tap sessions in {folder} ({time.perf_counter() - t0:.0f} s; "
          f"tap session and test {c_tap:.2f} s CPU each)")
    chain = bench.sensor("accelerometer").chain
    stated = stated_delay(chain)
    print(f"\ntap test ({args.taps} taps) against the latency the windows need (true delay in 1-100 Hz less the "
          f"statement's filters, {(stated.filter + stated.sensor) * 1e3:.4f} ms):")
    errors = []
    for name, path, delay in truths:
        latency, config = tapped[path]
        need = chain_delay(config, bench)[0] - stated.filter - stated.sensor
        errors.append(latency - need)
        print(f"  {name:20s} {path.stem:28s} accel_delay {delay * 1e3:6.3f} ms  mount {config.accelerometer.resonance:7.0f} Hz"
              f"  needed {need * 1e3:7.4f} ms  tap test {latency * 1e3:7.4f} ms  error {errors[-1] * 1e6:+6.2f} us")
    errors = np.abs(errors)
    print(f"  tap test error: median {np.median(errors) * 1e6:.2f} us, largest {errors.max() * 1e6:.2f} us "
          f"({len(errors)} truths)")

    ensembles = build_ensembles(bench, bench.states, settings=EnsembleSettings(), compute=QUIET)
    ways = {"stated, latency from wearbench taptest": lambda p, d: replace(chain, latency=round(tapped[p][0], 6)),
            "stated, latency copied from the truth": lambda p, d: replace(chain, latency=round(d, 5)),
            "signal alone (no statement)": lambda p, d: None}
    delay_rates(bench, truths, tapped, ensembles, WindowOptions(alpha=args.alpha), ways)


if __name__ == "__main__":
    main()
