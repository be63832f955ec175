"""Contact laws against their formulas and published properties."""

from __future__ import annotations

import math

import numpy as np
import pytest
from wearbench.model.contact import (
    MIN_IMPACT_SPEED,
    contact_stiffness,
    friction_factor,
    friction_force,
    impact_speed,
    normal_force,
)
from wearbench.model.surface_tables import depth_at as surfaces_depth_at
from wearbench.model.surface_tables import depth_eval


def test_conformal_stiffness_is_about_seven_times_the_printed_form():
    args = (206e9, 0.3, 206e9, 0.3, 0.015, 0.0144)
    conformal = contact_stiffness(*args, "conformal")
    paper = contact_stiffness(*args, "paper")
    s = 2 * (1 - 0.09) / 206e9
    assert paper == pytest.approx(4 / (3 * s) * math.sqrt(0.015 * 0.0144 / 0.0294))
    assert conformal / paper == pytest.approx(math.sqrt(0.0294 / 0.0006), rel=1e-12)
    assert 6.5 < conformal / paper < 7.5
    with pytest.raises(ValueError, match="stiffness form"):
        contact_stiffness(*args, "nonsense")


def test_lankarani_nikravesh_damping_and_laws():
    k, n = 1e10, 1.5
    assert normal_force(-1e-6, 1.0, k, n, 0.9, 1.0, 0) == 0.0
    hertz = k * (1e-5) ** n
    assert normal_force(1e-5, 0.3, k, n, 0.9, 1.0, 2) == pytest.approx(hertz)
    assert normal_force(1e-5, 0.3, k, n, 1.0, 1.0, 0) == pytest.approx(hertz)  # ce = 1: no damping
    assert normal_force(1e-5, 0.3, k, n, 0.9, 1.0, 0) == pytest.approx(hertz * (1 + 0.75 * 0.19 * 0.3))
    assert normal_force(1e-5, 0.3, k, n, 0.5, 1.0, 1) == pytest.approx(hertz * (1 + 1.6 * 0.5 / 0.5 * 0.3))
    assert normal_force(1e-5, -100.0, k, n, 0.5, 1.0, 1) == 0.0  # never pulls
    assert impact_speed(0.0) == MIN_IMPACT_SPEED and impact_speed(-0.2) == 0.2


def test_modified_coulomb_dead_band_and_ramp():
    v0, vm = 1e-4, 1e-3
    assert friction_factor(5e-5, v0, vm) == 0.0
    assert friction_factor(5.5e-4, v0, vm) == pytest.approx(0.5)
    assert friction_factor(-2e-3, v0, vm) == 1.0
    assert friction_force(100.0, 2e-3, 0.1, v0, vm) == pytest.approx(-10.0)
    assert friction_force(100.0, -2e-3, 0.1, v0, vm) == pytest.approx(10.0)
    assert friction_force(100.0, 0.0, 0.1, v0, vm) == 0.0


def test_depth_interpolation_matches_the_surfaces_contract():
    rng = np.random.default_rng(1)
    depths = rng.uniform(0, 1e-4, 37)
    for phi in rng.uniform(-10, 10, 50):
        assert depth_eval(depths, depths.size, phi)[0] == pytest.approx(surfaces_depth_at(depths, phi), abs=1e-18)
