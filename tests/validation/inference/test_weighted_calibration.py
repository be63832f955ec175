"""A calibration session conditions the ensembles (``calibrated.WeightedStatistics``): realisation i of
every state is one drawn bench seen through one drawn sensor path, so the realisations whose known
state explains the calibration session are the ones that resemble the real bench. Synthetic paired
ensembles with three kinds of sensor path (ten realisations each), a real bench on one of them."""

import numpy as np
import pytest
from wearbench.validation.inference.ensemble import Ensemble, EnsembleSettings
from wearbench.validation.inference.identify import IdentifyOptions, fit_states, identify_features
from wearbench.validation.inference.relative_states import WeightedStatistics, tempered_weights
from wearbench.validation.inference.statistics import shrunk_covariance
from wearbench.validation.measurement.features import CycleFeatures, FeatureSpec

pytestmark = [pytest.mark.slow, pytest.mark.no_kernels]  # simulates its ensembles first (CI runs it)

SPEC = FeatureSpec()
P = SPEC.size
M = 30
SB, SV, SW = 0.02, 0.004, 0.25  # bench offset shared by the states, its state-specific part, cycle noise
RNG = np.random.default_rng(31)
MEANS = {"A": np.zeros(P), "B": RNG.normal(0.0, 0.12, P), "C": RNG.normal(0.0, 0.12, P)}
PATHS = np.zeros((3, P))
PATHS[:, SPEC.bins:] = RNG.normal(0.0, 0.5, (3, P - SPEC.bins))  # each kind reshapes every band its own way
KIND = np.arange(M) % 3


def cycles(rng, mean, offset, n):
    return mean + offset + rng.normal(0.0, np.sqrt(SV), P) + rng.normal(0.0, np.sqrt(SW), (n, P))


@pytest.fixture(scope="module")
def ensembles():
    rng = np.random.default_rng(1)
    offsets = [rng.normal(0.0, np.sqrt(SB), P) + PATHS[k] for k in KIND]
    return {s: Ensemble(s, EnsembleSettings(realisations=M, cycles=8), np.stack([cycles(rng, m, b, 8) for b in offsets]),
                        np.zeros((M, 8, 4)), np.zeros((M, 8)), 2 * np.pi) for s, m in MEANS.items()}


@pytest.fixture(scope="module")
def weighted(ensembles):
    return WeightedStatistics.fit(ensembles, "A")


def test_tempered_weights_keep_the_effective_sample_size():
    ll = np.r_[np.zeros(4), np.full(28, -1000.0)]  # four realisations explain the session, the rest do not
    w, beta = tempered_weights(ll, 8.0)
    assert 0 < beta < 1 and 1.0 / np.sum(w * w) == pytest.approx(8.0, rel=1e-6)
    assert w[:4].min() > w[4:].max()  # the order of the likelihoods is kept
    w, beta = tempered_weights(np.linspace(0.0, -1e-3, 32), 8.0)  # all alike: the likelihood as it is
    assert beta == 1.0 and 1.0 / np.sum(w * w) > 31.9
    w, _ = tempered_weights(np.r_[0.0, -50.0, -50.0], 8.0)  # fewer realisations than asked: equal weights
    np.testing.assert_allclose(w, 1.0 / 3.0)


def test_weighted_shrunk_covariance_reduces_to_the_unweighted_one():
    x = np.random.default_rng(4).normal(size=(20, 6)) @ np.diag([1.0, 2.0, 3.0, 1.0, 0.5, 4.0])
    np.testing.assert_allclose(shrunk_covariance(x, np.full(20, 0.3)), shrunk_covariance(x), rtol=1e-12)
    weights = np.r_[np.ones(12), np.zeros(8)]  # zero weight: the rows are not there
    np.testing.assert_allclose(shrunk_covariance(x, weights), shrunk_covariance(x[:12]), rtol=1e-12)
    with pytest.raises(ValueError, match="effective"):
        shrunk_covariance(x, np.r_[1.0, 1.0, np.zeros(18)])


def test_the_calibration_session_picks_the_realisations_of_its_bench(ensembles, weighted):
    rng = np.random.default_rng(2)
    assert weighted.ess == 8.0
    named_cal, named_uncal = 0, 0
    prior = fit_states(ensembles, IdentifyOptions())
    for _ in range(6):
        offset = rng.normal(0.0, np.sqrt(SB), P) + PATHS[1]  # the real bench's path is of the second kind
        cal = cycles(rng, MEANS["A"], offset, 20).mean(axis=0)
        w = weighted.weights(cal, 20)
        assert w[KIND == 1].sum() > 0.99  # measured >= 0.9998
        assert 1.0 / np.sum(w * w) >= 8.0 - 1e-6  # the rule: at least 8 realisations carry the weight
        models = weighted.models(cal, 20, reference="test calibration")
        assert models.stats["B"].realisations == 8
        for truth in ("B", "C"):
            x = CycleFeatures(SPEC, cycles(rng, MEANS[truth], offset, 20), np.zeros(20))
            after = identify_features(x, models)
            assert after.verdict in (truth, "undecided"), (truth, after.posterior, after.p_value, after.p_direction)
            assert after.sensor_path == "test calibration"
            named_cal += after.verdict == truth
            named_uncal += identify_features(x, prior).verdict == truth
    assert named_cal >= 10  # measured 11 of 12 (uncalibrated: 12 of 12, the paths' spread is low-rank here)


def test_conditioned_spread_is_narrower_than_the_ensembles(ensembles, weighted):
    """Between-bench spread of the band features: the conditioned ensembles' is that of one kind of
    path (benches only, SB), the ensembles' holds all three kinds."""
    rng = np.random.default_rng(3)
    cal = cycles(rng, MEANS["A"], rng.normal(0.0, np.sqrt(SB), P) + PATHS[0], 20).mean(axis=0)
    options = IdentifyOptions(sensor_path="none")
    narrow = WeightedStatistics(**{**weighted.__dict__, "options": options}).states(cal, 20)["A"]
    wide = fit_states(ensembles, options).stats["A"]
    bands = slice(SPEC.bins, None)
    assert np.trace(narrow.between[bands, bands]) < 0.25 * np.trace(wide.between[bands, bands])
    truth = (MEANS["A"] + PATHS[0])[bands]
    rms = lambda st: np.sqrt(np.mean((st.mean[bands] - truth) ** 2))
    assert rms(narrow) < 0.3 * rms(wide)  # the conditioned mean is the bench's path, not the paths' average
