"""The accelerometer's cross-axis part: the lateral force on the slider from the model's pin reactions
(checked against Newton's law along the guide), the carriage's lateral mode against its analytic
steady-state response, the axial path untouched, the drawn spread and the config's errors."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from wearbench.bench.schema import BenchError
from wearbench.hardware.emulators.carriage import carriage, lateral_force
from wearbench.hardware.emulators.config import Accelerometer, EmulatorConfig, emulator_config
from wearbench.hardware.emulators.sensor import SensorChain

FS = 50000.0  # no anti-alias filter: the chain runs at the sample rate, the bilinear warp stays below 0.2 %


def chain(**kw) -> SensorChain:
    return SensorChain(Accelerometer(**{"adc_bits": 0, "clipping": False, **kw}), FS, 1e6, np.random.default_rng(0))


def phasor(y: np.ndarray, f: float) -> complex:
    """Complex amplitude of the sinusoid at ``f`` in ``y`` (second half, transient gone): y = Re(c e^{jwt})."""
    n = y.size // 2
    t = np.arange(n, y.size) / FS
    basis = np.column_stack([np.cos(2 * np.pi * f * t), -np.sin(2 * np.pi * f * t)])
    re, im = np.linalg.lstsq(basis, y[n:], rcond=None)[0]
    return complex(re, im)


@pytest.mark.parametrize("ratio", [0.5, 1.0, 2.0])
def test_cross_axis_output_is_the_sensitivity_times_the_lateral_mode_response(ratio):
    """A lateral force over mass a_f = sin(w t) on a carriage mode (f0 = 1 kHz, zeta 0.05) gives
    a_lat = H(jw) a_f with H = -w^2 / (w0^2 - w^2 + 2j zeta w0 w) (m x'' + c x' + k x = f); the output
    is cross_axis x sensitivity x a_lat, amplitude and phase, with no axial signal."""
    f0, zeta, cross, gain = 1000.0, 0.05, -0.03, 1.02
    c = chain(cross_axis=cross, lateral_mode=f0, lateral_damping=zeta, sensitivity=gain)
    f = ratio * f0
    t = np.arange(round(0.4 * FS)) / FS
    y = c.process(np.zeros_like(t), np.sin(2 * np.pi * f * t)).astype(float)
    w, w0 = 2 * np.pi * f, 2 * np.pi * f0
    h = -w * w / (w0 * w0 - w * w + 2j * zeta * w0 * w)
    expected = cross * gain * h * -1j  # sin(wt) = Re(-j e^{jwt})
    got = phasor(y, f)
    assert abs(got) == pytest.approx(abs(expected), rel=0.01)
    assert abs(np.angle(got / expected)) < 0.02
    if ratio == 1.0:
        assert abs(got) == pytest.approx(abs(cross) * gain / (2 * zeta), rel=0.01)  # Q = 1/(2 zeta) at the mode


def test_the_axial_path_is_unchanged_by_the_cross_axis_part():
    """With cross-axis on, the axial signal takes the same mount resonance and DAQ filter as the chain
    without it (a zero lateral force adds nothing); with cross-axis 0 the lateral force is ignored."""
    rng = np.random.default_rng(5)
    axial = {"resonance": 1500.0, "damping": 0.04, "aa_filter": "butterworth", "aa_cutoff": 0.05}
    x = rng.normal(0.0, 10.0, 20000) + 3.0
    plain = chain(**axial).process(x).astype(float)
    on = chain(**axial, cross_axis=0.05, lateral_mode=700.0)
    assert on.lateral and on.oversample == chain(**axial).oversample
    np.testing.assert_allclose(on.process(x, np.zeros_like(x)).astype(float), plain, rtol=1e-5, atol=1e-4)
    off = chain(**axial, cross_axis=0.0, lateral_mode=700.0)
    assert not off.lateral
    np.testing.assert_array_equal(off.process(x, rng.normal(0.0, 50.0, x.size)), chain(**axial).process(x))
    with pytest.raises(ValueError, match="lateral force"):
        chain(**axial, cross_axis=0.05, lateral_mode=700.0).process(x)


def test_lateral_force_obeys_newtons_law_along_the_guide(testbed):
    """The pin reactions the model writes to its table give the force on the slider: along the guide
    (the ideal guide pushes only sideways) it is mass x the slider's acceleration, to round-off. Read
    with the sensor turned by -90 deg, the 'lateral' direction is the guide, so lateral_force must
    reproduce the slider's acceleration; the lateral part itself is of the same size (the rod's angle)."""
    from wearbench.model.realisation import simulate_state

    run = simulate_state(testbed, testbed.states[1], 7, revolutions=0.6, settle=0.2, output_rate=20000.0)
    bench = run.realisation.bench
    assert carriage(bench) == (math.pi, (("E", 1.0),))  # guide at 90 deg, sensor along it: lateral = -x
    turned = dataclasses.replace(bench, sensors=tuple(
        dataclasses.replace(s, axis=s.axis - 0.5 * math.pi) if s.kind == "accelerometer" else s for s in bench.sensors))
    along = lateral_force(turned, run.table)
    np.testing.assert_allclose(along, run.acc, rtol=0, atol=1e-9 * np.abs(run.acc).max())
    lateral = lateral_force(bench, run.table)
    assert 0.3 < np.sqrt(np.mean(lateral**2)) / np.sqrt(np.mean(run.acc**2)) < 3.0


def test_a_spread_draws_cross_axis_per_seed_and_keeps_the_axial_path(testbed):
    """The default spread draws |cross-axis| in 1-5 % at an angle (both signs), a lateral mode in
    0.3-3 kHz and its damping; a seed's axial path is the same with cross-axis off ([0, 0]); the
    bench file's default (stud mount) keeps cross-axis off; the config round-trips."""
    paths = [emulator_config(testbed, "0.3 mm new", seed, accelerometer={"spread": {}}).accelerometer
             for seed in range(60)]
    cross = np.array([a.cross_axis for a in paths])
    assert np.all(np.abs(cross) <= 0.05) and (cross > 0).sum() > 15 and (cross < 0).sum() > 15
    assert all(300 <= a.lateral_mode <= 3000 and 0.02 <= a.lateral_damping <= 0.1 and a.lateral for a in paths)
    axial = [emulator_config(testbed, "0.3 mm new", seed, accelerometer={"spread": {"cross_axis": [0, 0]}}
                             ).accelerometer for seed in range(60)]
    assert all(not a.lateral for a in axial)
    assert [(a.resonance, a.damping, a.sensitivity) for a in axial] == [
        (a.resonance, a.damping, a.sensitivity) for a in paths]
    cfg = emulator_config(testbed, "0.6 mm new", 11, accelerometer={"spread": {"cross_axis": [0.02, 0.02]}})
    assert abs(cfg.accelerometer.cross_axis) <= 0.02
    assert EmulatorConfig.from_table(cfg.to_table(), bench=testbed) == cfg
    assert not EmulatorConfig.from_bench(testbed).accelerometer.lateral


@pytest.mark.parametrize("table, key, expected", [
    ({"cross_axis": 0.3, "lateral_mode": "1 kHz"}, "emulator.accelerometer.cross_axis", "[-0.2, 0.2]"),
    ({"cross_axis": 0.03}, "emulator.accelerometer.cross_axis", "without a lateral_mode"),
    ({"cross_axis": "3 %", "lateral_mode": "1 kHz"}, "emulator.accelerometer.cross_axis", "plain number"),
    ({"cross_axis": 0.03, "lateral_mode": "1 kg"}, "emulator.accelerometer.lateral_mode", "Hz"),
    ({"cross_axis": 0.03, "lateral_mode": "1 kHz", "lateral_damping": 0}, "emulator.accelerometer.lateral_damping",
     "(0.0, 2.0]"),
    ({"spread": {"cross_axis": [0.05, 0.01]}}, "emulator.accelerometer.spread.cross_axis", "low <= high"),
    ({"spread": {"cross_axis": 0.03}}, "emulator.accelerometer.spread.cross_axis", "[low, high]"),
    ({"spread": {"lateral_mode": ["3 kHz", "0 Hz"]}}, "emulator.accelerometer.spread.lateral_mode", "positive"),
    ({"spread": {"lateral_damping": [0.02, 3]}}, "emulator.accelerometer.spread.lateral_damping", "2.0]"),
])
def test_cross_axis_errors_name_file_key_value(testbed, table, key, expected):
    with pytest.raises(BenchError) as e:
        EmulatorConfig.from_table({"truth": {"seed": 3}, "accelerometer": table}, bench=testbed)
    assert e.value.key == key and "ninebar-testbed.toml" in str(e.value)
    assert expected in str(e.value), str(e.value)


def test_cross_axis_on_a_bench_without_a_carriage_is_refused():
    """The slider-crank's rod-slider pin has clearance: its lateral force is not in the table's pin
    reactions, so a cross-axis sensor is refused with the reason, not played as zero."""
    from wearbench.bench.load import load_bench, shipped_bench

    bench = load_bench(shipped_bench("slider-crank"))
    assert carriage(bench) is None
    with pytest.raises(BenchError) as e:
        EmulatorConfig.from_table({"accelerometer": {"cross_axis": 0.02, "lateral_mode": "1 kHz"}}, bench=bench)
    assert e.value.key == "emulator.accelerometer.cross_axis" and "prismatic guide" in str(e.value)
    with pytest.raises(BenchError) as e:
        EmulatorConfig.from_table({"truth": {"seed": 2}, "accelerometer": {"spread": {}}}, bench=bench)
    assert e.value.key == "emulator.accelerometer.spread.cross_axis"
    assert not EmulatorConfig.from_table({"truth": {"seed": 2}, "accelerometer": {"spread": {"cross_axis": [0, 0]}}},
                                         bench=bench).accelerometer.lateral


def _record(testbed, accelerometer: dict, seconds: float, fs: float) -> np.ndarray:
    from wearbench.hardware.emulators.device import AccelBlock, BenchDevice, ManualClock

    raw = {"adc_bits": 0, "clipping": False, "noise": "0 m/s^2", "bias": "0 m/s^2", **accelerometer}
    cfg = EmulatorConfig.from_table({"signal": "model", "truth": {"twin": True}, "accelerometer": raw}, bench=testbed)
    clock = ManualClock()
    d = BenchDevice(testbed, cfg, clock)
    d.configure_accelerometer(1e4, fs)
    d.enable()
    d.set_speed(2 * math.pi)
    clock.advance(0.5)  # at speed (200 rad/s^2: 31 ms) before the stream starts
    d.read()
    d.start_stream()
    blocks = []
    for _ in range(round(seconds / 0.1)):
        clock.advance(0.1)
        blocks += [b.samples for b in d.read() if isinstance(b, AccelBlock)]
    return np.concatenate(blocks).astype(float)


@pytest.mark.slow
def test_the_device_plays_the_tables_lateral_force_through_the_lateral_mode(testbed, tmp_path, monkeypatch):
    """The twin at 1 rev/s, sampled at 20 kHz: per revolution, the cross-axis part of the output
    (cross-axis on minus off) over the axial output is, harmonic by harmonic, cross x H(jw) x L/A,
    with L and A the lateral force and the acceleration of the model table (the unknown start angle
    cancels in the ratio) and H the lateral mode's analytic response."""
    from wearbench.hardware.emulators.config import Truth
    from wearbench.hardware.emulators.device import table_speed
    from wearbench.hardware.emulators.signal import model_table

    monkeypatch.setenv("WEARBENCH_CACHE", str(tmp_path / "cache"))
    fs, f0, zeta, cross = 20000.0, 150.0, 0.1, 0.04
    lateral = {"cross_axis": cross, "lateral_mode": f"{f0} Hz", "lateral_damping": zeta}
    off = _record(testbed, {}, 3.0, fs)
    on = _record(testbed, lateral, 3.0, fs)
    n = round(fs)  # one revolution
    y_off, y_diff = np.fft.rfft(off[-n:]), np.fft.rfft(on[-n:] - off[-n:])
    table = model_table(testbed, Truth(), table_speed(2 * math.pi), rate=2 * fs)  # the table the device plays
    a_tab, l_tab = np.fft.rfft(table.acc[::2]), np.fft.rfft(table.lateral[::2])
    k = np.arange(1, 400)
    k = k[np.abs(l_tab[k]) > 1e-3 * np.abs(l_tab[1:400]).max()]
    k = k[np.abs(a_tab[k]) > 1e-3 * np.abs(a_tab[1:400]).max()]
    w, w0 = 2 * np.pi * k, 2 * np.pi * f0
    h = -w * w / (w0 * w0 - w * w + 2j * zeta * w0 * w)
    predicted = cross * h * l_tab[k] / a_tab[k]
    measured = y_diff[k] / y_off[k]
    assert k.size > 100
    err = np.abs(measured - predicted) / np.abs(predicted)
    # measured: median 0.08 %, 90 % below 0.33 % (the largest, 10 %, where both spectra are near a zero)
    assert np.median(err) < 0.003 and np.quantile(err, 0.9) < 0.01, (np.median(err), np.quantile(err, 0.9))
