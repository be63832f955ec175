"""The sensor path as nuisance parameters: the analytic marginal against Monte Carlo, what a band
gain does to the verdict with and without the prior, calibration recovering a known path, and the
diagnosis telling a gain from a change of shape."""

import numpy as np
import pytest
from scipy import stats
from wearbench.validation.inference.ensemble import Ensemble, EnsembleSettings
from wearbench.validation.inference.identify import (
    NONE,
    IdentifyOptions,
    fit_states,
    identify_features,
)
from wearbench.validation.inference.sensor_path import SensorPath, calibrate_path, design_matrix
from wearbench.validation.inference.statistics import StateStatistics
from wearbench.validation.measurement.features import CycleFeatures, FeatureSpec

pytestmark = pytest.mark.no_kernels

SPEC = FeatureSpec()
P = SPEC.size
SB, SW = 0.04, 0.25
B_MEAN = np.random.default_rng(99).normal(0.0, 0.15, P)  # B differs from A in shape, not in level


def draw(rng, mean, realisations, cycles):
    return mean + rng.normal(0.0, np.sqrt(SB), (realisations, 1, P)) + rng.normal(0.0, np.sqrt(SW),
                                                                                  (realisations, cycles, P))


def ensemble(name, features):
    m, c, _ = features.shape
    return Ensemble(name, EnsembleSettings(realisations=m, cycles=c), features, np.zeros((m, c, 4)),
                    np.zeros((m, c)), 2 * np.pi)


def test_marginal_likelihood_equals_the_monte_carlo_integral_over_the_gains():
    """log N(x; mu + A m, C + A P A^T) against log E_theta N(x; mu + A theta, C), theta ~ N(m, P),
    on a small spec (2 bins, 1 band: 4 features, 2 nuisance parameters)."""
    spec = FeatureSpec(bins=2, bands=((50.0, 150.0),))
    rng = np.random.default_rng(0)
    mean = np.array([3.0, -2.0, 1.0, 1.5])
    path = SensorPath((0.02, 0.3), ((0.05 ** 2, 0.0), (0.0, 0.4 ** 2)), "test")
    st = StateStatistics(mean, np.eye(4) * 0.2, np.eye(4) * 0.05, np.zeros(4), 10 ** 9, 8)
    marg = st.with_nuisance(*path.nuisance(spec, mean))
    cov0 = st.covariance(5)
    theta = rng.multivariate_normal(path.theta_mean, path.theta_cov, 400_000)
    a = design_matrix(spec, mean)
    for x in (mean + 0.3, mean + np.array([0.5, -0.5, 1.0, -0.2])):
        mc = stats.multivariate_normal(np.zeros(4), cov0).logpdf(x - mean - theta @ a.T)
        mc = np.log(np.mean(np.exp(mc)))
        assert marg.log_likelihood(x, 5) == pytest.approx(mc, abs=0.01)


def test_prior_is_a_mode_between_300_hz_and_3_khz():
    prior = SensorPath.prior(SPEC)
    sd = np.sqrt(np.diag(prior.theta_cov))
    assert abs(prior.theta_mean[0]) < 1e-3 and 0.02 < sd[0] < 0.04  # +/-5 % uniform: sd 2.9 %
    # modes from 300 Hz hardly touch 50-150 Hz; the bands they fall in or above spread by factors
    # of 3 (measured: 50-150 Hz mean +0.02, sd 0.04; 150-400 Hz sd 0.44; 400-1000 Hz sd 0.58, log10)
    assert abs(prior.theta_mean[1]) < 0.1 and sd[1] < 0.1 and 0.3 < sd[2] < sd[3]
    assert np.all(np.linalg.eigvalsh(prior.theta_cov) > 0)


def band_offset(rng, offset):
    x = draw(rng, np.zeros(P), 1, 20)[0]
    x[:, 3 * SPEC.bins:] += offset
    return CycleFeatures(SPEC, x, np.zeros(20))


@pytest.fixture(scope="module")
def models():
    rng = np.random.default_rng(7)
    ens = {s: ensemble(s, draw(rng, m, 24, 8)) for s, m in (("A", np.zeros(P)), ("B", B_MEAN))}
    opts = IdentifyOptions(floor_curve=1e-6, floor_energy=1e-6)
    return {"prior": fit_states(ens, opts), "none": fit_states(ens, IdentifyOptions(
        floor_curve=1e-6, floor_energy=1e-6, sensor_path="none"))}


def test_a_band_gain_is_absorbed_by_the_prior_and_diagnosed_without_it(models):
    """-8 dB in the 400-1000 Hz band (a low carriage mode): taken as exact, the path makes it 'none',
    and the diagnosis finds the gain; with the prior, A is named."""
    rng = np.random.default_rng(8)
    session = band_offset(rng, -0.8)
    exact = identify_features(session, models["none"])
    assert exact.verdict == NONE and exact.diagnosis["sensor_path_explains"], exact.diagnosis
    assert exact.diagnosis["band_gain_db"]["400-1000 Hz"] == pytest.approx(-8.0, abs=1.5)
    assert max(exact.diagnosis["blocks"], key=exact.diagnosis["blocks"].get) == "impacts 400-1000 Hz"
    marg = identify_features(session, models["prior"])
    assert marg.verdict == "A" and marg.sensor_path.startswith("prior")


def test_a_change_of_shape_is_not_a_gain(models):
    """+/-0.8 in alternate crank-angle bins of one band: no band gain explains it, with or without the prior."""
    rng = np.random.default_rng(9)
    x = draw(rng, np.zeros(P), 1, 20)[0]
    x[:, 3 * SPEC.bins:] += np.where(np.arange(SPEC.bins) % 2, 0.8, -0.8)
    for kind in ("prior", "none"):
        r = identify_features(CycleFeatures(SPEC, x, np.zeros(20)), models[kind])
        assert r.verdict == NONE and not r.diagnosis["sensor_path_explains"], r.diagnosis
        assert "not explain" in r.notes[-1]


def test_calibration_recovers_the_path_and_then_names_the_state(models):
    """Calibrate on a session of the known state A with a -8 dB band: the posterior holds -0.8 within
    3 of its sd and is narrower than the prior; identification with it names A."""
    rng = np.random.default_rng(10)
    st = models["none"].stats["A"]
    prior = SensorPath.prior(SPEC)
    known = band_offset(rng, -0.8)
    cal = calibrate_path(known.values.mean(axis=0), st.mean, st.covariance(20), SPEC, prior, source="cal")
    sd = np.sqrt(np.diag(cal.theta_cov))
    assert abs(cal.theta_mean[3] + 0.8) < 3 * sd[3] and sd[3] < 0.3 * np.sqrt(prior.theta_cov[3, 3])
    rng2 = np.random.default_rng(11)
    ens = {s: ensemble(s, draw(rng2, m, 24, 8)) for s, m in (("A", np.zeros(P)), ("B", B_MEAN))}
    calibrated = fit_states(ens, IdentifyOptions(floor_curve=1e-6, floor_energy=1e-6), sensor=cal)
    r = identify_features(band_offset(rng, -0.8), calibrated)
    assert r.verdict == "A" and r.sensor_path == "cal"


def test_mount_response_is_a_second_order_mode_with_the_emulators_chain():
    """Steady sinusoids through a drawn mount: gain ``g`` well below the mode, ``g / (2 zeta)`` at it,
    ``g (f_n / f)^2`` well above (the analytic second-order low-pass); and the same samples as the bench
    emulator's sensor chain with only its mounting resonance and sensitivity on."""
    from wearbench.hardware.emulators.config import Accelerometer
    from wearbench.hardware.emulators.sensor import SensorChain
    from wearbench.validation.inference.sensor_path import mount_response

    fs, fn, zeta, g = 20_000.0, 700.0, 0.05, 1.04
    t = np.arange(int(0.6 * fs)) / fs
    # (above the mode the bilinear map's frequency warping takes a few % at 1.5 kHz of a 20 kHz rate)
    for f, expected, rel in ((30.0, g, 0.01), (fn, g / (2 * zeta), 0.02), (1500.0, g / abs(1 - (1500 / fn) ** 2), 0.05)):
        y = mount_response(np.sin(2 * np.pi * f * t), fs, fn, zeta, g)[t > 0.4]
        assert np.sqrt(2 * np.mean(y ** 2)) == pytest.approx(expected, rel=rel), f
    x = np.random.default_rng(3).normal(0.0, 50.0, 4000)
    acc = Accelerometer(resonance=fn, damping=zeta, sensitivity=g, adc_bits=0, clipping=False)
    chain = SensorChain(acc, fs, 1e6, np.random.default_rng(0))
    assert chain.oversample == 1
    np.testing.assert_allclose(mount_response(x, fs, fn, zeta, g), chain.process(x), rtol=1e-5, atol=1e-3)
    with pytest.raises(ValueError, match="mode 9500 Hz"):
        mount_response(x, fs, 9500.0, zeta)


def test_drawn_paths_cover_the_stated_spread_and_key_the_ensembles():
    from wearbench.bench.load import load_bench, shipped_bench
    from wearbench.validation.inference.ensemble import ensembles_key
    from wearbench.validation.inference.sensor_path import PathSpread

    spread = PathSpread()
    draws = np.array([spread.draw(s) for s in range(1, 401)])
    assert spread.draw(7) == spread.draw(7) and spread.draw(7) != spread.draw(8)
    modes = np.log10(draws[:, 0])
    assert 300 <= draws[:, 0].min() and draws[:, 0].max() <= 3000
    assert np.histogram(modes, 4, (np.log10(300), np.log10(3000)))[0].min() > 70  # log-uniform
    assert 0.02 <= draws[:, 1].min() and draws[:, 1].max() <= 0.1 and np.all(np.abs(draws[:, 2] - 1) <= 0.05)
    bench = load_bench(shipped_bench("ninebar-testbed"))
    keys = {ensembles_key(bench, bench.states, bench.speed, EnsembleSettings(sensor_paths=p))
            for p in (None, spread, PathSpread(mode=(500.0, 3000.0)))}
    assert len(keys) == 3
    old = {k: v for k, v in vars(EnsembleSettings()).items() if k != "sensor_paths"}
    old["features"] = SPEC.to_dict()
    assert EnsembleSettings.from_dict(old).sensor_paths is None  # a file from before drawn paths
    with pytest.raises(ValueError, match="sensor paths"):
        PathSpread(mode=(3000.0, 300.0))
