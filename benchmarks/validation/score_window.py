"""Benchmark: score one five-cycle window at 10 kHz (a 1 Hz bench: 50,000 samples) with all metrics.

Target: < 1 s for ``score_window`` (ISO/TS 18571 with banded DTW, NRMSE, peaks, correlation,
Sprague-Geers). A textbook full-matrix DTW would need n^2 float64 = 20 GB here; the banded one
needs n (2 band + 1) bytes. Prints a table of the steps of one window comparison (median of
``--repeat`` runs, after one warm-up run that compiles the numba DTW).

    .venv/bin/python -m benchmarks.validation.score_window [--samples 50000] [--repeat 5] [--band 0.05]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from wearbench.validation.comparison.alignment import estimate_lag, shift_signal
from wearbench.validation.comparison.dtw import dtw_banded
from wearbench.validation.comparison.metrics import iso18571, score_window, sprague_geers
from wearbench.validation.measurement.filters import FilterSpec, apply_filter


def signals(n: int, fs: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Five cycles of a slider-like acceleration with impacts; theory = a perturbed, delayed copy."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    phi = 2 * np.pi * 5 * t / t[-1]

    def acc(phi, gain, spikes):
        base = 40 * np.cos(phi) + 15 * np.cos(2 * phi + 0.5)
        for centre, height in spikes:
            base = base + height * np.exp(-((np.mod(phi, 2 * np.pi) - centre) / 0.03) ** 2)
        return gain * base

    test = acc(phi, 1.0, [(2.0, 60.0), (4.1, -45.0)]) + rng.normal(0, 1.5, n)
    theory = acc(phi - 0.004, 1.08, [(2.02, 70.0), (4.05, -30.0)])
    return test, theory


def timed(fn, repeat: int) -> tuple[float, object]:
    out = fn()  # warm-up (numba compilation, caches)
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=50_000)
    ap.add_argument("--fs", type=float, default=10_000.0)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--band", type=float, default=0.05, help="DTW band, fraction of one of the five cycles")
    args = ap.parse_args()
    n, fs = args.samples, args.fs
    cycle = n / 5
    band = max(1, int(args.band * cycle))
    max_lag = int(0.2 * cycle)
    test, theory = signals(n, fs)
    spec = FilterSpec(kind="cfc", cfc=180)
    ft, fth = apply_filter(test, fs, spec), apply_filter(theory, fs, spec)
    lag = estimate_lag(ft, fth, max_lag)
    aligned = shift_signal(fth, lag)

    rows = [
        ("CFC 180 filter, both signals", lambda: (apply_filter(test, fs, spec), apply_filter(theory, fs, spec))),
        ("residual shift (xcorr + sub-sample)", lambda: estimate_lag(ft, fth, max_lag)),
        ("apply fractional shift", lambda: shift_signal(fth, lag)),
        (f"banded DTW alone (band {band})", lambda: dtw_banded(ft, aligned, band)),
        ("ISO/TS 18571 (all four scores)", lambda: iso18571(ft, aligned, max_lag=max_lag, dtw_band=band)),
        ("Sprague-Geers", lambda: sprague_geers(ft, aligned)),
        ("score_window: every metric", lambda: score_window(ft, aligned, fs, cycle_samples=cycle, max_lag=max_lag,
                                                            dtw_band=band)),
    ]
    print(f"one window: {n} samples at {fs:g} Hz (5 cycles), DTW band {band} samples, phase search +/-{max_lag}, "
          f"median of {args.repeat}")
    print(f"{'step':44s} {'time (ms)':>10s}")
    results = {}
    for name, fn in rows:
        dt, out = timed(fn, args.repeat)
        results[name] = out
        print(f"{name:44s} {1e3 * dt:10.1f}")
    total_name = "score_window: every metric"
    total, _ = timed(rows[-1][1], 1)
    full_gb = n * n * 8 / 1e9
    band_mb = n * (2 * band + 1) / 1e6
    print(f"\nDTW memory: banded {band_mb:.0f} MB (direction bytes) vs full matrix {full_gb:.0f} GB (float64)")
    s = results[total_name]
    print(f"scores: R = {s.iso_rating:.3f} ({s.iso_grade}), corridor {s.iso_corridor:.3f}, phase {s.iso_phase:.3f}, "
          f"magnitude {s.iso_magnitude:.3f}, slope {s.iso_slope:.3f}, NRMSE {s.nrmse:.3f}, S&G C {s.sg_comprehensive:.3f}; "
          f"shift found {lag / fs * 1e3:+.3f} ms")
    print(f"target < 1000 ms for score_window: {'met' if total < 1.0 else 'NOT met'} ({1e3 * total:.0f} ms)")


if __name__ == "__main__":
    main()
