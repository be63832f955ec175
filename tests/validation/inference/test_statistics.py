"""Cycle features and state statistics against analytic values and a second method."""

import numpy as np
import pytest
from scipy import stats
from wearbench.validation.inference.statistics import StateStatistics, shrunk_covariance
from wearbench.validation.measurement.features import CycleFeatures, FeatureSpec, cycle_features

pytestmark = pytest.mark.no_kernels

FS = 10_000.0


def record(revs=6, speed=2 * np.pi, tone=None, bias=0.0):
    """a = 30 cos(theta) (+ a 300 Hz tone of amplitude 5 in the crank-angle bin 90-100 deg)."""
    t = np.arange(int(revs * 2 * np.pi / speed * FS)) / FS
    theta = 0.3 + speed * t
    acc = 30 * np.cos(theta) + bias
    if tone:
        inside = (np.mod(theta, 2 * np.pi) >= np.radians(90)) & (np.mod(theta, 2 * np.pi) < np.radians(100))
        acc = acc + inside * 5 * np.sin(2 * np.pi * 300 * t)
    return t, theta, acc


def test_curve_bins_are_bin_means_of_the_low_passed_signal():
    t, theta, acc = record(bias=0.7)
    f = cycle_features(t, theta, acc, FeatureSpec(bins=36))
    assert f.cycles == 5  # crank angle 0.3 .. 38.0 rad: complete cycles from 2 pi to 12 pi
    edges = np.radians(np.arange(37) * 10.0)
    exact = 30 * (np.sin(edges[1:]) - np.sin(edges[:-1])) / np.radians(10.0)  # mean of 30 cos over a bin
    np.testing.assert_allclose(f.curve, np.tile(exact, (5, 1)), atol=0.05)  # bias removed; 1 Hz passes 50 Hz


def test_energy_bins_see_the_band_and_only_where_it_is():
    t, theta, acc = record(tone=True)
    f = cycle_features(t, theta, acc, FeatureSpec(bins=36, floor=1e-6, bands=((100, 1000),)))
    power = 10 ** f.energy[:, 0]
    np.testing.assert_allclose(power[:, 9], 12.5, rtol=0.15)  # 5^2 / 2 in the 90-100 deg bin
    assert np.all(np.delete(power, [8, 9, 10], axis=1) < 0.05)  # kinematics (1 Hz) is outside 100-1000 Hz


def test_each_band_sees_only_its_own_tone():
    t, theta, acc = record(tone=True)  # the tone: 300 Hz
    spec = FeatureSpec(bins=36, floor=1e-6, bands=((50, 150), (150, 400), (400, 1000)))
    power = 10 ** cycle_features(t, theta, acc, spec).energy
    assert power.shape == (5, 3, 36) and spec.size == 4 * 36
    np.testing.assert_allclose(power[:, 1, 9], 12.5, rtol=0.15)
    assert np.all(power[:, [0, 2], 9] < 0.05 * 12.5)  # 300 Hz is outside 50-150 and 400-1000 Hz


def test_reverse_rotation_and_clipping():
    t, theta, acc = record()
    clipped = np.abs(acc) >= 29.0  # the flags a session's clipped column gives
    f = cycle_features(t, -theta, np.clip(acc, -29.0, 29.0), clipped=clipped)
    assert f.cycles == 5 and np.all(f.clipped > 0)
    assert f.clipped.sum() <= clipped.sum()  # the flags inside complete cycles
    assert cycle_features(t, theta, acc, clipped=np.abs(acc) >= 100.0).clipped.sum() == 0
    assert cycle_features(t, theta, acc).clipped.sum() == 0  # flags not known: none counted
    with pytest.raises(ValueError, match="clipped flags"):
        cycle_features(t, theta, acc, clipped=clipped[:-1])


def test_too_coarse_a_record_is_refused():
    t = np.arange(0, 5, 0.05)
    with pytest.raises(ValueError, match="bin holds no sample"):
        cycle_features(t, 2 * np.pi * t, np.cos(2 * np.pi * t), FeatureSpec(bins=36, lowpass=5, bands=((6, 9),)))


def schafer_strimmer(x: np.ndarray) -> np.ndarray:
    """Schäfer & Strimmer's target D written out from the paper's definitions, sample by sample:
    r_ij the correlations, Var(r_ij) = n / (n - 1)^3 sum_k (w_kij - wbar_ij)^2."""
    n, p = x.shape
    z = (x - x.mean(axis=0)) / x.std(axis=0, ddof=1)
    w = np.array([np.outer(zk, zk) for zk in z])
    r = w.sum(axis=0) / (n - 1)
    var_r = n / (n - 1) ** 3 * sum((wk - w.mean(axis=0)) ** 2 for wk in w)
    off = ~np.eye(p, dtype=bool)
    lam = min(1.0, max(0.0, var_r[off].sum() / (r[off] ** 2).sum()))
    rs = np.where(off, r * (1 - lam), 1.0)
    return rs * np.outer(x.std(axis=0, ddof=1), x.std(axis=0, ddof=1))


@pytest.mark.parametrize("n", [3, 25, 400])
def test_the_shrunk_covariance_is_the_papers_estimator(n):
    """The matrix-product form against the definitions summed sample by sample, with strongly and
    weakly correlated features (the intensity between 0 and 1), and a duplicated one (r = 1)."""
    rng = np.random.default_rng(n)
    x = rng.normal(size=(n, 6)) @ rng.normal(size=(6, 6))
    x[:, 5] = 2 * x[:, 0]
    np.testing.assert_allclose(shrunk_covariance(x), schafer_strimmer(x), rtol=1e-12, atol=1e-12 * np.abs(x).max() ** 2)


def test_shrinkage_beats_the_sample_covariance_when_features_outnumber_samples():
    rng = np.random.default_rng(3)
    p, n = 40, 20
    truth = 0.3 ** np.abs(np.subtract.outer(np.arange(p), np.arange(p))) * np.outer(np.arange(1, p + 1), np.arange(1, p + 1)) ** 0.5
    errs_sample, errs_shrunk = [], []
    for _ in range(20):
        x = rng.multivariate_normal(np.zeros(p), truth, size=n)
        errs_sample.append(np.linalg.norm(np.cov(x, rowvar=False) - truth))
        errs_shrunk.append(np.linalg.norm(shrunk_covariance(x) - truth))
        np.testing.assert_allclose(np.diag(shrunk_covariance(x)), np.var(x, axis=0, ddof=1))  # target keeps variances
    assert np.mean(errs_shrunk) < 0.8 * np.mean(errs_sample)
    # with many samples the correlations survive (little shrinkage)
    x = rng.multivariate_normal(np.zeros(p), truth, size=5000)
    np.testing.assert_allclose(shrunk_covariance(x), truth, atol=0.08 * truth.max())


def test_hierarchical_fit_recovers_between_and_within_covariances():
    rng = np.random.default_rng(7)
    m, c, p = 400, 10, 3
    sb, sw = np.diag([4.0, 1.0, 0.25]), np.diag([1.0, 9.0, 0.5])
    mu = np.array([1.0, -2.0, 0.5])
    values = (mu + rng.multivariate_normal(np.zeros(p), sb, size=m)[:, None, :]
              + rng.multivariate_normal(np.zeros(p), sw, size=(m, c)))
    s = StateStatistics.fit(values, np.zeros(p))
    np.testing.assert_allclose(np.diag(s.between), np.diag(sb), rtol=0.2)
    np.testing.assert_allclose(np.diag(s.within), np.diag(sw), rtol=0.1)
    np.testing.assert_allclose(s.mean, mu, atol=0.25)
    # the density is the multivariate normal of the mean of n cycles (scipy as second method)
    x = mu + 0.3
    for n in (1, 5, 20):
        ref = stats.multivariate_normal(s.mean, s.covariance(n)).logpdf(x)
        assert s.log_likelihood(x, n) == pytest.approx(ref, rel=1e-10)
    assert s.covariance(20)[0, 0] < s.covariance(1)[0, 0]


def test_feature_container_blocks():
    spec = FeatureSpec(bins=4, bands=((1, 2), (2, 3)))
    f = CycleFeatures(spec, np.arange(24.0).reshape(2, 12), np.zeros(2, dtype=int))
    assert f.curve.shape == (2, 4) and f.energy.shape == (2, 2, 4) and f.energy[0, 1, 0] == 8.0
    with pytest.raises(ValueError, match="bands"):
        FeatureSpec(bands=((400, 100),))
