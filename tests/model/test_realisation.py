"""Realisations: benches drawn within their tolerances, reproducible, and the nominal one unchanged."""

import math
from dataclasses import replace

import numpy as np
import pytest
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.bench.schema import Tolerances
from wearbench.model import build_scene, simulate
from wearbench.model.realisation import draw_realisation, simulate_state

BENCH = load_bench(shipped_bench("ninebar-testbed"))


def test_draws_are_reproducible_and_differ_between_seeds():
    a, b, c = (draw_realisation(BENCH, s) for s in (5, 5, 6))
    assert a == b and a != c
    assert a.bench.bodies[0].mass != BENCH.bodies[0].mass


def test_draws_follow_the_declared_spread():
    tol = Tolerances(mass=0.03, length=0.2e-3)
    masses, ends = [], []
    for seed in range(400):
        r = draw_realisation(BENCH, seed, tol)
        masses.append(r.bench.body("rod2").mass / BENCH.body("rod2").mass - 1)
        ends.append(r.bench.body("rod2").points["end"][0] - BENCH.body("rod2").points["end"][0])
    assert np.std(masses) == pytest.approx(0.03, rel=0.12) and abs(np.mean(masses)) < 0.006
    assert np.std(ends) == pytest.approx(0.2e-3, rel=0.12)
    assert max(np.abs(masses)) <= 3 * 0.03 + 1e-12  # cut at 3 standard deviations


def test_zero_tolerances_give_the_nominal_bench():
    zero = Tolerances(**{f: 0.0 for f in Tolerances.__dataclass_fields__})
    r = draw_realisation(BENCH, 3, zero)
    assert r.bench == BENCH and r.speed_scale == 1.0 and r.ripple == 0.0


def test_the_nominal_realisation_is_the_plain_simulation():
    state = BENCH.states[0]
    run = simulate_state(BENCH, state, None, revolutions=0.25, settle=0.0, output_rate=5000)
    ref = simulate(build_scene(BENCH, clearances=dict(state.clearances)), t_end=0.25 * 2 * math.pi / BENCH.speed,
                   output_rate=5000)
    np.testing.assert_array_equal(run.acc, ref.table["slider_acc"].to_numpy())


def test_a_drawn_realisation_turns_at_its_own_speed_after_settling():
    run = simulate_state(BENCH, BENCH.states[0], 11, revolutions=0.5, settle=0.25, output_rate=5000)
    real = run.realisation
    assert run.t[0] == 0.0
    assert run.motor_angle[-1] - run.motor_angle[0] == pytest.approx(math.pi, rel=0.01)  # half a turn kept
    slope = np.polyfit(run.t, run.motor_angle, 1)[0]
    assert slope == pytest.approx(BENCH.speed * real.speed_scale, rel=3 * real.ripple + 1e-3)


def test_bad_requests_are_refused():
    with pytest.raises(ValueError, match="revolutions"):
        simulate_state(BENCH, None, 1, revolutions=0)
    with pytest.raises(ValueError, match="speed 0"):
        simulate_state(replace(BENCH, speed=0.0), None, 1, revolutions=1)
