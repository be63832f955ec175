"""Theory ensembles: content keys, the shipped precomputed ensembles, save/load, a small real build."""

from dataclasses import replace

import numpy as np
import pytest
from wearbench.bench.content import bench_key
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.compute.options import SERIAL
from wearbench.validation.inference.artefacts import shipped_path
from wearbench.validation.inference.ensemble import (
    EnsembleSettings,
    build_ensembles,
    ensembles_key,
    load_ensembles,
    save_ensembles,
)

BENCH = load_bench(shipped_bench("ninebar-testbed"))


def test_bench_key_follows_physics_not_names_or_paths():
    key = bench_key(BENCH)
    assert bench_key(replace(BENCH, name="other", description="x", source="# moved", path=None, sha256="")) == key
    ranged = replace(BENCH, sensors=tuple(replace(s, range=2 * s.range) if s.range else s for s in BENCH.sensors))
    assert bench_key(ranged) == key  # what a sensor records is not the motion
    heavier = replace(BENCH, bodies=(replace(BENCH.bodies[0], mass=BENCH.bodies[0].mass * 1.01),) + BENCH.bodies[1:])
    assert bench_key(heavier) != key
    assert bench_key(BENCH.with_clearances({"A": 0.4e-3})) != key


def test_settings_are_validated():
    with pytest.raises(ValueError, match="at least 3 realisations"):
        EnsembleSettings(realisations=2)
    with pytest.raises(ValueError, match="filter"):
        EnsembleSettings(curve_filter="cfc999")
    with pytest.raises(ValueError, match="sensor paths up to 3000 Hz need an output rate"):
        EnsembleSettings(output_rate=5000.0)
    assert EnsembleSettings(output_rate=5000.0, sensor_paths=None).sensor_paths is None


def test_a_small_ensemble_builds_on_the_compute_layer_and_round_trips(tmp_path, monkeypatch):
    monkeypatch.setenv("WEARBENCH_CACHE", str(tmp_path / "cache"))
    settings = EnsembleSettings(realisations=3, cycles=2, settle=0.5, output_rate=10_000.0)
    state = BENCH.states[0]
    ens = build_ensembles(BENCH, [state], settings=settings, compute=SERIAL)[state.name]
    assert ens.features.shape == (3, 2, settings.features.size) and ens.curves.shape == (3, 2, 720)
    assert not ens.failures and np.all(np.isfinite(ens.features))
    assert len({tuple(np.round(f[0, :5], 6)) for f in ens.features}) == 3  # every realisation differs
    lo, med, hi = ens.band()
    assert np.all(lo <= med) and np.all(med <= hi) and np.ptp(med) > 10.0  # the kinematics is in the band
    key = ensembles_key(BENCH, [state], BENCH.speed, settings)
    path = save_ensembles({state.name: ens}, tmp_path / "e.npz", key=key, bench=BENCH, states=[state])
    back = load_ensembles(path, key=key)[state.name]
    np.testing.assert_array_equal(back.features, ens.features)
    np.testing.assert_allclose(back.curves, ens.curves, rtol=1e-6)
    assert back.settings == settings and load_ensembles(path, key="stale") is None
    # a rerun is served from the cache: the same arrays, no simulation
    again = build_ensembles(BENCH, [state], settings=settings, compute=SERIAL)[state.name]
    np.testing.assert_array_equal(again.features, ens.features)
    # an ensemble of another size and first seed shares the realisations of the seeds they have in
    # common (seeds 1-3 here): only seed 0 is simulated
    from wearbench.validation.inference import ensemble as module

    ran = []
    real = module.realisation_summary
    monkeypatch.setattr(module, "realisation_summary", lambda *a, **k: ran.append(k["seed"]) or real(*a, **k))
    # realisation_keys names the cache entries the build reads: only seed 0's is missing
    from wearbench.compute.task_cache import MISSING, cache_load

    keys = module.realisation_keys(BENCH, [state], BENCH.speed, replace(settings, realisations=4, seed=0))
    assert [cache_load(k) is MISSING for k in keys] == [True, False, False, False]
    wider = build_ensembles(BENCH, [state], settings=replace(settings, realisations=4, seed=0), compute=SERIAL)[state.name]
    assert ran == [0]
    np.testing.assert_array_equal(wider.features[1:], ens.features)


def test_the_shipped_ensembles_are_current():
    """The demo's precomputed ensembles must match the code: regenerate them when this fails
    (`wearbench ensemble ninebar-testbed --ship --force`)."""
    path = shipped_path("ensembles", BENCH.name)
    assert path.exists(), path
    key = ensembles_key(BENCH, BENCH.states, BENCH.speed, EnsembleSettings())
    assert load_ensembles(path, key=key) is not None, "stale: the model, bench or settings changed since"
