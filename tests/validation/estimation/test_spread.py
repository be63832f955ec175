"""The spread between wear realisations, on synthetic design ensembles whose truth is known.

Each wear realisation (the design's reference run, the spread's runs, every truth's own wear) moves
the features' mean by its own offset, drawn with covariance ``S(N)`` growing with cycles run. The
spread measured from paired runs must recover ``2 S`` (a run against the reference, itself a
realisation), and truths worn as themselves must lie in their cycles-run intervals at the stated
rate with the spread, where without it they do not.
"""

import numpy as np
import pytest
from wearbench.validation.estimation.estimate import (
    Estimator,
    estimate_features,
    fit_estimator,
    load_estimator,
    save_estimator,
    save_estimator_spread,
)
from wearbench.validation.estimation.spread import (
    SpreadDesign,
    WearSpread,
    measure_spread,
    spread_key,
    spread_path,
)
from wearbench.validation.measurement.features import CycleFeatures

from tests.validation.estimation.test_estimate import DESIGN, OPTIONS, SB, SPEC, SW, P, true_mean

pytestmark = pytest.mark.no_kernels

RUN_SD = 0.2  # sd per feature of a wear realisation's offset after the design's last cycles run
NC, NN, M, C = len(DESIGN.clearances), len(DESIGN.cycles), 16, 8


def offset(rng: np.random.Generator, n: float) -> np.ndarray:
    """One wear realisation's offset of the features' mean after ``n`` cycles: variance linear in n."""
    return rng.normal(0.0, RUN_SD * np.sqrt(n / DESIGN.cycles[-1]), P)


def seeds(rng: np.random.Generator) -> np.ndarray:
    """The design's realisations at one point, less its mean: bench offsets and cycle noise (M, C, P)."""
    return rng.normal(0.0, np.sqrt(SB), (M, 1, P)) + rng.normal(0.0, np.sqrt(SW), (M, C, P))


def synthetic(runs: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Reference features (NC, NN, M, C, P), spread runs' (runs, NC, NN - 1, R, C, P) with R = 8
    paired seeds, and the offsets of each (reference first; (1 + runs, NC, NN, P))."""
    noise = np.stack([np.stack([seeds(rng) for _ in DESIGN.cycles]) for _ in DESIGN.clearances])
    offsets = np.stack([[[offset(rng, n) for n in DESIGN.cycles] for _ in DESIGN.clearances]
                        for _ in range(1 + runs)])
    means = np.array([[true_mean(c, n) for n in DESIGN.cycles] for c in DESIGN.clearances])
    ref = means[:, :, None, None] + offsets[0][:, :, None, None] + noise
    spread = np.stack([means[:, 1:, None, None] + offsets[k][:, 1:, None, None] + noise[:, 1:, :8]
                       for k in range(1, 1 + runs)])
    return ref, spread, offsets


def test_the_spread_measured_from_paired_runs_is_twice_a_realisations_covariance():
    """Against the reference (itself a realisation), a run's mean differs by two realisations'
    offsets: the measured covariance's diagonal is 2 RUN_SD^2 N/N_max, 0 unworn; with no offsets
    the paired seeds leave nothing, and unpaired noise little: clipping the negative eigenvalues of a
    moment that is noise alone leaves a floor under a quarter of the paired means' error."""
    rng = np.random.default_rng(11)
    ref, runs, _ = synthetic(24, rng)
    cov = measure_spread(ref, runs)
    assert cov.shape == (NN, P, P) and np.all(cov[0] == 0)
    for j, n in enumerate(DESIGN.cycles[1:], 1):
        expected = 2 * RUN_SD ** 2 * n / DESIGN.cycles[-1]
        assert np.mean(np.diagonal(cov[j])) == pytest.approx(expected, rel=0.15)
    same = np.broadcast_to(ref[None, :, 1:, :8], runs.shape)  # no run differs from the reference
    assert np.max(np.abs(measure_spread(ref, same))) == 0.0
    other_seeds = same + np.random.default_rng(12).normal(0.0, np.sqrt(SW), same.shape)  # unpaired noise only
    assert np.mean(np.diagonal(measure_spread(ref, other_seeds)[-1])) < 0.25 * SW / (8 * C)


def _estimator(ref, runs, depth_runs=None) -> Estimator:
    depth = np.outer(np.ones(NC), np.array(DESIGN.cycles) * 2e-11)
    est = Estimator("synthetic", "k", DESIGN, ref, depth, 2 * np.pi)
    if runs is None:
        return est
    design = SpreadDesign(runs.shape[0], runs.shape[3])
    spread = WearSpread(est.key, spread_key(est.key, design), design, DESIGN.cycles, measure_spread(ref, runs),
                        depth[None].repeat(design.runs, 0) if depth_runs is None else depth_runs)
    return Estimator("synthetic", "k", DESIGN, ref, depth, 2 * np.pi, spread=spread)


@pytest.mark.slow
def test_truths_that_wore_as_themselves_lie_in_their_cycles_run_intervals_only_with_the_spread():
    """Five designs (each reference run's offset is shared by every truth it judges, so coverage is
    counted over several), 12 truths each, each worn as itself: the 90 % cycles-run intervals hold
    the truth at the stated rate with the spread (measured 54 of 60), less often without (43 of 60)."""
    hits, widths = {"alone": 0, "spread": 0}, {"alone": [], "spread": []}
    for design in range(5):
        rng = np.random.default_rng(100 + design)
        ref, runs, _ = synthetic(3, rng)
        models = {"alone": fit_estimator(_estimator(ref, None), OPTIONS),
                  "spread": fit_estimator(_estimator(ref, runs), OPTIONS)}
        for _ in range(12):
            c, n = rng.uniform(0.25e-3, 0.65e-3), rng.uniform(0.0, 6e5)
            x = (true_mean(c, n) + offset(rng, n) + rng.normal(0.0, np.sqrt(SB), P)
                 + rng.normal(0.0, np.sqrt(SW), (20, P)))
            for name, model in models.items():
                e = estimate_features(CycleFeatures(SPEC, x, np.zeros(20)), model)
                hits[name] += e.cycles_run.contains(n)
                widths[name].append(e.cycles_run.hi90 - e.cycles_run.lo90)
    # binomial(60, 0.9): 48..60 holds 99.7 %
    assert hits["spread"] >= 48, hits
    assert hits["alone"] <= hits["spread"] - 6, hits
    assert np.median(widths["spread"]) > 1.2 * np.median(widths["alone"])


def test_the_depth_interval_draws_on_every_wear_runs_depth():
    rng = np.random.default_rng(14)
    ref, runs, _ = synthetic(2, rng)
    base = np.outer(np.ones(NC), np.array(DESIGN.cycles) * 2e-11)
    est = _estimator(ref, runs, np.stack([0.6 * base, 1.4 * base]))
    x = true_mean(0.45e-3, 4e5) + rng.normal(0.0, np.sqrt(SW), (20, P))
    one = estimate_features(CycleFeatures(SPEC, x, np.zeros(20)), fit_estimator(_estimator(ref, runs), OPTIONS))
    three = estimate_features(CycleFeatures(SPEC, x, np.zeros(20)), fit_estimator(est, OPTIONS))
    assert three.cycles_run == one.cycles_run  # the runs' depths move the depth alone
    assert three.depth.lo90 < 0.8 * one.depth.lo90 and three.depth.hi90 > 1.2 * one.depth.hi90


def test_a_spread_is_kept_beside_its_estimator_and_ignored_beside_another(tmp_path):
    rng = np.random.default_rng(15)
    ref, runs, _ = synthetic(2, rng)
    est = _estimator(ref, runs)
    save_estimator(est, tmp_path / "e.npz")
    save_estimator_spread(est, spread_path(tmp_path / "e.npz"))
    back = load_estimator(tmp_path / "e.npz")
    assert back.spread.key == est.spread.key and np.array_equal(back.spread.covariance, est.spread.covariance)
    assert np.array_equal(back.spread.depth, est.spread.depth) and back.spread.design == SpreadDesign(2, 8)
    other = Estimator("synthetic", "another key", DESIGN, ref, est.depth, 2 * np.pi)
    save_estimator(other, tmp_path / "e.npz")
    assert load_estimator(tmp_path / "e.npz").spread is None  # the sidecar is the other estimator's: stale


def test_a_spread_design_is_checked():
    with pytest.raises(ValueError, match="--wear-runs -1"):
        SpreadDesign(-1)
    with pytest.raises(ValueError, match="at least 3"):
        SpreadDesign(2, 2)
    assert SpreadDesign(0, 0).runs == 0


def test_a_spread_the_design_cannot_pair_is_refused_before_anything_is_simulated(monkeypatch):
    from wearbench.bench.load import load_bench, shipped_bench
    from wearbench.compute.options import Compute
    from wearbench.validation.estimation.estimate import EstimatorDesign, build_estimator
    from wearbench.validation.inference.ensemble import EnsembleSettings

    monkeypatch.setattr(Compute, "run", lambda *a, **k: pytest.fail("a batch of simulations was started"))
    bench = load_bench(shipped_bench("fourbar"))
    design = EstimatorDesign((0.3e-3, 0.6e-3), (0.0, 200_000.0), EnsembleSettings(realisations=6, cycles=4))
    with pytest.raises(ValueError, match="--wear-runs 2: the spread pairs 12 realisations"):
        build_estimator(bench, design, spread=SpreadDesign(2), shipped=False)


def test_a_damaged_spread_beside_an_estimator_is_named_and_the_files_are_left_as_they_were(tmp_path):
    """A cut sidecar, or another artefact under its name, is refused in one line naming the file; the
    estimator and the sidecar stay byte for byte."""
    from wearbench.validation.inference.artefacts import ArtefactError

    rng = np.random.default_rng(16)
    ref, runs, _ = synthetic(2, rng)
    est = _estimator(ref, runs)
    path, beside = tmp_path / "e.npz", spread_path(tmp_path / "e.npz")
    save_estimator(est, path)
    save_estimator_spread(est, beside)
    beside.write_bytes(beside.read_bytes()[:500])  # cut while copied
    kept = path.read_bytes(), beside.read_bytes()
    with pytest.raises(ArtefactError, match=f"{beside}"):
        load_estimator(path)
    assert (path.read_bytes(), beside.read_bytes()) == kept
    save_estimator(est, beside)  # an estimator where the spread belongs
    with pytest.raises(ArtefactError, match=rf"{beside} is an estimator, not a wear spread"):
        load_estimator(path)
    assert path.read_bytes() == kept[0]
