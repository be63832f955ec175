"""The rate at which a bench's features change along its life, about the estimator's: ``track``
marginalises it (``rate_spread``), a lognormal on the factor the features see. Checked against the
analytic convolution of two Gaussians in log factor, at the estimator's range edge (renormalised
there, not pulled down), and on lives with a planted rate error (covered with the spread, missed
without it)."""

from __future__ import annotations

import numpy as np
import pytest
from wearbench.validation.features import CycleFeatures
from wearbench.validation.track import RATE_SPREAD, _spread_rate, track_features

from . import test_estimate
from .test_estimate import SPEC, true_mean

model = test_estimate.model  # the synthetic estimator (a fixture)


def test_the_rate_spread_convolves_a_gaussian_in_log_factor_to_the_sum_of_variances():
    """log L Gaussian in log k (mean 0.1, sd 0.15) with the rate's lognormal sd 0.2: the marginal is
    Gaussian in log k with sd sqrt(0.15^2 + 0.2^2) = 0.25 and the same mean (the analytic convolution)."""
    logk = np.linspace(np.log(0.2), np.log(5.0), 401)
    inside = np.ones(logk.size, bool)
    log_lik = np.stack([-0.5 * ((logk - 0.1) / 0.15) ** 2] * 2) - 7.0
    out = _spread_rate(log_lik, inside, logk[1] - logk[0], 0.2)
    w = np.exp(out[0] - out[0].max())
    mean = np.sum(w * logk) / w.sum()
    sd = np.sqrt(np.sum(w * (logk - mean) ** 2) / w.sum())
    assert mean == pytest.approx(0.1, abs=1e-3) and sd == pytest.approx(0.25, rel=0.01)
    assert np.array_equal(_spread_rate(log_lik, inside, logk[1] - logk[0], 0.0), log_lik)


def test_at_the_estimators_range_edge_the_spread_renormalises_and_leaves_the_outside_impossible():
    """A flat likelihood stays flat up to the last factor inside the range (the factors beyond it are
    unknown to the estimator, not impossible for the rate), and stays -inf beyond it."""
    logk = np.linspace(np.log(0.2), np.log(5.0), 161)
    inside = np.exp(logk) <= 1.5
    log_lik = np.where(inside, -3.0, -np.inf)[None]
    out = _spread_rate(log_lik, inside, logk[1] - logk[0], 0.25)
    assert np.allclose(out[0, inside], -3.0) and np.all(out[0, ~inside] == -np.inf)


def life(n_runs, eta):
    """Noise-free sessions (20 cycles each at the true mean) of a bench at 0.4 mm worn at the file's rate
    (factor 1.0) whose features change at ``eta`` times that rate."""
    return [CycleFeatures(SPEC, np.repeat(true_mean(0.4e-3, eta * n)[None], 20, axis=0), np.zeros(20)) for n in n_runs]


def test_a_planted_rate_error_is_covered_with_the_rate_spread_and_missed_without_it(model):
    """Lives worn at the file's rate (factor 1.0) whose features run 0.7 or 1.4 times as fast: without
    the spread the factor's 90 % interval sits on the features' rate and misses 1.0; with a spread of
    0.3 (the rates' own log sd is 0.35) it holds 1.0, and a bench without a rate error stays centred
    with an interval no more than twice as wide."""
    runs = [0.0, 1e5, 2e5, 3e5]
    for eta in (0.7, 1.4):
        plain = track_features(life(runs, eta), runs, model, coefficient=5.2e-14, rate_spread=0.0)
        spread = track_features(life(runs, eta), runs, model, coefficient=5.2e-14, rate_spread=0.3)
        assert plain.factor.median == pytest.approx(eta, rel=0.1) and not plain.factor.contains(1.0)
        assert spread.factor.contains(1.0) and spread.rate_spread == 0.3 and plain.rate_spread == 0.0
    plain = track_features(life(runs, 1.0), runs, model, coefficient=5.2e-14, rate_spread=0.0)
    spread = track_features(life(runs, 1.0), runs, model, coefficient=5.2e-14, rate_spread=0.3)
    assert track_features(life(runs, 1.0), runs, model, coefficient=5.2e-14).rate_spread == RATE_SPREAD == 0.2
    assert plain.factor.contains(1.0, 50) and spread.factor.contains(1.0, 50)
    width = lambda t: np.log(t.factor.hi90 / t.factor.lo90)
    assert width(plain) < width(spread) < 2.0 * width(plain) + 2 * 1.645 * 0.3
    with pytest.raises(ValueError, match="rate_spread"):
        track_features(life(runs, 1.0), runs, model, coefficient=5.2e-14, rate_spread=1.5)
