"""The tap test: the accelerometer's latency behind the encoder, measured from a recorded tap session.

A tapper strikes the slider with the cranks at rest; the drive latches its trigger on the encoder's
clock (a "tap" event, ``acquisition/taps.py``). The accelerometer sees the tap through its chain. For
each tap the response predicted by the bench's ``[sensor.chain]`` statement (its filters, no latency)
to the recorded half-sine pulse at the latch is fitted to the measured response by least squares in
gain and shift, in the frequency band the windows are aligned in (``band``, default 1-100 Hz: the
band the statement's delay is averaged over, so a mount the statement does not name counts as it
does in a window). The shift is what the statement leaves out: less the stated clock drift's share
since the stream began, it is the tap's ``latency``. Over all taps: the median and a distribution-free
interval for it (order statistics). Fitting a shift of the whole response, not picking an onset, is
what keeps the filter's smearing out of it. Imports numpy, scipy, the bench schema, acquisition's
session reader and the chain statement's response.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from scipy import optimize, stats
from wearbench.acquisition.session_file import read_session
from wearbench.acquisition.taps import RecordedTap, recorded_taps
from wearbench.bench.schema import Bench, SensorChainStatement
from wearbench.validation.measurement.chain_delay import stated_response
from wearbench.validation.measurement.session import stream_start

__all__ = ["TapFit", "TapTest", "TapTestError", "fit_shift", "half_sine_spectrum", "tap_test"]

PRE = 0.05       # s of samples before a latch in its segment (bias and noise come from them)
POST = 0.3       # s after it: the response must have died away (a 300 Hz mount at damping 0.02: e^-11)
MIN_SNR = 20.0   # peak response / noise rms below which a tap is too weak to time
MIN_MATCH = 0.9  # fraction of the band's energy the stated response must explain
SPREAD = 5e-5    # s: a tap further than this (or 6 robust sigmas) from the median is inconsistent


class TapTestError(ValueError):
    """A tap session that cannot give a latency; the message names the file, the tap and why."""


@dataclass(frozen=True)
class TapFit:
    """One tap: its ``latch`` (s, session clock), the fitted ``shift`` (s) of the measured response
    behind the stated chain's prediction, the stated clock drift's ``drift`` share (s) in it, the
    ``latency`` (shift - drift, s), the ``gain`` (measured / predicted), ``snr`` and ``match`` (the
    fraction of the band's energy the shifted prediction explains)."""

    number: int
    latch: float
    shift: float
    drift: float
    gain: float
    snr: float
    match: float

    @property
    def latency(self) -> float:
        return self.shift - self.drift


@dataclass(frozen=True)
class TapTest:
    """The latency over all taps: ``latency`` (median, s), its ``interval`` (s) of ``coverage``
    (order statistics of the taps' latencies), and the statement with that latency (``chain``)."""

    source: str
    taps: tuple[TapFit, ...]
    latency: float
    interval: tuple[float, float]
    coverage: float
    band: tuple[float, float]
    chain: SensorChainStatement

    def line(self) -> str:
        """The ``[sensor.chain]`` line to enter."""
        return f'latency = "{self.latency * 1e3:.3f} ms"'

    def describe(self) -> str:
        lo, hi = self.interval
        return (f"latency {self.latency * 1e3:.3f} ms ({self.coverage:.0%} interval {lo * 1e3:.3f} .. {hi * 1e3:.3f} ms) "
                f"from {len(self.taps)} taps, fitted in {self.band[0]:g}-{self.band[1]:g} Hz")

    def to_dict(self) -> dict:
        return {"source": self.source, "latency_s": self.latency, "interval_s": list(self.interval),
                "coverage": self.coverage, "band_hz": list(self.band),
                "taps": [{"number": t.number, "latch_s": t.latch, "shift_s": t.shift, "drift_s": t.drift,
                          "latency_s": t.latency, "gain": t.gain, "snr": t.snr, "match": t.match} for t in self.taps]}


def half_sine_spectrum(f: np.ndarray, width: float) -> np.ndarray:
    """Fourier transform at ``f`` (Hz) of a unit-peak half-sine pulse of ``width`` s starting at 0:
    a (1 + e^{-j w width}) / (a^2 - w^2), a = pi / width (valid away from w = a, far above the band)."""
    w = 2 * np.pi * np.asarray(f, dtype=float)
    a = np.pi / width
    return a * (1 + np.exp(-1j * w * width)) / (a * a - w * w)


def fit_shift(measured: np.ndarray, predicted: np.ndarray, f: np.ndarray, *,
              search: tuple[float, float] = (-0.01, 0.02)) -> tuple[float, float, float]:
    """(shift s, gain, match) of the least-squares fit ``measured ~ gain x predicted x e^{-j 2 pi f shift}``
    over the spectra at ``f`` (Hz), the shift within ``search`` (s): a grid fine against the band's
    shortest period, then Brent's method around its best point."""
    w = 2 * np.pi * np.asarray(f, dtype=float)
    cross = measured * np.conj(predicted)

    def corr(tau: float) -> float:
        return float(np.real(np.sum(cross * np.exp(1j * w * tau))))

    step = 0.05 / max(float(np.max(f)), 1.0)
    grid = np.arange(search[0], search[1] + step, step)
    values = np.real(np.exp(1j * np.outer(grid, w)) @ cross)
    i = int(np.argmax(values))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    res = optimize.minimize_scalar(lambda t: -corr(t), bounds=(lo, hi), method="bounded",
                                   options={"xatol": 1e-9})
    tau = float(res.x)
    pp = float(np.sum(np.abs(predicted) ** 2))
    mm = float(np.sum(np.abs(measured) ** 2))
    c = corr(tau)
    return tau, c / pp, (c * c / (pp * mm)) if mm > 0 else 0.0


def _accelerometer_chain(bench: Bench, source: str) -> SensorChainStatement:
    try:
        acc = bench.sensor("accelerometer")
    except KeyError:
        raise TapTestError(f"{source}: the bench {bench.name!r} has no [[sensor]] of kind accelerometer") from None
    if acc.chain is None:
        raise TapTestError(f"{source}: the bench's accelerometer {acc.name!r} has no [sensor.chain] statement; "
                           "state its anti-alias filter and mounted resonance (or their delays) first: the tap test "
                           "measures what they leave out")
    return acc.chain


def _median_interval(x: np.ndarray, level: float = 0.95) -> tuple[tuple[float, float], float]:
    """Distribution-free interval for the median: order statistics (k, n + 1 - k) with coverage
    1 - 2 P(Binomial(n, 1/2) <= k - 1), the narrowest reaching ``level`` (else the whole range)."""
    xs, n = np.sort(x), x.size
    best = 1
    for k in range(1, n // 2 + 1):
        if 1 - 2 * stats.binom.cdf(k - 1, n, 0.5) >= level:
            best = k
    return (float(xs[best - 1]), float(xs[n - best])), float(1 - 2 * stats.binom.cdf(best - 1, n, 0.5))


def tap_test(path: str | Path, bench: Bench | None = None, *, band: tuple[float, float] = (1.0, 100.0),
             chain: SensorChainStatement | None = None) -> TapTest:
    """The latency of the session at ``path`` (a tap session's MCAP) under ``bench``'s statement
    (default: the bench recorded in the session; ``chain`` replaces its ``[sensor.chain]``)."""
    source = str(path)
    session = read_session(path)
    bench = bench or session.bench
    if bench is None:
        raise TapTestError(f"{source}: the session holds no bench file; give the bench")
    chain = replace(chain or _accelerometer_chain(bench, source), latency=0.0)
    taps = recorded_taps(session.events)
    if not taps:
        raise TapTestError(f"{source}: no taps recorded (no 'tap' events with a latched trigger); record a tap "
                           "session with 'wearbench taptest BENCH'")
    acc = session.acceleration
    if acc.empty:
        raise TapTestError(f"{source}: no accelerometer samples")
    t = acc["time"].to_numpy()
    x = acc["acc"].to_numpy()
    clipped = acc["clipped"].to_numpy(bool)  # the reader's flags
    fs = session.sample_rate  # the rate the blocks were recorded at, not the bench file's nominal one
    start = stream_start(acc, fs)
    fits = [_fit_tap(tap, taps, t, x, clipped, fs, chain, band, start, source) for tap in taps]
    lat = np.array([f.latency for f in fits])
    med = float(np.median(lat))
    mad = 1.4826 * float(np.median(np.abs(lat - med)))
    off = [f for f in fits if abs(f.latency - med) > max(SPREAD, 6 * mad)]
    if off:
        listed = ", ".join(f"tap {f.number} at {f.latch:.3f} s: {f.latency * 1e3:.3f} ms" for f in off)
        raise TapTestError(f"{source}: inconsistent taps: {listed} against the median {med * 1e3:.3f} ms of "
                           f"{len(fits)} (expected within {max(SPREAD, 6 * mad) * 1e3:.3f} ms): a double strike, a "
                           "tap while the cranks moved, or a latch of another edge; repeat those taps")
    interval, coverage = _median_interval(lat)
    return TapTest(source, tuple(fits), med, interval, coverage, (float(band[0]), float(band[1])),
                   replace(chain, latency=round(med, 6)))


def _fit_tap(tap: RecordedTap, taps: list[RecordedTap], t: np.ndarray, x: np.ndarray, clipped: np.ndarray,
             fs: float, chain: SensorChainStatement, band: tuple[float, float], start: float,
             source: str) -> TapFit:
    name = f"{source}: tap {tap.number} at {tap.latch:.4f} s"
    others = [o.latch for o in taps if o is not tap]
    before = max([o for o in others if o < tap.latch], default=-math.inf)
    after = min([o for o in others if o > tap.latch], default=math.inf)
    gap = min(tap.latch - before, after - tap.latch)
    if gap < PRE + POST:
        raise TapTestError(f"{name}: another tap {gap:.3f} s away; expected >= {PRE + POST:g} s between taps (a "
                           "response must die away before the next tap's segment begins)")
    sel = (t >= tap.latch - PRE) & (t < tap.latch + POST)
    n_expected = int((PRE + POST) * fs) - 2
    if np.count_nonzero(sel) < n_expected or t[sel][0] > tap.latch - PRE + 2 / fs:
        raise TapTestError(f"{name}: the accelerometer record does not cover {PRE * 1e3:g} ms before to "
                           f"{POST * 1e3:g} ms after the tap ({np.count_nonzero(sel)} of {n_expected} samples)")
    if np.any(np.abs(np.diff(t[sel]) * fs - 1) > 0.1):
        raise TapTestError(f"{name}: accelerometer samples are missing in its response (dropped blocks); "
                           "repeat the tap")
    if np.any(clipped[sel]):
        raise TapTestError(f"{name}: the accelerometer clipped in its response ({int(np.count_nonzero(clipped[sel]))} "
                           "samples at full scale); tap more softly (a lower peak) or raise the range")
    ts, xs = t[sel], x[sel].astype(float)
    quiet = ts < tap.latch - 0.005
    xs = xs - float(np.mean(xs[quiet]))
    noise = float(np.std(xs[quiet]))
    snr = float(np.max(np.abs(xs[~quiet]))) / max(noise, 1e-12)
    if snr < MIN_SNR:
        raise TapTestError(f"{name}: too weak: the response peaks at {snr:.1f} x the noise rms before it (expected >= "
                           f"{MIN_SNR:g}); tap harder, or check the accelerometer sees the slider")
    n = xs.size
    f = np.fft.rfftfreq(n, 1.0 / fs)
    keep = (f >= band[0]) & (f <= band[1])
    if np.count_nonzero(keep) < 4:
        raise TapTestError(f"{name}: the band {band[0]:g}-{band[1]:g} Hz holds {np.count_nonzero(keep)} frequencies "
                           f"of a {n / fs:.3f} s segment; expected >= 4")
    f = f[keep]
    measured = np.fft.rfft(xs)[keep] * np.exp(-2j * np.pi * f * ts[0]) / fs
    predicted = tap.peak * half_sine_spectrum(f, tap.width) * stated_response(chain, f) * np.exp(-2j * np.pi * f * tap.latch)
    shift, gain, match = fit_shift(measured, predicted, f)
    if match < MIN_MATCH:
        raise TapTestError(f"{name}: the stated chain's response explains {match:.0%} of the measured one in "
                           f"{band[0]:g}-{band[1]:g} Hz (expected >= {MIN_MATCH:.0%}): a double strike, or a chain "
                           "unlike its statement")
    drift = chain.clock_drift / (1.0 + chain.clock_drift) * (tap.latch - start)
    return TapFit(tap.number, tap.latch, shift, drift, gain, snr, match)
