"""The accelerometer's physics comes from the model: steady-state tables per speed and true state."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from wearbench.hardware.emulators.config import EmulatorConfig, Truth
from wearbench.hardware.emulators.device import AccelBlock, BenchDevice, ManualClock
from wearbench.hardware.emulators.signal import model_table

pytestmark = pytest.mark.slow
W = 2 * math.pi


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("WEARBENCH_CACHE", str(tmp_path / "cache"))


def test_model_table_is_the_theory_revolution_looped(testbed, tmp_path):
    """The twin plays the third revolution of the model started as the model starts, sample for
    sample: what `simulate` itself gives (the theory of a twin experiment)."""
    from wearbench.model import build_scene, simulate

    table = model_table(testbed, Truth(), W)
    assert "model" in table.source and table.acc.size >= 20000 * 0.9
    # slider velocity is periodic: the acceleration integrates to zero over one revolution
    assert abs(table.acc.mean()) < 1e-2 * np.abs(table.acc).max()
    theory = simulate(build_scene(testbed.with_speed(W)), revolutions=3, speed=W, output_rate=20000.0).table
    t, acc = theory["t"].to_numpy(), theory["slider_acc"].to_numpy()
    third = (t >= 2.0 - 1e-9) & (t < 3.0 - 1e-9)
    np.testing.assert_allclose(table.at(W * t[third]), acc[third], rtol=0, atol=1e-9 * np.abs(acc).max())
    t0 = time.perf_counter()
    again = model_table(testbed, Truth(), W)  # from the disk cache
    assert time.perf_counter() - t0 < 0.5
    np.testing.assert_array_equal(again.acc, table.acc)
    assert list((tmp_path / "cache" / "emulator").glob("*.npz"))


def test_truth_clearances_replace_what_the_bench_claims(testbed):
    # the device's table with a hidden 0.5 mm equals the model of a bench that states 0.5 mm ...
    hidden = model_table(testbed, Truth(clearances={"A": 0.5e-3, "B": 0.5e-3}), W)
    stated = model_table(testbed.with_clearances({"A": 0.5e-3, "B": 0.5e-3}), Truth(), W)
    np.testing.assert_allclose(hidden.acc, stated.acc, rtol=1e-9, atol=1e-9 * np.abs(stated.acc).max())
    # ... and differs from what the test bed claims (0.3 mm)
    claimed = model_table(testbed, Truth(), W)
    assert np.sqrt(np.mean((hidden.acc - claimed.acc) ** 2)) > 1e-3 * np.abs(claimed.acc).max()


def test_device_streams_the_model_signal_at_the_commanded_speed(testbed):
    cfg = EmulatorConfig.from_table({"signal": "model", "accelerometer": {"adc_bits": 0}}, bench=testbed)
    clock = ManualClock()
    d = BenchDevice(testbed, cfg, clock)
    d.configure_accelerometer(2000.0, 20000.0)
    d.enable()
    d.set_speed(W)
    clock.advance(1.0)
    d.start_stream()
    clock.advance(1.0)
    x = np.concatenate([b.samples for b in d.read() if isinstance(b, AccelBlock)])
    table = d.prepare(W)
    ramp = W / testbed.motor.max_acceleration
    t = 1.0 + np.arange(x.size) / 20000.0
    np.testing.assert_allclose(x, table.at(W * t - W * ramp / 2, W), rtol=1e-5, atol=1e-4)
    assert "model" in d.signal_description


def test_truth_wear_surfaces_enter_the_signal(testbed, tmp_path):
    from wearbench.model.surfaces import JointSurfaces

    n = 360
    phi = (np.arange(n) + 0.5) * 2 * np.pi / n
    worn = JointSurfaces(bearing=40e-6 * np.maximum(0, np.cos(phi)) ** 4, journal=np.zeros(n), label="first wear")
    path = worn.save(tmp_path / "A-worn.npz")
    cfg = EmulatorConfig.from_table({"truth": {"wear": {"A": str(path)}, "wear_stage": "first wear"}}, bench=testbed)
    assert cfg.truth.wear["A"] == path and cfg.truth.wear_stage == "first wear"
    table = model_table(testbed, cfg.truth, W)
    clean = model_table(testbed, Truth(), W)
    assert np.sqrt(np.mean((table.acc - clean.acc) ** 2)) > 1e-3 * np.abs(clean.acc).max()


def test_cached_table_follows_the_content_of_a_rewritten_surface_file(testbed, tmp_path):
    """The disk cache is keyed on what a surface file holds, not its name: re-wearing a joint into
    the same file must not replay the old table."""
    from wearbench.model.surfaces import JointSurfaces

    n = 360
    phi = (np.arange(n) + 0.5) * 2 * np.pi / n
    path = tmp_path / "A.npz"
    JointSurfaces(bearing=np.zeros(n), journal=np.zeros(n), label="new").save(path)
    first = model_table(testbed, Truth(wear={"A": path}), W)
    JointSurfaces(bearing=60e-6 * np.maximum(0, np.cos(phi)) ** 4, journal=np.zeros(n), label="worn").save(path)
    second = model_table(testbed, Truth(wear={"A": path}), W)
    assert len(list((tmp_path / "cache" / "emulator").glob("*.npz"))) == 2
    assert np.sqrt(np.mean((first.acc - second.acc) ** 2)) > 1e-3 * np.abs(first.acc).max()
