"""Scores: known answers for identity, pure scaling, pure shift and added noise.

Expected values are computed here from the definitions by other means (closed forms, numerical
quadrature), not by calling the code under test a second time.
"""

import numpy as np
import pytest
from scipy import integrate, stats
from wearbench.validation.comparison.metrics import (
    aggregate,
    grade,
    iso18571,
    score_window,
    sprague_geers,
)

FS = 10_000.0
N = 20_000  # five "cycles" of 4000 samples
T = np.arange(N) / FS


def periodic(t=T):
    """A smooth periodic test signal: 5 whole periods in the window, several harmonics."""
    w = 2 * np.pi * 2.5
    return 30 * np.sin(w * t) + 12 * np.sin(3 * w * t + 0.4) + 5 * np.sin(7 * w * t + 1.1)


def test_identical_signals_score_one_on_every_metric():
    x = periodic()
    s = score_window(x, x.copy(), FS, cycle_samples=4000, dtw_band=200)
    for name in ("iso_rating", "iso_corridor", "iso_phase", "iso_magnitude", "iso_slope", "correlation"):
        assert getattr(s, name) == 1.0, name
    for name in ("iso_lag_s", "nrmse", "peak_error", "peak_time_shift", "sg_magnitude", "sg_phase",
                 "sg_comprehensive"):
        assert getattr(s, name) == pytest.approx(0.0, abs=1e-12), name
    assert s.iso_grade == "excellent"


@pytest.mark.parametrize("scale", [0.8, 1.1, 1.3])
def test_pure_scaling(scale):
    x = periodic()
    y = scale * x
    e = abs(scale - 1)
    iso = iso18571(x, y, dtw_band=0)  # no warping: the magnitude error is exactly |s - 1|
    assert iso.phase == 1.0 and iso.lag == 0
    assert iso.magnitude == pytest.approx(max(0.0, 1 - e / 0.5), abs=1e-9)
    assert iso.slope == pytest.approx(1 - e / 2.0, abs=1e-9)
    # corridor: fraction of the window where |s-1||x| is inside the corridors, by quadrature on a
    # fine continuous grid of one period (the definition, evaluated independently)
    peak = np.max(np.abs(periodic(np.linspace(0, 0.4, 400_001))))
    inner, outer = 0.05 * peak, 0.5 * peak

    def point_score(t):
        d = e * abs(periodic(np.array([t]))[0])
        return 1.0 if d <= inner else (0.0 if d >= outer else ((outer - d) / (outer - inner)) ** 2)

    expected, _ = integrate.quad(point_score, 0, 0.4, limit=500)
    assert iso.corridor == pytest.approx(expected / 0.4, abs=2e-3)
    # with warping allowed the magnitude score can only improve
    assert iso18571(x, y, dtw_band=200).magnitude >= iso.magnitude - 1e-12
    sg = sprague_geers(x, y)
    assert sg.magnitude == pytest.approx(scale - 1, abs=1e-12) and sg.phase == pytest.approx(0, abs=1e-6)
    s = score_window(x, y, FS, dtw_band=200)
    assert s.nrmse == pytest.approx(e * np.sqrt(np.mean(x**2)) / np.ptp(x), rel=1e-9)
    assert s.peak_error == pytest.approx(scale - 1, abs=1e-12)
    assert s.correlation == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("lag", [5, 40, 300])
def test_pure_shift(lag):
    x = periodic()
    y = np.roll(x, lag)  # theory late by `lag` samples; periodic, so the overlaps are identical
    iso = iso18571(x, y, max_lag=1000, dtw_band=100)
    assert iso.lag == lag
    assert iso.phase == pytest.approx(1 - lag / (0.2 * N), abs=1e-12)
    assert iso.magnitude == pytest.approx(1.0, abs=1e-12) and iso.slope == pytest.approx(1.0, abs=1e-12)
    # Sprague-Geers: no magnitude error; phase error = arccos(normalised autocorrelation)/pi
    sg = sprague_geers(x, y)
    w = 2 * np.pi * 2.5 * lag / FS
    amps = np.array([30.0, 12.0, 5.0]) ** 2
    rho = np.sum(amps * np.cos(np.array([1, 3, 7]) * w)) / np.sum(amps)
    assert sg.magnitude == pytest.approx(0, abs=1e-9)
    assert sg.phase == pytest.approx(np.arccos(rho) / np.pi, abs=1e-6)
    s = score_window(x, y, FS, cycle_samples=4000, max_lag=1000, dtw_band=100)
    assert s.peak_time_shift == pytest.approx(lag / FS)
    assert s.iso_lag_s == pytest.approx(lag / FS)


def test_shift_lowers_phase_more_than_a_smaller_shift():
    x = periodic()
    phases = [iso18571(x, np.roll(x, k), max_lag=1000, dtw_band=50).phase for k in (0, 10, 100, 400)]
    assert phases == sorted(phases, reverse=True) and phases[0] == 1.0


@pytest.mark.parametrize("sigma", [0.5, 2.0, 6.0])
def test_added_noise(sigma):
    x = periodic()
    rng = np.random.default_rng(7)
    y = x + rng.normal(0, sigma, N)
    iso = iso18571(x, y, max_lag=1000, dtw_band=50)
    peak = np.max(np.abs(x))
    inner, outer = 0.05 * peak, 0.5 * peak
    # expected corridor score for |N(0, sigma)| deviations, by quadrature
    f = lambda d: (1.0 if d <= inner else max(0.0, (outer - d) / (outer - inner)) ** 2)
    expected, _ = integrate.quad(lambda d: f(d) * 2 * stats.norm.pdf(d, scale=sigma), 0, 10 * sigma,
                                 points=[inner, outer], limit=200)
    assert iso.corridor == pytest.approx(expected, abs=4 * 0.5 / np.sqrt(N) + 1e-3)
    assert abs(iso.lag) <= 2 and iso.phase >= 1 - 2 / (0.2 * N)  # noise barely moves the phase
    s = score_window(x, y, FS, max_lag=1000, dtw_band=50)
    assert s.nrmse == pytest.approx(sigma / np.ptp(x), rel=0.03)
    expected_corr = np.std(x) / np.sqrt(np.var(x) + sigma**2)
    assert s.correlation == pytest.approx(expected_corr, abs=3e-3)
    # white noise dominates the derivative: the slope score falls fastest
    assert iso.slope < iso.corridor


def test_noise_lowers_scores_monotonically():
    x = periodic()
    rng = np.random.default_rng(3)
    noise = rng.normal(size=N)
    ratings = [iso18571(x, x + s * noise, max_lag=500, dtw_band=50).rating for s in (0.0, 0.5, 2.0, 8.0)]
    assert ratings == sorted(ratings, reverse=True) and ratings[0] == 1.0


def test_grades():
    assert [grade(r) for r in (0.95, 0.94, 0.81, 0.8, 0.59, 0.58, 0.1)] == [
        "excellent", "good", "good", "fair", "fair", "poor", "poor"]


def test_aggregate_spread():
    x = periodic()
    windows = [score_window(x, s * x, FS, dtw_band=20) for s in (0.9, 1.0, 1.1)]
    table = aggregate(windows)
    assert table.loc["peak_error", "mean"] == pytest.approx(0.0, abs=1e-12)
    assert table.loc["peak_error", "std"] == pytest.approx(0.1, rel=1e-9)
    assert table.loc["peak_error", "min"] == pytest.approx(-0.1) and table.loc["peak_error", "max"] == pytest.approx(0.1)
    assert (table["windows"] == 3).all()


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="equal length"):
        score_window(np.zeros(100), np.zeros(99), FS)
    with pytest.raises(ValueError, match="NaN"):
        score_window(np.full(100, np.nan), np.zeros(100), FS)


# ---- the plain call is the standard: against its reference implementation (TU Graz) -----------

def _reference(x, y):
    orm = pytest.importorskip("objective_rating_metrics.rating")
    t = np.arange(x.size) * 1e-4
    r = orm.ISO18571(np.column_stack([t, x]), np.column_stack([t, y]))
    return {"corridor": r.corridor_rating(ndigits=-1), "phase": r.phase_rating(ndigits=-1),
            "magnitude": r.magnitude_rating(ndigits=-1), "slope": r.slope_rating(ndigits=-1),
            "rating": r.overall_rating(ndigits=-1)}


def _tie_cases():
    rng = np.random.default_rng(7)
    t = np.linspace(0, 1, 400, endpoint=False)
    wave = np.sin(2 * np.pi * 4 * t)
    square = np.sign(np.sin(2 * np.pi * 3 * t)) + 0.5 * np.sign(np.sin(2 * np.pi * 7 * t))
    pulse, pair = np.zeros(201), np.zeros(201)
    pulse[96:105] = 1.0
    pair[86:95] = pair[106:115] = 1.0  # mirror-symmetric: the shifts +10 and -10 correlate alike
    return {
        "random": (rng.normal(size=300), rng.normal(size=300)),
        "noisy sine": (wave, 1.1 * np.roll(wave, 7) + 0.05 * rng.normal(size=400)),
        "phase tie": (pulse, pair),
        "dtw tie": (pulse, np.convolve(pulse, np.ones(5) / 5, mode="same")),  # flat runs: equal-cost paths
        "quantised": (np.round(4 * wave) / 4, np.round(4 * 0.9 * np.roll(wave, 5)) / 4),
        "steps": (square, 0.8 * np.roll(square, 9)),
    }


@pytest.mark.slow
@pytest.mark.parametrize("case", list(_tie_cases()))
def test_plain_call_matches_the_reference_implementation(case):
    x, y = _tie_cases()[case]
    ours = iso18571(x, y)
    ref = _reference(x, y)
    for key, value in ref.items():
        assert getattr(ours, key) == pytest.approx(value, abs=1e-12), key


def test_phase_tie_takes_the_comparison_late_shift():
    x, y = _tie_cases()["phase tie"]
    assert iso18571(x, y).lag == 10  # the standard: comparison late first
    assert iso18571(x, y, ties="wearbench").lag == -10  # the pipeline's order, kept explicitly
    assert iso18571(x, y).rating == pytest.approx(_reference(x, y)["rating"], abs=1e-12)


def test_dtw_tie_order_matters_and_is_the_standards():
    x, y = _tie_cases()["dtw tie"]
    band = int(np.ceil(0.1 * x.size)) - 1
    standard, diagonal = iso18571(x, y), iso18571(x, y, dtw_band=band, ties="wearbench")
    assert standard.lag == diagonal.lag == 0
    assert abs(standard.magnitude - diagonal.magnitude) > 0.01  # the tie order decides E_M here
    assert standard.magnitude == pytest.approx(_reference(x, y)["magnitude"], abs=1e-12)


@pytest.mark.parametrize("y", [np.zeros(100), np.full(100, 3.0)])
def test_constant_signals_are_refused(y):
    x = np.sin(np.linspace(0, 6, 100))
    with pytest.raises(ValueError, match="constant"):
        iso18571(x, y)
    with pytest.raises(ValueError, match="constant"):
        iso18571(y, x)
