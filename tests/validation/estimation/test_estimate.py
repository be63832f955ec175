"""Clearance and wear estimates on synthetic design ensembles whose truth is known.

The features follow the hierarchical model of ``statistics.py`` with a mean that is a smooth
function of (clearance, cycles run); truths are drawn uniformly over the design box, each with its
own bench offset and cycles (never the design's draws). Their 90 % and 50 % intervals must hold
them at about those rates, a bench far outside the box must get "no parameter value explains it",
and the posterior at the candidate states must rank them as ``identify`` does.
"""

import numpy as np
import pytest
from scipy import stats
from wearbench.validation.estimation.estimate import (
    NO_VALUE,
    Estimator,
    EstimatorDesign,
    estimate_features,
    fit_estimator,
    load_estimator,
    save_estimator,
)
from wearbench.validation.inference.ensemble import Ensemble, EnsembleSettings
from wearbench.validation.inference.identify import IdentifyOptions, fit_states, identify_features
from wearbench.validation.measurement.features import CycleFeatures, FeatureSpec

pytestmark = pytest.mark.no_kernels

SPEC = FeatureSpec()
P = SPEC.size
SB, SW = 0.02, 0.2
DESIGN = EstimatorDesign((0.25e-3, 0.35e-3, 0.45e-3, 0.55e-3, 0.65e-3), (0.0, 2e5, 4e5, 6e5),
                         EnsembleSettings(realisations=16, cycles=8))
SHAPES = np.random.default_rng(42).normal(0.0, 0.25, (4, P))  # how the features move with c and N
OPTIONS = IdentifyOptions(floor_curve=1e-6, floor_energy=1e-6)


def true_mean(c: float, n: float) -> np.ndarray:
    u = 2 * (c - 0.25e-3) / 0.4e-3 - 1
    v = 2 * n / 6e5 - 1
    return u * SHAPES[0] + v * SHAPES[1] + 0.5 * u * v * SHAPES[2] + 0.3 * u * u * SHAPES[3]


def draw(rng, mean, realisations, cycles):
    return (mean + rng.normal(0.0, np.sqrt(SB), (realisations, 1, P))
            + rng.normal(0.0, np.sqrt(SW), (realisations, cycles, P)))


def session(rng, c, n, cycles=20):
    return CycleFeatures(SPEC, draw(rng, true_mean(c, n), 1, cycles)[0], np.zeros(cycles))


@pytest.fixture(scope="module")
def model():
    rng = np.random.default_rng(0)
    feats = np.stack([np.stack([draw(rng, true_mean(c, n), 16, 8) for n in DESIGN.cycles])
                      for c in DESIGN.clearances])
    depth = np.outer(np.ones(5), np.array(DESIGN.cycles) * 2e-11)  # 4 um per 200k cycles
    est = Estimator("synthetic", "k", DESIGN, feats, depth, 2 * np.pi)
    return fit_estimator(est, OPTIONS)


def test_truths_drawn_from_the_prior_lie_in_their_intervals_at_the_stated_rates(model):
    rng = np.random.default_rng(1)
    hits = {(p, lvl): 0 for p in ("c", "n") for lvl in (50, 90)}
    truths = 40
    for _ in range(truths):
        c, n = rng.uniform(0.25e-3, 0.65e-3), rng.uniform(0.0, 6e5)
        e = estimate_features(session(rng, c, n), model)
        assert e.explains
        for lvl in (50, 90):
            hits["c", lvl] += e.clearance.contains(c, lvl)
            hits["n", lvl] += e.cycles_run.contains(n, lvl)
    # binomial(40, 0.9): 31..40 holds 99.5 %; binomial(40, 0.5): 12..28 holds 99.4 %
    for p in ("c", "n"):
        assert 31 <= hits[p, 90] <= truths, hits
        assert 12 <= hits[p, 50] <= 28, hits


def test_a_bench_outside_the_prior_is_explained_by_no_parameter_value(model):
    rng = np.random.default_rng(2)
    far = CycleFeatures(SPEC, draw(rng, true_mean(1.2e-3, 3e5), 1, 20)[0], np.zeros(20))
    e = estimate_features(far, model)
    assert not e.explains and e.verdict == NO_VALUE and e.p_value < 1e-3
    inside = estimate_features(session(rng, 0.4e-3, 3e5), model)
    assert inside.explains and inside.p_value > 0.01


def test_intervals_narrow_with_cycles_and_the_depth_follows_the_wear(model):
    rng = np.random.default_rng(3)
    x = draw(rng, true_mean(0.45e-3, 2e5), 1, 40)[0]
    short = estimate_features(CycleFeatures(SPEC, x[:5], np.zeros(5)), model)
    long = estimate_features(CycleFeatures(SPEC, x, np.zeros(40)), model)
    w = lambda i: i.hi90 - i.lo90
    assert w(long.clearance) < w(short.clearance) and w(long.cycles_run) < w(short.cycles_run)
    assert long.depth.median == pytest.approx(long.cycles_run.median * 2e-11, rel=0.05)


def test_identify_and_estimate_rank_the_candidate_states_alike(model):
    """Candidates: three design points. identify (their ensembles) and the estimate's posterior at
    those points order them alike in nearly every session (sessions between and at the points)."""
    est = model.estimator
    points = {(0, 0): "a", (2, 1): "b", (2, 2): "c"}
    ens = {nm: Ensemble(nm, DESIGN.settings, est.features[i, j], np.zeros((1, 1, 1)), np.zeros((1, 1)), 2 * np.pi)
           for (i, j), nm in points.items()}
    ident = fit_states(ens, OPTIONS)
    rng = np.random.default_rng(4)
    agree = total = 0
    for c, n in [(0.25e-3, 0), (0.45e-3, 2e5), (0.45e-3, 4e5), (0.45e-3, 3e5), (0.35e-3, 1e5)] * 4:
        s = session(rng, c, n)
        r = identify_features(s, ident)
        xbar = s.values.mean(axis=0)
        ll = {nm: model.log_likelihood(xbar, 20, DESIGN.clearances[i], DESIGN.cycles[j])
              for (i, j), nm in points.items()}
        agree += sorted(ll, key=ll.get) == sorted(r.posterior, key=r.posterior.get)
        total += 1
    assert agree >= 0.9 * total, (agree, total)


def test_save_and_load_keep_the_estimator(model, tmp_path):
    est = model.estimator
    path = save_estimator(est, tmp_path / "e.npz")
    back = load_estimator(path, key="k")
    assert back.design == est.design and np.array_equal(back.features, est.features)
    assert load_estimator(path, key="other") is None


def test_design_must_be_a_grid_of_stages():
    with pytest.raises(ValueError, match="equally spaced from 0"):
        EstimatorDesign((0.3e-3, 0.4e-3), (1e5, 2e5))
    with pytest.raises(ValueError, match="increasing"):
        EstimatorDesign((0.4e-3, 0.3e-3), (0.0, 1e5))


def test_interval_of_a_known_distribution():
    from wearbench.validation.estimation.estimate import Interval

    x = np.linspace(-6, 6, 2001)
    i = Interval.from_weights(x, stats.norm.pdf(x))
    assert i.median == pytest.approx(0, abs=1e-3) and i.hi90 == pytest.approx(1.645, abs=0.01)
    assert i.lo50 == pytest.approx(-0.674, abs=0.01)


def test_joint_posterior_figure_and_json(model, tmp_path):
    import json

    from wearbench.reports.estimate import posterior_figure

    e = estimate_features(session(np.random.default_rng(5), 0.4e-3, 2e5), model)
    path = posterior_figure(e, tmp_path / "p.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    d = json.loads(json.dumps(e.to_dict()))
    assert d["clearance"]["lo90"] <= d["clearance"]["median"] <= d["clearance"]["hi90"] and "posterior" not in d


@pytest.mark.slow
def test_track_recovers_a_wear_coefficient_1_3_times_the_files(model, tmp_path):
    """Lives of one bench each (clearance 0.4 mm, true coefficient 1.3x the file's; the five sessions
    share the bench's offset from the file, as a real bench's do) recorded at 0, 100k, ... 400k
    cycles: the 90 % intervals of the factor and of the initial clearance hold the truth in most
    lives, and so do those of the cycles until a 0.45 mm limit (depth 4 um per 200k cycles of the
    file's rate here: the truth reaches 50 um of growth after 50e-6 / (2e-11 x 1.3) = 1.92M cycles)."""
    from wearbench.reports.track import track_figure
    from wearbench.validation.estimation.track import track_features

    rng = np.random.default_rng(6)
    runs = [0.0, 1e5, 2e5, 3e5, 4e5]
    truth_limit = (0.45e-3 - 0.4e-3) / (2e-11 * 1.3)
    hits = limits = clearances = 0
    lives = 10
    for _ in range(lives):
        bench_offset = rng.normal(0.0, np.sqrt(SB), P)
        feats = [CycleFeatures(SPEC, true_mean(0.4e-3, 1.3 * n) + bench_offset + rng.normal(0.0, np.sqrt(SW), (20, P)),
                               np.zeros(20)) for n in runs]
        t = track_features(feats, runs, model, coefficient=5.2e-14, limit=0.45e-3)
        hits += t.factor.contains(1.3, 90)
        limits += t.cycles_to_limit is not None and t.cycles_to_limit.contains(truth_limit, 90)
        clearances += t.clearance.contains(0.4e-3, 90)
        assert t.coefficient.median == pytest.approx(t.factor.median * 5.2e-14)
    assert hits >= 8 and limits >= 8 and clearances >= 8, (hits, limits, clearances)
    assert track_figure(t, tmp_path / "life.png").read_bytes()[:4] == b"\x89PNG"
    assert t.prediction[0][1].median == 0.0 and t.prediction[-1][0] > 4e5
    with pytest.raises(ValueError, match="one value per session"):
        track_features(feats, runs[:3], model, coefficient=5.2e-14)


def test_the_predictive_band_holds_a_true_benchs_cycles_at_its_rate(model, tmp_path):
    """The 90 % posterior predictive band of one cycle: about 90 % of a bench's measured cycle
    features inside it when the bench follows the model; its width by sampling is the analytic
    2 x 1.645 sd of one cycle under the model (between-bench, cycle-to-cycle, sensor path, emulator
    error), widened only by the posterior's own spread; far fewer inside for a bench the model
    cannot produce; the figure puts the cycles over the band."""
    from wearbench.reports.estimate import predictive_figure

    rng = np.random.default_rng(8)
    inside, widths = [], []
    for c, n in [(0.3e-3, 1e5), (0.4e-3, 3e5), (0.5e-3, 5e5), (0.6e-3, 2e5)] * 3:
        e = estimate_features(session(rng, c, n), model)
        inside.append(e.inside)
        widths.append(np.median((e.band[2] - e.band[0]) / (2 * 1.645 * np.sqrt(np.diag(model.covariance(1.0))))))
    assert 0.85 <= np.mean(inside) <= 0.95, inside
    assert 0.97 <= np.median(widths) <= 1.08, widths
    s = session(rng, 0.45e-3, 3e5)
    far = estimate_features(CycleFeatures(SPEC, s.values + 4.0 * np.sqrt(SB + SW), s.clipped), model)
    assert far.inside < 0.3 and not far.explains
    path = predictive_figure(e, tmp_path / "band.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert e.line().startswith(f"{e.clearance.median * 1e3:.3f} mm [") and far.line() == NO_VALUE


def test_the_joint_likelihood_of_a_benchs_sessions_is_their_stacked_gaussian(model):
    """Woodbury's quadratic form equals the dense one of the stacked session means (shared bench and
    sensor path, each session's own cycle-to-cycle and estimator error); with one session it is the
    estimator's own distance."""
    from scipy import linalg
    from wearbench.validation.estimation.track import joint_log_likelihood

    rng = np.random.default_rng(11)
    st = model.stats[model.reference]
    ns = [20, 10, 5]
    xbars = np.stack([session(rng, 0.4e-3, n).values.mean(axis=0) for n in (1e5, 2e5, 3e5)])
    means = np.stack([np.stack([model.mean(c, n) for n in (1e5, 2e5, 3e5)]) for c in (0.3e-3, 0.4e-3, 0.5e-3)])
    shared = st.between + st.nuisance @ st.nuisance.T
    own = model.covariance(np.inf) - shared  # design mean, floor, emulator error
    dense = np.kron(np.ones((3, 3)), shared) + linalg.block_diag(*[st.within / n + own for n in ns])
    for g in range(3):
        r = (xbars - means[g]).ravel()
        assert -0.5 * r @ np.linalg.solve(dense, r) == pytest.approx(
            joint_log_likelihood(model, xbars, ns, means[g]), rel=1e-8)
    one = joint_log_likelihood(model, xbars[:1], [20], model.grid_mean[:, :, None, :])
    assert np.allclose(-2 * one, model.distances(xbars[0], 20), rtol=1e-8)



def test_the_edge_note_fires_when_a_tenth_of_the_factor_lies_at_the_grids_edge(model):
    """Sessions at 0 and 100k cycles (no factor in 0.2-5 leaves the design's 600k: nothing caps the
    grid) of a bench worn 4.45x and 4.6x the file's rate, its cycle features exactly the model's mean:
    the posterior mass of the factor in the outer three grid cells at either end, computed here from
    the dense stacked Gaussian, decides the note (> 0.1). At 4.45x it is 0.05-0.1: counted twice,
    the note would fire."""
    from scipy import linalg, special
    from wearbench.validation.estimation.track import K_RANGE, track_features

    runs, n = [0.0, 1e5], 20
    ks = np.geomspace(*K_RANGE, 161)
    st = model.stats[model.reference]
    shared = st.between + st.nuisance @ st.nuisance.T
    own = model.covariance(np.inf) - shared + st.within / n
    chol = linalg.cho_factor(np.kron(np.ones((2, 2)), shared) + linalg.block_diag(own, own))

    def edge_mass(xbars):
        means = np.stack([model.mean(np.full((ks.size, 2), c), ks[:, None] * np.array(runs)) for c in model.grid_c])
        r = (xbars - means).reshape(-1, 2 * P)  # (c x k, stacked sessions)
        logp = (-0.5 * np.sum(r * linalg.cho_solve(chol, r.T).T, axis=1) / model.temperature).reshape(-1, ks.size)
        marginal = np.exp(special.logsumexp(logp, axis=0) - special.logsumexp(logp))
        return marginal[:3].sum() + marginal[-3:].sum()

    for factor, fires in ((4.45, False), (4.6, True)):
        xbars = np.stack([model.mean(0.4e-3, factor * n) for n in runs])
        mass = edge_mass(xbars)
        assert (0.05 < mass < 0.1) if not fires else mass > 0.1, (factor, mass)
        feats = [CycleFeatures(SPEC, np.repeat(x[None], n, axis=0), np.zeros(n)) for x in xbars]
        t = track_features(feats, runs, model, coefficient=5.2e-14, drift=False, rate_spread=0.0)  # the dense form
        assert any("reaches the edge" in note for note in t.notes) == fires, (factor, mass, t.notes)


@pytest.mark.slow
def test_the_wear_drift_is_measured_from_the_designs_shared_benches_and_enters_the_stacked_gaussian():
    """A design whose realisations keep their bench at every design point (as the real design's seeds
    do) and whose offset moves by a drawn d (sd 0.1, 0.2 in two halves of the features) from new to
    worn: wear_drift recovers that variance, and not the cycle-to-cycle noise; with the drift, the
    sessions' likelihood equals the dense stacked Gaussian's log density, determinant included."""
    from scipy import linalg
    from wearbench.validation.estimation.track import joint_log_likelihood, wear_drift

    rng = np.random.default_rng(12)
    m = 40
    sd = np.where(np.arange(P) < P // 2, 0.1, 0.2)
    bench, moved = rng.normal(0.0, np.sqrt(SB), (m, P)), rng.normal(0.0, sd, (m, P))
    feats = np.stack([np.stack([true_mean(c, n) + bench[:, None] + (n > 0) * moved[:, None]
                                + rng.normal(0.0, np.sqrt(SW), (m, 8, P)) for n in DESIGN.cycles])
                      for c in DESIGN.clearances])
    depth = np.outer(np.ones(5), np.array(DESIGN.cycles) * 2e-11)
    fitted = fit_estimator(Estimator("synthetic", "k", DESIGN, feats, depth, 2 * np.pi), OPTIONS)
    drift = wear_drift(fitted)
    got = np.sqrt(np.diag(drift))
    assert np.median(got[: P // 2]) == pytest.approx(0.1, rel=0.15) and np.median(got[P // 2:]) == pytest.approx(0.2, rel=0.15)

    st = fitted.stats[fitted.reference]
    ns, worn = [20, 10, 5], np.array([0.0, 0.5, 1.0])
    xbars = np.stack([session(rng, 0.4e-3, n).values.mean(axis=0) for n in (0.0, 1e5, 2e5)])
    means = np.stack([np.stack([fitted.mean(c, n) for n in (0.0, 1e5, 2e5)]) for c in (0.3e-3, 0.4e-3)])
    shared = st.between + st.nuisance @ st.nuisance.T
    own = fitted.covariance(np.inf) - shared
    dense = (np.kron(np.ones((3, 3)), shared) + np.kron(np.outer(worn, worn), drift)
             + linalg.block_diag(*[st.within / n + own for n in ns]))
    for g in range(2):
        r = (xbars - means[g]).ravel()
        expected = -0.5 * (r @ np.linalg.solve(dense, r) + np.linalg.slogdet(dense)[1])
        got = joint_log_likelihood(fitted, xbars, ns, means[g], worn, drift)
        assert got == pytest.approx(expected, rel=1e-8)


def test_a_short_session_is_said_to_be_short(model):
    """A session of fewer complete cycles than a window gets its intervals with a note that says so
    (a 1.65-cycle session got full intervals and no word)."""
    rng = np.random.default_rng(8)
    short = estimate_features(session(rng, 0.4e-3, 2e5, cycles=2), model, label="short")
    assert any("only 2 complete crank cycles" in n for n in short.notes)
    assert not any("complete crank cycle" in n for n in estimate_features(session(rng, 0.4e-3, 2e5), model).notes)
