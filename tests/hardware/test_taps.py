"""The emulator's tapper: a tap reaches the accelerometer through the mechanism signal's own delay
and chain, its trigger is latched on the encoder's clock, and every wire carries the command."""

from __future__ import annotations

import math

import numpy as np
import pytest
from wearbench.hardware.emulators.device import BenchDevice, DeviceError, ManualClock
from wearbench.hardware.emulators.sensor import SensorChain
from wearbench.hardware.protocol import messages as m
from wearbench.hardware.protocol.frames import FrameParser
from wearbench.hardware.protocol.taps import LATCH_RESOLUTION, parse_tap_message, tap_message

pytestmark = pytest.mark.no_kernels

CHAIN = {"noise": "0 m/s^2", "bias": "0 m/s^2", "adc_bits": 0, "resonance": "2 kHz", "damping": 0.05,
         "aa_filter": "butterworth", "aa_order": 8, "aa_cutoff": 0.3}


@pytest.fixture
def device(testbed, make_config):
    def make(delay_ms: float = 0.0, **acc):
        clock = ManualClock()
        cfg = make_config(accelerometer={**CHAIN, **acc}, truth={"accel_delay": f"{delay_ms!r} ms"})
        return BenchDevice(testbed, cfg, clock), clock
    return make


def _samples(dev: BenchDevice, clock: ManualClock, seconds: float) -> tuple[np.ndarray, np.ndarray]:
    """(stamp times, samples) of the accelerometer over ``seconds`` of device time."""
    clock.advance(seconds)
    blocks = [b for b in dev.read() if hasattr(b, "samples")]
    t = np.concatenate([b.time + np.arange(len(b.samples)) / b.sample_rate for b in blocks])
    return t, np.concatenate([b.samples for b in blocks]).astype(float)


@pytest.mark.parametrize("delay_ms", [0.0, 0.37])
def test_a_tap_passes_through_the_accelerometers_own_delay_and_chain(device, delay_ms):
    """Second method: the tap's half-sine, delayed by the truth's accel_delay and filtered by a fresh
    SensorChain of the same accelerometer, is what the device streams (the same path as the mechanism)."""
    dev, clock = device(delay_ms)
    dev.start_stream()
    tap = dev.tap(after=0.05, width=3e-4, peak=500.0)
    t, x = _samples(dev, clock, 0.2)
    chain = SensorChain(dev.config.accelerometer, dev.sample_rate, dev.range, np.random.default_rng(0))
    m_ = chain.oversample
    ti = np.arange(t.size * m_) / (dev.sample_rate * m_) - (m_ - 1) / (dev.sample_rate * m_)
    expected = chain.process(tap.pulse(ti - delay_ms * 1e-3))
    np.testing.assert_allclose(x, expected, atol=1e-3 * 500)
    assert np.max(np.abs(x)) > 20.0  # the tap was seen


def test_a_tap_while_the_mechanism_turns_adds_the_chains_response_at_the_truths_delay(testbed, make_config):
    """Two devices playing the same turning pattern, one tapped, differ by the chain's response to the
    pulse alone at the truth's accel_delay (the chain is linear without noise and ADC): the tap is summed
    into the mechanism's signal before the device's one chain, as a real hammer's blow is."""
    outs = []
    for tapped in (False, True):
        clock = ManualClock()
        dev = BenchDevice(testbed, make_config(signal="harmonic", accelerometer=CHAIN,
                                               truth={"accel_delay": "0.2 ms"}), clock)
        dev.enable()
        dev.set_speed(6.0, 1e6)
        dev.start_stream()
        clock.advance(0.3)
        dev.read()
        if tapped:
            tap = dev.tap(after=0.05, width=2e-4, peak=300.0)
        outs.append(_samples(dev, clock, 0.2))
    (t, plain), (_, with_tap) = outs
    chain = SensorChain(dev.config.accelerometer, dev.sample_rate, dev.range, np.random.default_rng(0))
    m_ = chain.oversample
    ti = t[0] + (np.arange(t.size * m_) - (m_ - 1)) / (dev.sample_rate * m_)
    chain._axial.zi = np.zeros((chain.sos.shape[0], 2))  # the pulse alone, from rest
    alone = chain.process(tap.pulse(ti - 2e-4))
    np.testing.assert_allclose(with_tap - plain, alone, atol=2e-3 * 300)
    assert np.max(np.abs(alone)) > 10.0


def test_the_latch_is_the_trigger_on_the_encoders_clock_to_a_microsecond(device):
    dev, clock = device()
    dev.start_stream()
    taps = [dev.tap(after=0.01 + 0.1 * k) for k in range(5)]
    assert dev.events() == []  # no latch before the trigger happened
    clock.advance(1.0)
    events = [e for e in dev.events() if e.code == m.FaultCode.TAP]
    assert [e.time for e in events] == [tap.latch for tap in taps]
    for tap, e in zip(taps, events, strict=True):
        assert 0 <= tap.time - tap.latch < LATCH_RESOLUTION + 1e-12
        assert abs(tap.latch / LATCH_RESOLUTION - round(tap.latch / LATCH_RESOLUTION)) < 1e-6
        assert parse_tap_message(e.message) == (tap.number, pytest.approx(tap.width), pytest.approx(tap.peak))


def test_a_tap_at_rest_needs_no_model_table(device):
    dev, clock = device()
    dev.config = dev.config.__class__(**{**dev.config.__dict__, "signal": "model"})  # the model, cranks at rest
    dev.start_stream()
    dev.tap(after=0.01)
    _, x = _samples(dev, clock, 0.1)
    assert dev._tables == {} and np.max(np.abs(x)) > 20.0


@pytest.mark.parametrize("kwargs, word", [({"after": -1.0}, "after"), ({"width": 0.0}, "width"),
                                          ({"width": 0.01}, "width"), ({"peak": math.nan}, "peak")])
def test_a_bad_tap_is_refused_naming_the_value(device, kwargs, word):
    dev, _ = device()
    with pytest.raises(DeviceError, match=word):
        dev.tap(**kwargs)


def test_the_tap_message_round_trips():
    assert parse_tap_message("device: " + tap_message(7, 2.5e-4, 1225.0)) == (7, pytest.approx(2.5e-4), 1225.0)
    assert parse_tap_message("accelerometer clipped") is None


def test_the_serial_tap_command_and_event_round_trip():
    cmd = m.Tap(0.125, 2e-4, 1000.0)
    ev = m.Event(1.234567, m.FaultCode.TAP, tap_message(0, 2e-4, 1000.0))
    back = [m.decode(f) for f in FrameParser().feed(m.encode(cmd, 3) + m.encode(ev, 4))]
    assert back[0] == m.Tap(pytest.approx(0.125), pytest.approx(2e-4), 1000.0)
    assert back[1].time == 1.234567 and back[1].code == m.FaultCode.TAP


def test_the_serial_emulator_fires_a_tap_and_sends_its_latch(testbed, make_config):
    from wearbench.hardware.emulators.serial_server import SerialEmulator

    clock = ManualClock()
    emu = SerialEmulator(BenchDevice(testbed, make_config(accelerometer=CHAIN), clock))
    replies = [m.decode(f) for f in FrameParser().feed(emu.receive(m.encode(m.Tap(0.01, 2e-4, 800.0), 1)))]
    assert replies[-1] == m.Ack(m.MessageType.TAP, 1, m.ErrorCode.OK)
    bad = [m.decode(f) for f in FrameParser().feed(emu.receive(m.encode(m.Tap(0.01, 1.0, 800.0), 2)))]
    assert bad[-1].error == m.ErrorCode.BAD_VALUE
    clock.advance(0.1)
    sent = [m.decode(f) for f in FrameParser().feed(emu.poll())]
    taps = [x for x in sent if isinstance(x, m.Event) and x.code == m.FaultCode.TAP]
    assert len(taps) == 1 and 0.01 <= taps[0].time <= 0.01 + LATCH_RESOLUTION
