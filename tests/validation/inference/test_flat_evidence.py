"""Issue 44, item 1: when a session's evidence does not move a posterior, the verdict says so, never a
silent prior. Synthetic ensembles and estimators under the hierarchical model of ``statistics.py``:
candidates the features cannot tell apart get "the features cannot tell the candidates apart"; a
session between separable candidates gets a note; an estimator whose features do not move with
clearance or wear gives "does not move the estimate from its prior", with the distances in the JSON.
And ``track`` with a design of two cycles-run values (it ended in an IndexError)."""

from __future__ import annotations

import numpy as np
import pytest
from wearbench.validation.estimation.estimate import (
    PRIOR_ONLY,
    Estimator,
    EstimatorDesign,
    estimate_features,
    fit_estimator,
)
from wearbench.validation.estimation.track import track_features
from wearbench.validation.inference.ensemble import Ensemble, EnsembleSettings
from wearbench.validation.inference.identify import (
    FLAT,
    INDISTINCT,
    fit_states,
    identify_features,
    prior_distance,
)
from wearbench.validation.measurement.features import CycleFeatures, FeatureSpec

pytestmark = pytest.mark.no_kernels

SPEC = FeatureSpec()
P = SPEC.size
SB, SW = 0.04, 0.25
SETTINGS = EnsembleSettings(realisations=12, cycles=8, sensor_paths=None)


def draw(rng, mean, realisations, cycles):
    bench = rng.normal(0.0, np.sqrt(SB), (realisations, 1, P))
    return mean + bench + rng.normal(0.0, np.sqrt(SW), (realisations, cycles, P))


def ensembles(rng, means):
    return {name: Ensemble(name, SETTINGS, draw(rng, m, 12, 8), np.zeros((12, 8, 36)), np.zeros((12, 8)), 6.28)
            for name, m in means.items()}


def session(rng, mean, cycles=20):
    return CycleFeatures(SPEC, draw(rng, mean, 1, cycles)[0], np.zeros(cycles, dtype=np.int64))


def test_prior_distance_is_zero_for_the_prior_and_near_one_for_certainty():
    assert prior_distance(np.full(4, 0.25)) == 0.0
    assert prior_distance(np.array([1.0, 0.0, 0.0, 0.0])) == 0.75
    assert prior_distance(np.ones((81, 61))) < 1e-12


@pytest.mark.slow
def test_candidates_the_features_cannot_tell_apart_say_so():
    rng = np.random.default_rng(3)
    same = np.zeros(P)
    models = fit_states(ensembles(rng, {"a": same, "b": same, "c": same}))
    assert models.held_out < 0.67  # chance is 1/3
    r = identify_features(session(rng, same), models)
    assert r.verdict == INDISTINCT and r.cycles_needed is None
    assert any("cannot tell the candidates apart" in n and "held out" in n for n in r.notes)
    d = r.to_dict()
    assert d["held_out"] == models.held_out and "evidence" in d and "flat" in d


def test_a_session_between_separable_candidates_is_said_not_to_move_the_posterior():
    rng = np.random.default_rng(4)
    a, b = np.zeros(P), np.full(P, 0.6)
    models = fit_states(ensembles(rng, {"a": a, "b": b}))
    assert models.held_out > 0.95
    named = identify_features(session(rng, a), models)
    assert named.verdict == "a" and not named.flat and named.evidence > 0.4
    between = identify_features(session(rng, 0.5 * (a + b), cycles=2), models)
    if between.evidence < FLAT:  # it landed in the middle: the printout says the prior was not moved
        assert between.flat and any("hardly moves the posterior" in n for n in between.notes)
    else:
        assert not between.flat


def _estimator(rng, slope_c: float, slope_n: float, cycles=(0.0, 200_000.0, 400_000.0)) -> Estimator:
    design = EstimatorDesign((0.25e-3, 0.45e-3, 0.65e-3), cycles, EnsembleSettings(realisations=8, cycles=6))
    c = np.asarray(design.clearances)[:, None, None, None, None]
    n = np.asarray(design.cycles)[None, :, None, None, None]
    mean = slope_c * (c - 0.45e-3) / 0.2e-3 + slope_n * n / design.cycles[-1]
    feats = np.stack([np.stack([draw(rng, 0.0, 8, 6) for _ in design.cycles]) for _ in design.clearances]) + mean
    depth = np.tile(np.asarray(design.cycles) * 1e-10, (3, 1))
    return Estimator("synthetic", "key", design, feats, depth, 6.28)


def test_an_estimate_the_session_does_not_move_is_its_prior_and_says_so():
    rng = np.random.default_rng(5)
    model = fit_estimator(_estimator(rng, 0.0, 0.0))
    est = estimate_features(session(rng, np.zeros(P)), model)
    assert est.flat and est.verdict == PRIOR_ONLY and est.line() == PRIOR_ONLY
    assert max(est.evidence.values()) < FLAT
    assert any("hardly moves the posterior from the uniform prior" in n for n in est.notes)
    assert est.to_dict()["flat"] is True and set(est.to_dict()["evidence"]) == {"clearance", "cycles_run"}


def test_an_estimate_the_session_moves_is_a_measurement():
    rng = np.random.default_rng(6)
    model = fit_estimator(_estimator(rng, 2.0, 1.5))
    est = estimate_features(session(rng, np.full(P, 2.0 * 0.5 + 1.5 * 0.5)), model)
    assert not est.flat and est.verdict != PRIOR_ONLY and min(est.evidence.values()) > FLAT


def test_track_takes_a_design_of_two_cycles_run_values():
    """A design of 0 and one wear stage (``estimator --design-cycles 0,200000``) ended track in an
    IndexError: the depth curve's last stage reached before the grid's start."""
    rng = np.random.default_rng(7)
    est = _estimator(rng, 2.0, 1.5, cycles=(0.0, 200_000.0))
    model = fit_estimator(est)
    sessions = [CycleFeatures(SPEC, est.features[1, j, 0], np.zeros(6, dtype=np.int64)) for j in range(2)]
    t = track_features(sessions, [0.0, 200_000.0], model, coefficient=5e-14)
    assert np.isfinite(t.factor.median) and len(t.depth) == 2
