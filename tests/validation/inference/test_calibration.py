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
