"""The nidaqmx backend without NI hardware: a clear message when the package is missing, and the
real driver code run against a stand-in ``nidaqmx`` module (same names and calls as NI's package:
``Task.ai_channels.add_ai_accel_chan``, ``timing.cfg_samp_clk_timing``,
``stream_readers.AnalogSingleChannelReader.read_many_sample``, ``errors.DaqError.error_code``)."""

from __future__ import annotations

import importlib.util
import sys
import types
from enum import Enum

import numpy as np
import pytest
from wearbench.acquisition.drivers import ACCELERATION, Block, DeviceTimeout, DriverError

pytestmark = pytest.mark.no_kernels


@pytest.mark.skipif(importlib.util.find_spec("nidaqmx") is not None, reason="nidaqmx is installed")
def test_missing_package_says_how_to_install(bench):
    from wearbench.acquisition.backends import open_rig

    with pytest.raises(DriverError, match=r"pip install 'wearbench\[nidaqmx\]'"):
        open_rig(bench, "nidaqmx", {"channel": "Dev1/ai0", "drive": "serial"})


def _fake_nidaqmx(signal: np.ndarray, devices=("Dev1",)):
    """A stand-in for NI's package: a continuous task that has produced ``signal`` (m/s^2)."""
    nidaqmx = types.ModuleType("nidaqmx")
    constants = types.ModuleType("nidaqmx.constants")
    constants.AccelUnits = Enum("AccelUnits", {"G": 10186, "METERS_PER_SECOND_SQUARED": 12470})
    constants.AccelSensitivityUnits = Enum("AccelSensitivityUnits", {"M_VOLTS_PER_G": 12509, "VOLTS_PER_G": 12510})
    constants.ExcitationSource = Enum("ExcitationSource", {"INTERNAL": 10200, "NONE": 10230})
    constants.AcquisitionType = Enum("AcquisitionType", {"FINITE": 10178, "CONTINUOUS": 10123})
    errors = types.ModuleType("nidaqmx.errors")

    class DaqError(Exception):
        def __init__(self, message, error_code):
            super().__init__(message)
            self.error_code = error_code

    errors.DaqError = DaqError
    calls = {}

    class Stream:
        def __init__(self):
            self.pos = 0

        @property
        def avail_samp_per_chan(self):
            return len(signal) - self.pos

    class Task:
        def __init__(self, new_task_name=""):
            self.in_stream = Stream()
            task = self
            self.ai_channels = types.SimpleNamespace(
                add_ai_accel_chan=lambda *a, **k: calls.setdefault("chan", (a, k)))

            class Timing:
                samp_clk_rate = 0.0

                def cfg_samp_clk_timing(self, rate, sample_mode, samps_per_chan):
                    calls["timing"] = (rate, sample_mode, samps_per_chan)
                    self.samp_clk_rate = rate * (1 + 1e-6)  # the hardware's coerced rate

            self.timing = Timing()
            self.started = False
            calls["task"] = task

        def start(self):
            self.started = True

        def stop(self):
            self.started = False

        def close(self):
            calls["closed"] = True

    class AnalogSingleChannelReader:
        def __init__(self, stream):
            self.stream = stream

        def read_many_sample(self, data, number_of_samples_per_channel, timeout):
            s, n = self.stream, number_of_samples_per_channel
            if calls.get("overrun"):
                raise DaqError("samples overwritten", -200279)
            if s.pos + n > len(signal):  # like DAQmx: wait for all n samples, or time out
                raise DaqError("timeout", -200284)
            data[:n] = signal[s.pos:s.pos + n]
            s.pos += n
            return n

    nidaqmx.Task = Task
    nidaqmx.constants, nidaqmx.errors = constants, errors
    nidaqmx.stream_readers = types.SimpleNamespace(AnalogSingleChannelReader=AnalogSingleChannelReader)
    nidaqmx.system = types.SimpleNamespace(System=types.SimpleNamespace(
        local=lambda: types.SimpleNamespace(devices=[types.SimpleNamespace(name=d) for d in devices])))
    return nidaqmx, calls


def _source(monkeypatch, signal, devices=("Dev1",)):
    fake, calls = _fake_nidaqmx(signal, devices)
    monkeypatch.setitem(sys.modules, "nidaqmx", fake)
    for name in ("constants", "errors", "stream_readers", "system"):
        monkeypatch.setitem(sys.modules, f"nidaqmx.{name}", getattr(fake, name))
    from wearbench.acquisition.backends.nidaqmx import DaqSource

    return DaqSource("Dev1/ai0", sensitivity=0.0102, block=100), calls


def test_daq_source_blocks(monkeypatch):
    signal = np.sin(np.arange(1050) * 0.01) * 30.0
    source, calls = _source(monkeypatch, signal)
    source.configure(490.0, 20000.0)
    (args, kw), (rate, mode, buffer) = calls["chan"], calls["timing"]
    assert args == ("Dev1/ai0",) and kw["min_val"] == -490.0 and kw["max_val"] == 490.0
    assert kw["units"].name == "METERS_PER_SECOND_SQUARED" and kw["sensitivity_units"].name == "VOLTS_PER_G"
    assert kw["sensitivity"] == pytest.approx(0.0102 * 9.80665) and kw["current_excit_source"].name == "INTERNAL"
    assert rate == 20000.0 and mode.name == "CONTINUOUS" and buffer == 100000
    source.start()
    blocks = [b for b in source.read(0.1) if isinstance(b, Block)]
    assert [b.sequence for b in blocks] == list(range(10))  # the last 50 samples wait for a full block
    assert all(b.stream == ACCELERATION and b.samples.dtype == np.float32 for b in blocks)
    np.testing.assert_array_equal(np.concatenate([b.samples for b in blocks]), signal[:1000].astype(np.float32))
    # device time from the sample count and the rate the hardware really runs at
    assert blocks[3].device_time == pytest.approx(300 / (20000.0 * (1 + 1e-6)))
    assert source.read(0.01) == []  # a DAQmx timeout is no data, not an error
    calls["overrun"] = True
    with pytest.raises(DeviceTimeout, match="overwritten"):
        source.read(0.01)
    source.close()
    assert calls["closed"]


def test_daq_device_missing(monkeypatch):
    with pytest.raises(DriverError, match=r"no NI-DAQmx device 'Dev1'.*simulated device"):
        _source(monkeypatch, np.zeros(10), devices=("cDAQ9",))
