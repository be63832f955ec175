"""benchmarks/statistics_equivalence.py's own parts: the Holm correction on hand-computed values, a
setting's name read back, and the absolute error scales (``--scales``) reaching the integrator."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.model import build_scene, simulate
from wearbench.model import simulation as S

PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "statistics_equivalence.py"
spec = importlib.util.spec_from_file_location("statistics_equivalence", PATH)
equivalence = importlib.util.module_from_spec(spec)
spec.loader.exec_module(equivalence)


def test_holm_against_hand_values():
    # sorted 0.01, 0.03, 0.04, 0.5 times 4, 3, 2, 1: 0.04, 0.09, 0.08 -> 0.09 (monotone), 0.5
    adj = equivalence.holm(np.array([0.01, 0.04, 0.03, 0.5]))
    assert adj == pytest.approx([0.04, 0.09, 0.09, 0.5])
    assert equivalence.holm(np.array([0.6, 0.9])).max() == 1.0  # capped


@pytest.mark.parametrize(("tolerances", "scales", "options"), [
    (None, None, {"method": "default"}),
    ((1e-5, 1e-8), None, {"method": "default", "rtol": 1e-5, "atol": 1e-8}),
    (None, (1e-6, 3e-6), {"method": "default", "scales": (1e-6, 3e-6)}),
])
def test_a_setting_is_read_back_from_its_name(tolerances, scales, options):
    assert equivalence.setting(equivalence.label("default", tolerances, scales)) == options


@pytest.fixture(scope="module")
def scene():
    return build_scene(load_bench(shipped_bench("slider-crank")))


def test_absolute_scales_are_the_error_scales_inside_the_block_only(scene):
    original = S._tolerances
    with equivalence.absolute_scales(2e-7, 5e-6):
        atol = S._tolerances(scene, 1.0)
    assert S._tolerances is original
    n = scene.n
    assert atol.shape == (2 * n,)
    np.testing.assert_array_equal(atol[:n].reshape(-1, 3), np.tile([2e-7, 2e-7, 2e-6], (n // 3, 1)))
    np.testing.assert_array_equal(atol[n:].reshape(-1, 3), np.tile([5e-6, 5e-6, 5e-5], (n // 3, 1)))


def test_absolute_scales_reach_the_integrator(scene):
    """Scales with velocities at 1e3 /s x positions are the model's own atol with rtol 0: the same run bit for
    bit; a looser velocity scale takes fewer steps."""
    plain = simulate(scene, revolutions=0.2, rtol=0.0, atol=1e-9)
    model_scales = S._tolerances(scene, 1e-9)
    with equivalence.absolute_scales(1e-9, 1e-9 * 1e3):
        np.testing.assert_array_equal(S._tolerances(scene, 1.0), model_scales)
        same = simulate(scene, revolutions=0.2, rtol=0.0, atol=1e-9)
    with equivalence.absolute_scales(1e-9, 1e-4):
        loose = simulate(scene, revolutions=0.2, rtol=0.0, atol=1e-9)
    assert same.summary["steps"] == plain.summary["steps"]
    np.testing.assert_array_equal(same.table.to_numpy(), plain.table.to_numpy())
    assert loose.summary["steps"] < plain.summary["steps"]
