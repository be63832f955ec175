"""The accelerometer's sensor chain: anti-alias filter before sampling (attenuation as designed),
clipping flagged at the range, and the chain inside the device."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal as sps
from wearbench.hardware.emulators.config import Accelerometer
from wearbench.hardware.emulators.device import AccelBlock, BenchDevice, ManualClock
from wearbench.hardware.emulators.sensor import SensorChain, oversampling
from wearbench.hardware.protocol.messages import FaultCode

pytestmark = pytest.mark.no_kernels

FS = 10000.0


def chain(**kw) -> SensorChain:
    acc = Accelerometer(**{"adc_bits": 0, "clipping": False, **kw})
    return SensorChain(acc, FS, 1e4, np.random.default_rng(0))


def amplitude(y: np.ndarray, f: float, fs: float) -> float:
    """Least-squares amplitude of the sinusoid at ``f`` in ``y`` (second half: transient gone)."""
    y = y[y.size // 2:]
    t = np.arange(y.size) / fs
    basis = np.column_stack([np.sin(2 * np.pi * f * t), np.cos(2 * np.pi * f * t)])
    coef = np.linalg.lstsq(basis, y, rcond=None)[0]
    return float(np.hypot(*coef))


def butterworth_gain(f: float, fc: float, order: int, fs: float) -> float:
    """Digital Butterworth by the bilinear transform, pre-warped at the cutoff (textbook closed form)."""
    ratio = math.tan(math.pi * f / fs) / math.tan(math.pi * fc / fs)
    return 1 / math.sqrt(1 + ratio ** (2 * order))


def sine_through(c: SensorChain, f: float, seconds: float = 0.5) -> np.ndarray:
    n = round(seconds * c.sample_rate)
    j = np.arange(n * c.oversample) - (c.oversample - 1)
    return c.process(np.sin(2 * np.pi * f * j / c.internal_rate)).astype(float)


@pytest.mark.parametrize("order, cutoff", [(8, 0.3), (4, 0.4)])
def test_anti_alias_attenuation_at_nyquist_as_designed(order, cutoff):
    c = chain(aa_filter="butterworth", aa_order=order, aa_cutoff=cutoff)
    assert c.oversample == 4 and c.internal_rate == 40000.0
    f = 0.499 * FS  # just below Nyquist: measurable after sampling without aliasing
    designed = butterworth_gain(f, cutoff * FS, order, c.internal_rate)
    assert amplitude(sine_through(c, f), f, FS) == pytest.approx(designed, rel=0.02)
    # the filter acts BEFORE sampling: 7 kHz folds to 3 kHz, attenuated by its gain at 7 kHz ...
    alias = amplitude(sine_through(c, 7000.0), 3000.0, FS)
    assert alias == pytest.approx(butterworth_gain(7000.0, cutoff * FS, order, c.internal_rate), rel=0.05)
    assert 20 * math.log10(alias) < -20
    # ... where point sampling without the filter keeps the full amplitude at the alias frequency
    assert amplitude(sine_through(chain(), 7000.0), 3000.0, FS) == pytest.approx(1.0, rel=1e-3)
    # passband: unity at DC, -3 dB at the cutoff
    assert amplitude(sine_through(c, 50.0), 50.0, FS) == pytest.approx(1.0, rel=1e-3)
    assert amplitude(sine_through(c, cutoff * FS), cutoff * FS, FS) == pytest.approx(1 / math.sqrt(2), rel=0.01)


def test_bessel_is_3_db_down_at_its_cutoff_and_keeps_the_delay_flat():
    c = chain(aa_filter="bessel", aa_order=4, aa_cutoff=0.2)
    assert amplitude(sine_through(c, 2000.0), 2000.0, FS) == pytest.approx(1 / math.sqrt(2), rel=0.02)
    _, gd = sps.group_delay((*sps.sos2tf(c.sos),), w=[100.0, 500.0, 1000.0], fs=c.internal_rate)
    assert np.ptp(gd) < 0.02 * gd[0]  # linear phase in the passband: impacts keep their shape


def test_oversampling_covers_the_mounting_resonance():
    plain = Accelerometer()
    assert oversampling(plain, FS) == 1  # no anti-alias filter: plain point sampling, as before
    stud = Accelerometer(aa_filter="butterworth", resonance=25e3, damping=0.03)
    m = oversampling(stud, FS)
    assert m * FS >= 2.5 * 25e3
    c = SensorChain(stud, FS, 1e4, np.random.default_rng(0))
    assert c.internal_rate == m * FS and c.sos.shape[0] == 1 + 4  # resonance + 8th-order AA


def test_clipping_is_at_the_range_and_counted():
    c = SensorChain(Accelerometer(adc_bits=16, clipping=True), FS, 100.0, np.random.default_rng(0))
    x = np.array([0.0, 50.0, 99.0, 150.0, -150.0, -100.0, 120.0])
    y = c.process(x).astype(float)
    lsb = 100.0 / 32768
    assert y[3] == pytest.approx(100.0 - lsb) and y[4] == pytest.approx(-100.0) and y[6] == y[3]
    assert c.clipped == 4  # at the extreme codes: 150, -150, -100 and 120 (99 is 2.6 % below)
    assert abs(y[1] - 50.0) <= lsb / 2


def test_device_flags_clipping_as_an_event(testbed, make_config):
    cfg = make_config(signal="harmonic", accelerometer={"aa_filter": "butterworth"})
    clock = ManualClock()
    d = BenchDevice(testbed, cfg, clock)
    d.configure_accelerometer(1.0, FS)  # the test pattern's 2.5 m/s^2 peaks exceed 1 m/s^2
    d.enable()
    d.set_speed(2 * math.pi)
    d.start_stream()
    x = []
    for _ in range(30):
        clock.advance(0.1)
        x += [b.samples for b in d.read() if isinstance(b, AccelBlock)]
    x = np.concatenate(x).astype(float)
    at_range = np.count_nonzero(x >= 1.0 - 1 / 32768 - 1e-9) + np.count_nonzero(x <= -1.0)
    assert d.clipped_samples == at_range > 0.1 * x.size
    clips = [e for e in d.events() if e.code == FaultCode.INFO and "clipped" in e.message]
    assert 2 <= len(clips) <= 4  # at most one a second over 3 s


def test_white_signal_through_the_anti_alias_filter(testbed, make_config):
    """A broadband shaker signal: near Nyquist the sampled spectrum lies far below the passband."""
    cfg = make_config(signal="white", accelerometer={"aa_filter": "butterworth", "aa_order": 8, "aa_cutoff": 0.3,
                                                     "adc_bits": 0})
    clock = ManualClock()
    d = BenchDevice(testbed, cfg, clock)
    d.configure_accelerometer(1000.0, FS)
    d.start_stream()
    x = []
    for _ in range(20):
        clock.advance(0.1)
        x += [b.samples for b in d.read() if isinstance(b, AccelBlock)]
    f, p = sps.welch(np.concatenate(x).astype(float), fs=FS, nperseg=1024)
    passband = np.median(p[(f > 100) & (f < 2000)])
    near_nyquist = np.median(p[f > 0.47 * FS])
    # aliased power at f: |H(f)|^2 + |H(fs - f)|^2 (+ higher folds), both about |H(fs/2)|^2 here
    designed = 2 * butterworth_gain(0.485 * FS, 0.3 * FS, 8, 4 * FS) ** 2
    assert 10 * math.log10(near_nyquist / passband) == pytest.approx(10 * math.log10(designed), abs=2.0)


def test_drift_noise_and_bias_behind_the_anti_alias_filter(testbed, make_config):
    """With the filter on (4x oversampled), the sample clock still drifts by its ppm and the DAQ's
    noise and bias, added after the filter, keep their size."""
    cfg = make_config(accelerometer={"aa_filter": "butterworth", "drift": "250 ppm", "noise": "0.5 m/s^2",
                                     "bias": "1.5 m/s^2"}, accel_block=10)
    clock = ManualClock()
    d = BenchDevice(testbed, cfg, clock)
    d.configure_accelerometer(490.0, FS)
    d.start_stream()
    x = []
    for _ in range(40):
        clock.advance(1.0)
        x += [b.samples for b in d.read() if isinstance(b, AccelBlock)]
    x = np.concatenate(x).astype(float)
    assert x.size / 40.0 / FS - 1 == pytest.approx(250e-6, abs=3e-5)  # one 10-sample block: 2.5e-5
    assert x.mean() == pytest.approx(1.5, abs=0.01) and x.std() == pytest.approx(0.5, rel=0.02)


def test_sensitivity_is_a_gain_before_bias_and_a_low_mount_mode_attenuates_the_band_above_it():
    """sensitivity 0.95 scales a 50 Hz sine by 0.95 (the bias is not scaled); a 300 Hz mode
    (second order, damping 0.05) passes 700 Hz at |1 / (1 - r^2 + 2j zeta r)|, r = 7/3 (within 5 %:
    the bilinear transform at 10 kHz, pre-warped at the mode, bends the response above it; measured 3 %)."""
    c = chain(sensitivity=0.95, bias=0.5)
    y = sine_through(c, 50.0)
    assert amplitude(y - 0.5, 50.0, FS) == pytest.approx(0.95, rel=1e-3)
    assert np.mean(y[-2000:]) == pytest.approx(0.5, abs=0.01)  # 10 whole periods
    r = 700.0 / 300.0
    expected = 1 / abs(1 - r * r + 2j * 0.05 * r)
    assert amplitude(sine_through(chain(resonance=300.0, damping=0.05), 700.0), 700.0, FS) == pytest.approx(
        expected, rel=0.05)
