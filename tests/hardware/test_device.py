"""BenchDevice: motor and encoder kinematics, every accelerometer imperfection measured, faults."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal as sps
from wearbench.bench.schema import BenchError
from wearbench.hardware.emulators.config import EmulatorConfig
from wearbench.hardware.emulators.device import (
    AccelBlock,
    BenchDevice,
    DeviceError,
    EncoderBlock,
    ManualClock,
)
from wearbench.hardware.emulators.signal import harmonic_table
from wearbench.hardware.protocol.messages import ErrorCode, FaultCode

pytestmark = pytest.mark.no_kernels

W = 2 * math.pi  # rad/s: the test bed's crank speed


def run(device: BenchDevice, clock: ManualClock, seconds: float, step: float = 0.05):
    blocks = []
    for _ in range(round(seconds / step)):
        clock.advance(step)
        blocks += device.read()
    acc = [b for b in blocks if isinstance(b, AccelBlock)]
    enc = [b for b in blocks if isinstance(b, EncoderBlock)]
    return acc, enc


def spinning(bench, config, speed=W, rate=20000.0, range_=490.0, settle=0.5):
    clock = ManualClock()
    d = BenchDevice(bench, config, clock)
    d.configure_accelerometer(range_, rate)
    d.enable()
    d.set_speed(speed)
    clock.advance(settle)
    d.start_stream()
    return d, clock


def samples(acc):
    return np.concatenate([b.samples for b in acc]).astype(np.float64)


def test_encoder_counts_and_index_follow_the_commanded_speed(testbed, make_config):
    d, clock = spinning(testbed, make_config(encoder={"index_angle": "30 deg"}), speed=3.0)
    _, enc = run(d, clock, 5.0)
    counts = np.concatenate([b.counts for b in enc])
    index = np.concatenate([b.index for b in enc])
    t = np.concatenate([b.times for b in enc])
    cpr = testbed.sensor("encoder").counts_per_rev
    slope = np.polyfit(t, counts, 1)[0]
    assert slope == pytest.approx(3.0 * cpr / (2 * math.pi), rel=1e-6)
    assert np.all(np.abs(counts - np.polyval(np.polyfit(t, counts, 1), t)) <= 1)
    # one index pulse per crank revolution, at crank angle 30 deg (+ the driver's phase origin)
    ti = t[index]
    assert np.diff(ti) == pytest.approx(2 * math.pi / 3.0, abs=2e-3)
    phase = testbed.drivers[0].phase
    angle_at_index = phase + counts[index] * 2 * math.pi / cpr
    # flagged at the first encoder sample after the crossing: late by at most one sample's travel
    late = np.mod(angle_at_index - math.radians(30) + 0.01, 2 * math.pi) - 0.01
    assert np.all((late > -2 * math.pi / cpr) & (late < 3.0 / 1000 + 2 * math.pi / cpr))
    st = d.motor_status()
    k = (lambda a: math.floor((a - math.radians(30)) / (2 * math.pi)))
    assert st.index_count == k(st.angle) - k(phase)
    assert st.speed == pytest.approx(3.0) and st.enabled and st.fault is None


def test_index_pulse_can_be_switched_off(testbed, make_config):
    d, clock = spinning(testbed, make_config(encoder={"index": False}))
    _, enc = run(d, clock, 2.0)
    assert not any(b.index.any() for b in enc) and d.motor_status().index_count == 0


def test_acceleration_limit_shapes_the_ramp(testbed, make_config):
    clock = ManualClock()
    d = BenchDevice(testbed, make_config(), clock)
    d.enable()
    d.set_speed(20.0, acceleration=50.0)
    clock.advance(0.2)
    assert d.motor_status().speed == pytest.approx(10.0)
    clock.advance(0.3)
    assert d.motor_status().speed == pytest.approx(20.0)
    assert d.motor_status().angle - testbed.drivers[0].phase == pytest.approx(0.5 * 50 * 0.4**2 + 20 * 0.1)


def test_speed_ripple_is_measurable(testbed, make_config):
    d, clock = spinning(testbed, make_config(motor={"ripple": 0.02, "ripple_harmonic": 3}))
    speeds = []
    for _ in range(400):
        clock.advance(0.0025)
        speeds.append(d.motor_status().speed)
    speeds = np.array(speeds)
    assert (speeds.max() - speeds.min()) / 2 == pytest.approx(0.02 * W, rel=0.02)
    assert speeds.mean() == pytest.approx(W, rel=1e-3)


def test_noise_and_bias(testbed, make_config):
    d, clock = spinning(testbed, make_config(accelerometer={"noise": "0.5 m/s^2", "bias": "1.5 m/s^2"}))
    x = samples(run(d, clock, 2.0)[0])
    assert x.mean() == pytest.approx(1.5, abs=0.01)
    assert x.std() == pytest.approx(0.5, rel=0.02)


def test_clipping_at_the_range(testbed, make_config):
    d, clock = spinning(testbed, make_config(accelerometer={"bias": "600 m/s^2", "noise": "20 m/s^2"}),
                        range_=490.0)
    x = samples(run(d, clock, 0.5)[0])
    assert x.max() == pytest.approx(490.0 * 32767 / 32768, rel=1e-6)
    assert (x == x.max()).mean() > 0.99
    d2, clock2 = spinning(testbed, make_config(accelerometer={"bias": "600 m/s^2", "clipping": False, "adc_bits": 0}))
    assert samples(run(d2, clock2, 0.1)[0]).min() > 490.0


@pytest.mark.parametrize("bits", [12, 16])
def test_adc_quantisation_step(testbed, make_config, bits):
    d, clock = spinning(testbed, make_config(accelerometer={"noise": "3 m/s^2", "adc_bits": bits}), range_=100.0)
    x = samples(run(d, clock, 0.5)[0])
    step = 100.0 / 2 ** (bits - 1)
    levels = np.unique(x)
    assert np.min(np.diff(levels)) == pytest.approx(step, rel=1e-5)
    np.testing.assert_allclose(levels / step, np.rint(levels / step), atol=1e-3)
    d0, clock0 = spinning(testbed, make_config(accelerometer={"noise": "3 m/s^2", "adc_bits": 0}), range_=100.0)
    assert np.min(np.diff(np.unique(samples(run(d0, clock0, 0.5)[0])))) < step / 100


def test_sample_clock_drift_ppm(testbed, make_config):
    cfg = make_config(accelerometer={"drift": "250 ppm"}, accel_block=100)
    d, clock = spinning(testbed, cfg, rate=10000.0)
    acc, _enc = run(d, clock, 40.0, step=0.5)
    n = sum(len(b.samples) for b in acc)
    # samples taken in 40 s of device time, stamped at the nominal rate
    assert n / 40.0 / 10000.0 - 1 == pytest.approx(250e-6, abs=3e-6)
    assert acc[-1].times[-1] == pytest.approx((n - 1) / 10000.0 + acc[0].time)


def test_mounting_resonance_peak(testbed, make_config):
    cfg = make_config(signal="white", accelerometer={"resonance": "1.2 kHz", "damping": 0.05, "adc_bits": 0})
    d, clock = spinning(testbed, cfg, rate=20000.0)
    x = samples(run(d, clock, 4.0)[0])
    f, p = sps.welch(x, fs=20000.0, nperseg=2048)
    band = f[p > p.max() / 2]  # half-power band of a lightly damped resonance: fn +/- zeta fn
    assert (band.min() + band.max()) / 2 == pytest.approx(1200, rel=0.02)
    assert band.max() - band.min() == pytest.approx(2 * 0.05 * 1200, rel=0.3)
    gain = p.max() / np.median(p[(f > 20) & (f < 200)])
    assert gain == pytest.approx(1 / (2 * 0.05) ** 2, rel=0.35)  # Q^2 = 100 in power


def test_signal_follows_the_crank_angle_and_truth_delay(testbed, make_config):
    # steady speed, harmonic table: sample k equals the table at the motor angle of t_k - delay
    plain = make_config(signal="harmonic", accelerometer={"adc_bits": 0})
    late = make_config(signal="harmonic", accelerometer={"adc_bits": 0}, truth={"accel_delay": "5 ms"})
    a = samples(run(*spinning(testbed, plain), 1.0)[0])
    b = samples(run(*spinning(testbed, late), 1.0)[0])
    np.testing.assert_allclose(b[100:], a[:-100], atol=1e-3)
    t = 0.5 + np.arange(a.size) / 20000.0
    ramp = W / testbed.motor.max_acceleration  # s to reach W from rest
    expected = harmonic_table(W).at(W * t - W * ramp / 2)
    np.testing.assert_allclose(a, expected, atol=2e-3 * np.abs(expected).max())


def test_dropped_blocks_leave_sequence_gaps(testbed, make_config):
    d, clock = spinning(testbed, make_config(faults={"drop_rate": 0.1}, accel_block=20))
    acc, _enc = run(d, clock, 5.0)
    seq = np.array([b.sequence for b in acc])
    lost = seq[-1] + 1 - seq.size
    assert np.all(np.diff(seq) >= 1)
    assert lost / (seq[-1] + 1) == pytest.approx(0.1, abs=0.02)


def test_stall_latches_a_fault(testbed, make_config):
    d, clock = spinning(testbed, make_config(faults={"stall_at": "1 s"}))
    run(d, clock, 0.9)
    assert d.motor_status().speed == pytest.approx(W)
    run(d, clock, 0.2)
    st = d.motor_status()
    assert st.fault == "stall" and st.speed == 0 and not st.enabled
    ev = d.events()
    assert [e.code for e in ev] == [FaultCode.STALL] and ev[0].time == pytest.approx(1.5)
    with pytest.raises(DeviceError) as err:
        d.enable()
    assert err.value.code == ErrorCode.FAULT_ACTIVE
    d.clear_fault()
    d.enable()
    d.set_speed(1.0)
    clock.advance(1.0)
    assert d.motor_status().speed == pytest.approx(1.0)


def test_lost_index_pulse_and_hung_firmware(testbed, make_config):
    """index_lost_at: the encoder's index flags stop at that stream time while its counts go on;
    freeze_at: from then on the device hands out no block and no event."""
    d, clock = spinning(testbed, make_config(faults={"index_lost_at": "2 s", "freeze_at": "4 s",
                                                     "stall_at": "4.5 s"}), speed=9.0)
    _, enc = run(d, clock, 3.9)
    t = np.concatenate([b.times for b in enc]) - 0.5  # stream time (the stream started at 0.5 s)
    index = np.concatenate([b.index for b in enc])
    counts = np.concatenate([b.counts for b in enc])
    assert index[t < 2.0].sum() >= 2 and index[t >= 2.0].sum() == 0  # 9 rad/s: a pulse every 0.7 s
    assert np.polyfit(t[t >= 2.0], counts[t >= 2.0], 1)[0] == pytest.approx(9.0 * 4000 / (2 * math.pi), rel=1e-3)
    assert not d.frozen
    acc, enc = run(d, clock, 1.0)
    assert d.frozen and max(b.time for b in acc + enc) < 4.5  # nothing stamped after the hang
    assert d.events() == []  # the stall at 4.5 s happened, but a hung device reports nothing


def test_overrun_when_the_host_stops_reading(testbed, make_config):
    d, clock = spinning(testbed, make_config(buffer="1 s"))
    clock.advance(10.0)
    acc = [b for b in d.read() if isinstance(b, AccelBlock)]
    assert sum(len(b.samples) for b in acc) <= 20000 + 200
    assert acc[0].sequence > 0
    assert any(e.code == FaultCode.OVERRUN for e in d.events())


def test_commands_are_refused_with_codes(testbed, make_config):
    clock = ManualClock()
    d = BenchDevice(testbed, make_config(), clock)
    with pytest.raises(DeviceError) as e:
        d.set_speed(1.0)
    assert e.value.code == ErrorCode.NOT_ENABLED
    d.enable()
    with pytest.raises(DeviceError) as e:
        d.set_speed(testbed.motor.max_speed * 1.01)
    assert e.value.code == ErrorCode.BAD_VALUE
    d.start_stream()
    with pytest.raises(DeviceError) as e:
        d.configure_accelerometer(100.0, 1000.0)
    assert e.value.code == ErrorCode.BUSY
    d.stop_stream()
    with pytest.raises(DeviceError):
        d.configure_accelerometer(100.0, 1e7)


def test_speed_profile(testbed, make_config):
    clock = ManualClock()
    d = BenchDevice(testbed, make_config(), clock)
    d.enable()
    d.set_profile([0.0, 1.0, 2.0], [2.0, 5.0, 0.0])
    clock.advance(0.9)
    assert d.motor_status().speed == pytest.approx(2.0)
    clock.advance(1.0)
    assert d.motor_status().speed == pytest.approx(5.0)
    clock.advance(1.0)
    assert d.motor_status().speed == 0


def test_config_errors_name_file_key_value(testbed):
    with pytest.raises(BenchError) as e:
        EmulatorConfig.from_table({"accelerometer": {"drift": "5000 ppm"}}, bench=testbed)
    assert "ninebar-testbed.toml" in str(e.value) and e.value.key == "emulator.accelerometer.drift"
    assert e.value.value == "5000 ppm"
    with pytest.raises(BenchError, match="unknown key"):
        EmulatorConfig.from_table({"faults": {"explode": 1}}, bench=testbed)
    with pytest.raises(BenchError, match="clearance joint"):
        EmulatorConfig.from_table({"truth": {"clearances": {"Q": "0.1 mm"}}}, bench=testbed)
    with pytest.raises(BenchError, match="bearing radius"):
        EmulatorConfig.from_table({"truth": {"clearances": {"A": "20 mm"}}}, bench=testbed)


def test_config_round_trips_through_its_table(testbed):
    cfg = EmulatorConfig.from_table({"signal": "harmonic", "accelerometer": {"noise": "0.1 m/s^2", "drift": "40 ppm"},
                                     "truth": {"clearances": {"A": "0.35 mm"}, "accel_delay": "1 ms"},
                                     "faults": {"stall_at": "3 s", "drop_rate": 0.01}}, bench=testbed)
    assert EmulatorConfig.from_table(cfg.to_table(), bench=testbed) == cfg
    assert EmulatorConfig.from_bench(testbed) == EmulatorConfig.from_table(testbed.emulator, bench=testbed)


def _pulses_before_stream(bench, speed, settle):
    """Index pulses (crank angle 0) between power-up and the stream start of :func:`spinning`."""
    phase, ramp = bench.drivers[0].phase, speed / bench.motor.max_acceleration
    angle = phase + speed * (settle - ramp / 2)
    return math.floor(angle / (2 * math.pi)) - math.floor(phase / (2 * math.pi))


def test_long_gaps_between_reads_keep_encoder_and_status_exact(testbed, make_config):
    # the host reads rarely (1.5 s, inside the 2 s buffer) while the speed changes in between
    d, clock = spinning(testbed, make_config(), speed=3.0)
    enc = []
    for speed in (5.0, -2.0, 4.0):
        clock.advance(1.5)
        enc += [b for b in d.read() if isinstance(b, EncoderBlock)]
        d.set_speed(speed)
    clock.advance(1.5)
    enc += [b for b in d.read() if isinstance(b, EncoderBlock)]
    counts = np.concatenate([b.counts for b in enc])
    assert [b.sequence for b in enc] == list(range(len(enc)))
    cpr = testbed.sensor("encoder").counts_per_rev
    # counts integrate the piecewise ramps exactly: compare with the status angle at the end
    st = d.motor_status()
    assert counts[-1] == pytest.approx((st.angle - testbed.drivers[0].phase) * cpr / (2 * math.pi), abs=1 + 4.0 * cpr / 1000 / (2 * math.pi))
    # every index pulse the encoder stream showed is counted, in both directions of rotation
    assert st.index_count == sum(int(b.index.sum()) for b in enc) + _pulses_before_stream(testbed, 3.0, 0.5)
    assert st.index_count > abs(math.floor(st.angle / (2 * math.pi)) - math.floor(testbed.drivers[0].phase / (2 * math.pi)))


def test_mounting_resonance_above_nyquist_rings_and_aliases(testbed, make_config):
    """A resonance above the sample rate's Nyquist frequency is modelled at an oversampled internal
    rate; without an anti-alias filter it folds to fs - fr, as on a DAQ without one."""
    cfg = make_config(signal="white", accelerometer={"resonance": "4 kHz", "damping": 0.03, "adc_bits": 0})
    d = BenchDevice(testbed, cfg, ManualClock())
    d.configure_accelerometer(1000.0, 5000.0)
    d.start_stream()
    d.clock.advance(4.0)
    x = samples([b for b in d.read() if isinstance(b, AccelBlock)])
    f, p = sps.welch(x, fs=5000.0, nperseg=1024)
    assert f[np.argmax(p)] == pytest.approx(1000.0, abs=15.0)
