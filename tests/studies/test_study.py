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
    STATISTICS,
    Cell,
    StudyConfig,
    _interval,
    cell_statistics,
    cycle_maxima,
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


def _cell(x: np.ndarray) -> Cell:
    return Cell(None, "s", {"q": x})


def test_bootstrap_interval_of_percentiles_covers_the_true_value_at_its_level():
    """Independent realisations (one cycle each) of a known distribution: the 95 % interval of the
    median and of the 95th percentile covers the true quantile in about 95 % of 300 studies."""
    rng = np.random.default_rng(7)
    truth = {s: sps.lognorm(0.4).ppf(p / 100) for s, p in STATISTICS.items()}
    hits = dict.fromkeys(STATISTICS, 0)
    trials = 300
    for _ in range(trials):
        x = rng.lognormal(0.0, 0.4, size=(1, 200, 1))
        st = cell_statistics(_cell(x), 1000, rng)["q"]
        for s in STATISTICS:
            lo, hi = _interval(st[s]["boot"], 0.95)
            hits[s] += lo <= truth[s] <= hi
    assert 0.90 <= hits["median"] / trials <= 0.99
    assert 0.86 <= hits["p95"] / trials <= 0.99  # a tail quantile's percentile interval runs slightly short


def test_bootstrap_resamples_wear_runs_as_units():
    """Realisations on one wear run's surfaces share them: when the runs differ (offsets 0, 0.3, 0.6
    under noise of sd 1), the interval carries the spread of the runs (sd of a mean of 3 resampled
    runs 0.14, a 95 % width near 0.5); the same numbers taken as independent realisations of one
    surface give about half that."""
    rng = np.random.default_rng(3)
    x = rng.normal(0.0, 1.0, size=(3, 20, 8)) + np.array([0.0, 0.3, 0.6])[:, None, None]
    runs = cell_statistics(_cell(x), 2000, rng)["q"]["median"]
    pooled = cell_statistics(_cell(x.reshape(1, 60, 8)), 2000, rng)["q"]["median"]
    w_runs, w_pooled = (np.subtract(*_interval(v["boot"], 0.95)[::-1]) for v in (runs, pooled))
    assert 0.35 < w_runs < 0.75
    assert w_runs > 1.5 * w_pooled


def test_verdict_is_decided_only_when_the_interval_excludes_one():
    assert verdict(1.01, 2.0) == "agrees"
    assert verdict(0.5, 0.99) == "disagrees"
    assert verdict(0.99, 1.5) == "not resolved"


def _stat(value: float, rel_sd: float, rng) -> dict:
    return {"value": value, "boot": value * (1 + rel_sd * rng.standard_normal(4000))}


def test_trends_answer_from_the_interval_of_each_ratio():
    """Synthetic cell statistics: forces twice as high after wear (tight intervals) agree; an
    after-wear force at B at 0.45 mm below its new one disagrees; wide intervals are not resolved."""
    rng = np.random.default_rng(1)
    cfg = StudyConfig(plan=StagePlan())
    stats, depth = {}, {}
    for case in (cfg.wear_case, *cfg.clearance_cases):
        labels = ["before wear", "first wear", "second wear"][: case.stages + 1]
        for k, label in enumerate(labels):
            fa = 1000.0 * 2**k
            fb = 1000.0 * 2**k if case.clearance != 0.45e-3 or k == 0 else 500.0
            stats[(case.name, label)] = {"fn_A": {MAX_STATISTIC: _stat(fa, 0.02, rng)},
                                         "fn_B": {MAX_STATISTIC: _stat(fb, 0.02, rng)},
                                         "acc": {MAX_STATISTIC: _stat(100.0 * 2**k, 0.5, rng)}}
            if k:  # max depth of 3 wear runs
                depth[(case.name, label)] = {"A": 1e-5 * k * (1 + 0.02 * rng.standard_normal(3)),
                                             "B": 2e-5 * k * (1 + 0.02 * rng.standard_normal(3))}
    got = {t["finding"]: t["verdict"] for t in trends(stats, depth, cfg, ["A", "B"])}
    assert len(got) == 11
    assert got["wear raises the peak contact force at A"] == "agrees"
    assert got["B wears deeper than A (after second wear)"] == "agrees"
    assert got["contact force at B grows after wear at every clearance"] == "disagrees"  # 0.45 mm: 0.5
    assert got["contact force at B after wear grows with clearance"] == "disagrees"  # 500 after 2000
    assert got["wear depth at A grows with clearance"] == "not resolved"  # equal depths: ratio 1
    assert got["wear raises the peak slider acceleration, second wear more than first"] == "not resolved"


def test_depth_ratio_interval_is_students_t_over_the_wear_runs():
    """Log depths of 3 runs with known spread: the paired interval is exp(mean +/- t(2) sd / sqrt 3) of
    the per-run log ratios; 2 runs of one case against 2 of another give Welch's interval; one run
    gives no interval."""
    from wearbench.studies.study import _t_ratio

    b, a = np.array([2.0, 2.2, 1.8]), np.array([1.0, 1.0, 1.0])
    d = np.log(b / a)
    half = sps.t.ppf(0.975, 2) * d.std(ddof=1) / math.sqrt(3)
    r, lo, hi = _t_ratio(b, a, True, 0.95)
    assert (r, lo, hi) == pytest.approx((math.exp(d.mean()), math.exp(d.mean() - half), math.exp(d.mean() + half)))
    welch = sps.ttest_ind(np.log([3.0, 3.3]), np.log([1.0, 1.1]), equal_var=False).confidence_interval(0.95)
    assert _t_ratio(np.array([3.0, 3.3]), np.array([1.0, 1.1]), False, 0.95)[1:] == pytest.approx(
        (math.exp(welch.low), math.exp(welch.high)))
    assert verdict(*_t_ratio(np.array([3.0]), np.array([1.0]), False, 0.95)[1:]) == "not resolved"


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
