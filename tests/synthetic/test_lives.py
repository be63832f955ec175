"""testing/lives.py: a truth's sensor path is checked before anything is simulated (a bad ``spread``,
or cross-axis on a bench whose accelerometer has no carriage on a guide, fails at once, naming it)."""

from __future__ import annotations

import importlib
import time

import pytest
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.synthetic.lives import life_features, truth_features

pytestmark = pytest.mark.no_kernels

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


def test_a_worn_states_truth_and_session_key_come_from_its_files(tmp_path):
    """``surfaces_wear`` reads the state's files (checked against the arrays read with numpy), and
    ``state_session``'s key follows their content: the same bytes elsewhere share it, one byte changed
    does not."""
    import dataclasses
    import shutil

    import numpy as np
    from wearbench.synthetic.lives import state_session, surfaces_wear

    bench = load_bench(shipped_bench("ninebar-testbed"))
    state = next(s for s in bench.states if s.name == "0.3 mm first wear")
    arrays = {j: np.load(f) for j, f in state.surfaces.items()}
    cycles, depth = surfaces_wear(state.surfaces)
    assert cycles == max(float(a["cycles"]) for a in arrays.values()) == 200_000
    assert depth == max(float(a["bearing"].max() + a["journal"].max()) for a in arrays.values())
    assert surfaces_wear({}) == (0.0, 0.0)

    task = state_session(bench, state, 7, 20, False)
    assert task.kwargs["clearance"] == 0.3e-3 and task.kwargs["files"] == dict(state.surfaces)
    moved = {j: shutil.copy(f, tmp_path / f"{j}.npz") for j, f in state.surfaces.items()}
    assert state_session(bench, dataclasses.replace(state, surfaces=moved), 7, 20, False).key == task.key
    edited = tmp_path / "edited.npz"
    data = bytearray(next(iter(state.surfaces.values())).read_bytes())
    data[-1] ^= 1
    edited.write_bytes(data)
    other = dict(state.surfaces, **{next(iter(state.surfaces)): edited})
    assert state_session(bench, dataclasses.replace(state, surfaces=other), 7, 20, False).key != task.key
    assert state_session(bench, state, 8, 20, False).key != task.key
    bare = state_session(bench, dataclasses.replace(state, clearances={}), 7, 20, False)  # the bench's own clearance
    assert bare.kwargs["clearance"] == max(j.clearance.radial_clearance for j in bench.clearance_joints)
