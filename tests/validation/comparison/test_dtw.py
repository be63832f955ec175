"""Banded DTW against a plain full-matrix DTW written independently here."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from wearbench.validation.comparison.dtw import dtw_banded


def full_dtw(x, y, band=None):
    """Textbook DTW by the full cost matrix (small inputs only), optional |i - j| <= band."""
    n, m = len(x), len(y)
    acc = np.full((n + 1, m + 1), np.inf)
    acc[0, 0] = 0.0
    for i in range(1, n + 1):
        for j in range(1, m + 1):
            if band is not None and abs(i - j) > band:
                continue
            acc[i, j] = (x[i - 1] - y[j - 1]) ** 2 + min(acc[i - 1, j - 1], acc[i - 1, j], acc[i, j - 1])
    # path
    i, j, path = n, m, [(n - 1, m - 1)]
    while (i, j) != (1, 1):
        options = [(acc[i - 1, j - 1], i - 1, j - 1), (acc[i - 1, j], i - 1, j), (acc[i, j - 1], i, j - 1)]
        _, i, j = min(options, key=lambda o: o[0])
        path.append((i - 1, j - 1))
    return acc[n, m], path[::-1]


@settings(max_examples=40, deadline=None)
@given(st.integers(2, 40), st.integers(0, 6), st.integers(0, 2**31 - 1))
def test_wide_band_equals_full_dtw(n, dm, seed):
    rng = np.random.default_rng(seed)
    x, y = rng.normal(size=n), rng.normal(size=n + dm)
    cost, pi, pj = dtw_banded(x, y, band=n + dm)
    ref_cost, ref_path = full_dtw(x, y)
    assert cost == pytest.approx(ref_cost, rel=1e-12, abs=1e-12)
    # the path is a valid warping path whose cost is the optimum
    assert (pi[0], pj[0]) == (0, 0) and (pi[-1], pj[-1]) == (n - 1, n + dm - 1)
    steps = np.column_stack([np.diff(pi), np.diff(pj)])
    assert np.all(np.isin(steps, [0, 1])) and np.all(steps.sum(axis=1) >= 1)
    assert np.sum((x[pi] - y[pj]) ** 2) == pytest.approx(ref_cost, rel=1e-12, abs=1e-12)
    assert list(zip(pi.tolist(), pj.tolist())) == ref_path  # random data: no ties


@pytest.mark.parametrize("band", [0, 1, 3, 7])
def test_narrow_band_equals_constrained_full_dtw(band):
    rng = np.random.default_rng(band)
    x, y = rng.normal(size=30), rng.normal(size=30)
    cost, pi, pj = dtw_banded(x, y, band=band)
    assert cost == pytest.approx(full_dtw(x, y, band=band)[0], rel=1e-12)
    assert np.all(np.abs(pi - pj) <= band)
    if band == 0:
        assert cost == pytest.approx(np.sum((x - y) ** 2))


def test_identical_and_shifted():
    t = np.linspace(0, 1, 2000)
    x = np.sin(2 * np.pi * 3 * t)
    cost, pi, pj = dtw_banded(x, x, band=50)
    assert cost == 0.0 and np.array_equal(pi, pj)
    # a delayed copy is warped back: cost far below the unwarped one
    y = np.sin(2 * np.pi * 3 * (t - 0.005))
    assert dtw_banded(x, y, band=50)[0] < 0.05 * np.sum((x - y) ** 2)


def test_bad_band():
    with pytest.raises(ValueError, match="band"):
        dtw_banded(np.zeros(10), np.zeros(14), band=2)
