"""A session's cycles against a theory ensemble's band by crank angle.

Band: per crank angle, the 5th, 50th and 95th percentile of the ensemble's filtered cycles; the
measured cycles are checked against it (the fraction of cycles outside, per angle), and the peaks of
the measured and the realisations' cycles are set side by side. Window verdicts against the
ensemble's own windows are in ``validation.windows``; the ensemble median is never scored as if it
were a motion (it has no impacts).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from wearbench.validation.inference.ensemble import Ensemble

__all__ = ["BandComparison", "compare_bands"]


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
    peaks_measured: np.ndarray
    peaks_theory: np.ndarray

    def summary(self) -> dict:
        return {"state": self.state, "cycles": int(self.measured.shape[0]),
                "fraction_outside_band": float(self.outside.mean()),
                "peak_acc_measured_median": float(np.median(self.peaks_measured)),
                "peak_acc_theory_p5_p50_p95": [float(x) for x in np.percentile(self.peaks_theory, [5, 50, 95])]}


def compare_bands(curves: np.ndarray, peaks: np.ndarray, ensemble: Ensemble) -> BandComparison:
    """Measured cycle ``curves`` (cycles, grid) and ``peaks`` against ``ensemble`` (same grid and filter)."""
    grid = ensemble.curves.shape[-1]
    if curves.ndim != 2 or curves.shape[1] != grid:
        raise ValueError(f"bands: measured curves of shape {curves.shape}, expected (cycles, {grid})")
    lo, median, hi = ensemble.band()
    outside = ((curves < lo) | (curves > hi)).mean(axis=0) if curves.shape[0] else np.zeros(grid)
    return BandComparison(ensemble.state, np.arange(grid) * (360.0 / grid), lo, median, hi, curves, outside,
                          np.asarray(peaks), ensemble.peaks.ravel())
