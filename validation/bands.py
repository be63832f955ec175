"""A session's cycles against a theory ensemble by crank angle: bands and five-cycle window scores.

Band: per crank angle, the 5th, 50th and 95th percentile of the ensemble's filtered cycles; the
measured cycles are checked against it (the fraction of cycles outside, per angle).

Window scores: each run of ``window`` consecutive measured cycles is scored (ISO/TS 18571 and the
rest, ``metrics.score_window``) against the ensemble median repeated, in the crank-angle domain
(the encoder has already aligned the two; the residual shift search is held to ``max_lag`` grid
steps, the sensor's plausible delay). What the model can achieve is measured the same way: every
run of ``window`` cycles of every realisation against the same median. A measured window is "as
good as the model can be" when its rating reaches the 5th percentile of that reference. A pointwise
score of one trajectory against another never decides a state here; the ensemble is the theory.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from wearbench.validation.ensemble import Ensemble
from wearbench.validation.metrics import score_window
from wearbench.validation.theory import TheoryCurve

__all__ = ["BandComparison", "compare_bands", "ensemble_theory"]


@dataclass
class BandComparison:
    """A session's cycle curves against one state's ensemble (see the module docstring)."""

    state: str
    angle_deg: np.ndarray  # (grid,)
    lo: np.ndarray
    median: np.ndarray
    hi: np.ndarray
    measured: np.ndarray  # (cycles, grid)
    outside: np.ndarray  # (grid,) fraction of measured cycles outside [lo, hi]
    window_ratings: np.ndarray  # ISO rating of each measured window against the median
    reference_ratings: np.ndarray  # ISO rating of each ensemble window against the median
    peaks_measured: np.ndarray
    peaks_theory: np.ndarray

    @property
    def rating_percentile(self) -> float:
        """Where the measured windows' median rating falls in the reference ratings (0-100)."""
        if self.window_ratings.size == 0:
            return float("nan")
        return float(100.0 * np.mean(self.reference_ratings <= np.median(self.window_ratings)))

    @property
    def as_good_as_model(self) -> bool:
        return bool(self.window_ratings.size) and float(np.median(self.window_ratings)) >= float(
            np.percentile(self.reference_ratings, 5))

    def summary(self) -> dict:
        ref = self.reference_ratings
        return {"state": self.state, "cycles": int(self.measured.shape[0]),
                "fraction_outside_band": float(self.outside.mean()),
                "windows": int(self.window_ratings.size),
                "iso_rating_measured_median": float(np.median(self.window_ratings)) if self.window_ratings.size else None,
                "iso_rating_model_p5_p50_p95": [float(x) for x in np.percentile(ref, [5, 50, 95])],
                "rating_percentile": self.rating_percentile, "as_good_as_model": self.as_good_as_model,
                "peak_acc_measured_median": float(np.median(self.peaks_measured)),
                "peak_acc_theory_p5_p50_p95": [float(x) for x in np.percentile(self.peaks_theory, [5, 50, 95])]}


def _windows(curves: np.ndarray, window: int) -> list[np.ndarray]:
    return [curves[i:i + window].ravel() for i in range(0, curves.shape[0] - window + 1, window)]


def _ratings(windows: list[np.ndarray], reference: np.ndarray, grid: int, max_lag: int) -> np.ndarray:
    return np.array([score_window(w, reference, float(grid), cycle_samples=grid, max_lag=max_lag,
                                  dtw_band=max(1, grid // 20)).iso_rating for w in windows])


def compare_bands(curves: np.ndarray, peaks: np.ndarray, ensemble: Ensemble, *, window: int = 5,
                  max_lag: int = 1) -> BandComparison:
    """Measured cycle ``curves`` (cycles, grid) and ``peaks`` against ``ensemble`` (same grid and filter)."""
    grid = ensemble.curves.shape[-1]
    if curves.ndim != 2 or curves.shape[1] != grid:
        raise ValueError(f"bands: measured curves of shape {curves.shape}, expected (cycles, {grid})")
    lo, median, hi = ensemble.band()
    outside = ((curves < lo) | (curves > hi)).mean(axis=0) if curves.shape[0] else np.zeros(grid)
    reference = np.tile(median, window)
    ens_windows = [w for r in ensemble.curves for w in _windows(r, window)]
    if not ens_windows:
        raise ValueError(f"bands: ensemble {ensemble.state!r} has {ensemble.curves.shape[1]} cycles per realisation, "
                         f"fewer than a {window}-cycle window")
    return BandComparison(ensemble.state, np.arange(grid) * (360.0 / grid), lo, median, hi, curves, outside,
                          _ratings(_windows(curves, window), reference, grid, max_lag),
                          _ratings(ens_windows, reference, grid, max_lag), np.asarray(peaks),
                          ensemble.peaks.ravel())


def ensemble_theory(ensemble: Ensemble, bench) -> TheoryCurve:
    """The ensemble median as a periodic theory curve by crank angle of the bench's encoder joint
    (for the classic window comparison and its figures)."""
    driver = bench.encoder_driver
    joint = driver.joint
    crank_speed = ensemble.speed * driver.ratio
    grid = ensemble.curves.shape[-1]
    median = ensemble.band()[1]
    u = np.arange(grid) * (2 * np.pi / grid)
    return TheoryCurve(f"{ensemble.state} (ensemble median)", joint, u, median, float(np.sign(crank_speed)),
                       float(crank_speed), pd.DataFrame({"u": u, "slider_acc": median}), periodic=True)
