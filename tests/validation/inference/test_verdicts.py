"""The arithmetic the identification benchmarks score with, on known inputs: the spread over rebuilds,
the size from which it meets the mark, and the verdict scores (Brier, top-1, named right / wrong)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest
from wearbench.validation.inference import verdicts as stability

pytestmark = pytest.mark.no_kernels

NAMES = ("a", "b", "c")


def result(verdict: str, **posterior: float) -> SimpleNamespace:
    return SimpleNamespace(verdict=verdict, posterior={s: posterior.get(s, 0.0) for s in NAMES})


def test_the_spread_is_max_minus_min():
    assert stability.spread([1.0, 1.44, 1.2]) == pytest.approx(0.44)
    assert stability.spread([1.0, 1.0, 1.0]) == 0.0


def test_the_stable_size_is_the_smallest_from_which_every_larger_size_meets_the_mark():
    assert stability.stable_size({16: 0.13, 32: 0.05, 64: 0.02}) == 32
    assert stability.stable_size({16: 0.05, 32: 0.13, 64: 0.02}) == 64  # 16 alone does not count
    assert stability.stable_size({16: 0.05, 32: 0.08}) == 16
    assert stability.stable_size({16: 0.05, 32: 0.13}) is None  # the largest size misses it
    assert stability.stable_size({32: 0.1}) == 32  # the mark itself passes
    assert stability.stable_size({32: float("nan")}) is None


def test_verdict_scores_against_hand_counts():
    results = [result("a", a=1.0),                       # sure and right: Brier 0
               result("undecided", a=0.5, b=0.5),        # split, top-1 right by order: 0.25 + 0.25
               result("b", b=0.9, c=0.1),                # named wrong (truth c): 0.81 + 0.81
               result("none of the candidates", c=1.0)]  # top-1 right, not named
    scores = stability.verdict_scores(results, ["a", "a", "c", "c"], NAMES)
    assert scores["brier"] == pytest.approx((0 + 0.5 + 1.62 + 0) / 4)
    assert scores["top1"] == pytest.approx(3 / 4)
    assert scores["right"] == pytest.approx(1 / 4)
    assert scores["wrong"] == pytest.approx(1 / 4)
