"""Cycles to a clearance limit that answer (issue 45): the probability that the limit was already
reached by the last session, the cycles that remain otherwise, and whether it lies beyond the
design's range of wear.

First :func:`limit_ahead` on a hand-built posterior whose answers are analytic: the wear factor ``k``
lognormal, the limit reached ``L / k`` cycles from new. Then lives of one bench each on a synthetic
estimator (``test_estimate.py``'s features, its wear depth 40 um per 200k cycles of the file's rate),
clearance 0.4 mm, wear 1.3x the file's. A life recorded to 400k has grown 104 um: a 0.45 mm limit
(50 um) is behind it. One recorded to 200k (52 um) reaches 0.486 mm after 86 um, 331k cycles from
new: 131k after its last session, inside the design (600k effective cycles, 120 um). A 0.7 mm limit
needs 300 um: far beyond the design's range."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from scipy import stats
from wearbench.cli import main
from wearbench.validation.estimation.estimate import Estimator, fit_estimator, save_estimator
from wearbench.validation.estimation.track import LimitAhead, limit_ahead, track_features
from wearbench.validation.measurement.features import CycleFeatures

from ...acquisition.conftest import FAST
from ..workflows import test_track_sessions
from .test_estimate import DESIGN, OPTIONS, SB, SPEC, SW, P, draw, true_mean

sessions = test_track_sessions.sessions  # two recorded sessions, at 0 and 150k cycles run (a fixture)
RATE = 2e-10  # wear depth per cycle of the file's rate (m)

# ---- a posterior of known answers -------------------------------------------------------------

K = stats.lognorm(s=0.3)  # the wear factor: lognormal, median 1
KS = np.geomspace(0.2, 5.0, 4001)
WK = K.pdf(KS) * KS  # weights of a log-spaced grid: density x dk
L, LAST = 1e6, 5e5  # the limit is reached L / k cycles from new; the last session at 500k


def remaining_quantile(p: float, last: float) -> float:
    """Given not reached by ``last``, the remaining r = L / k - last has
    P(r <= x) = (F(K0) - F(L / (last + x))) / F(K0), K0 = L / last: its p point."""
    return L / K.ppf(K.cdf(L / last) * (1 - p)) - last


def test_the_probability_reached_and_the_cycles_that_remain_are_the_analytic_ones():
    """P(L / k <= last) = P(k >= L / last) (2.3 sd above the median: 0.010); the rest's density at 0
    remaining is 0.14 of its mode's, so its 90 % interval is the central one, its 5 / 50 / 95 % points."""
    a = limit_ahead(L / KS, True, WK, LAST)
    assert a.p_reached == pytest.approx(K.sf(L / LAST), abs=1e-3) and a.p_never == 0.0 and a.p_beyond_design == 0.0
    r = a.remaining
    assert r.kind == "central"
    for got, p in ((r.lo90, 0.05), (r.lo50, 0.25), (r.median, 0.5), (r.hi50, 0.75), (r.hi90, 0.95)):
        assert got == pytest.approx(remaining_quantile(p, LAST), rel=0.01), p
    assert a.verdict == (f"not reached by the last session (P reached {a.p_reached:.2f}): a further "
                         f"{r.median:,.0f} cycles (90 % {r.lo90:,.0f}-{r.hi90:,.0f})")


def test_a_limit_behind_the_bench_for_most_of_the_posterior_is_said_reached_with_its_probability():
    """The last session at 1.6M: P(k >= 0.625) = 0.942 reached; the rest piles at 0 remaining (the
    density of L / k falls from the last session on), so its interval is [0, q90]: "at most"."""
    a = limit_ahead(L / KS, True, WK, 1.6e6)
    assert a.p_reached == pytest.approx(K.sf(L / 1.6e6), abs=1e-3)
    assert a.verdict.startswith(f"reached by the last session with P {a.p_reached:.2f}; otherwise a further ")
    r = a.remaining
    assert r.kind == "upper bound" and r.lo90 == 0.0 and r.lo50 == 0.0 and "(90 % at most " in a.verdict
    assert r.hi90 == pytest.approx(remaining_quantile(0.9, 1.6e6), rel=0.01)
    assert r.median == pytest.approx(remaining_quantile(0.5, 1.6e6), rel=0.01)
    assert limit_ahead(L / KS, True, WK, 2.5e6).verdict == (
        f"already reached by the last session (P {K.sf(L / 2.5e6):.2f})")


def test_a_limit_past_the_design_is_said_to_lie_beyond_it_and_never_where_it_is_not_reached():
    """Half the clearances reach it within the design's range (effective cycles L), half past it
    (3L); the second half's probability of being ahead is P(beyond the design)."""
    cycles = np.stack([L / KS, 3 * L / KS])
    covered = np.array([[True], [False]])
    a = limit_ahead(cycles, covered, WK / 2, 1.2e6)
    assert a.p_reached == pytest.approx(0.5 * K.sf(L / 1.2e6) + 0.5 * K.sf(3 * L / 1.2e6), abs=1e-3)
    assert a.p_beyond_design == pytest.approx(0.5 * K.cdf(3 * L / 1.2e6), abs=1e-3)
    assert a.p_beyond_design >= 0.5 * (1 - a.p_reached)
    assert "beyond the design's range of wear (P " in a.verdict and "extrapolated" in a.verdict
    never = limit_ahead(np.full(KS.shape, np.inf), False, WK, LAST)
    assert never.remaining is None and never.p_never == 1.0 and "not within 100 x" in never.verdict
    with pytest.raises(ValueError, match="no mass"):
        limit_ahead(L / KS, True, np.zeros_like(KS), LAST)


def test_the_verdict_reads_as_the_record_says():
    a = LimitAhead(0.3, 0.1, 0.0, None, 2e5)
    assert a.verdict.startswith("reached by the last session with P 0.30; otherwise not within 100 x")


# ---- lives on a synthetic estimator ------------------------------------------------------------


@pytest.fixture(scope="module")
def model():
    rng = np.random.default_rng(0)
    feats = np.stack([np.stack([draw(rng, true_mean(c, n), 16, 8) for n in DESIGN.cycles])
                      for c in DESIGN.clearances])
    depth = np.outer(np.ones(5), np.array(DESIGN.cycles) * RATE)
    return fit_estimator(Estimator("synthetic", "k", DESIGN, feats, depth, 2 * np.pi), OPTIONS)


def lives(model, runs, limit, n=6, seed=6):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        offset = rng.normal(0.0, np.sqrt(SB), P)
        feats = [CycleFeatures(SPEC, true_mean(0.4e-3, 1.3 * r) + offset + rng.normal(0.0, np.sqrt(SW), (20, P)),
                               np.zeros(20)) for r in runs]
        out.append(track_features(feats, runs, model, coefficient=5.2e-14, limit=limit))
    return out


@pytest.mark.slow
def test_a_life_past_the_limit_says_it_was_reached_with_its_probability(model, tmp_path):
    from wearbench.reports.track import track_figure

    tracks = lives(model, [0.0, 1e5, 2e5, 3e5, 4e5], 0.45e-3)
    p = [t.ahead.p_reached for t in tracks]
    assert min(p) > 0.5 and np.mean(p) > 0.8, p
    for t in tracks:
        v = t.ahead.verdict
        assert v.startswith(("already reached by the last session (P ",
                             f"reached by the last session with P {t.ahead.p_reached:.2f}; otherwise a further")), v
        data = json.loads(json.dumps(t.to_dict()))
        assert data["ahead"]["p_reached"] == t.ahead.p_reached and data["limit_verdict"] == v
        assert t.cycles_to_limit is not None and t.design_cycles == 6e5  # kept beside it, from new
    assert any(t.ahead.verdict.startswith("already reached") for t in tracks)
    assert track_figure(tracks[0], tmp_path / "life.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.slow
def test_a_life_before_the_limit_gets_a_finite_interval_of_the_cycles_that_remain(model, tmp_path):
    from wearbench.reports.track import design_end, track_figure

    tracks = lives(model, [0.0, 1e5, 2e5], 0.486e-3)
    truth = 0.086e-3 / (RATE * 1.3) - 2e5  # 131k after the last session
    held = 0
    for t in tracks:
        a = t.ahead
        assert a.p_reached < 0.5 and a.remaining is not None and np.isfinite(a.remaining.hi90), a
        assert "a further " in a.verdict and a.remaining.median > 0 and a.p_beyond_design < 0.5
        held += a.remaining.contains(truth)
    assert held >= 5, [t.ahead.remaining for t in tracks]
    assert design_end(tracks[0]) == pytest.approx(6e5 / tracks[0].factor.median)
    assert track_figure(tracks[0], tmp_path / "life.png").read_bytes()[:4] == b"\x89PNG"


def test_a_limit_far_past_the_design_is_said_to_lie_beyond_it(model):
    for t in lives(model, [0.0, 1e5, 2e5], 0.7e-3, n=3):
        a = t.ahead
        assert a.p_reached < 0.01 and a.p_beyond_design > 0.95, a
        assert a.verdict.startswith(f"not reached by the last session (P reached {a.p_reached:.2f}): beyond the "
                                    "design's range of wear (P "), a.verdict
        assert "extrapolated" in a.verdict


def test_track_prints_and_writes_the_limit(model, sessions, tmp_path, capsys):
    """`wearbench track --limit` prints the limit's line from the track's verdict and --json carries it."""
    s0, s1, _ = sessions
    path = save_estimator(replace(model.estimator, speed=FAST), tmp_path / "bench.npz")
    out = tmp_path / "life.json"
    code = main(["track", str(s0), str(s1), "--estimator", str(path), "--calibration", "none", "--no-move",
                 "--limit", "0.6mm", "--json", str(out)])
    printed = capsys.readouterr().out
    data = json.loads(out.read_text())
    assert code == (0 if data["explains"] else 1)
    assert data["ahead"]["p_reached"] is not None and data["limit_verdict"]
    if data["explains"]:
        assert f"clearance limit 0.6 mm: {data['limit_verdict']}" in printed
        assert "reached after" not in printed
