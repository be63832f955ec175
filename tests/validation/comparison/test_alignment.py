"""Alignment: the lag search and its sub-sample refinement recover a known fractional delay."""

import numpy as np
import pytest
from wearbench.validation.comparison.alignment import estimate_lag, lag_correlations, shift_signal
from wearbench.validation.measurement.filters import FilterSpec, apply_filter

pytestmark = pytest.mark.no_kernels

FS = 10_000.0


def bandlimited(t, seed=0):
    """Random smooth signal as an analytic function of time (so any delay is exact)."""
    rng = np.random.default_rng(seed)
    f = rng.uniform(0.5, 300.0, 25)
    a = rng.uniform(0.2, 1.0, 25) / np.sqrt(f)
    p = rng.uniform(0, 2 * np.pi, 25)
    return np.sum(a[:, None] * np.sin(2 * np.pi * f[:, None] * t[None, :] + p[:, None]), axis=0)


@pytest.mark.parametrize("lag", [0.0, 0.3, -0.45, 2.71, -17.25, 63.9])
def test_recovers_fractional_lag(lag):
    t = np.arange(20_000) / FS
    x = bandlimited(t)
    y = 1.7 * bandlimited(t - lag / FS) + 0.4  # theory late by `lag` samples, other gain and offset
    assert estimate_lag(x, y, max_lag=200) == pytest.approx(lag, abs=0.1)
    assert estimate_lag(x, y, max_lag=200) == pytest.approx(lag, abs=0.01)  # in fact much better


def test_recovers_lag_in_noise_after_filtering():
    t = np.arange(30_000) / FS
    rng = np.random.default_rng(5)
    lag = 7.37
    x = bandlimited(t, 2) + rng.normal(0, 0.05, t.size)
    y = bandlimited(t - lag / FS, 2)
    spec = FilterSpec(kind="cfc", cfc=180)
    assert estimate_lag(apply_filter(x, FS, spec), apply_filter(y, FS, spec), 300) == pytest.approx(lag, abs=0.1)


def test_lag_search_limit_avoids_whole_cycle_alias():
    """A periodic signal correlates perfectly one cycle away; the limited search stays near 0."""
    t = np.arange(50_000) / FS  # five cycles of 1 s
    x = np.sin(2 * np.pi * t) + 0.3 * np.sin(2 * np.pi * 9 * t)
    y = np.roll(x, 25)
    lags, rho = lag_correlations(x, y, 2000)
    assert lags[np.argmax(rho)] == 25
    assert estimate_lag(x, y, 2000) == pytest.approx(25, abs=0.01)


def test_lag_correlations_match_direct_pearson():
    rng = np.random.default_rng(0)
    x, y = rng.normal(size=500), rng.normal(size=500)
    lags, rho = lag_correlations(x, y, 20)
    for L, r in zip(lags, rho):
        a = x[max(-L, 0): 500 - max(L, 0)]
        b = y[max(L, 0): 500 - max(-L, 0)]
        assert r == pytest.approx(np.corrcoef(a, b)[0, 1], abs=1e-10)


def test_shift_signal_undoes_lag():
    t = np.arange(5000) / FS
    lag = 3.4
    y = bandlimited(t - lag / FS, 1)
    back = shift_signal(y, lag)
    assert np.max(np.abs(back[100:-100] - bandlimited(t, 1)[100:-100])) < 1e-4
