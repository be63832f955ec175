"""The rate at which a bench's features change along its life, about the estimator's: ``track``
marginalises it (``rate_spread``), a lognormal on the factor the features see. Checked against the
analytic convolution of two Gaussians in log factor, at the estimator's range edge (renormalised
there, not pulled down), and on lives with a planted rate error (covered with the spread, missed
without it); a rate that falls with clearance, planted on lives, is measured by ``life_rate``, stored
with the move, and covers a bench the constant spread misses."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from wearbench.validation.estimation.move import Rate, life_move, load_move, save_move
from wearbench.validation.estimation.track import (
    RATE_SPREAD,
    _spread_rate,
    life_rate,
    track_features,
)
from wearbench.validation.measurement.features import CycleFeatures

from . import test_estimate
from .test_estimate import SB, SPEC, SW, P, true_mean

pytestmark = pytest.mark.no_kernels

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


@pytest.mark.slow
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


def rate_lives(rng, lives: int = 16):
    """Lives of benches worn 1.3x the file's (sessions at 0-400k cycles, 20 cycles each, as session
    means with their bench offset and noise) whose features change at a rate that falls with the
    initial clearance: the estimator's at 0.30 mm, half of it at 0.55 mm (log-linear between)."""
    runs, out = np.arange(5) * 1e5, []
    for c in rng.uniform(0.30e-3, 0.55e-3, lives):
        offset = rng.normal(0.0, np.sqrt(SB), P)
        xbars = np.stack([true_mean(c, 1.3 * planted_rate(c) * n) + offset + rng.normal(0.0, np.sqrt(SW / 20), P)
                          for n in runs])
        out.append((xbars, runs, float(c), 1.3))
    return out


def planted_rate(c: float) -> float:
    return float(np.exp(np.log(0.5) * (c - 0.30e-3) / 0.25e-3))


@pytest.mark.slow
def test_a_planted_clearance_dependent_rate_is_measured_and_covers_the_factor_where_a_constant_spread_misses(model):
    """life_rate on 16 lives whose features' rate falls from 1x at 0.30 mm to 0.5x at 0.55 mm finds a
    rate near 1x at the low end and well below it at the high end; with it stored on the move, a new
    bench at 0.53 mm (rate 0.53x) gets the true factor 1.3 inside its 90 % interval, which the constant
    spread misses, and a bench at 0.32 mm (rate 0.97x) keeps it inside its 50 % interval."""
    rng = np.random.default_rng(5)
    lives = rate_lives(rng)
    move = life_move(model, lives)
    rate = life_rate(model, lives, move, cycles=20)
    low, high = (float(np.exp(rate.at(c)[0])) for c in (0.30e-3, 0.55e-3))
    assert 0.9 <= low <= 1.1 and high < 0.75, rate
    measured = replace(move, rate=rate)
    runs = list(np.arange(5) * 1e5)

    def sessions(c):
        return [CycleFeatures(SPEC, np.repeat(true_mean(c, 1.3 * planted_rate(c) * n)[None], 20, axis=0),
                              np.zeros(20)) for n in runs]

    constant = track_features(sessions(0.53e-3), runs, model, coefficient=5.2e-14, move=move)
    curve = track_features(sessions(0.53e-3), runs, model, coefficient=5.2e-14, move=measured)
    assert constant.rate_spread == RATE_SPREAD and not constant.factor.contains(1.3)
    assert curve.rate_spread is None and curve.move["rate"]["mean"] == list(rate.mean)
    assert curve.factor.contains(1.3)
    assert track_features(sessions(0.32e-3), runs, model, coefficient=5.2e-14, move=measured).factor.contains(1.3, 50)
    forced = track_features(sessions(0.53e-3), runs, model, coefficient=5.2e-14, move=measured, rate_spread=0.2)
    assert forced.rate_spread == 0.2 and forced.factor.median == pytest.approx(constant.factor.median)


def test_a_measured_rate_is_stored_with_the_move_and_a_bad_one_is_refused(model, tmp_path):
    """The rate survives save and load with the move; a move saved without one loads with none; a rate
    field of the wrong shape or with a negative sd is refused naming the file and the field."""
    lives = rate_lives(np.random.default_rng(6), lives=4)
    move = life_move(model, lives)
    rate = Rate((0.3e-3, 0.55e-3), (0.0, -0.4), (0.1, 0.3))
    back = load_move(save_move(replace(move, rate=rate), tmp_path / "a.move.npz"), move.estimator)
    assert back.rate == rate and "0.67x (log sd 0.30) at 0.550 mm" in back.describe()
    assert load_move(save_move(move, tmp_path / "b.move.npz"), move.estimator).rate is None
    assert rate.at(0.2e-3) == (0.0, 0.1) and rate.at(0.7e-3) == (-0.4, 0.3)  # held beyond the knots
    with pytest.raises(ValueError, match="lognormal sd"):
        Rate((0.3e-3, 0.55e-3), (0.0, -0.4), (0.1, -0.3))
    data = dict(np.load(tmp_path / "a.move.npz"))
    for bad, match in ((data["rate"][:2], r"field 'rate' shape \(2, 2\)"), (data["rate"] * [[1], [1], [-1]],
                                                                             "field 'rate': rate: clearances")):
        np.savez(tmp_path / "bad.move.npz", **{**data, "rate": bad})
        with pytest.raises(ValueError, match=match):
            load_move(tmp_path / "bad.move.npz", move.estimator)
