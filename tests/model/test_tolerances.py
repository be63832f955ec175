"""An adaptive method's error scales and drift limit: absolute scales per kind of state component (the
atol pair, issue 47 moved it from benchmarks/model/statistics_equivalence.py into the model) and the
method's drift tolerance reach the compiled loop."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.model import SimulationError, build_scene, simulate
from wearbench.model.methods import RK4Paper
from wearbench.model.simulation import error_scales


@pytest.fixture(scope="module")
def scene():
    return build_scene(load_bench(shipped_bench("slider-crank")))


def test_error_scales_per_kind_of_component(scene):
    n = scene.n
    atol = error_scales(scene, (2e-7, 5e-6))
    assert atol.shape == (2 * n,)
    np.testing.assert_array_equal(atol[:n].reshape(-1, 3), np.tile([2e-7, 2e-7, 2e-6], (n // 3, 1)))
    np.testing.assert_array_equal(atol[n:].reshape(-1, 3), np.tile([5e-6, 5e-6, 5e-5], (n // 3, 1)))
    one = error_scales(scene, 1e-9)  # a number: velocities at a contact frequency scale of 1e3 /s
    np.testing.assert_array_equal(one[n:], one[:n] * 1e3)


def test_absolute_scales_reach_the_integrator(scene):
    """Scales with velocities at 1e3 /s x positions are the model's own atol with rtol 0: the same run bit for
    bit; a looser velocity scale takes fewer steps."""
    plain = simulate(scene, revolutions=0.2, rtol=0.0, atol=1e-9)
    np.testing.assert_array_equal(error_scales(scene, (1e-9, 1e-9 * 1e3)), error_scales(scene, 1e-9))
    same = simulate(scene, revolutions=0.2, rtol=0.0, atol=(1e-9, 1e-9 * 1e3))
    loose = simulate(scene, revolutions=0.2, rtol=0.0, atol=(1e-9, 1e-4))
    assert same.summary["steps"] == plain.summary["steps"]
    np.testing.assert_array_equal(same.table.to_numpy(), plain.table.to_numpy())
    assert loose.summary["steps"] < plain.summary["steps"]


def test_the_methods_drift_tolerance_stops_a_run(slider_crank):
    # the paper's RK4 does not project: on the ideal slider-crank its drift stays tiny but not zero; a
    # method whose limit lies below it stops there, naming the drift
    ideal = build_scene(slider_crank, clearances={"S": None})
    free = simulate(ideal, revolutions=0.5, method=RK4Paper)
    drift = free.summary["max_constraint_drift"]
    assert 0 < drift < 1e-6
    tight = dataclasses.replace(RK4Paper, drift_tolerance=drift / 10)
    with pytest.raises(SimulationError, match="constraint drift") as info:
        simulate(ideal, revolutions=0.5, method=tight)
    assert info.value.quantity == "constraint drift" and 0 < info.value.t < free.table["t"].iloc[-1]
