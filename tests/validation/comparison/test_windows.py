"""Five-cycle window verdicts against ensembles built here from a known generator (no model).

The generator stands in for a chaotic mechanism: per cycle a smooth kinematic curve (its harmonics
differ a little per realisation, as a bench drawn within tolerances does) plus two impacts whose crank
angle and size scatter from cycle to cycle; state "soft" rings at 250 Hz, state "hard" impacts 1.8x
harder at 150 Hz. A measured session is a fresh draw of the same generator (a seed no realisation
uses) read through a sensor that is ``DELAY`` late, with noise. Independent truth: the state it was
drawn from and the delay it was given.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from wearbench.compute.options import QUIET
from wearbench.reports.assessment import write_assessment_report
from wearbench.validation.comparison.windows import (
    FEATURE_STATISTICS,
    WindowOptions,
    measured_curves,
    score_windows,
    separation,
    window_theory,
)
from wearbench.validation.inference.ensemble import Ensemble, EnsembleSettings
from wearbench.validation.inference.identify import (
    IdentifyOptions,
    StateModels,
    candidate_ratio,
    direction_distance2,
    fit_states,
)
from wearbench.validation.inference.statistics import StateStatistics
from wearbench.validation.measurement.chain_delay import StatedDelay
from wearbench.validation.measurement.features import FeatureSpec, cycle_curves, cycle_features
from wearbench.validation.measurement.filters import parse_filter
from wearbench.validation.measurement.session import MeasuredSession
from wearbench.validation.workflows.assess import assess_sessions

FS = 5000.0
OMEGA = 2 * np.pi  # crank rad/s
DELAY = 0.6e-3
STATES = {"soft": (1.0, 250.0), "hard": (1.8, 150.0)}
SETTINGS = EnsembleSettings(realisations=24, cycles=8)


def generate(state: str, seed: int, cycles: float, *, delay: float = 0.0, noise: float = 0.0):
    """(t, crank angle, acceleration) of one draw of ``state``."""
    rng = np.random.default_rng(seed)
    size, freq = STATES[state]
    t = np.arange(0.0, cycles * 2 * np.pi / OMEGA, 1 / FS)
    a1, a2, p2 = 5 * (1 + 0.04 * rng.standard_normal()), 2 * (1 + 0.05 * rng.standard_normal()), 0.0003 * rng.standard_normal()
    phase0 = rng.uniform(0, 2 * np.pi)

    def acc(tt):
        theta = OMEGA * tt + phase0
        x = a1 * np.sin(theta) + a2 * np.sin(2 * theta + p2) + 1.5 * np.sin(7 * theta + 7 * p2)
        for k in range(int(np.floor(theta[0] / (2 * np.pi))) - 1, int(np.ceil(theta[-1] / (2 * np.pi))) + 1):
            for centre in (np.radians(60), np.radians(200)):
                hit = (2 * np.pi * k + centre + np.radians(4) * rng.standard_normal() - phase0) / OMEGA
                amp = 40 * size * np.exp(0.3 * rng.standard_normal())
                dt = tt - hit
                on = dt >= 0
                x[on] += amp * np.exp(-dt[on] / 4e-3) * np.sin(2 * np.pi * freq * dt[on])
        return x

    return t, OMEGA * t + phase0, acc(t - delay) + noise * rng.standard_normal(t.size)


def ensemble(state: str) -> Ensemble:
    feats, curves, peaks = [], [], []
    spec = parse_filter(SETTINGS.curve_filter, remove_bias=False)
    for i in range(SETTINGS.realisations):
        t, angle, acc = generate(state, 1 + i, SETTINGS.cycles + 1.5)
        f = cycle_features(t, angle, acc, SETTINGS.features)
        c, p = cycle_curves(t, angle, acc, grid=SETTINGS.grid, filter_spec=spec)
        feats.append(f.values[:SETTINGS.cycles])
        curves.append(c[:SETTINGS.cycles])
        peaks.append(p[:SETTINGS.cycles])
    return Ensemble(state, SETTINGS, np.stack(feats), np.stack(curves), np.stack(peaks), OMEGA)


def session(state: str, seed: int, cycles: int = 21) -> MeasuredSession:
    t, angle, acc = generate(state, seed, cycles + 0.5, delay=DELAY, noise=0.05)
    enc = pd.DataFrame({"time": t[::5], "angle": angle[::5]})  # encoder at 1 kHz
    return MeasuredSession(f"{state} #{seed}", pd.DataFrame({"time": t, "acc": acc}), enc)


@pytest.fixture(scope="module")
def ensembles():
    return {s: ensemble(s) for s in STATES}


@pytest.fixture(scope="module")
def assessed(ensembles):
    sessions = [session(s, 5000 + 10 * k + d) for k, s in enumerate(STATES) for d in range(3)]
    return assess_sessions(sessions, ensembles=ensembles, compute=QUIET)


def test_delay_is_found_within_a_fifth_of_a_millisecond(assessed):
    delays = [w.delay_s for a in assessed for w in a.windows[a.session.label.split(" #")[0]].windows]
    assert len(delays) == 6 * 4
    assert np.mean(np.abs(np.array(delays) - DELAY) < 0.2e-3) >= 0.9, delays


def test_without_a_statement_the_delay_is_said_to_come_from_the_signal_alone(assessed):
    fit = assessed[0].windows[assessed[0].state].delay
    assert fit.stated is None and fit.delay == fit.signal_alone
    assert fit.describe().startswith("fitted from the signal alone")


DRIFT = 100e-6  # a sample clock 100 ppm fast: the delay grows by 1.35 ms over the 13.5 s session


@pytest.fixture(scope="module")
def drifting(ensembles):
    """A "soft" session whose accelerometer is 0.3 ms late at its start and DRIFT later per second,
    its curves, features and the "soft" state's window theory."""
    t, angle, _ = generate("soft", 7000, 13.5)
    truth = 0.3e-3 + DRIFT * t
    _, _, acc = generate("soft", 7000, 13.5, delay=truth, noise=0.05)
    mc = measured_curves(t, angle, acc, grid=SETTINGS.grid, filter_spec=SETTINGS.curve_filter)
    f = cycle_features(t, angle, acc, SETTINGS.features)
    theory = window_theory(ensembles["soft"], crank_speed=OMEGA, models=fit_states(ensembles, window_cycles=5))
    return mc, f, theory


def test_a_stated_delay_with_its_drift_aligns_every_window(drifting):
    mc, f, theory = drifting
    stated = StatedDelay(filter=0.2e-3, sensor=0.0, latency=0.1e-3, clock_drift=DRIFT, uncertainty=0.05e-3,
                         band=(1.0, 100.0))
    sw = score_windows(mc, theory, f, stated)
    assert len(sw.windows) == 2
    for w in sw.windows:  # each window at its own delay: the statement at its middle, plus the residual
        assert w.delay_s == pytest.approx(0.3e-3 + DRIFT * 0.5 * (w.t_start + w.t_end), abs=0.06e-3)
    fit = sw.delay
    assert abs(fit.residual) <= 0.05e-3 and not fit.disagrees
    for w in sw.windows:  # scores.json: "stated X + fitted residual Y" per window
        d = w.to_dict()
        assert d["delay_stated_s"] == pytest.approx(0.3e-3 + DRIFT * 0.5 * (w.t_start + w.t_end), abs=2e-6)
        assert d["delay_residual_s"] == pytest.approx(fit.residual)
    assert fit.describe().startswith("stated ") and "fitted residual" in fit.describe()
    assert sw.summary()["delay"]["source"] == "stated"
    # the signal alone, one delay for the session, misses the windows' drift by far more
    alone = score_windows(mc, theory, f)
    assert max(abs(w.delay_s - (0.3e-3 + DRIFT * 0.5 * (w.t_start + w.t_end))) for w in alone.windows) > 0.2e-3


def test_a_wrong_statement_holds_its_residual_at_the_bound_and_is_flagged(drifting):
    mc, f, theory = drifting
    wrong = StatedDelay(filter=0.2e-3, sensor=0.0, latency=1.6e-3, clock_drift=DRIFT, uncertainty=0.05e-3,
                        band=(1.0, 100.0))  # 1.5 ms too late: a tap test misread
    fit = score_windows(mc, theory, f, wrong).delay
    assert fit.at_bound and fit.residual == pytest.approx(-0.05e-3) and fit.disagrees
    assert "disagrees" in fit.describe()


def test_windows_separate_the_right_state_from_the_wrong_one(assessed):
    right, wrong = [], []
    for a in assessed:
        truth = a.session.label.split(" #")[0]
        for state, sw in a.windows.items():
            (right if state == truth else wrong).extend(w.consistent for w in sw.windows)
    assert np.mean(right) >= 0.8, right
    assert np.mean(wrong) <= 0.05, wrong  # inconsistent with the wrong state


def test_a_wrong_window_departs_where_the_impacts_are(assessed):
    a = next(a for a in assessed if a.session.label.startswith("soft"))
    departs = [d for w in a.windows["hard"].windows for d in w.departs]
    assert any("impacts" in d for d in departs), departs
    # the impacts are near 60 and 200 deg: every impact-band departure lies within 40 deg after one
    for d in departs:
        if d.startswith("impacts"):
            lo = float(d.split()[-2].split("-")[0])
            assert 40 <= lo < 120 or 180 <= lo < 260, d


def test_null_is_calibrated_on_held_out_realisations(ensembles):
    """Windows of fresh draws of the true state are consistent at about 1 - alpha, and their
    percentiles among held-out realisation windows spread over 0-100."""
    models = fit_states(ensembles, window_cycles=5)
    theory = window_theory(ensembles["soft"], crank_speed=OMEGA, models=models, options=WindowOptions())
    got = []
    for seed in range(6000, 6006):
        t, angle, acc = generate("soft", seed, 11.5)
        mc = measured_curves(t, angle, acc, grid=SETTINGS.grid, filter_spec=SETTINGS.curve_filter)
        f = cycle_features(t, angle, acc, SETTINGS.features)
        got += score_windows(mc, theory, f).windows
    assert len(got) == 12
    assert np.mean([w.consistent for w in got]) >= 0.75
    assert np.ptp([w.percentile for w in got]) > 40


@pytest.mark.slow
def test_each_feature_statistic_can_decide_with_its_own_held_out_null(ensembles):
    """With any feature statistic as the verdict, fresh draws of the true state are consistent at
    about 1 - alpha and draws of the other state are not; the verdict reads that statistic's p-value,
    whose null is the held-out realisations' windows; without the fitted statistics it is refused."""
    models = fit_states(ensembles, window_cycles=5)
    draws = {}
    for state in STATES:
        for seed in range(6100, 6104):
            t, angle, acc = generate(state, seed, 11.5)
            draws.setdefault(state, []).append((measured_curves(t, angle, acc, grid=SETTINGS.grid,
                                                                filter_spec=SETTINGS.curve_filter),
                                                cycle_features(t, angle, acc, SETTINGS.features)))
    for stat in FEATURE_STATISTICS:
        options = WindowOptions(statistic=stat)
        theory = window_theory(ensembles["soft"], crank_speed=OMEGA, models=models, options=options)
        assert theory.null[stat].size == models.window_null["soft"].shape[0]
        got = {s: [w for mc, f in d for w in score_windows(mc, theory, f).windows] for s, d in draws.items()}
        assert all(w.consistent == (w.p_values[stat] >= options.alpha) for ws in got.values() for w in ws)
        assert np.mean([w.consistent for w in got["soft"]]) >= 0.75, stat
        assert not any(w.consistent for w in got["hard"]), stat
        bare = window_theory(ensembles["soft"], crank_speed=OMEGA, options=options)
        with pytest.raises(ValueError, match=f"{stat!r} verdict needs"):
            score_windows(draws["soft"][0][0], bare, draws["soft"][0][1])


@pytest.mark.slow
def test_report_has_one_window_verdict_per_session_and_a_theory_with_impacts(assessed, tmp_path):
    report = write_assessment_report(assessed, tmp_path)
    scores = json.loads(report.scores_json.read_text())
    rows = scores["identification"]
    assert len(rows) == len(assessed)
    for row, a in zip(rows, assessed, strict=True):
        assert row["window_state"] == a.state
        assert set(row["windows"]) == set(STATES)
        w = row["windows"][a.state]["window_details"][0]
        for key in ("corridor", "phase", "magnitude", "slope", "rating"):
            assert 0 <= w["iso"][key] <= 1
        assert row["window_verdict"].startswith(("consistent", "inconsistent", "mixed", "cannot decide"))
    text = report.html.read_text()
    assert "windows against it" in text and "ensemble median" not in text
    # the realisation drawn beside the measurement has impacts: its peak is that of the ensemble's cycles
    a = assessed[0]
    w = a.windows[a.state].windows[0]
    assert np.max(np.abs(w.realisation_window)) > 0.5 * np.median(ensembles_peaks(a))
    assert any(p.name.startswith("window_") for p in report.figures)


def ensembles_peaks(a) -> np.ndarray:
    return a.bands.peaks_theory


@pytest.mark.slow
def test_calibration_is_computed_once_per_ensembles_content(ensembles, monkeypatch, tmp_path):
    """The costly part (fitted statistics, window nulls) comes from the result cache the second time,
    with the same verdicts; other ensembles are a miss."""
    from wearbench.validation.workflows import assess

    monkeypatch.setenv("WEARBENCH_CACHE", str(tmp_path))
    s = session("soft", 5100)
    first = assess.assess_sessions([s], ensembles=ensembles, compute=QUIET)[0]

    def refit(*args, **kwargs):
        raise AssertionError("fitted again")

    monkeypatch.setattr(assess, "fit_states", refit)
    again = assess.assess_sessions([s], ensembles=ensembles, compute=QUIET)[0]
    for state in STATES:
        assert [w.p for w in again.windows[state].windows] == [w.p for w in first.windows[state].windows]
    other = {k: Ensemble(e.state, e.settings, e.features, e.curves * 1.01, e.peaks, e.speed) for k, e in ensembles.items()}
    with pytest.raises(AssertionError, match="fitted again"):
        assess.assess_sessions([s], ensembles=other, compute=QUIET)


def test_stream_start_counts_the_blocks_before_the_first_recorded_one():
    from wearbench.validation.measurement.session import stream_start

    t, angle, acc = generate("soft", 7100, 3.5)
    keep = slice(600, None)  # the first three 200-sample blocks were not recorded
    frame = pd.DataFrame({"time": t[keep], "acc": acc[keep], "sequence": np.arange(t.size)[keep] // 200})
    s = MeasuredSession("late start", frame, pd.DataFrame({"time": t[::5], "angle": angle[::5]}))
    assert stream_start(s.acceleration, s.fs) == pytest.approx(t[0], abs=1e-9)


def test_separation_matches_a_simulation_of_the_tests_it_bounds():
    """The closed forms of ``separation`` (Neyman-Pearson power, the chi-square test along the
    candidates' directions, the Bayes error) against windows drawn from the Gaussians themselves,
    judged by the likelihood ratio and by ``identify.direction_distance2``."""
    rng = np.random.default_rng(7)
    p = 6
    a = rng.standard_normal((p, p))
    within, between = a @ a.T / p + np.eye(p), 0.2 * np.eye(p)
    means = {"A": np.zeros(p), "B": 0.9 * rng.standard_normal(p), "C": 2.0 * rng.standard_normal(p)}
    st = {k: StateStatistics(m, within, between, np.full(p, 0.01), 32, 8) for k, m in means.items()}
    models = StateModels(tuple(st), st, 1.0, {}, {}, {}, {}, {}, IdentifyOptions())
    got = separation(models, "A", "B", cycles=5, alpha=0.05)
    cov = st["A"].covariance(5)
    d = means["B"] - means["A"]
    assert got["distance"] == pytest.approx(np.sqrt(d @ np.linalg.solve(cov, d)), rel=1e-9)
    under_a = rng.multivariate_normal(means["A"], cov, 40000)
    under_b = rng.multivariate_normal(means["B"], cov, 40000)
    w = np.linalg.solve(cov, d)
    lr_a, lr_b = under_a @ w, under_b @ w
    assert np.mean(lr_b > np.quantile(lr_a, 0.95)) == pytest.approx(got["power"], abs=0.01)
    half = 0.5 * d @ w  # equal priors: the likelihood ratio's midpoint
    assert 0.5 * (np.mean(lr_a > half) + np.mean(lr_b <= half)) == pytest.approx(got["bayes_error"], abs=0.01)
    others = [means["B"], means["C"]]
    t_a = [direction_distance2(st["A"], others, x, 5) for x in under_a[:3000]]
    t_b = [direction_distance2(st["A"], others, x, 5) for x in under_b[:3000]]
    assert np.mean(np.array(t_b) > np.quantile(t_a, 0.95)) == pytest.approx(got["power_direction"], abs=0.03)
    assert got["power_direction"] < got["power"] and 0 < got["bayes_error"] < 0.5


GAUSS_SPEC = FeatureSpec(bins=3, bands=((50.0, 150.0),))  # 6 features
GAUSS_MEANS = {"new": 0.0, "first": 0.9, "second": 1.8, "other": None}  # along one direction; "other" apart


def gaussian_benches(rng, mean: np.ndarray, benches: int, cycles: int) -> np.ndarray:
    """(benches, cycles, p) features: each bench its own offset (between-bench spread), each cycle its
    own scatter (cycle to cycle), as an ensemble's realisations."""
    p = mean.size
    return (mean + 0.3 * rng.standard_normal((benches, 1, p)) + rng.standard_normal((benches, cycles, p)))


@pytest.fixture(scope="module")
def gaussian_states():
    """Four states whose features are Gaussian (independent truth: the generator), three of them on
    one line (wear stages), one off it; their ensembles (80 realisations of 10 cycles) and fitted
    statistics, the sensor path taken as exact."""
    rng = np.random.default_rng(11)
    line, off = np.eye(6)[0], np.eye(6)[3]
    means = {s: (1.2 * off if v is None else v * line) for s, v in GAUSS_MEANS.items()}
    settings = EnsembleSettings(realisations=80, cycles=10, features=GAUSS_SPEC, sensor_paths=None)
    ensembles = {s: Ensemble(s, settings, gaussian_benches(rng, m, 80, 10), np.zeros((80, 10, 36)),
                             np.zeros((80, 10)), OMEGA) for s, m in means.items()}
    options = IdentifyOptions(floor_curve=1e-3, floor_energy=1e-3, sensor_path="none")
    return means, fit_states(ensembles, options, window_cycles=5)


def test_likelihood_ratio_null_is_calibrated_on_fresh_benches(gaussian_states):
    """Fresh benches of each state (drawn from the generator, never in the ensemble), judged by
    ``features_lr`` against the held-out realisation windows' ratios, are called inconsistent at
    alpha within the binomial error of the fresh windows and of the null's size; the windows of the
    next wear stage are caught more often than by the chi-square along the candidates."""
    means, models = gaussian_states
    rng = np.random.default_rng(12)
    alpha = 0.1
    for state in ("new", "first"):
        st, null = models.stats[state], models.window_null[state]
        assert null.shape[1] == 3
        others = [models.stats[t].mean for t in models.states if t != state]
        fresh = gaussian_benches(rng, means[state], 600, 5).mean(axis=1)  # one five-cycle window per bench
        lr = np.array([candidate_ratio(st, others, x, 5) for x in fresh])
        rate = np.mean([(1 + np.sum(null[:, 2] >= v)) / (1 + null.shape[0]) < alpha for v in lr])
        # binomial error of the fresh windows and of the null's: 6 overlapping windows per realisation,
        # counted as 2 independent ones
        sigma = np.sqrt(alpha * (1 - alpha) * (1 / fresh.shape[0] + 1 / (null.shape[0] / 3)))
        assert abs(rate - alpha) <= 3 * sigma, (state, rate, sigma)
    st, null = models.stats["new"], models.window_null["new"]
    others = [models.stats[t].mean for t in models.states if t != "new"]
    worn = gaussian_benches(rng, means["first"], 600, 5).mean(axis=1)
    caught = {j: np.mean([(1 + np.sum(null[:, j] >= f(x))) / (1 + null.shape[0]) < alpha for x in worn])
              for j, f in ((1, lambda x: direction_distance2(st, others, x, 5)),
                           (2, lambda x: candidate_ratio(st, others, x, 5)))}
    assert caught[2] > caught[1] + 0.05, caught


def test_likelihood_ratio_power_matches_the_closed_form_for_collinear_states():
    """Candidates on one line through the judged state: the ratio's rejection region is x > a or
    x < -b along that line (x the window's whitened offset), so its power has a closed form; with
    all candidates on one side it is the Neyman-Pearson test against the truth itself."""
    p = 4
    cov = np.eye(p)
    e = np.eye(p)[0]

    def models_of(positions: dict[str, float]) -> StateModels:
        st = {k: StateStatistics(v * e, 5 * cov, np.zeros((p, p)), np.zeros(p), 10 ** 6, 10 ** 6)
              for k, v in positions.items()}  # covariance of a 5-cycle mean: the identity
        return StateModels(tuple(st), st, 1.0, {}, {}, {}, {}, {}, IdentifyOptions())

    alpha = 0.05
    one_side = separation(models_of({"S": 0.0, "A": 1.5, "B": 3.0}), "S", "A", alpha=alpha)
    assert one_side["power_lr"] == pytest.approx(one_side["power"], abs=1e-4)
    # both sides: new (-c1) and second wear (+c2) about first wear; c1 (-x - c1/2) > t or c2 (x - c2/2) > t
    c1, c2 = 2.1, 2.3
    got = separation(models_of({"S": 0.0, "new": -c1, "second": c2}), "S", "second", alpha=alpha)

    def region(t: float) -> tuple[float, float]:
        return t / c2 + c2 / 2, t / c1 + c1 / 2  # x > a or x < -b

    from scipy import optimize
    from scipy import stats as st
    t = optimize.brentq(lambda t: st.norm.sf(region(t)[0]) + st.norm.cdf(-region(t)[1]) - alpha, -20, 20)
    a, b = region(t)
    power = st.norm.sf(a - c2) + st.norm.cdf(-b - c2)
    assert got["power_lr"] == pytest.approx(power, abs=1e-4)
    assert got["power_direction"] < got["power_lr"] < got["power"]
    # the combination with the all-feature distance spends some of alpha on it: between the two
    assert got["power_direction"] < got["power_lr_all"] < got["power_lr"] + 0.01


@pytest.mark.slow
def test_likelihood_ratio_power_matches_a_simulation_of_the_statistic(gaussian_states):
    """``separation``'s ``power_lr`` (multivariate normal integral) and ``power_lr_all`` (its own
    simulation) against windows drawn from the fitted Gaussians and judged by
    ``identify.candidate_ratio`` and the all-feature distance."""
    _, models = gaussian_states
    rng = np.random.default_rng(13)
    got = separation(models, "new", "first", cycles=5, alpha=0.05)
    st = models.stats["new"]
    cov = st.covariance(5)
    others = [models.stats[t].mean for t in models.states if t != "new"]
    draws = {s: rng.multivariate_normal(models.stats[s].mean, cov, 20000) for s in ("new", "first")}
    lr = {s: np.array([candidate_ratio(st, others, x, 5) for x in d]) for s, d in draws.items()}
    d2 = {s: np.array([st.distance2(x, 5) for x in d]) for s, d in draws.items()}
    assert np.mean(lr["first"] > np.quantile(lr["new"], 0.95)) == pytest.approx(got["power_lr"], abs=0.012)

    def min_p(s):
        return np.minimum(np.mean(lr["new"][None, :] >= lr[s][:, None], axis=1),
                          np.mean(d2["new"][None, :] >= d2[s][:, None], axis=1))

    sub = {s: slice(None, 4000) for s in draws}
    lr = {s: v[sub[s]] for s, v in lr.items()}
    d2 = {s: v[sub[s]] for s, v in d2.items()}
    assert np.mean(min_p("first") < np.quantile(min_p("new"), 0.05)) == pytest.approx(got["power_lr_all"], abs=0.03)
    assert got["power_direction"] < got["power_lr"] <= got["power"] + 1e-9


def test_a_window_away_from_every_candidate_passes_the_ratio_but_not_its_combination(gaussian_states):
    """The ratio is one-sided: a bench far from the state but toward no candidate (beyond new wear,
    away from the worn stages and the other state) is consistent by ``features_lr`` and caught by
    ``features_lr_all`` (the all-feature distance in it), each against its held-out null."""
    from wearbench.validation.comparison.windows import _min_p

    _, models = gaussian_states
    rng = np.random.default_rng(14)
    st, null = models.stats["new"], models.window_null["new"]
    others = [models.stats[t].mean for t in models.states if t != "new"]
    away = gaussian_benches(rng, -2.5 * np.eye(6)[0] - 2.5 * np.eye(6)[3], 200, 5).mean(axis=1)
    combined = _min_p(null[:, [0, 2]])

    def p(col: int, v: float) -> float:
        return (1 + np.sum(null[:, col] >= v)) / (1 + null.shape[0])

    p_lr = np.array([p(2, candidate_ratio(st, others, x, 5)) for x in away])
    p_all = np.array([p(0, st.distance2(x, 5)) for x in away])
    p_comb = np.array([(1 + np.sum(combined <= min(a, b))) / (1 + combined.size) for a, b in zip(p_lr, p_all)])
    assert np.mean(p_lr < 0.05) < 0.05 and np.mean(p_comb < 0.05) > 0.9, (np.mean(p_lr < 0.05), np.mean(p_comb < 0.05))
