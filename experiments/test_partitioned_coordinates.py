"""experiments/partitioned_coordinates.py's reduced right-hand side (issue 27's partitioned coordinates): on the
test bed's states from a real run (contacts included) the 24 accelerations equal those of the augmented solve
``kernel.accel`` at the same state, and the position solve lands on the run's (projected) positions.

The experiment's own check, beside it: no test run loads it (``testpaths`` is tests/); run it by hand with
``.venv/bin/pytest experiments``."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.model import kernel as K
from wearbench.model.realisation import state_scene

sys.path.insert(0, str(Path(__file__).resolve().parent))  # as when the script runs from its folder
import partitioned_coordinates as pc


@pytest.fixture(scope="module")
def scene():
    bench = load_bench(shipped_bench("ninebar-testbed"))
    return state_scene(bench, next(s for s in bench.states if s.name == "0.3 mm new"))


@pytest.mark.slow  # ~35 s of numba compilation on a cold cache (3 s warm)
def test_partitioned_accelerations_equal_the_augmented_ones(scene):
    speed = scene.bench.speed
    _, ts, qs, vs, inc, v0i = pc.sample_states(scene, speed, revolutions=0.05)  # 50 ms at 20 kHz
    assert inc.any(), "expected contacts among the states (the contact forces must enter the check)"
    part = pc.choose_partition(scene, 0.0, qs[0], vs[0], speed)
    assert part.indep.size == scene.dof == 4
    assert sorted(np.concatenate([part.dep, part.indep]).tolist()) == list(range(scene.n))
    Z = pc.new_reduced(scene, part, ts[0], qs[0], vs[0], speed)
    n, m = scene.n, scene.m
    a_part, a_aug, q_part = np.zeros((ts.size, n)), np.zeros((ts.size, n)), np.zeros((ts.size, n))
    done = pc.check_states(ts, qs, vs, speed, scene.params, part, Z, scene.work(), inc, v0i,
                           np.zeros((len(scene.clearance_joints), K.NCO)), pc.NEWTON_TOL, pc.NEWTON_MAXIT, a_part,
                           a_aug, q_part, np.zeros(m), scene.work())
    assert done == ts.size
    rel = np.abs(a_part - a_aug).max(axis=1) / np.abs(a_aug).max(axis=1)
    assert rel.max() < 1e-9
    assert np.abs(q_part - qs).max() < 1e-10  # Newton from the previous sample lands on this one
    assert Z.counts[1] <= 2 * Z.counts[0]  # about one Newton update per call from the predicted start
