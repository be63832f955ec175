"""Time alignment of a comparison signal to a reference: lag search and sub-sample refinement.

Holds ``lag_correlations`` (Pearson correlation of the overlapping parts for every integer lag in a
limited range, in O(n log n) by FFT and running sums: the ISO/TS 18571 phase search),
``estimate_lag`` (that search, refined to a fraction of a sample by maximising the correlation with
the spline-interpolated comparison) and ``shift_signal`` (cubic-spline evaluation at shifted sample positions).

Sign convention everywhere: a lag ``L > 0`` means the comparison is late,
``comparison[i + L] ~ reference[i]``. Keep the search well under half a signal period: a periodic
signal correlates as well one whole cycle away. Imports nothing from wearbench.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import make_interp_spline
from scipy.optimize import minimize_scalar

__all__ = ["estimate_lag", "lag_correlations", "shift_signal"]


def _xcorr(reference: np.ndarray, comparison: np.ndarray, max_lag: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Plain cross-correlation ``sum_i ref[i] comp[i + L]`` for L in [-max_lag, max_lag] (lags, values, fft size)."""
    n = reference.size
    m = 1 << int(np.ceil(np.log2(2 * n)))
    spec = np.conj(np.fft.rfft(reference, m)) * np.fft.rfft(comparison, m)
    c = np.fft.irfft(spec, m)
    lags = np.arange(-max_lag, max_lag + 1)
    return lags, c[lags % m], m


def lag_correlations(reference: np.ndarray, comparison: np.ndarray, max_lag: int) -> tuple[np.ndarray, np.ndarray]:
    """Pearson correlation of the overlapping parts of two equal-length signals for each integer lag.

    Returns (lags, rho) for lags -max_lag..max_lag; the overlap at lag L pairs ``reference[i]`` with
    ``comparison[i + L]``. A constant overlap (zero variance) gets rho = 0.
    """
    x = np.asarray(reference, dtype=float)
    y = np.asarray(comparison, dtype=float)
    if x.shape != y.shape or x.ndim != 1:
        raise ValueError(f"lag search: expected two 1-D signals of equal length, got {x.shape} and {y.shape}")
    n = x.size
    max_lag = int(min(max_lag, n - 2))
    if max_lag < 0:
        raise ValueError(f"lag search: signals of {n} samples are too short")
    # centre to keep the running-sum formula well conditioned
    x = x - x.mean()
    y = y - y.mean()
    lags, sxy, _ = _xcorr(x, y, max_lag)
    cx, cxx = np.concatenate(([0.0], np.cumsum(x))), np.concatenate(([0.0], np.cumsum(x * x)))
    cy, cyy = np.concatenate(([0.0], np.cumsum(y))), np.concatenate(([0.0], np.cumsum(y * y)))
    pos = np.maximum(lags, 0)
    neg = np.maximum(-lags, 0)
    k = n - np.abs(lags)
    # L >= 0: x[0 : n-L], y[L : n];  L < 0: x[-L : n], y[0 : n+L]
    x0, x1 = neg, neg + k
    y0, y1 = pos, pos + k
    sx, sxx = cx[x1] - cx[x0], cxx[x1] - cxx[x0]
    sy, syy = cy[y1] - cy[y0], cyy[y1] - cyy[y0]
    num = k * sxy - sx * sy
    den2 = (k * sxx - sx * sx) * (k * syy - sy * sy)
    tiny = 1e-300 + 1e-24 * (k * k * (sxx.max() + 1e-300) * (syy.max() + 1e-300))
    rho = np.where(den2 > tiny, num / np.sqrt(np.maximum(den2, tiny)), 0.0)
    # recompute the few best exactly (FFT round-off must not break ties of near-identical signals)
    for idx in np.argsort(rho)[-3:]:
        L = int(lags[idx])
        a = x[max(-L, 0): n - max(L, 0)]
        b = y[max(L, 0): n - max(-L, 0)]
        sa, sb = a.std(), b.std()
        rho[idx] = float(np.mean((a - a.mean()) * (b - b.mean())) / (sa * sb)) if sa > 0 and sb > 0 else 0.0
    return lags, np.clip(rho, -1.0, 1.0)


def estimate_lag(reference: np.ndarray, comparison: np.ndarray, max_lag: int) -> float:
    """The lag (samples, fractional) that best aligns ``comparison`` to ``reference``, |lag| <= max_lag.

    Integer peak of the Pearson correlation (``lag_correlations``), then the maximum, within one
    sample of it, of the Pearson correlation between the reference's interior (a fixed overlap, so no
    pull towards lag 0) and the comparison evaluated at shifted positions by cubic spline.
    """
    lags, rho = lag_correlations(reference, comparison, max_lag)
    i = int(np.argmax(rho))
    L = int(lags[i])
    if i == 0 or i == lags.size - 1:
        return float(L)  # at the edge of the search: no bracket to refine in
    x = np.asarray(reference, dtype=float)
    spline = make_interp_spline(np.arange(x.size, dtype=float), np.asarray(comparison, dtype=float), k=3)
    edge = abs(L) + 2
    core = np.arange(edge, x.size - edge, dtype=float)
    xc = x[edge: x.size - edge]
    xc = (xc - xc.mean()) / (xc.std() or 1.0)

    def negative_correlation(tau: float) -> float:
        yc = spline(core + tau)
        sd = yc.std()
        return 0.0 if sd == 0 else -float(np.mean(xc * (yc - yc.mean())) / sd)

    best = minimize_scalar(negative_correlation, bounds=(L - 1.0, L + 1.0), method="bounded",
                           options={"xatol": 1e-4})
    return float(np.clip(best.x, -max_lag, max_lag))


def shift_signal(x: np.ndarray, lag: float) -> np.ndarray:
    """``x`` evaluated at sample positions ``i + lag`` (cubic spline; ends extrapolated).

    If ``comparison`` is late by ``lag`` (``estimate_lag``), ``shift_signal(comparison, lag)`` is aligned.
    """
    x = np.asarray(x, dtype=float)
    if lag == 0.0:
        return x.copy()
    i = np.arange(x.size, dtype=float)
    return make_interp_spline(i, x, k=3)(i + lag, extrapolate=True)
