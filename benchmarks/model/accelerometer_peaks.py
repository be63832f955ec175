"""How large do the test bed's impacts get at the accelerometer? Prints one table (what the shipped
test bed's accelerometer range is chosen from).

For each [[state]] of ninebar-testbed.toml and SEEDS non-twin truths, the emulator device streams
REVOLUTIONS revolutions at 10 kHz through several sensor chains (no clipping, no ADC, no noise);
rows give the largest |acceleration| of each chain over all seeds (median and max of the per-session
peaks), and the raw model run's peak at the table's 20 kHz resolution.

    .venv/bin/python -m benchmarks.model.accelerometer_peaks [SEEDS] [REVOLUTIONS]
"""

from __future__ import annotations

import math
import sys

import numpy as np
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.hardware.emulators.config import emulator_config
from wearbench.hardware.emulators.device import AccelBlock, BenchDevice, ManualClock

G = 9.80665
RATE = 10000.0
CLEAN = {"noise": "0 m/s^2", "bias": "0 m/s^2", "clipping": False, "adc_bits": 0, "drift": "0 ppm"}
CHAINS = {
    "point sampled (no filter)": {"aa_filter": "none", "resonance": "0 Hz"},
    "AA Butterworth 8 @ 0.3 fs": {"aa_filter": "butterworth", "aa_order": 8, "aa_cutoff": 0.3, "resonance": "0 Hz"},
    "stud IEPE 25 kHz z=0.03 + AA": {"aa_filter": "butterworth", "aa_order": 8, "aa_cutoff": 0.3,
                                      "resonance": "25 kHz", "damping": 0.03},
    "bracket 5 kHz z=0.05 + AA": {"aa_filter": "butterworth", "aa_order": 8, "aa_cutoff": 0.3,
                                  "resonance": "5 kHz", "damping": 0.05},
    "slider mode 1.5 kHz z=0.05 + AA": {"aa_filter": "butterworth", "aa_order": 8, "aa_cutoff": 0.3,
                                        "resonance": "1.5 kHz", "damping": 0.05},
}


def peak(bench, state, seed, chain, revolutions) -> tuple[float, float]:
    cfg = emulator_config(bench, state, seed, accelerometer={**CLEAN, **chain}, revolutions=revolutions)
    clock = ManualClock()
    d = BenchDevice(bench, cfg, clock)
    d.configure_accelerometer(1e5, RATE)
    d.enable()
    d.set_speed(bench.speed)
    clock.advance(0.5)
    d.start_stream()
    x = []
    for _ in range(round((revolutions - 1) * 2 * math.pi / abs(bench.speed) / 0.1)):
        clock.advance(0.1)
        x += [b.samples for b in d.read() if isinstance(b, AccelBlock)]
    raw = float(np.abs(d.prepare(bench.speed).acc).max())
    return float(np.abs(np.concatenate(x)).max()), raw


def main() -> None:
    seeds = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    revolutions = int(sys.argv[2]) if len(sys.argv) > 2 else 10
    bench = load_bench(shipped_bench("ninebar-testbed"))
    rows = []
    raws: dict[str, list[float]] = {}
    for state in bench.states:
        peaks: dict[str, list[float]] = {name: [] for name in CHAINS}
        for seed in range(1, seeds + 1):
            for name, chain in CHAINS.items():
                p, raw = peak(bench, state.name, seed, chain, revolutions)
                peaks[name].append(p)
            raws.setdefault(state.name, []).append(raw)
        for name in CHAINS:
            v = np.array(peaks[name])
            rows.append((state.name, name, f"{np.median(v) / G:.1f}", f"{v.max() / G:.1f}"))
        v = np.array(raws[state.name])
        rows.append((state.name, "raw model run (20 kHz table)", f"{np.median(v) / G:.1f}", f"{v.max() / G:.1f}"))
    head = ("state", "sensor chain at 10 kHz", "median peak (g)", "max peak (g)")
    widths = [max(len(r[i]) for r in [head, *rows]) for i in range(4)]
    for r in [head, tuple("-" * w for w in widths), *rows]:
        print("  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)))
    print(f"\n{seeds} seeds x {revolutions} revolutions per state; peaks over the whole run after settling")


if __name__ == "__main__":
    main()
