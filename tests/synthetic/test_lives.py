"""testing/lives.py: a truth's sensor path is checked before anything is simulated (a bad ``spread``,
or cross-axis on a bench whose accelerometer has no carriage on a guide, fails at once, naming it)."""

from __future__ import annotations

import importlib
import time

import pytest
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.synthetic.lives import life_features, truth_features

for _module in ("wearbench.model.realisation", "wearbench.model.wear_stages"):
    importlib.import_module(_module)  # imported here, so the timing below holds the calls only


@pytest.mark.parametrize(("name", "spread", "match"), [
    ("ninebar-testbed", "yes", r"spread = 'yes': expected False, True or 'cross-axis'"),
    ("fourbar", "cross-axis", r"fourbar: cross-axis needs the accelerometer's carriage"),
])
def test_a_bad_sensor_path_fails_before_the_wear_run(name, spread, match):
    bench = load_bench(shipped_bench(name))
    c = bench.clearance_joints[0].clearance.radial_clearance
    t0 = time.process_time()
    with pytest.raises(ValueError, match=match):
        truth_features(bench, c, 200_000.0, 40_001, 2, spread)  # a wear run and a simulation had it not failed
    with pytest.raises(ValueError, match=match):
        life_features(bench, c, 1.3, 100_000.0, 5, 40_001, 2, spread)  # five wear stages
    assert time.process_time() - t0 < 2.0  # failed up front: the runs take minutes
