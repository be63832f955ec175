"""Intervals that respect the range's edge (issue 45): where the posterior piles at an end of the
range a parameter can take, the 90 % interval is one-sided from that end (the highest-density one
reaches it) and says so; where the mass is interior it stays central.

Distributions whose highest-density interval is known analytically first (an exponential and a
half-normal: [0, q90]; a symmetric one: the 5 / 95 % quantiles), then the estimator on synthetic
design ensembles (``test_estimate.py``'s model): a new bench (0 cycles run) is told "at most ..."
and its interval holds 0; a bench in mid-life keeps its central interval."""

import json

import numpy as np
import pytest
from scipy import stats
from wearbench.validation.estimation.estimate import Interval, estimate_features
from wearbench.validation.measurement.features import CycleFeatures

from .test_estimate import SPEC, model, session  # noqa: F401 (model: the module's fixture)

pytestmark = pytest.mark.no_kernels

X = np.linspace(0.0, 6.0, 3001)


@pytest.mark.parametrize("dist", [stats.expon(scale=0.8), stats.halfnorm(scale=1.0)])
def test_a_posterior_piled_at_the_lower_edge_gets_its_analytic_highest_density_interval(dist):
    """Densities decreasing from 0: the shortest 90 % interval is [0, q90], "at most q90"; the
    one-sided 50 % interval [0, median]; the central one (without edges) misses 0."""
    ppf = lambda p: dist.ppf(p * dist.cdf(6.0))  # the distribution cut at the grid's end, 6
    i = Interval.from_weights(X, dist.pdf(X), edges=True)
    assert i.kind == "upper bound" and i.lo90 == 0.0 and i.lo50 == 0.0
    assert i.hi90 == pytest.approx(ppf(0.9), abs=0.003)
    assert i.median == pytest.approx(ppf(0.5), abs=0.003) and i.hi50 == i.median
    assert i.contains(0.0) and i.text(lambda v: f"{v:.1f}") == f"at most {ppf(0.9):.1f}"
    central = Interval.from_weights(X, dist.pdf(X))
    assert central.kind == "central" and not central.contains(0.0)
    assert central.lo90 == pytest.approx(ppf(0.05), abs=0.003)
    assert i.hi90 - i.lo90 < central.hi90 - central.lo90


def test_the_mirror_image_gets_a_lower_bound():
    i = Interval.from_weights(X, stats.halfnorm.pdf(6.0 - X), edges=True)
    assert i.kind == "lower bound" and i.hi90 == 6.0 and i.lo90 == pytest.approx(6.0 - stats.halfnorm.ppf(0.9), abs=0.005)
    assert i.text(lambda v: f"{v:.2f}") == f"at least {6.0 - stats.halfnorm.ppf(0.9):.2f}"


def test_a_symmetric_posterior_stays_central_with_its_5_and_95_percent_points():
    i = Interval.from_weights(X, stats.norm.pdf(X, 3.0, 0.7), edges=True)
    assert i.kind == "central" and i == Interval.from_weights(X, stats.norm.pdf(X, 3.0, 0.7))
    assert (i.lo90, i.hi90) == pytest.approx((3.0 - 1.645 * 0.7, 3.0 + 1.645 * 0.7), abs=0.005)
    assert (i.lo50, i.hi50) == pytest.approx((3.0 - 0.674 * 0.7, 3.0 + 0.674 * 0.7), abs=0.005)
    assert i.text(lambda v: f"{v:.2f}") == f"{i.lo90:.2f}-{i.hi90:.2f}"


@pytest.mark.parametrize(("mean", "kind"), [(0.5, "upper bound"), (3.0, "central"), (4.0, "central"),
                                            (5.5, "lower bound")])
def test_the_highest_density_interval_decides_where_the_mode_is_near_an_edge(mean, kind):
    """A normal of sd 1 cut to [0, 6]: 0.5 sd from an end the shortest 90 % interval reaches the end
    (it needs +/- 0.88 sd about the mode); 2 sd and more from both ends the central one is kept."""
    w = stats.norm.pdf(X, mean, 1.0)
    i, central = Interval.from_weights(X, w, edges=True), Interval.from_weights(X, w)
    assert i.kind == kind
    if kind == "central":
        assert i == central
    else:
        assert i.hi90 - i.lo90 < central.hi90 - central.lo90


def test_a_flat_posterior_keeps_its_central_interval():
    assert Interval.from_weights(X, np.ones_like(X), edges=True).kind == "central"


def test_an_end_of_zero_weight_is_no_edge_the_posterior_reaches():
    """Cells of zero weight beyond the support are cut first: the one-sided bound is the support's
    end, not the grid's."""
    w = np.where(X <= 3.0, stats.norm.pdf(X, 3.0, 0.5), 0.0)
    i = Interval.from_weights(X, w, edges=True)
    assert i.kind == "lower bound" and i.hi90 == pytest.approx(3.0, abs=0.003)


def test_map_and_kind_are_kept_and_checked():
    i = Interval.from_weights(X, stats.expon.pdf(X), edges=True).map(lambda v: 2 * v)
    q90 = stats.expon.ppf(0.9 * stats.expon.cdf(6.0))  # the exponential cut at the grid's end, 6
    assert i.kind == "upper bound" and i.hi90 == pytest.approx(2 * q90, abs=0.01)
    with pytest.raises(ValueError, match="interval kind 'both'"):
        Interval(1.0, 0.0, 2.0, 0.0, 3.0, "both")


def test_a_new_bench_is_told_at_most_and_its_interval_holds_0(model):  # noqa: F811
    """A new bench (0 cycles run) whose cycles are the model's own mean: its posterior piles at 0, so the
    cycles-run and wear-depth 90 % intervals are upper bounds from 0 ("at most ..."), and hold 0; the
    verdict, the one-line summary, the JSON, the table row and the notes say so."""
    x = np.repeat(model.mean(0.4e-3, 0.0)[None], 20, axis=0)
    e = estimate_features(CycleFeatures(SPEC, x, np.zeros(20)), model)
    n, d = e.cycles_run, e.depth
    assert e.explains and n.kind == "upper bound" and n.lo90 == 0.0 and n.contains(0.0), n
    assert d.kind == "upper bound" and d.lo90 == 0.0 and d.contains(0.0), d
    assert f"cycles [at most {n.hi90 / 1e3:.0f}k]" in e.line() and "cycles run (90 % at most " in e.verdict
    assert any(note.startswith("one-sided 90 % intervals where the posterior piles") for note in e.notes), e.notes
    data = json.loads(json.dumps(e.to_dict()))
    assert data["cycles_run"]["kind"] == "upper bound" and data["clearance"]["kind"] == e.clearance.kind
    assert e.row()["cycles_run_interval"] == "upper bound" and e.row()["wear_depth_m_interval"] == "upper bound"
    central = Interval.from_weights(model.grid_n, e.posterior.sum(axis=0))
    assert n.hi90 < central.hi90  # [0, q90] against [q5, q95]


def test_new_benches_drawn_from_the_tolerances_hold_0_at_the_stated_rate(model):  # noqa: F811
    """40 sessions of new benches (own bench offset and cycles): the cycles-run interval holds 0 at
    about its 90 % (binomial(40, 0.9) >= 31 with probability 0.995), every one-sided one does, and the
    central intervals of the same posteriors hold it far less often."""
    rng = np.random.default_rng(21)
    held = central = 0
    for _ in range(40):
        e = estimate_features(session(rng, rng.uniform(0.27e-3, 0.63e-3), 0.0), model)
        held += e.cycles_run.contains(0.0)
        assert e.cycles_run.kind == "central" or e.cycles_run.contains(0.0)
        central += Interval.from_weights(model.grid_n, e.posterior.sum(axis=0)).contains(0.0)
    assert held >= 31 and central < held - 5, (held, central)


def test_a_bench_in_mid_life_keeps_its_central_interval(model):  # noqa: F811
    rng = np.random.default_rng(22)
    for c, n in ((0.35e-3, 2.5e5), (0.45e-3, 3e5), (0.55e-3, 3.5e5)):
        e = estimate_features(session(rng, c, n), model)
        assert e.cycles_run.kind == "central" and e.clearance.kind == "central", (c, n, e.cycles_run)
        assert e.cycles_run.lo90 > 0 and not any(note.startswith("one-sided") for note in e.notes)


def test_the_printout_and_the_figure_say_one_sided(model, tmp_path, capsys, monkeypatch):  # noqa: F811
    """`wearbench estimate` prints "at most" with the interval's kind; the posterior figure is written."""
    from wearbench.cli import main
    from wearbench.reports.estimate import posterior_figure
    from wearbench.validation.workflows import measure

    x = np.repeat(model.mean(0.4e-3, 0.0)[None], 20, axis=0)
    e = estimate_features(CycleFeatures(SPEC, x, np.zeros(20)), model, label="new")
    assert posterior_figure(e, tmp_path / "p.png", model).read_bytes()[:4] == b"\x89PNG"
    monkeypatch.setattr(measure, "estimate_sessions", lambda *a, **k: [e])
    assert main(["estimate", "new.mcap", "--calibration", "none"]) == 0
    out = capsys.readouterr().out
    assert f"cycles run {e.cycles_run.median:,.0f}  50 % at most {e.cycles_run.hi50:,.0f}  90 % at most " \
           f"{e.cycles_run.hi90:,.0f} (upper bound: the posterior piles at the edge" in out, out
    assert "um (upper bound" in out
