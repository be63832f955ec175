"""`track` answers only where one bench's life explains the sessions: lives drawn from the synthetic
estimator's own generative model pass its consistency test at about its rate, and sessions that
cannot be one bench (two clearances, one recording twice with a worn one) are told so."""

from __future__ import annotations

import numpy as np
import pytest
from wearbench.validation.estimation.track import CONSISTENCY, NO_LIFE, track_features
from wearbench.validation.measurement.features import CycleFeatures

from . import test_estimate
from .test_estimate import SB, SPEC, SW, P, true_mean

pytestmark = pytest.mark.no_kernels

model = test_estimate.model  # the synthetic estimator (a fixture)

RUNS = [0.0, 1e5, 2e5, 3e5]


def life(rng, clearance: float, factor: float = 1.3, runs=RUNS, offsets=None) -> list[CycleFeatures]:
    """Sessions of one bench (one offset drawn from the tolerances) after ``runs`` cycles."""
    offset = rng.normal(0.0, np.sqrt(SB), P) if offsets is None else offsets
    return [CycleFeatures(SPEC, true_mean(clearance, factor * n) + offset + rng.normal(0.0, np.sqrt(SW), (20, P)),
                          np.zeros(20)) for n in runs]


@pytest.mark.slow
def test_lives_of_one_bench_are_explained_at_the_tests_rate(model):
    """30 lives drawn from the model the estimator was fitted on: the joint test passes in all but a
    few (its level is 0.001; the p-values are not piled near zero)."""
    rng = np.random.default_rng(31)
    p = [track_features(life(rng, c), RUNS, model, coefficient=5.2e-14).p_value
         for c in rng.uniform(0.3e-3, 0.6e-3, 30)]
    assert sum(v < CONSISTENCY for v in p) <= 1, p
    assert np.median(p) > 0.05, p


def test_two_benches_mixed_in_one_life_are_not_explained(model):
    """Sessions of a 0.3 mm bench and of a 0.6 mm bench, given as one life: each is a bench the
    estimator explains alone, together no (c, k) does; track says so instead of a wear factor."""
    rng = np.random.default_rng(32)
    small, large = life(rng, 0.3e-3), life(rng, 0.6e-3)
    mixed = track_features([small[0], large[1], small[2], large[3]], RUNS, model, coefficient=5.2e-14,
                           labels=["a0", "b1", "a2", "b3"])
    assert all(p >= CONSISTENCY for p in mixed.session_p)
    assert mixed.p_value < CONSISTENCY and not mixed.explains
    assert mixed.verdict.startswith(NO_LIFE) and "as one bench's life" in mixed.verdict
    assert mixed.to_dict()["explains"] is False
    one = track_features(small, RUNS, model, coefficient=5.2e-14)
    assert one.explains and one.verdict.startswith("initial clearance")


def test_a_session_no_parameter_explains_alone_is_named(model):
    rng = np.random.default_rng(33)
    sessions = life(rng, 0.45e-3)
    far = CycleFeatures(SPEC, sessions[1].values + 3.0, np.zeros(20))  # 3 m/s^2 off in every feature
    t = track_features([sessions[0], far, *sessions[2:]], RUNS, model, coefficient=5.2e-14,
                       labels=["s0", "far", "s2", "s3"])
    assert not t.explains and "no parameter value explains far even alone" in t.verdict


@pytest.mark.parametrize("runs", [[0.0, 100.0, 200.0, 300.0]])
def test_cycles_run_typed_in_thousands_are_not_a_wear_factor(model, runs):
    """0, 100, 200, 300 cycles where 0-300k were meant: at most a few thousand effective cycles, where
    the estimator sees no wear; the factor is refused, not answered with the prior."""
    rng = np.random.default_rng(34)
    with pytest.raises(ValueError, match="cycles run 0-300: .*typed in thousands"):
        track_features(life(rng, 0.45e-3), runs, model, coefficient=5.2e-14)
