"""Scores of one comparison window: ISO/TS 18571, Sprague-Geers, NRMSE, peaks, correlation.

Holds ``iso18571`` (``IsoScore``), ``sprague_geers``, ``score_window`` (``WindowScores``: every
metric of one window) and ``aggregate`` (mean, spread and range over windows). The measured (test)
signal is the reference, the theory the comparison. Pure numpy; imports only validation.dtw and
validation.alignment.

ISO/TS 18571:2014, as in its reference implementation (OpenVT, TU Graz):
- corridor Z: inner/outer half-widths a0 = 0.05 and b0 = 0.5 of max|reference|, exponent kZ = 2,
  mean over samples;
- phase E_P: Pearson correlation of the overlapping parts for integer lags up to eps_P N
  (eps_P = 0.2); E_P = ((eps_P N - |lag|) / (eps_P N))^kP, kP = 1;
- magnitude E_M: DTW (squared local cost, unit steps) of the phase-shifted, truncated pair,
  e_mag = ||C_w - T_w||_1 / ||T_w||_1, E_M = ((eps_M - e_mag) / eps_M)^kM, eps_M = 0.5, kM = 1;
- slope E_S: central differences smoothed by a 9-point moving average (1, 3, 5, 7 at the ends) of the
  shifted pair, e_slope = L1 ratio, E_S = (eps_S - e_slope) / eps_S, eps_S = 2;
- R = 0.4 Z + 0.2 E_P + 0.2 E_M + 0.2 E_S; grade excellent R > 0.94, good > 0.8, fair > 0.58, poor.

Called plainly, ``iso18571(x, y)`` is the standard as its reference implementation computes it
(checked against ``objective-rating-metrics``, TU Graz, in tests/validation/test_metrics.py): DTW
band ceil(0.1 N) - 1 samples, phase search up to eps_P N, ties as the standard breaks them (the
smallest shift; on an exact +/-m tie the comparison late first; DTW steps (i, j-1), (i-1, j), then
the diagonal). Constant signals (all zero included) have no correlation and raise ValueError.

Where the wearbench pipeline (validation.compare, validation.bands, through ``score_window``)
departs from it, each an explicit option, and why:
- DTW band: the reference implementation uses a Sakoe-Chiba band of 10 % of the window; the
  pipeline passes ``dtw_band`` samples (validation.compare: 5 % of one crank cycle, 1 % of a
  five-cycle window). On a periodic signal a 10 % band (half a cycle) lets the warping pair an impact
  with the next impact and hides magnitude errors; it would also cost 10x the time and memory
  (500 M band cells at 50,000 samples).
- Ties (``ties="wearbench"``, ``score_window``'s default): on an exact +/-m phase tie the comparison
  early first, DTW ties to the diagonal first. Exact ties need quantised or step-shaped signals;
  kept so the pipeline's scores do not move (E_M differs by up to 0.05 on such signals).
- Phase search: limited to ``max_lag`` (validation.compare: 0.2 of one cycle) instead of 0.2 N, since
  a five-cycle window shifted by 0.2 N = one whole cycle correlates perfectly with itself. The score
  still normalises by eps_P N, so values stay comparable with the standard's.
- Sampling: the standard asks for 10 kHz; we score at the session's own rate (the test bed records
  at 10 kHz; the theory is evaluated on the measured sample times).
- Errors that are zero for a perfect match (NRMSE, peak errors, Sprague-Geers) are reported as errors,
  not scores; ``correlation`` and the ISO sub-scores are 1 for a perfect match.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields

import numpy as np
import pandas as pd
from wearbench.validation.comparison.alignment import lag_correlations
from wearbench.validation.comparison.dtw import dtw_banded

__all__ = [
    "ISO_WEIGHTS",
    "IsoScore",
    "SpragueGeers",
    "WindowScores",
    "aggregate",
    "grade",
    "iso18571",
    "score_window",
    "sprague_geers",
]

A0, B0, K_Z = 0.05, 0.5, 2.0
EPS_P, K_P = 0.2, 1.0
EPS_M, K_M = 0.5, 1.0
EPS_S, K_S = 2.0, 1.0
ISO_WEIGHTS = (0.4, 0.2, 0.2, 0.2)  # corridor, phase, magnitude, slope
GRADES = ((0.94, "excellent"), (0.8, "good"), (0.58, "fair"))


def grade(rating: float) -> str:
    """ISO/TS 18571 grade of an overall rating R."""
    for limit, name in GRADES:
        if rating > limit:
            return name
    return "poor"


@dataclass(frozen=True)
class IsoScore:
    """ISO/TS 18571 sub-scores (0..1), overall rating, grade, and the raw errors behind them."""

    corridor: float
    phase: float
    magnitude: float
    slope: float
    rating: float
    grade: str
    lag: int  # samples, comparison late if > 0
    magnitude_error: float
    slope_error: float


def _pair(reference: np.ndarray, comparison: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    x = np.asarray(reference, dtype=float)
    y = np.asarray(comparison, dtype=float)
    if x.ndim != 1 or x.shape != y.shape or x.size < 16:
        raise ValueError(f"scores: expected two 1-D signals of equal length >= 16, got {x.shape} and {y.shape}")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise ValueError("scores: signals contain NaN or infinite samples")
    return x, y


def _smoothed_slope(x: np.ndarray) -> np.ndarray:
    """Central-difference derivative (per sample) smoothed by the standard's 9-point moving average."""
    d = np.gradient(x)
    out = np.empty_like(d)
    out[4:-4] = np.convolve(d, np.ones(9) / 9.0, mode="valid")
    for k, nr in enumerate((1, 3, 5, 7)):
        out[k] = d[:nr].mean()
        out[-1 - k] = d[-nr:].mean()
    return out


def _ratio(num: float, den: float) -> float:
    if den > 0:
        return num / den
    return 0.0 if num == 0 else np.inf


def iso18571(reference: np.ndarray, comparison: np.ndarray, *, max_lag: int | None = None,
             dtw_band: int | None = None, ties: str = "standard") -> IsoScore:
    """ISO/TS 18571 rating of ``comparison`` (theory) against ``reference`` (test), same sampling.

    Defaults are the standard's. max_lag: phase search range (samples), default eps_P N. dtw_band:
    Sakoe-Chiba half-width (samples), default ceil(0.1 N') - 1 of the shifted length N' (the
    standard's 10 %). ties: "standard" or "wearbench" (see the module docstring). Raises ValueError
    for a constant signal.
    """
    if ties not in ("standard", "wearbench"):
        raise ValueError(f"iso18571: ties = {ties!r}: expected 'standard' or 'wearbench'")
    x, y = _pair(reference, comparison)
    for name, s in (("reference", x), ("comparison", y)):
        if np.ptp(s) == 0:
            raise ValueError(f"iso18571: the {name} signal is constant ({s[0]:.6g} throughout); ISO/TS 18571 "
                             "needs a varying signal (its phase score is a correlation)")
    n = x.size
    # corridor (unshifted)
    t_norm = np.max(np.abs(x))
    inner, outer = A0 * t_norm, B0 * t_norm
    diff = np.abs(x - y)
    if outer > inner:
        c = np.clip((outer - diff) / (outer - inner), 0.0, 1.0) ** K_Z
    else:
        c = np.zeros(n)
    c[diff <= inner] = 1.0
    corridor = float(c.mean())
    # phase
    limit = EPS_P * n
    search = int(np.floor(limit)) if max_lag is None else int(min(max_lag, np.floor(limit)))
    lags, rho = lag_correlations(x, y, search)
    best = np.flatnonzero(rho >= rho.max() - 1e-12)  # ties (a whole period away): the smallest lag
    smallest = lags[best][np.abs(lags[best]) == np.abs(lags[best]).min()]
    lag = int(smallest.max() if ties == "standard" else smallest.min())  # +m: the comparison late
    phase = 1.0 if lag == 0 else float(max(0.0, (limit - abs(lag)) / limit) ** K_P)
    xs = x[max(-lag, 0): n - max(lag, 0)]
    ys = y[max(lag, 0): n - max(-lag, 0)]
    # magnitude by DTW of the shifted pair
    band = int(np.ceil(0.1 * xs.size)) - 1 if dtw_band is None else int(dtw_band)
    _, pi, pj = dtw_banded(xs, ys, max(band, 0), ties="standard" if ties == "standard" else "diagonal")
    e_mag = _ratio(float(np.sum(np.abs(ys[pj] - xs[pi]))), float(np.sum(np.abs(xs[pi]))))
    magnitude = float(np.clip((EPS_M - e_mag) / EPS_M, 0.0, 1.0) ** K_M)
    # slope of the shifted pair
    dx, dy = _smoothed_slope(xs), _smoothed_slope(ys)
    e_slope = _ratio(float(np.sum(np.abs(dy - dx))), float(np.sum(np.abs(dx))))
    slope = float(np.clip((EPS_S - e_slope) / EPS_S, 0.0, 1.0) ** K_S)
    w = ISO_WEIGHTS
    rating = w[0] * corridor + w[1] * phase + w[2] * magnitude + w[3] * slope
    return IsoScore(corridor, phase, magnitude, slope, float(rating), grade(rating), lag, float(e_mag),
                    float(e_slope))


@dataclass(frozen=True)
class SpragueGeers:
    """Sprague-Geers (2004) magnitude M, phase P and comprehensive C errors (0 for a perfect match)."""

    magnitude: float
    phase: float
    comprehensive: float


def sprague_geers(measured: np.ndarray, computed: np.ndarray) -> SpragueGeers:
    """M = sqrt(psi_cc / psi_mm) - 1, P = arccos(psi_mc / sqrt(psi_mm psi_cc)) / pi, C = sqrt(M^2 + P^2).

    psi_ab = integral of a b over the window (uniform sampling, so sums; the sample interval cancels).
    """
    m, c = _pair(measured, computed)
    mm, cc, mc = float(m @ m), float(c @ c), float(m @ c)
    if mm == 0 or cc == 0:
        return SpragueGeers(np.inf, np.inf, np.inf) if mm != cc else SpragueGeers(0.0, 0.0, 0.0)
    mag = float(np.sqrt(cc / mm) - 1.0)
    phase = float(np.arccos(np.clip(mc / np.sqrt(mm * cc), -1.0, 1.0)) / np.pi)
    return SpragueGeers(mag, phase, float(np.hypot(mag, phase)))


@dataclass(frozen=True)
class WindowScores:
    """Every metric of one window; ``iso_*`` and ``correlation`` are 1 for a perfect match, the rest 0.

    nrmse: RMS(theory - test) / (max(test) - min(test)). peak_error: (max|theory| - max|test|) /
    max|test|. peak_time_shift: seconds theory peak minus test peak (median over cycles when the
    cycle length is known). correlation: Pearson at zero lag.
    """

    iso_rating: float
    iso_grade: str
    iso_corridor: float
    iso_phase: float
    iso_magnitude: float
    iso_slope: float
    iso_lag_s: float
    nrmse: float
    peak_error: float
    peak_time_shift: float
    correlation: float
    sg_magnitude: float
    sg_phase: float
    sg_comprehensive: float

    def to_dict(self) -> dict:
        return asdict(self)


NUMERIC_METRICS = tuple(f.name for f in fields(WindowScores) if f.name != "iso_grade")


def _peak_time_shift(x: np.ndarray, y: np.ndarray, fs: float, cycle_samples: float | None) -> float:
    if not cycle_samples or cycle_samples >= x.size:
        return float((np.argmax(np.abs(y)) - np.argmax(np.abs(x))) / fs)
    shifts = []
    edges = np.arange(0.0, x.size - 0.5 * cycle_samples + 1e-9, cycle_samples)
    for a in edges:
        i0, i1 = round(a), min(round(a + cycle_samples), x.size)
        d = int(np.argmax(np.abs(y[i0:i1])) - np.argmax(np.abs(x[i0:i1])))
        half = (i1 - i0) / 2
        d = (d + half) % (i1 - i0) - half  # a peak near the cycle edge: take the nearer copy
        shifts.append(d)
    return float(np.median(shifts) / fs)


def score_window(test: np.ndarray, theory: np.ndarray, fs: float, *, cycle_samples: float | None = None,
                 max_lag: int | None = None, dtw_band: int | None = None, ties: str = "wearbench") -> WindowScores:
    """All metrics of one window of test and theory sampled together at ``fs`` Hz.

    cycle_samples: samples per crank cycle (per-cycle peak timing); max_lag, dtw_band, ties: see
    ``iso18571`` (the pipeline's ties by default; dtw_band None: 1 % of the window, as before).
    """
    x, y = _pair(test, theory)
    if dtw_band is None:
        dtw_band = int(np.ceil(0.01 * x.size))
    iso = iso18571(x, y, max_lag=max_lag, dtw_band=dtw_band, ties=ties)
    span = float(x.max() - x.min())
    nrmse = _ratio(float(np.sqrt(np.mean((y - x) ** 2))), span)
    px, py = float(np.max(np.abs(x))), float(np.max(np.abs(y)))
    sx, sy = x.std(), y.std()
    corr = float(np.mean((x - x.mean()) * (y - y.mean())) / (sx * sy)) if sx > 0 and sy > 0 else 0.0
    sg = sprague_geers(x, y)
    return WindowScores(
        iso_rating=iso.rating, iso_grade=iso.grade, iso_corridor=iso.corridor, iso_phase=iso.phase,
        iso_magnitude=iso.magnitude, iso_slope=iso.slope, iso_lag_s=iso.lag / fs, nrmse=nrmse,
        peak_error=_ratio(py - px, px), peak_time_shift=_peak_time_shift(x, y, fs, cycle_samples),
        correlation=float(np.clip(corr, -1.0, 1.0)), sg_magnitude=sg.magnitude, sg_phase=sg.phase,
        sg_comprehensive=sg.comprehensive)


def aggregate(scores: list[WindowScores]) -> pd.DataFrame:
    """Mean, standard deviation, min and max of each numeric metric over windows (rows: metrics)."""
    if not scores:
        raise ValueError("aggregate: no windows were scored")
    frame = pd.DataFrame([s.to_dict() for s in scores])[list(NUMERIC_METRICS)]
    table = pd.DataFrame({"mean": frame.mean(), "std": frame.std(ddof=1) if len(frame) > 1 else 0.0 * frame.mean(),
                          "min": frame.min(), "max": frame.max()})
    table["windows"] = len(frame)
    return table
