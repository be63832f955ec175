"""How well can a sensor delay be found from the signal at all? The floor set by the bench's tolerances.

A measured window is aligned with the theory by the encoder's crank angle; the accelerometer's delay
behind the encoder is what is left, and ``validation.windows`` fits it on the session's curve. But a
bench drawn within its tolerances moves its own curve in crank angle too (lengths, ground points,
masses, friction), and nothing in the signal tells that shift from a delay. Here every realisation
of the shipped ensembles plays a session whose true delay is 0: the time shift that best aligns its
mean cycle (8 cycles) with the other realisations' mean, by least squares over the crank harmonics up
to ``fmax``, (a) of the CFC 180 curve (what ``windows`` fits, at 10 Hz) and (b) of the impacts'
energy envelope by crank angle (high-passed at 50 Hz, log10 of the mean square: the impacts' onset
times); and (c) the chaos alone: a realisation's cycles 1-4 against its own cycles 5-8 (one bench).
Prints the shifts' percentiles and the fraction within 0.2 ms (issue 26's mark: 0.90).

    .venv/bin/python -m benchmarks.validation.delay_floor       # shipped ensembles, no simulation (about a minute)
"""

from __future__ import annotations

import numpy as np
from scipy import signal
from wearbench.compute.options import QUIET


def shifts(spec: np.ndarray, f: np.ndarray, fmax: float, search: float = 3e-3) -> np.ndarray:
    """Per realisation (rows of the crank-harmonic spectra ``spec``), the shift (s) in +/- ``search``
    minimising the squared difference from the other rows' mean over harmonics 0 < f <= fmax."""
    h = (f > 0) & (f <= fmax)
    grid = np.linspace(-search, search, 601)
    rot = np.exp(2j * np.pi * f[h][None, :] * grid[:, None])  # (shifts, harmonics)
    out = []
    for r in range(spec.shape[0]):
        ref = np.delete(spec, r, axis=0).mean(axis=0)[h]
        cost = np.sum(np.abs(spec[r, h][None, :] * rot - ref[None, :]) ** 2, axis=1)
        out.append(grid[int(np.argmin(cost))])
    return np.asarray(out)


def main() -> None:
    from wearbench.bench.load import load_bench, shipped_bench
    from wearbench.validation.inference.ensemble import build_ensembles

    bench = load_bench(shipped_bench("ninebar-testbed"))
    ens = build_ensembles(bench, bench.states, compute=QUIET)
    print("time shift of a realisation's 8-cycle mean against the others' (true delay 0), ms")
    print(f"{'state':20s} {'signal':38s} {'p5':>6s} {'p50':>6s} {'p95':>6s}  within 0.2 ms")
    for name, e in ens.items():
        m, c, grid = e.curves.shape
        period = 2 * np.pi / e.speed / bench.encoder_driver.ratio
        f = np.fft.rfftfreq(grid, period / grid)
        hp = signal.sosfiltfilt(signal.butter(4, 50.0, btype="high", fs=grid / period, output="sos"),
                                e.curves.reshape(m, -1), axis=1).reshape(m, c, grid)
        rows = [(f"curve, harmonics <= {fmax:g} Hz", np.fft.rfft(e.curves.mean(axis=1), axis=1), fmax)
                for fmax in (10.0, 20.0, 50.0)]
        rows += [(f"impact envelope, harmonics <= {fmax:g} Hz",
                  np.fft.rfft(np.log10((hp ** 2).mean(axis=1) + 1.0), axis=1), fmax) for fmax in (20.0, 100.0)]
        for label, spec, fmax in rows:
            t = shifts(spec, f, fmax) * 1e3
            p5, p50, p95 = np.percentile(t, [5, 50, 95])
            print(f"{name:20s} {label:38s} {p5:+6.2f} {p50:+6.2f} {p95:+6.2f}  {np.mean(np.abs(t) <= 0.2):.2f}")
        # the chaos alone: one realisation's cycles 1-4 against its cycles 5-8 (the same bench)
        h = (f > 0) & (f <= 10.0)
        a, b = np.fft.rfft(e.curves[:, : c // 2].mean(axis=1), axis=1), np.fft.rfft(e.curves[:, c // 2:].mean(axis=1),
                                                                                    axis=1)
        grid_t = np.linspace(-3e-3, 3e-3, 601)
        rot = np.exp(2j * np.pi * f[h][None, :] * grid_t[:, None])
        t = np.array([grid_t[int(np.argmin(np.sum(np.abs(a[r, h] * rot - b[r, h]) ** 2, axis=1)))]
                      for r in range(m)]) * 1e3
        p5, p50, p95 = np.percentile(t, [5, 50, 95])
        print(f"{name:20s} {'same bench, half against half, 10 Hz':38s} {p5:+6.2f} {p50:+6.2f} {p95:+6.2f}  "
              f"{np.mean(np.abs(t) <= 0.2):.2f}")


if __name__ == "__main__":
    main()
