"""The stated sensor-chain delay (``[sensor.chain]``): the host's closed-form group delay against
textbook values and a numerical phase slope, and against the delay the emulator (the far end, which
never reads the statement) actually puts between its accelerometer stamps and the crank angle."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy import signal as sps
from scipy.optimize import minimize_scalar
from wearbench.bench.schema import SensorChainStatement
from wearbench.hardware.emulators.config import EmulatorConfig
from wearbench.hardware.emulators.device import AccelBlock, BenchDevice, ManualClock
from wearbench.hardware.emulators.signal import harmonic_table
from wearbench.validation.measurement.chain_delay import analog_group_delay, stated_delay

pytestmark = pytest.mark.no_kernels

W = 2 * math.pi


@pytest.mark.parametrize("order, cutoff", [(8, 3000.0), (4, 500.0), (2, 1200.0)])
def test_butterworth_delay_at_dc_is_the_textbook_value(order, cutoff):
    # Butterworth poles on a circle: tau(0) = sum sin(theta_k) / wc = 1 / (wc sin(pi / 2n))
    chain = SensorChainStatement(filter="butterworth", filter_order=order, filter_cutoff=cutoff)
    expected = 1.0 / (2 * math.pi * cutoff * math.sin(math.pi / (2 * order)))
    assert stated_delay(chain, band=(0.01, 0.1)).filter == pytest.approx(expected, rel=1e-6)


@pytest.mark.parametrize("kind", ["butterworth", "bessel"])
def test_group_delay_is_the_phase_slope(kind):
    # a second method: minus the numerical derivative of the unwrapped phase of scipy's freqs
    design = sps.butter if kind == "butterworth" else sps.bessel
    kw = {} if kind == "butterworth" else {"norm": "mag"}
    z, p, _ = design(6, 2 * math.pi * 800.0, analog=True, output="zpk", **kw)
    b, a = sps.zpk2tf(z, p, 1.0)
    f = np.linspace(1.0, 2000.0, 20001)
    _, h = sps.freqs(b, a, worN=2 * np.pi * f)
    slope = -np.gradient(np.unwrap(np.angle(h)), 2 * np.pi * f)
    np.testing.assert_allclose(analog_group_delay(z, p, f)[1:-1], slope[1:-1], rtol=1e-4)
    # and a second-order resonance: tau(0) = 2 zeta / wn
    chain = SensorChainStatement(resonance=25e3, damping=0.03)
    assert stated_delay(chain, band=(0.01, 0.1)).sensor == pytest.approx(2 * 0.03 / (2 * math.pi * 25e3), rel=1e-6)


def test_stated_delays_are_taken_as_stated():
    chain = SensorChainStatement(filter_delay=0.31e-3, sensor_delay=0.02e-3, latency=0.1e-3, clock_drift=50e-6,
                                 uncertainty=0.05e-3)
    d = stated_delay(chain)
    assert d.constant == pytest.approx(0.43e-3)
    assert d.at(10.0) == pytest.approx(0.43e-3 + 10 * 50e-6 / (1 + 50e-6))
    assert "stated 0.430 ms" in d.describe()


def _measured_delays(bench, config: EmulatorConfig, rate: float, seconds: float, at: tuple[float, ...]) -> list[float]:
    """The delay of the device's accelerometer stamps behind the crank angle, fitted on 1 s around
    each time in ``at`` (s since the stream started): the harmonic pattern (kinematic, 1 and 2 Hz at
    this speed) at the motor angle of (stamp - delay)."""
    clock = ManualClock()
    d = BenchDevice(bench, config, clock)
    d.configure_accelerometer(bench.sensor("accelerometer").range, rate)
    d.enable()
    d.set_speed(W)
    clock.advance(2.0)   # ramped up and steady
    d.start_stream()
    start = clock()
    blocks = []
    for _ in range(round(seconds / 0.1)):
        clock.advance(0.1)
        blocks += [b for b in d.read() if isinstance(b, AccelBlock)]
    t = np.concatenate([b.time + np.arange(b.samples.size) / b.sample_rate for b in blocks]) - start
    x = np.concatenate([b.samples for b in blocks]).astype(float)
    ramp = W / bench.motor.max_acceleration
    table = harmonic_table(W)
    out = []
    for t0 in at:
        sel = np.abs(t - t0) <= 0.5
        tt, xx = t[sel] + start, x[sel]
        def cost(tau: float, tt=tt, xx=xx) -> float:
            return float(np.mean((xx - table.at(W * (tt - tau) - W * ramp / 2)) ** 2))

        out.append(minimize_scalar(cost, bounds=(-2e-3, 4e-3), method="bounded", options={"xatol": 1e-8}).x)
    return out


def test_the_test_beds_statement_matches_what_its_emulator_does(wearbench_bench):
    # the far end: the test bed's own [emulator.accelerometer] chain (resonance, 8th-order anti-alias
    # filter, 20 ppm clock drift) playing the kinematic pattern, with a latency of 0.4 ms; no noise, no ADC
    bench = wearbench_bench
    table = {**bench.emulator, "signal": "harmonic", "truth": {"accel_delay": "0.4 ms"}}
    table["accelerometer"] = {**table["accelerometer"], "noise": "0 m/s^2", "bias": "0 m/s^2", "adc_bits": 0}
    config = EmulatorConfig.from_table(table, bench=bench)
    acc = bench.sensor("accelerometer")
    measured = _measured_delays(bench, config, acc.sample_rate, 12.0, at=(1.0, 6.0, 11.0))
    # the host side: what the bench file states (the emulator never reads it), with the tap test's 0.4 ms
    stated = stated_delay(replace(acc.chain, latency=0.4e-3))
    for t0, m in zip((1.0, 6.0, 11.0), measured, strict=True):
        assert m == pytest.approx(stated.at(t0), abs=2e-6), (t0, m, stated.at(t0))
    # the drift is seen: the delay grows by 20 ppm of the 10 s between the first and the last
    assert measured[2] - measured[0] == pytest.approx(10.0 * 20e-6, rel=0.02)
    # and a statement without the drift, or with another filter, is off by more than the 2 us above
    assert abs(replace(stated, clock_drift=0.0).at(11.0) - measured[2]) > 1e-4
    bessel = stated_delay(replace(acc.chain, latency=0.4e-3, filter="bessel"))
    assert abs(bessel.at(6.0) - measured[1]) > 2e-5
