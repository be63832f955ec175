"""The paper's studies as ensemble statistics: per-cycle maxima, the bootstrap (its coverage against a
known distribution, runs resampled as units), the verdict rule, and the quick study on two seeds."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest
from scipy import stats as sps
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.cli import main
from wearbench.model.wear_stages import StagePlan
from wearbench.studies.study import (
    MAX_STATISTIC,
    Cell,
    StudyConfig,
    _t_interval,
    cell_statistics,
    cell_units,
    cycle_maxima,
    replication,
    run_study,
    trends,
    verdict,
)


def test_cycle_maxima_are_the_maxima_of_each_whole_motor_revolution():
    """Motor turning backwards (the studies' -5 pi rad/s), 3.4 revolutions, 100 samples a turn: the
    maximum of a signal that equals its cycle number plus the phase is reached at each cycle's end."""
    turns = np.arange(0, 3.4, 0.01)
    motor = -2 * math.pi * turns
    x = np.floor(turns + 1e-12) + (turns % 1)  # k + phase in cycle k
    got = cycle_maxima(motor, {"x": x, "neg": -x}, cycles=5)
    assert got["x"] == pytest.approx([0.99, 1.99, 2.99])  # 3 whole cycles, the partial 4th dropped
    assert got["neg"] == pytest.approx([0.0, -1.0, -2.0])
    assert cycle_maxima(motor, {"x": x}, cycles=2)["x"] == pytest.approx([0.99, 1.99])
    with pytest.raises(ValueError, match="no whole cycle"):
        cycle_maxima(motor[:50], {"x": x[:50]}, cycles=1)


EULER_GAMMA = 0.5772156649015329


BETA = 0.15  # scale of the per-cycle Gumbel term (log): a realisation's log max then spreads by about 0.19


def _two_level(rng, runs: int, per_run: int, cycles: int, mu: float, tau: float, sigma: float) -> np.ndarray:
    """(runs, per_run, cycles) per-cycle maxima of a synthetic cell: log x = mu + run effect (sd tau)
    + realisation effect (sd sigma) + BETA times a standard Gumbel per cycle (the law of maxima). The
    largest of C standard Gumbels is Gumbel(log C, 1), so the mean log of a realisation's max is
    mu + BETA (log C + Euler's gamma)."""
    return np.exp(mu + tau * rng.standard_normal((runs, 1, 1)) + sigma * rng.standard_normal((runs, per_run, 1))
                  + BETA * rng.gumbel(size=(runs, per_run, cycles)))


def _true_max(mu: float, cycles: int) -> float:
    return math.exp(mu + BETA * (math.log(cycles) + EULER_GAMMA))


def _old_bootstrap_max(x: np.ndarray, rng, n: int = 400) -> tuple[float, float]:
    """The interval this replaces: resample the runs, then the realisations within them, percentile
    interval of the geometric mean of the realisations' max."""
    logs = np.log(x.max(axis=2))
    w, m = logs.shape
    boot = logs[rng.integers(0, w, (n, w))[:, :, None], rng.integers(0, m, (n, w, m))].mean(axis=(1, 2))
    return tuple(np.exp(np.percentile(boot, [2.5, 97.5])))


def test_cell_units_are_realisations_before_wear_and_wear_runs_after():
    """The log of each realisation's max (or median) over its cycles; grouped by wear run, each
    run's mean of them."""
    x = np.array([[[1.0, 4.0, 2.0], [3.0, 9.0, 5.0]], [[2.0, 2.0, 8.0], [1.0, 6.0, 7.0]]])
    assert cell_units(x, "max", False) == pytest.approx(np.log([4.0, 9.0, 8.0, 7.0]))
    assert cell_units(x, "median", False) == pytest.approx(np.log([2.0, 5.0, 2.0, 6.0]))
    assert cell_units(x, "max", True) == pytest.approx([np.log(36.0) / 2, np.log(56.0) / 2])
    stat = cell_statistics(Cell(None, "first wear", {"q": x}, by_run=True), 0.95)["q"]["max"]
    assert stat["value"] == pytest.approx((4 * 9 * 8 * 7) ** 0.25)


@pytest.mark.parametrize(("runs", "per_run", "tau", "sigma"), [
    (1, 12, 0.0, 0.3),   # before wear: 12 independent realisations
    (3, 4, 0.3, 0.1),    # after wear, the wear runs dominate the spread
    (6, 2, 0.15, 0.2),   # the default's after-wear cell, both levels alike
])
def test_cell_interval_covers_the_true_max_of_a_run_at_its_level(runs, per_run, tau, sigma):
    """2000 synthetic cells with a known truth (the max of 8 cycles from the Gumbel law; the
    median's from 400000 independent draws): the 95 % interval covers it in 93-97 % of them."""
    rng = np.random.default_rng(11)
    cycles, mu, trials = 8, math.log(5000.0), 2000
    truth = {"max": _true_max(mu, cycles),
             "median": math.exp(mu + BETA * np.median(rng.gumbel(size=(400_000, cycles)), axis=1).mean())}
    hits = dict.fromkeys(truth, 0)
    for _ in range(trials):
        cell = Cell(None, "s", {"q": _two_level(rng, runs, per_run, cycles, mu, tau, sigma)}, by_run=runs > 1)
        st = cell_statistics(cell, 0.95)["q"]
        for s, true in truth.items():
            hits[s] += st[s]["lo"] <= true <= st[s]["hi"]
    for s in truth:
        assert 0.93 <= hits[s] / trials <= 0.97, (s, hits[s] / trials)


def test_few_wear_runs_are_few_draws_the_old_bootstrap_was_too_narrow():
    """3 wear runs whose surfaces set most of the spread: the bootstrap that resampled runs, then
    realisations (the previous interval) covers the true max in well under 95 % of cells (a
    resample of 3 runs has 10 distinct run sets and the spread of 3, not of the population); the
    t interval over the runs keeps its level."""
    rng = np.random.default_rng(5)
    cycles, mu, trials = 8, math.log(5000.0), 600
    truth = _true_max(mu, cycles)
    old = new = 0
    for _ in range(trials):
        x = _two_level(rng, 3, 4, cycles, mu, 0.3, 0.1)
        lo, hi = _old_bootstrap_max(x, rng)
        old += lo <= truth <= hi
        st = cell_statistics(Cell(None, "s", {"q": x}, by_run=True), 0.95)["q"]["max"]
        new += st["lo"] <= truth <= st["hi"]
    assert old / trials < 0.85  # 0.78
    assert new / trials >= 0.92


@pytest.mark.parametrize("paired", [False, True])
def test_ratio_interval_covers_the_true_ratio(paired):
    """Before (12 realisations) against after wear (6 runs of 2), true ratio of the max 1.3: Welch's
    interval covers it in 93-97 % of 2000 studies. Two stages of the same 6 runs (a run effect they
    share, sd 0.3, and one of their own, sd 0.1): the paired interval covers, Welch's (ignoring the
    sharing) is far too wide (covers nearly always)."""
    rng = np.random.default_rng(2)
    cycles, mu, trials, shift = 8, math.log(5000.0), 2000, math.log(1.3)
    hits = welch = 0
    for _ in range(trials):
        if paired:
            shared = 0.3 * rng.standard_normal((6, 1, 1))
            a = _two_level(rng, 6, 2, cycles, mu, 0.1, 0.2) * np.exp(shared)
            b = _two_level(rng, 6, 2, cycles, mu + shift, 0.1, 0.2) * np.exp(shared)
            ua, ub = cell_units(a, "max", True), cell_units(b, "max", True)
            _, wlo, whi = _t_interval(ub, ua, False, 0.95)
            welch += wlo <= shift <= whi
        else:
            ua = cell_units(_two_level(rng, 1, 12, cycles, mu, 0.0, 0.3), "max", False)
            ub = cell_units(_two_level(rng, 6, 2, cycles, mu + shift, 0.15, 0.2), "max", True)
        _, lo, hi = _t_interval(ub, ua, paired, 0.95)
        hits += lo <= shift <= hi
    assert 0.93 <= hits / trials <= 0.97
    if paired:
        assert welch / trials > 0.99


def test_verdict_is_decided_only_when_the_interval_excludes_one():
    assert verdict(1.01, 2.0) == "agrees"
    assert verdict(0.5, 0.99) == "disagrees"
    assert verdict(0.99, 1.5) == "not resolved"


def _stat(value: float, sd: float, rng, units: int) -> dict:
    """A cell's statistic for ``trends``: ``units`` log values around log(value), spread ``sd``."""
    return {"value": value, "units": math.log(value) + sd * rng.standard_normal(units)}


def _synthetic_study(rng, force_a, force_b, acc, sd_force: float, sd_acc: float, depth_sd: float,
                     b_over_a: float = 2.0):
    """Cell statistics (12 units before wear, 6 wear runs after) and wear-run depths (B ``b_over_a``
    times A's) of a synthetic study; force_a/force_b/acc(case, stage) give the true values."""
    cfg = StudyConfig(plan=StagePlan())
    stats, depth = {}, {}
    for case in (cfg.wear_case, *cfg.clearance_cases):
        labels = ["before wear", "first wear", "second wear"][: case.stages + 1]
        for k, label in enumerate(labels):
            n = 6 if k else 12
            stats[(case.name, label)] = {"fn_A": {MAX_STATISTIC: _stat(force_a(case, k), sd_force, rng, n)},
                                         "fn_B": {MAX_STATISTIC: _stat(force_b(case, k), sd_force, rng, n)},
                                         "acc": {MAX_STATISTIC: _stat(acc(case, k), sd_acc, rng, n)}}
            if k:  # max depth of 6 wear runs
                depth[(case.name, label)] = {"A": 1e-5 * k * np.exp(depth_sd * rng.standard_normal(6)),
                                             "B": b_over_a * 1e-5 * k * np.exp(depth_sd * rng.standard_normal(6))}
    return {t["finding"]: t["verdict"] for t in trends(stats, depth, cfg, ["A", "B"])}


def test_trends_answer_from_the_interval_of_each_ratio():
    """Synthetic cell statistics: forces twice as high after wear (tight intervals) agree; an
    after-wear force at B at 0.45 mm below its new one disagrees; wide intervals are not resolved."""
    rng = np.random.default_rng(1)
    got = _synthetic_study(rng, lambda c, k: 1000.0 * 2**k,
                           lambda c, k: 1000.0 * 2**k if c.clearance != 0.45e-3 or k == 0 else 500.0,
                           lambda c, k: 100.0 * 2**k, 0.02, 1.0, 0.02)
    assert len(got) == 11
    assert got["wear raises the peak contact force at A"] == "agrees"
    assert got["B wears deeper than A (after second wear)"] == "agrees"
    assert got["contact force at B grows after wear at every clearance"] == "disagrees"  # 0.45 mm: 0.5
    assert got["contact force at B after wear grows with clearance"] == "disagrees"  # 500 after 2000
    assert got["wear depth at A grows with clearance"] == "not resolved"  # equal depths: ratio 1
    assert got["wear raises the peak slider acceleration, second wear more than first"] == "not resolved"


@pytest.mark.slow
def test_a_finding_with_no_effect_rarely_disagrees():
    """Every true ratio 1 (forces and accelerations spread 0.2 in log, depths 0.05): over 400 synthetic
    studies a finding disagrees in at most 2.5 % (+ sampling) of them, its 1 to 3 ratios' levels shared
    out (Bonferroni), and agrees as rarely."""
    rng = np.random.default_rng(4)
    def one(case, stage):
        return 1000.0

    counts = {"agrees": 0, "disagrees": 0, "not resolved": 0}
    for _ in range(400):
        for v in _synthetic_study(rng, one, one, one, 0.2, 0.2, 0.05, b_over_a=1.0).values():
            counts[v] += 1
    assert counts["disagrees"] / 4400 <= 0.03, counts
    assert counts["agrees"] / 4400 <= 0.03, counts  # all of a finding's ratios above 1 by chance


def test_t_interval_is_students_paired_or_welchs():
    """Log depths of 3 runs with known spread: the paired interval is mean +/- t(2) sd / sqrt 3 of the
    per-run log ratios; 2 runs of one case against 2 of another give Welch's interval (scipy's); one
    run gives no interval."""
    b, a = np.log([2.0, 2.2, 1.8]), np.log([1.0, 1.0, 1.0])
    d = b - a
    half = sps.t.ppf(0.975, 2) * d.std(ddof=1) / math.sqrt(3)
    assert _t_interval(b, a, True, 0.95) == pytest.approx((d.mean(), d.mean() - half, d.mean() + half))
    x, y = np.log([3.0, 3.3]), np.log([1.0, 1.1])
    welch = sps.ttest_ind(x, y, equal_var=False).confidence_interval(0.95)
    assert _t_interval(x, y, False, 0.95)[1:] == pytest.approx((welch.low, welch.high))
    one = sps.ttest_1samp(b, 0.0).confidence_interval(0.9)
    assert _t_interval(b, None, False, 0.9)[1:] == pytest.approx((one.low, one.high))
    assert verdict(*np.exp(_t_interval(np.log([3.0]), np.log([1.0]), False, 0.95)[1:])) == "not resolved"


@pytest.mark.slow
@pytest.mark.timeout(1800)  # two quick studies: about 2 min on 2 idle cores, 10 min on a loaded machine
def test_quick_study_verdicts_do_not_flip_between_seeds(tmp_path):
    """The quick study with seeds 1 and 1001 (other wear runs, other realisations, other resamples):
    every cell has an interval, every trend a verdict; no trend agrees on one seed and disagrees on
    the other, and the two seeds' intervals of the same cell overlap (they estimate the same thing)."""
    out = tmp_path / "study"
    assert main(["study", str(shipped_bench("ninebar")), "--quick", "--out", str(out), "--workers", "0"]) == 0
    first = json.loads((out / "study.json").read_text())
    t3 = pd.read_csv(out / "table3.csv", header=[0, 1], index_col=0)
    assert list(t3.index) == ["clearance A", "clearance B"] and t3.shape == (2, 6) and (t3.to_numpy() > 0).all()
    assert (out / "figures" / "fig09-11_slider.png").exists()
    assert (out / "figures" / "fig29-30_poincare_0.45mm.png").exists()
    assert (out / "wear" / "surfaces" / "A_2.npz").exists() and (out / "wear" / "run2" / "surfaces" / "A_2.npz").exists()
    assert "| finding | verdict |" in (out / "table3.md").read_text()

    bench = load_bench(shipped_bench("ninebar"))
    plan = StagePlan.from_bench(bench, stages=1)
    second = run_study(bench, tmp_path / "seed2", StudyConfig.quick(plan, seed=1001, workers=0))
    for summary in (first, second):
        cells = pd.DataFrame(summary["cells"])
        assert len(cells) == 9 * 3 * 2  # 9 (case, state) cells x (A, B, acc) x (median, p95)
        assert ((cells["lo"] <= cells["value"] + 1e-9) & (cells["value"] <= cells["hi"] + 1e-9)).all()
        assert len(summary["trends"]) == 11
        assert sum(summary["trend_counts"].values()) == 11
    flips = [(a["finding"], a["verdict"], b["verdict"]) for a, b in zip(first["trends"], second["trends"], strict=True)
             if {a["verdict"], b["verdict"]} == {"agrees", "disagrees"}]
    assert not flips
    a, b = (pd.DataFrame(s["cells"]).set_index(["case", "state", "quantity", "statistic"]) for s in (first, second))
    overlap = (a["lo"] <= b.loc[a.index, "hi"]) & (b.loc[a.index, "lo"] <= a["hi"])
    assert overlap.mean() >= 0.85, a[~overlap]


def test_wear_run_from_the_assembled_start_is_the_plain_wear_run():
    """``run_stages(start=...)`` given the state the model starts from anyway (assembled positions,
    ideal velocities) wears bit for bit as without it; a realisation's start wears differently."""
    from wearbench.model import build_scene
    from wearbench.model.realisation import draw_realisation, realisation_start
    from wearbench.model.wear_stages import run_stages

    bench = load_bench(shipped_bench("ninebar"))
    plan = StagePlan(stages=1, stage_cycles=1000.0, update_depth=1.0, min_updates=1, settle=0)
    clear, speed = {"A": 0.6e-3, "B": 0.6e-3}, -5 * math.pi
    scene = build_scene(bench, clearances=clear)
    plain = run_stages(bench, plan, clearances=clear, speed=speed)
    same = run_stages(bench, plan, clearances=clear, speed=speed, start=(scene.q0, scene.v_unit * speed))
    real = draw_realisation(bench, 5)
    other = run_stages(bench, plan, clearances=clear, speed=speed, start=realisation_start(real, scene, speed))
    for j in clear:
        np.testing.assert_array_equal(plain.final[j].bearing, same.final[j].bearing)
        assert not np.array_equal(plain.final[j].bearing, other.final[j].bearing)


def test_a_realisation_on_surfaces_in_memory_is_the_one_on_their_files(tmp_path):
    """``simulate_state(surfaces=...)`` and a state naming the same surfaces' files give the same table."""
    from wearbench.bench.schema import WearState
    from wearbench.model.realisation import simulate_state
    from wearbench.model.surfaces import JointSurfaces

    bench = load_bench(shipped_bench("ninebar"))
    n = bench.wear.regions
    angle = np.arange(n) * 2 * math.pi / n
    worn = {j: JointSurfaces(20e-6 * np.maximum(np.cos(angle), 0), 10e-6 * np.maximum(np.sin(angle), 0), 1e5, "w")
            for j in ("A", "B")}
    files = WearState("w", {}, {j: s.save(tmp_path / f"{j}.npz") for j, s in worn.items()})
    kw = {"revolutions": 0.3, "settle": 0.2, "output_rate": 5000.0}
    a = simulate_state(bench, WearState("w"), 3, surfaces=worn, **kw)
    b = simulate_state(bench, files, 3, **kw)
    pd.testing.assert_frame_equal(a.table, b.table, check_exact=True)
    assert np.array_equal(a.acc, b.acc) and np.array_equal(a.t, a.table["t"].to_numpy())


@pytest.mark.slow
def test_replication_probability_is_calibrated_under_its_flat_prior():
    """Effects drawn from a wide flat prior, two runs of each: among first runs that predict a rerun
    "agrees" with probability p (binned), the second run agrees at rate p (a second method: the
    simulated reruns); the probabilities of the three verdicts add up to one."""
    rng = np.random.default_rng(5)
    n, se, level = 200_000, 1.0, 0.95
    delta = rng.uniform(-12, 12, n)
    first, second = delta + rng.normal(0, se, n), delta + rng.normal(0, se, n)
    keep = np.abs(first) < 8  # away from the prior's edges, where it stops being flat
    t = sps.norm.ppf(0.975)
    predicted = np.array([replication([(d, se, 1e9)], level)["agrees"] for d in first[keep][:20_000]])
    agreed = second[keep][:20_000] > t * se
    for lo, hi in ((0.05, 0.2), (0.2, 0.4), (0.4, 0.6), (0.6, 0.8), (0.8, 0.95)):
        sel = (predicted >= lo) & (predicted < hi)
        assert sel.sum() > 300
        assert agreed[sel].mean() == pytest.approx(predicted[sel].mean(), abs=0.04)
    r = replication([(1.0, 1.0, 8.0), (-0.5, 0.7, 5.0)], level)
    assert r["agrees"] + r["disagrees"] + r["not resolved"] == pytest.approx(1.0)


def test_size_for_nine_in_ten_is_the_power_calculation():
    """One ratio at z = t + 1.2816 resolves in 9 of 10 reruns at today's size (factor 1); at half that z
    it takes 4x the units (se ~ 1/sqrt(units)); two such ratios need more than one; a finding whose
    estimate is 0 points nowhere."""
    t = sps.norm.ppf(0.975)
    z = t + sps.norm.ppf(0.9)
    assert replication([(z, 1.0, 1e9)], 0.95)["size_for_90"] == pytest.approx(1.0, rel=1e-6)
    assert replication([(z / 2, 1.0, 1e9)], 0.95)["size_for_90"] == pytest.approx(4.0, rel=1e-6)
    assert replication([(z, 1.0, 1e9)] * 2, 0.95)["size_for_90"] > 1.0
    assert replication([(-z, 1.0, 1e9), (z, 1.0, 1e9)], 0.95)["size_for_90"] < 1.0  # disagrees: any one below
    assert math.isinf(replication([(0.0, 1.0, 1e9)], 0.95)["size_for_90"])
