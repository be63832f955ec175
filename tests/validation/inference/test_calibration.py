"""The calibration store: keyed on bench physics, the accelerometer's recorded calibration and the
mount; a stored calibration is never replaced unless asked; fit_calibration recovers a known gain."""

import numpy as np
import pytest
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.validation.inference.calibration import (
    calibration_key,
    find_calibration,
    fit_calibration,
    load_calibration,
    save_calibration,
)
from wearbench.validation.inference.ensemble import Ensemble, EnsembleSettings
from wearbench.validation.inference.identify import IdentifyOptions, fit_states
from wearbench.validation.measurement.features import CycleFeatures, FeatureSpec

pytestmark = pytest.mark.no_kernels

SPEC = FeatureSpec()
P = SPEC.size
META = {"calibration": {"accelerometer.name": "slider_acc", "accelerometer.sensitivity": "0.00102",
                        "accelerometer.range": "4903.3", "accelerometer.axis": "0.0"}}


def draw(rng, mean, realisations, cycles):
    return mean + rng.normal(0, 0.2, (realisations, 1, P)) + rng.normal(0, 0.5, (realisations, cycles, P))


@pytest.fixture(scope="module")
def exact_models():
    rng = np.random.default_rng(0)
    ens = {s: Ensemble(s, EnsembleSettings(realisations=24, cycles=8), draw(rng, m, 24, 8), np.zeros((24, 8, 4)),
                       np.zeros((24, 8)), 2 * np.pi)
           for s, m in (("new", np.zeros(P)), ("worn", rng.normal(0, 0.2, P)))}
    return fit_states(ens, IdentifyOptions(sensor_path="none"))


def test_key_follows_bench_sensor_mount_and_features():
    bench = load_bench(shipped_bench("ninebar-testbed"))
    base = calibration_key(bench, META, SPEC)
    other_sensor = {"calibration": {**META["calibration"], "accelerometer.sensitivity": "0.001"}}
    assert calibration_key(bench, other_sensor, SPEC) != base
    assert calibration_key(bench, META, SPEC, "carriage 2") != base
    assert calibration_key(bench, META, FeatureSpec(bins=36)) != base
    assert calibration_key(bench.with_clearances({"A": 0.4e-3}), META, SPEC) != base
    assert calibration_key(bench, {"calibration": dict(META["calibration"]), "session": {"operator": "x"}},
                           SPEC) == base


def test_fit_recovers_a_band_gain_and_the_store_keeps_it(exact_models, tmp_path):
    rng = np.random.default_rng(1)
    x = draw(rng, np.zeros(P), 1, 20)[0]
    x[:, 2 * SPEC.bins:3 * SPEC.bins] += 0.6  # +6 dB in 150-400 Hz
    cal = fit_calibration([CycleFeatures(SPEC, x, np.zeros(20))], exact_models, "new", key="k" * 64,
                          bench="b", labels=["s1"])
    assert cal.path.gains_db()["band 2"] == pytest.approx(6.0, abs=1.5) and cal.p_value > 0.01
    assert "calibration kkkkkkkkkkkk" in cal.path.source
    path = save_calibration(cal, tmp_path)
    assert load_calibration(path) == cal and find_calibration("k" * 64, tmp_path) == cal
    assert find_calibration("j" * 64, tmp_path) is None
    before = path.read_bytes()
    with pytest.raises(FileExistsError, match="--force") as refused:
        save_calibration(cal, tmp_path)
    assert "it holds" in str(refused.value) and path.read_bytes() == before
    save_calibration(cal, tmp_path, force=True)
    assert load_calibration(path) == cal and sorted(p.name for p in tmp_path.iterdir()) == [path.name]
    with pytest.raises(ValueError, match="state 'nominal'"):
        fit_calibration([CycleFeatures(SPEC, x, np.zeros(20))], exact_models, "nominal", key="k", bench="b",
                        labels=["s1"])
    (tmp_path / "bad.json").write_text("{}")
    with pytest.raises(ValueError, match="not a calibration"):
        load_calibration(tmp_path / "bad.json")


def test_a_sessions_key_is_what_it_was_before_the_range_was_recorded_once(tmp_path):
    """Sessions recorded before issue 47's item 7 wrote the bench file's range as ``accelerometer.range``
    too; sessions now record the range once (the stream's ``acceleration.range``). A session recorded
    now of the same bench and sensor finds the calibrations keyed on the older ones."""
    import math
    from pathlib import Path

    from wearbench.acquisition.backends import open_rig
    from wearbench.acquisition.recorder import Recorder
    from wearbench.acquisition.session import SessionPlan
    from wearbench.validation.inference.calibration import sensor_record
    from wearbench.validation.measurement.session import load_session

    before = load_session(Path(__file__).parents[2] / "acquisition" / "data" / "session_layout2_before.mcap")
    assert "accelerometer.range" in before.metadata["calibration"]
    rig = open_rig(before.bench, "sim", {"speedup": math.inf, "config": {"signal": "harmonic", "cache": False}})
    try:
        assert Recorder(rig, before.bench, SessionPlan(speed=62.0, cycles=2), tmp_path / "now.mcap").run().completed
    finally:
        rig.close()
    now = load_session(tmp_path / "now.mcap")
    assert "accelerometer.range" not in now.metadata["calibration"]
    assert sensor_record(now.metadata, now.bench) == sensor_record(before.metadata, before.bench)
    assert calibration_key(now.bench, now.metadata, SPEC) == calibration_key(before.bench, before.metadata, SPEC)
