"""Results that do not depend on how they are asked for: the run's duration and the output grid."""

from __future__ import annotations

import importlib

import numpy as np
import pandas as pd
import pytest
from wearbench.bench.load import load_bench, resolve_bench
from wearbench.model import build_scene, simulate


@pytest.fixture(scope="module")
def scene():
    return build_scene(load_bench(resolve_bench("ninebar-testbed")), clearances={"A": 0.6e-3, "B": 0.6e-3})


@pytest.fixture(scope="module")
def half(scene):
    return simulate(scene, revolutions=0.5)


def test_the_start_of_a_run_does_not_depend_on_its_length(scene, half):
    # the step cap used to be min(t_end, period) / 100: a half revolution stepped differently
    longer = simulate(scene, revolutions=1.5)
    a, b = half.table, longer.table.iloc[: len(half.table)]
    assert np.array_equal(a["t"], b["t"])
    cap = 2 * np.pi / abs(half.summary["speed"]) / 100  # largest step: the shorter run's last step
    inner = a["t"].to_numpy() < a["t"].iloc[-1] - cap
    assert inner.mean() > 0.95
    for column in ("slider_acc", "A_fn", "B_fn", "A_ex", "B_ey"):
        # the same steps up to the shorter run's last one: identical numbers
        np.testing.assert_array_equal(a[column][inner], b[column][inner], err_msg=column)
        # its last step ends at t_end instead: the same to within the dense output's accuracy
        scale = np.abs(b[column]).max()
        assert np.abs(a[column] - b[column]).max() <= 1e-2 * scale, column


def test_peaks_come_from_the_dense_output_not_the_grid(scene, half):
    s, grid = half.summary, half.table
    fine = simulate(scene, revolutions=0.5, output_rate=1e6).table  # independent check: a 50x finer grid
    pairs = [(s["peak_slider_acc"], np.abs(grid["slider_acc"]).max(), np.abs(fine["slider_acc"]).max())]
    pairs += [(s["peak_fn"][j], grid[f"{j}_fn"].max(), fine[f"{j}_fn"].max()) for j in ("A", "B")]
    for dense, coarse, finer in pairs:
        assert dense >= coarse
        assert finer <= dense * (1 + 1e-6)  # no sample of the fine grid is above the dense peak
        assert dense - finer <= 1e-4 * dense  # and the fine grid comes within 0.01 % of it
    # the default grid alone misses the top of the impact by more than that
    assert max((d - c) / d for d, c, _ in pairs) > 1e-3


def test_pausing_the_compiled_loop_changes_nothing(scene, half, monkeypatch):
    # the loop returns to Python every few thousand steps (so Ctrl-C acts): pausing every 97 steps
    # or never gives the same numbers
    S = importlib.import_module("wearbench.model.simulation")  # the module (the package exports the function)

    runs = []
    for every in (97, 10**9):
        monkeypatch.setattr(S, "STEPS_PER_CALL", every)
        runs.append(simulate(scene, revolutions=0.5, record_contacts=True))
    paused, whole = runs
    assert paused.summary["steps"] == whole.summary["steps"] > 10 * 97
    for column in ("slider_acc", "A_fn", "B_fn"):
        np.testing.assert_array_equal(paused.table[column], whole.table[column], err_msg=column)
    assert paused.summary["peak_fn"] == whole.summary["peak_fn"]
    pd.testing.assert_frame_equal(paused.contacts["A"], whole.contacts["A"])
