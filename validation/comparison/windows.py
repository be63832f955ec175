"""Five-cycle windows against the theory ensemble's own windows, by crank angle, with a verdict.

A measured window (``cycles`` consecutive steady crank cycles, CFC 180, on the ensemble's crank-angle
grid) is compared with the windows of the ensemble's realisations of one state, impacts included:
the band (5-95 % per crank angle over the realisations' cycles), single realisations, and the same
statistics of held-out realisations, which calibrate the verdict.

Alignment: the encoder's crank angle aligns the two; what is left is the sensor chain's delay (the
accelerometer late behind the encoder: anti-alias filter, mounting, DAQ). Where the bench states its
chain (``[sensor.chain]``, ``chain_delay.StatedDelay``), each cycle is read at the stated delay (its
filters' group delay, latency, and the clock drift since the stream began), and one residual for the
session is fitted on top, limited to the statement's uncertainty; a residual at its bound is flagged,
and called a disagreement when the signal alone puts the delay further from the statement than the
uncertainty plus ``delay_floor`` (how far a fit on the signal scatters per session). Without a
statement the delay is fitted from the signal alone, one for the session, on all its windows at
once, limited to ``0 <= delay <= max_delay``. Either fit minimises the mean squared standardised
deviation from the realisations' per-angle mean, both low-passed at ``delay_lowpass`` (the measured
signal re-sampled at the crank's times plus the delay, from the full-rate record). Below 10 Hz the
impacts' chaos leaks least into the fit; the bench's tolerances and the chaos still shift its curve by
as much as the delay (``benchmarks/validation/delay_floor.py``), so the signal alone does not place it to 0.2 ms.

Scores of a window against a state (see README "How sessions are scored" for the measurement behind
the choice of the verdict's statistic):
- ``features_all`` / ``features_direction``: squared Mahalanobis distance of the window's mean cycle
  features (the identification's) from the state, in all features / along the directions to the
  other candidates only (``identify``'s consistency test, for one window); ``features``: the smaller
  of those two p-values (itself calibrated on the held-out windows);
- ``features_lr``: the generalised likelihood ratio of the best other candidate against the state
  (``identify.candidate_ratio``, same whitened features and covariance): one-sided, it spends no
  power on departures away from every candidate, and so does not catch them (an unmodelled state, a
  sensor path unlike the prior); ``features_lr_all``: the smaller of its p-value and the all-feature
  distance's, calibrated on the held-out windows as ``features`` is;
- ``outside``: fraction of the window outside the band;
- ``z2``: mean over the window of ((x - mean) / sd)^2 per crank angle;
- ``energy``: energy distance between the window's cycles and the ensemble's cycles, both as 10 deg
  bin means standardised by the ensemble's per-bin spread;
- ``iso_*``: ISO/TS 18571 of the window against ``iso_realisations`` realisations' windows (mean
  rating and sub-scores, as the standard defines them), with the ratings of realisation windows
  against the same realisations as the reference ("as good as the model can be");
- ``iso_lowpass``: ISO/TS 18571 of the window low-passed at ``lowpass`` Hz (below the chaos of the
  impacts, where the model is deterministic) against the ensemble mean low-passed the same way.
Each statistic of each held-out realisation's windows (statistics from the other realisations)
gives its null distribution; a window's p-value is the fraction of null values at least as bad. The
verdict "consistent" holds at p >= ``alpha`` (the false-alarm rate) for the chosen ``statistic``;
the crank angles where an inconsistent window departs are those of the features beyond the
Bonferroni limit of the state's spread, and the 10 deg bins where more of it lies outside the band
than in any held-out realisation window.

Imports validation.ensemble, features, filters, metrics, cycles, chain_delay, identify (angle ranges).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd
from scipy import linalg, optimize, signal, stats
from wearbench.validation.comparison.metrics import iso18571
from wearbench.validation.inference.ensemble import Ensemble
from wearbench.validation.inference.identify import (
    StateModels,
    angle_ranges,
    candidate_ratio,
    direction_distance2,
    feature_ranges,
)
from wearbench.validation.measurement.chain_delay import StatedDelay
from wearbench.validation.measurement.cycles import WindowSpec, choose_windows, crank_turns
from wearbench.validation.measurement.features import CycleFeatures, FeatureSpec, sample_rate
from wearbench.validation.measurement.filters import apply_filter, parse_filter

__all__ = ["COMBINED", "FEATURE_STATISTICS", "STATISTICS", "DelayFit", "MeasuredCurves", "SessionWindows", "WindowOptions", "WindowTheory", "WindowVerdict",
           "fit_delay", "measured_curves", "score_windows", "separation", "window_theory"]

TWO_PI = 2.0 * np.pi
BINS = 36  # 10 deg bins for the energy distance and the departure angles
# each: larger = worse; the feature ones need the candidates' fitted statistics (``StateModels``)
FEATURE_STATISTICS = ("features", "features_all", "features_direction", "features_lr", "features_lr_all")
# the min-p statistics: name -> the two statistics whose smaller p-value they are
COMBINED = {"features": ("features_all", "features_direction"), "features_lr_all": ("features_all", "features_lr")}
STATISTICS = (*FEATURE_STATISTICS, "outside", "z2", "energy", "iso", "iso_lowpass")


@dataclass(frozen=True)
class WindowOptions:
    """How windows are judged (see the module docstring)."""

    cycles: int = 5
    alpha: float = 0.05          # false-alarm rate of the verdict (per window)
    statistic: str = "features_lr"  # the verdict's statistic, one of STATISTICS (README: chosen on fresh truths)
    max_delay: float = 2e-3      # s, without a statement the sensor chain's delay is fitted in [0, max_delay]
    delay_floor: float = 7.5e-4  # s, how far a fit on the signal alone scatters: p95 of its error (README)
    delay_step: float = 2.5e-5   # s, grid of the delay search (then refined by a parabola)
    delay_lowpass: float = 10.0  # Hz, the delay is fitted on both signals low-passed here (README: why)
    iso_realisations: int = 3    # realisations each window is rated against (ISO/TS 18571)
    reference_realisations: int = 12  # held-out realisations whose windows give the ISO scores' null
    lowpass: float = 10.0        # Hz, for iso_lowpass

    def for_crank(self, crank_hz: float, lowpass: float | None = None) -> WindowOptions:
        """These options at a crank turning ``crank_hz`` revolutions per second. The slow curves'
        low-passes (``lowpass``, ``delay_lowpass``) and the delay search's ``delay_step`` and
        ``delay_floor`` are stated for a 1 Hz crank, as the defaults are, and scale with it: the
        low-passes in crank orders (``lowpass``: the bench's resolved one, Hz, for both;
        ``measurement.scaling``), the step and floor in crank periods (the step at least a
        2000th of ``max_delay``). ``max_delay`` stays in seconds: a sensor chain's delay does not move
        with the crank. At 1 Hz: these options."""
        f = float(crank_hz)
        low, slow = (self.lowpass * f, self.delay_lowpass * f) if lowpass is None else (lowpass, lowpass)
        return replace(self, lowpass=low, delay_lowpass=slow, delay_floor=self.delay_floor / f,
                       delay_step=max(self.delay_step / f, self.max_delay / 2000))

    def __post_init__(self) -> None:
        if self.statistic not in STATISTICS:
            raise ValueError(f"window statistic {self.statistic!r}: expected one of {', '.join(STATISTICS)}")
        if not 0 < self.alpha < 0.5:
            raise ValueError(f"window alpha = {self.alpha}: expected a false-alarm rate in (0, 0.5)")
        if self.cycles < 1 or not self.max_delay >= 0 or not self.delay_step > 0 or self.iso_realisations < 1:
            raise ValueError(f"window options: cycles = {self.cycles}, max_delay = {self.max_delay} s, delay_step = "
                             f"{self.delay_step} s, iso_realisations = {self.iso_realisations}: expected at least one "
                             "cycle and realisation, a delay bound >= 0 and a positive step")


@dataclass(frozen=True)
class MeasuredCurves:
    """A measured record ready for crank-angle windows: the filtered signal at its own rate and the
    times the crank passes each grid angle of each complete cycle (cycles cut at crank angle 0)."""

    t: np.ndarray          # (samples,) s
    filtered: np.ndarray   # (samples,) m/s^2, bias removed, filtered as the ensemble's curves
    times: np.ndarray      # (cycles, grid) s
    steady: np.ndarray     # (cycles,) bool: cycle speed within 2 % of the median
    peaks: np.ndarray      # (cycles,) peak |filtered| in each cycle (m/s^2)
    slow: np.ndarray       # (samples,) m/s^2, the same low-passed at ``WindowOptions.delay_lowpass``
    stream_start: float = 0.0  # s, when the accelerometer's stream began (its clock drift counts from there)

    def at(self, delay: float | np.ndarray, cycles: slice | np.ndarray = slice(None), *,
           slow: bool = False) -> np.ndarray:
        """The cycles' curves with the accelerometer read ``delay`` s (one, or one per cycle) later
        than the crank angle (``slow``: of the low-passed signal the delay is fitted on)."""
        delay = np.asarray(delay, dtype=float)
        return np.interp(self.times[cycles] + (delay[:, None] if delay.ndim else delay), self.t,
                         self.slow if slow else self.filtered)

    def stated(self, stated: StatedDelay, cycles: slice | np.ndarray = slice(None)) -> np.ndarray:
        """The stated delay of each of the cycles (s), at the cycle's middle."""
        mid = 0.5 * (self.times[cycles, 0] + self.times[cycles, -1])
        return np.asarray(stated.at(mid - self.stream_start), dtype=float)


def measured_curves(t: np.ndarray, angle: np.ndarray, acc: np.ndarray, *, grid: int, filter_spec: str,
                    speed_tolerance: float = 0.02, lowpass: float = 10.0, fs: float | None = None,
                    stream_start: float | None = None) -> MeasuredCurves:
    """``MeasuredCurves`` of a record (times t, absolute crank angle at t, acceleration), filtered as
    ``validation.features.cycle_curves`` filters the ensemble's (bias over whole cycles removed), and
    low-passed at ``lowpass`` Hz for the delay fit. fs: the sample rate (Hz; a measured session's
    ``fs``, default ``features.sample_rate`` of ``t``); stream_start: when the accelerometer's stream
    began (s; default the first sample)."""
    t, acc = np.asarray(t, dtype=float), np.asarray(acc, dtype=float)
    turns = crank_turns(angle)
    u, cycle, k0, k1 = turns.progress, turns.cycle, turns.first, turns.last
    fs = sample_rate(t) if fs is None else fs
    start = float(t[0]) if stream_start is None else float(stream_start)
    if k1 < k0:
        return MeasuredCurves(t, acc, np.zeros((0, grid)), np.zeros(0, dtype=bool), np.zeros(0), acc, start)
    whole = (cycle >= k0) & (cycle <= k1)
    filtered = apply_filter(acc - acc[whole].mean(), fs, parse_filter(filter_spec, remove_bias=False))
    marks = np.arange(k0, k1 + 1)[:, None] * TWO_PI + np.arange(grid + 1)[None, :] * (TWO_PI / grid)
    times = np.interp(marks, u, t)
    duration = times[:, -1] - times[:, 0]
    med = np.median(duration)
    peaks = np.array([np.max(np.abs(filtered[cycle == k]), initial=0.0) for k in range(k0, k1 + 1)])
    return MeasuredCurves(t, filtered, times[:, :-1], np.abs(duration - med) <= speed_tolerance * med, peaks,
                          _lowpass(filtered, fs, lowpass), start)


def _binned(x: np.ndarray) -> np.ndarray:
    """(..., grid) -> (..., BINS) bin means."""
    return x.reshape(*x.shape[:-1], BINS, -1).mean(axis=-1)


def _pairwise(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(((a[:, None, :] - b[None, :, :]) ** 2).sum(-1)).mean())


@dataclass
class _Reference:
    """Per-angle statistics of a set of realisations (all of a state's, or all but one)."""

    lo: np.ndarray
    hi: np.ndarray
    mean: np.ndarray
    sd: np.ndarray
    cells: np.ndarray   # (cycles, BINS) standardised bin means of the cycles
    self_term: float    # mean distance between the cycles' bins (energy distance's third term)
    lowpassed: np.ndarray  # (cycles * grid,) the mean curve low-passed, repeated over a window
    slow_mean: np.ndarray | None = None  # (grid,) per-angle mean and spread of the realisations low-passed
    slow_sd: np.ndarray | None = None    # at delay_lowpass (what the delay is fitted on)

    @classmethod
    def of(cls, curves: np.ndarray, scale: np.ndarray, cycles: int, fs_grid: float, lowpass: float,
           delay_lowpass: float | None = None, self_term: float | None = None) -> _Reference:
        flat = curves.reshape(-1, curves.shape[-1])
        lo, hi = np.percentile(flat, [5.0, 95.0], axis=0)
        mean = flat.mean(axis=0)
        sd = np.maximum(flat.std(axis=0), 1e-6)
        cells = _binned(flat) / scale
        self_term = _pairwise(cells, cells) if self_term is None else self_term
        ref = cls(lo, hi, mean, sd, cells, self_term, _lowpass(np.tile(mean, cycles), fs_grid, lowpass))
        if delay_lowpass:
            m, c, grid = curves.shape
            slow = _lowpass(curves.reshape(m, c * grid), fs_grid, delay_lowpass)[:, grid:-grid].reshape(-1, grid)
            ref.slow_mean, ref.slow_sd = slow.mean(axis=0), np.maximum(slow.std(axis=0), 1e-6)
        return ref


def _lowpass(x: np.ndarray, fs: float, cutoff: float) -> np.ndarray:
    sos = signal.butter(4, min(cutoff, 0.4 * fs), fs=fs, output="sos")
    return signal.sosfiltfilt(sos, x, padtype="odd", padlen=min(x.shape[-1] - 1, int(3 * fs / cutoff)))


def _iso(x: np.ndarray, y: np.ndarray, grid: int):
    return iso18571(x, y, max_lag=1, dtw_band=max(1, grid // 20), ties="wearbench")


@dataclass
class WindowTheory:
    """One state's ensemble prepared for windows: the band, the realisations' windows, and the null
    distribution of every statistic over held-out realisation windows."""

    state: str
    grid: int
    crank_speed: float                 # rad/s (magnitude)
    options: WindowOptions
    reference: _Reference
    scale: np.ndarray                  # (BINS,) per-bin spread of the cycles
    windows: np.ndarray                # (realisations, windows per realisation, cycles * grid)
    iso_pool: np.ndarray               # indices of the realisations windows are rated against
    null: dict[str, np.ndarray]        # statistic -> (null windows,)
    null_bins: np.ndarray              # (null windows, BINS) fraction outside the band per bin
    null_iso: np.ndarray               # (null windows,) mean ISO rating of realisation windows
    models: StateModels | None = None  # the candidates' feature statistics (the features statistic)

    @property
    def fs_grid(self) -> float:
        return self.grid * self.crank_speed / TWO_PI

    @property
    def band(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        r = self.reference
        return r.lo, np.median(self.windows.reshape(-1, self.grid), axis=0), r.hi

    def feature_distances(self, features: np.ndarray) -> dict[str, float]:
        """``features_all``, ``features_direction`` (squared distances: ``identify``'s consistency
        test, for one window) and ``features_lr`` (``identify.candidate_ratio``) of a window's cycle
        features (cycles, p) against this state."""
        mod = self.models
        st = mod.stats[self.state]
        wbar = np.asarray(features, dtype=float)[:, mod.columns].mean(axis=0)
        n = features.shape[0]
        others = [mod.stats[t].mean for t in mod.states if t != self.state]
        return {"features_all": st.distance2(wbar, n), "features_direction": direction_distance2(st, others, wbar, n),
                "features_lr": candidate_ratio(st, others, wbar, n)}

    def feature_departures(self, features: np.ndarray, spec: FeatureSpec) -> list[str]:
        """Crank-angle ranges of the features whose window mean lies beyond the Bonferroni limit
        (two-sided ``alpha`` over all features) of this state's spread for a window of that length."""
        mod = self.models
        st = mod.stats[self.state]
        x = np.asarray(features, dtype=float)[:, mod.columns]
        z = (x.mean(axis=0) - st.mean) / np.sqrt(np.diag(st.covariance(x.shape[0])))
        flags = np.zeros(spec.size, dtype=bool)
        flags[mod.columns] = np.abs(z) > stats.norm.isf(self.options.alpha / (2 * z.size))
        return feature_ranges(flags, spec)

    def statistics(self, x: np.ndarray, ref: _Reference,
                   pool: np.ndarray | None) -> tuple[dict[str, float], dict, np.ndarray]:
        """Every statistic of window ``x`` (cycles, grid) against ``ref`` (the ISO ones against the
        realisations ``pool``, none when None); ISO sub-scores; per-bin fraction outside the band."""
        flat = x.ravel()
        out = (x < ref.lo) | (x > ref.hi)
        cells = _binned(x) / self.scale
        energy = 2 * _pairwise(cells, ref.cells) - _pairwise(cells, cells) - ref.self_term
        values = {"outside": float(out.mean()), "z2": float(np.mean(((x - ref.mean) / ref.sd) ** 2)),
                  "energy": float(energy)}
        sub: dict = {}
        if pool is not None:
            isos = [_iso(flat, self.windows[r, 0], self.grid) for r in pool]
            sub = {k: float(np.mean([getattr(s, k) for s in isos])) for k in ("rating", "corridor", "phase",
                                                                             "magnitude", "slope")}
            low = _iso(_lowpass(flat, self.fs_grid, self.options.lowpass), ref.lowpassed, self.grid)
            values.update(iso=1.0 - sub["rating"], iso_lowpass=1.0 - low.rating)
            sub["lowpass_rating"] = float(low.rating)
            sub["ratings"] = [float(i.rating) for i in isos]
        return values, sub, _binned(out.astype(float)).mean(axis=0)


def separation(models: StateModels, judged: str, truth: str, cycles: int = 5, alpha: float = 0.05,
               draws: int = 40000) -> dict[str, float]:
    """How well ``cycles``-cycle windows of ``truth`` can be told from ``judged`` at all, from the
    fitted feature statistics alone (Gaussian; the truth's windows spread as the judged state's do,
    as the pooled statistics have them): ``distance``, the Mahalanobis distance between the two means
    under the judged state's window covariance (between-bench, cycle-to-cycle, sensor path, floors);
    ``power``, the most any test of "consistent with judged" at false-alarm ``alpha`` can call the
    truth's windows inconsistent (Neyman-Pearson: the likelihood ratio, here the projection on the
    line between the means); ``power_direction``, the same for the chi-square test along the
    directions to all other candidates (``features_direction`` with an exact null); ``power_lr``, for
    the likelihood ratio toward the best other candidate (``features_lr`` with an exact null: the
    maximum of correlated Gaussians, by ``scipy.stats.multivariate_normal.cdf`` to 1e-6);
    ``power_lr_all``, for the smaller p-value of that and the all-feature distance (``features_lr_all``,
    by simulation: ``draws`` seeded windows under each state); ``bayes_error``, the least
    misclassification rate between the two at equal priors."""
    st = models.stats[judged]
    chol = st.whitener(cycles)
    z = linalg.solve_triangular(chol, models.stats[truth].mean - st.mean, lower=True)
    delta = float(np.linalg.norm(z))
    k = max(1, len(models.states) - 1)
    out = {"distance": delta, "power": float(stats.norm.sf(stats.norm.isf(alpha) - delta)),
           "power_direction": float(stats.ncx2.sf(stats.chi2.isf(alpha, k), k, delta ** 2)),
           "bayes_error": float(stats.norm.cdf(-delta / 2))}
    others = [models.stats[t].mean for t in models.states if t != judged]
    if not others:
        return {**out, "power_lr": 0.0, "power_lr_all": float(stats.ncx2.sf(stats.chi2.isf(alpha, z.size), z.size,
                                                                              delta ** 2))}
    # whitened by the judged state's covariance: T = max_j (x . u_j - |u_j|^2 / 2), x ~ N(0, I) or N(z, I)
    u = np.stack([linalg.solve_triangular(chol, m - st.mean, lower=True) for m in others], axis=1)
    half = 0.5 * np.sum(u * u, axis=0)
    gram = u.T @ u
    gram = gram + 1e-9 * np.trace(gram) * np.eye(len(others))  # collinear candidates: a singular Gram matrix

    def below(t: float, mean: np.ndarray) -> float:  # P(T <= t)
        return float(stats.multivariate_normal.cdf(np.full(len(others), t), mean, gram, abseps=1e-7, releps=1e-7,
                                                   rng=np.random.default_rng(0)))

    spread = float(np.sqrt(np.max(np.diag(gram))))
    lo, hi = -float(half.max()) - 10 * spread, float(np.max(-half)) + 10 * spread
    threshold = optimize.brentq(lambda t: below(t, -half) - (1 - alpha), lo, hi, xtol=1e-9)
    out["power_lr"] = 1.0 - below(threshold, u.T @ z - half)
    # the min-p combination with the all-feature distance |x|^2, by simulation
    rng = np.random.default_rng(1)
    null = rng.standard_normal((draws, z.size))
    alt = z + rng.standard_normal((draws, z.size))

    def pair(x: np.ndarray) -> np.ndarray:
        return np.stack([np.max(x @ u - half, axis=1), np.sum(x * x, axis=1)], axis=1)

    t0, t1 = pair(null), pair(alt)
    ref = np.sort(t0, axis=0)

    def min_p(t: np.ndarray) -> np.ndarray:
        return np.min([1.0 - np.searchsorted(ref[:, j], t[:, j], side="left") / draws for j in range(2)], axis=0)

    out["power_lr_all"] = float(np.mean(min_p(t1) < np.quantile(min_p(t0), alpha)))
    return out


def _min_p(null: np.ndarray) -> np.ndarray:
    """Per row of (windows, k) distances (larger = worse): the smallest of its k empirical p-values."""
    ranks = [(1 + np.sum(null[:, j][None, :] >= null[:, j][:, None], axis=1)) / (1 + null.shape[0])
             for j in range(null.shape[1])]
    return np.min(ranks, axis=0)


def window_theory(ensemble: Ensemble, *, crank_speed: float, models: StateModels | None = None,
                  options: WindowOptions = WindowOptions()) -> WindowTheory:
    """Prepare ``ensemble`` (one state) for window verdicts; ``crank_speed`` (rad/s) of the encoder's
    crank; ``models``: the candidates' fitted statistics (``identify.fit_states``), needed for the
    ``features`` statistic (its held-out windows' distances are the null)."""
    curves = np.asarray(ensemble.curves, dtype=float)
    m, c, grid = curves.shape
    n = options.cycles
    if c < n:
        raise ValueError(f"windows: ensemble {ensemble.state!r} has {c} cycles per realisation, fewer than a "
                         f"{n}-cycle window")
    if grid % BINS:
        raise ValueError(f"windows: ensemble grid {grid} is not a multiple of {BINS} (10 deg bins)")
    if models is not None and (ensemble.state not in models.window_null or models.window_cycles != n):
        raise ValueError(f"windows: the fitted statistics hold no {n}-cycle windows of {ensemble.state!r}; fit "
                         f"them with fit_states(..., window_cycles={n}) on the same ensembles")
    starts = sorted({0, c - n})
    windows = np.stack([np.stack([curves[r, s:s + n].ravel() for s in starts]) for r in range(m)])
    scale = np.maximum(_binned(curves.reshape(-1, grid)).std(axis=0), 1e-6)
    speed = abs(float(crank_speed))
    fs_grid = grid * speed / TWO_PI
    k = min(options.iso_realisations, m - 1)
    theory = WindowTheory(ensemble.state, grid, speed, options,
                          _Reference.of(curves, scale, n, fs_grid, options.lowpass, options.delay_lowpass), scale,
                          windows,
                          np.arange(k), {}, np.zeros((0, BINS)), np.zeros(0), models)
    null: dict[str, list[float]] = {s: [] for s in STATISTICS if s not in FEATURE_STATISTICS}
    bins, iso = [], []
    cells = _binned(curves.reshape(-1, grid)) / scale
    dist = np.sqrt(((cells[:, None, :] - cells[None, :, :]) ** 2).sum(-1))  # between all cycles, once
    for r in range(m):
        keep = np.repeat(np.arange(m) != r, c)
        ref = _Reference.of(np.delete(curves, r, axis=0), scale, n, fs_grid, options.lowpass,
                            self_term=float(dist[np.ix_(keep, keep)].mean()))
        rated = r < options.reference_realisations  # ISO/TS 18571 (the costly part) on the first ones only
        pool = np.array([i for i in range(m) if i != r][:k]) if rated else None
        for w in windows[r]:
            st, sub, b = theory.statistics(w.reshape(n, grid), ref, pool)
            for key, values in null.items():
                if key in st:
                    values.append(st[key])
            bins.append(b)
            if rated:
                iso.append(sub["rating"])
    theory.null = {key: np.asarray(v) for key, v in null.items()}
    if models is not None:
        held_out = models.window_null[ensemble.state]
        theory.null.update(features_all=held_out[:, 0], features_direction=held_out[:, 1])
        if held_out.shape[1] > 2:  # the likelihood ratio toward the candidates (not in calibrated.py's nulls)
            theory.null["features_lr"] = held_out[:, 2]
        for name, parts in COMBINED.items():
            if all(p in theory.null for p in parts):
                theory.null[name] = _min_p(np.stack([theory.null[p] for p in parts], axis=1))
    theory.null_bins = np.asarray(bins)
    theory.null_iso = np.asarray(iso)
    return theory


@dataclass
class WindowVerdict:
    """One measured window against one state (see the module docstring)."""

    state: str
    start_cycle: int
    t_start: float
    t_end: float
    delay_s: float                   # the accelerometer read this late behind the crank angle (window mean)
    statistics: dict[str, float]
    p_values: dict[str, float]
    iso: dict[str, float]            # mean ISO/TS 18571 rating and sub-scores against realisations
    iso_percentile: float            # of the rating among realisation windows' ratings (0-100)
    percentile: float                # of the verdict statistic among held-out realisation windows (0-100)
    verdict_statistic: str
    consistent: bool
    departs: list[str]               # crank-angle ranges where an inconsistent window departs (empty if consistent)
    measured: np.ndarray = field(repr=False)   # (cycles, grid) after the delay
    times: np.ndarray = field(repr=False)      # (cycles, grid) s from the window's start
    realisation: int = 0             # the realisation shown beside it (median ISO rating of the pool)
    realisation_window: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)  # its window
    delay_stated_s: float | None = None  # the bench's statement at the window (None: from the signal alone)

    @property
    def p(self) -> float:
        """The verdict's p-value (its statistic's)."""
        return self.p_values[self.statistic]

    @property
    def statistic(self) -> str:
        return self.verdict_statistic

    def to_dict(self) -> dict:
        return {"state": self.state, "start_cycle": self.start_cycle, "t_start": self.t_start, "t_end": self.t_end,
                "delay_s": self.delay_s, "delay_stated_s": self.delay_stated_s,
                "delay_residual_s": None if self.delay_stated_s is None else self.delay_s - self.delay_stated_s,
                "consistent": self.consistent, "p": self.p, "departs": self.departs,
                "percentile": self.percentile, "statistics": self.statistics, "p_values": self.p_values,
                "iso": self.iso, "iso_percentile": self.iso_percentile, "realisation_shown": self.realisation}


@dataclass
class SessionWindows:
    """A session's windows against one state, and that state's band (lo, median, hi per angle)."""

    state: str
    options: WindowOptions
    windows: list[WindowVerdict]
    band: tuple[np.ndarray, np.ndarray, np.ndarray]
    delay: DelayFit | None = None  # how the session's delay was found (None: no window)

    @property
    def consistent(self) -> int:
        return sum(w.consistent for w in self.windows)

    @property
    def label(self) -> str:
        """E.g. "consistent 4/4" or "inconsistent 1/4 consistent"."""
        n = len(self.windows)
        if not n:
            return "no window"
        word = "consistent" if self.consistent == n else "inconsistent" if self.consistent == 0 else "mixed"
        return f"{word} ({self.consistent}/{n} windows)"

    def summary(self) -> dict:
        return {"state": self.state, "windows": len(self.windows), "consistent_windows": self.consistent,
                "verdict": self.label, "statistic": self.options.statistic, "alpha": self.options.alpha,
                "delay_s_median": float(np.median([w.delay_s for w in self.windows])) if self.windows else None,
                "delay": self.delay.to_dict() if self.delay else None,
                "window_details": [w.to_dict() for w in self.windows]}


def _fit_shift(m: MeasuredCurves, cycles: np.ndarray, ref: _Reference, base: np.ndarray | float, lo: float,
               hi: float, step: float) -> tuple[float, bool]:
    """(shift in [lo, hi] on top of ``base`` (per cycle), whether it sits at a bound) minimising the
    cycles' mean squared standardised deviation from the realisations, both low-passed at
    ``delay_lowpass`` (below the impacts' chaos)."""
    if hi <= lo:
        return float(lo), False
    n = max(2, int(np.ceil((hi - lo) / step)))
    taus = np.linspace(lo, hi, n + 1)
    cost = np.array([np.mean(((m.at(base + tau, cycles, slow=True) - ref.slow_mean) / ref.slow_sd) ** 2)
                     for tau in taus])
    i = int(np.argmin(cost))
    if 0 < i < taus.size - 1:
        a, b, c = cost[i - 1: i + 2]
        den = a - 2 * b + c
        if den > 0:
            return float(taus[i] + 0.5 * (taus[1] - taus[0]) * (a - c) / den), False
    return float(taus[i]), True


@dataclass(frozen=True)
class DelayFit:
    """The session's accelerometer delay behind the encoder against one state's theory: from the
    signal alone (``stated`` None), or the bench's statement plus a fitted residual within its
    uncertainty (``at_bound``: the residual sits at it; ``disagrees``: and the signal alone puts the
    delay further from the statement than the uncertainty plus the signal's floor)."""

    signal_alone: float                 # s, the fit on the signal alone in [0, max_delay]
    floor: float                        # s, how far that scatters per session (WindowOptions.delay_floor)
    stated: StatedDelay | None = None
    stated_mean: float = 0.0            # s, the statement over the session's windows' cycles
    residual: float = 0.0               # s, fitted on top of the statement
    at_bound: bool = False
    disagrees: bool = False

    @property
    def delay(self) -> float:
        """The session's delay (s): the statement's mean plus the residual, or the signal's fit."""
        return self.stated_mean + self.residual if self.stated else self.signal_alone

    def describe(self) -> str:
        if self.stated is None:
            return (f"fitted from the signal alone: {self.signal_alone * 1e3:.2f} ms (no [sensor.chain] statement; "
                    f"a fit on the acceleration scatters by about +/- {self.floor * 1e3:.1f} ms per session)")
        text = (f"stated {self.stated_mean * 1e3:.3f} ms + fitted residual {self.residual * 1e3:+.3f} ms "
                f"(within +/- {self.stated.uncertainty * 1e3:.3f} ms)")
        if self.at_bound:
            text += f"; the residual is at its bound, the signal alone puts the delay at {self.signal_alone * 1e3:.2f} ms"
            text += (": the statement disagrees with the signal beyond its floor" if self.disagrees else
                     f" (within the signal's floor of +/- {self.floor * 1e3:.1f} ms)")
        return text

    def to_dict(self) -> dict:
        out = {"source": "stated" if self.stated else "signal", "delay_s": self.delay,
               "signal_alone_s": self.signal_alone, "signal_floor_s": self.floor, "text": self.describe()}
        if self.stated:
            out.update(stated_s=self.stated_mean, residual_s=self.residual, at_bound=self.at_bound,
                       disagrees=self.disagrees, statement=self.stated.to_dict())
        return out


def fit_delay(m: MeasuredCurves, cycles: np.ndarray, ref: _Reference, options: WindowOptions,
              stated: StatedDelay | None = None) -> DelayFit:
    """The session's delay on ``cycles`` against ``ref`` (see the module docstring)."""
    alone, _ = _fit_shift(m, cycles, ref, 0.0, 0.0, options.max_delay, options.delay_step)
    if stated is None:
        return DelayFit(alone, options.delay_floor)
    base = m.stated(stated, cycles)
    u = stated.uncertainty
    residual, at_bound = _fit_shift(m, cycles, ref, base, -u, u, min(options.delay_step, u / 4 if u else 1.0))
    mean = float(base.mean())
    far = abs(alone - mean) > u + options.delay_floor
    return DelayFit(alone, options.delay_floor, stated, mean, residual, at_bound and u > 0, at_bound and far)


def _p_value(null: np.ndarray, value: float) -> float:
    return float((1 + np.sum(null >= value)) / (1 + null.size))


def score_windows(measured: MeasuredCurves, theory: WindowTheory, features: CycleFeatures | None = None,
                  stated: StatedDelay | None = None) -> SessionWindows:
    """Every window of consecutive steady cycles of ``measured`` against ``theory`` (one state);
    ``features``: the same record's cycle features (``features.cycle_features``, same cycles), needed
    for the ``features`` statistic; ``stated``: the bench's stated sensor-chain delay (None: the delay
    is fitted from the signal alone)."""
    opts, grid, n = theory.options, theory.grid, theory.options.cycles
    if measured.times.shape[1] != grid:
        raise ValueError(f"windows: measured curves on {measured.times.shape[1]} points per cycle, the ensemble's "
                         f"on {grid}")
    use_features = features is not None and theory.models is not None
    if opts.statistic in FEATURE_STATISTICS and not use_features:
        raise ValueError(f"windows: the {opts.statistic!r} verdict needs the session's cycle features and the fitted "
                         "state statistics (window_theory(..., models=fit_states(...)))")
    if use_features and opts.statistic not in theory.null:
        raise ValueError(f"windows: the fitted statistics hold no held-out {opts.statistic!r} of {theory.state!r} "
                         "(identify.fit_states keeps it; these came from elsewhere)")
    if use_features and features.cycles != measured.times.shape[0]:
        raise ValueError(f"windows: {features.cycles} cycles of features for {measured.times.shape[0]} cycles of "
                         "curves; compute both from the same record")
    table = pd.DataFrame({"steady": measured.steady})
    out = []
    starts = choose_windows(table, WindowSpec("all", cycles=n))
    # the sensor chain's delay: stated plus one residual, or one from the signal, on all windows at once
    fit = fit_delay(measured, np.concatenate([np.arange(s, s + n) for s in starts]), theory.reference, opts,
                    stated) if starts else None
    for s in starts:
        cyc = slice(s, s + n)
        base = measured.stated(stated, cyc) if stated is not None else None
        delay = base + fit.residual if base is not None else np.full(n, fit.delay)
        x = measured.at(delay, cyc)
        values, sub, bins = theory.statistics(x, theory.reference, theory.iso_pool)
        p = {k: _p_value(theory.null[k], v) for k, v in values.items()}
        departs = [f"band {r}" for r in angle_ranges(bins > theory.null_bins.max(axis=0), BINS)]
        if use_features:
            distances = theory.feature_distances(features.values[cyc])
            values.update({k: v for k, v in distances.items() if k in theory.null})
            p.update({k: _p_value(theory.null[k], values[k]) for k in distances if k in theory.null})
            for name, parts in COMBINED.items():  # the smaller p-value, against the held-out windows' smaller ones
                if name in theory.null:
                    values[name] = -min(p[parts[0]], p[parts[1]])
                    p[name] = float((1 + np.sum(theory.null[name] <= -values[name])) / (1 + theory.null[name].size))
            departs = theory.feature_departures(features.values[cyc], features.spec) + departs
        consistent = p[opts.statistic] >= opts.alpha
        departs = [] if consistent else departs  # where an inconsistent window departs; none otherwise
        null = theory.null[opts.statistic]
        v = values[opts.statistic]
        percentile = float(100.0 * np.mean(-null < v)) if opts.statistic in COMBINED else float(
            100.0 * np.mean(null < v))
        shown = int(theory.iso_pool[np.argsort(sub.pop("ratings"))[len(theory.iso_pool) // 2]])
        t0 = float(measured.times[s, 0])
        out.append(WindowVerdict(theory.state, s, t0, float(measured.times[s + n - 1, -1]), float(delay.mean()),
                                 values, p, sub,
                                 float(100.0 * np.mean(theory.null_iso <= sub["rating"])), percentile,
                                 opts.statistic, consistent, departs, x,
                                 measured.times[cyc] - t0, shown, theory.windows[shown, 0],
                                 float(base.mean()) if base is not None else None))
    return SessionWindows(theory.state, opts, out, theory.band, fit)
