"""The ``nidaqmx`` backend: an IEPE accelerometer on an NI DAQ through NI's ``nidaqmx`` package.

Optional extra (``pip install wearbench[nidaqmx]``, plus the NI-DAQmx driver). The channel is an
``ai_accel`` channel in m/s^2 with internal IEPE excitation, on a hardware-timed continuous sample
clock, read block by block with ``AnalogSingleChannelReader.read_many_sample`` into a reused
buffer. Device time is the sample count over the sample clock rate (the DAQ's own clock). A DAQ
drives no motor: ``drive`` names the backend whose drive and encoder stream are used with it
("serial", "can" or "canopen"; its options come from its own table). Options (``[hardware.nidaqmx]``):
``channel`` (e.g. "cDAQ1Mod1/ai0", required), ``drive`` (required), ``block`` (samples per
block, default rate/50), ``excitation`` (A, default 0.004), ``buffer`` (s, default 5).
Imports nidaqmx lazily; says clearly when the package or the device is missing.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import Any

import numpy as np
from wearbench.acquisition.drivers import (
    ACCELERATION,
    ENCODER,
    AccelerationSource,
    Block,
    DeviceDisconnected,
    DeviceTimeout,
    DriverError,
    Event,
    Rig,
    StreamInfo,
)
from wearbench.bench.schema import Bench

__all__ = ["DaqSource", "OnlyStreams", "import_nidaqmx", "open_rig"]

G0 = 9.80665
_OVERWRITE = (-200279, -200277)  # DAQmx: samples overwritten / the buffer overflowed
_TIMEOUT = -200284


def import_nidaqmx():
    try:
        import nidaqmx
        import nidaqmx.constants
        import nidaqmx.stream_readers
    except ImportError as exc:
        raise DriverError("the nidaqmx backend needs NI's nidaqmx package: pip install 'wearbench[nidaqmx]' "
                          f"(and the NI-DAQmx driver from ni.com) ({exc})") from None
    return nidaqmx


class DaqSource(AccelerationSource):
    """An IEPE accelerometer channel on a hardware-timed sample clock."""

    name = "nidaqmx"

    def __init__(self, channel: str, sensitivity: float, *, block: int | None = None,
                 excitation: float = 0.004, buffer: float = 5.0):
        self.nidaqmx = import_nidaqmx()
        self.channel, self.sensitivity = channel, sensitivity  # V per m/s^2
        self.block_size, self.excitation, self.buffer = block, excitation, buffer
        device = channel.split("/")[0]
        try:
            names = [d.name for d in self.nidaqmx.system.System.local().devices]
        except Exception as exc:  # noqa: BLE001 - the driver itself is missing or broken
            raise DriverError(f"NI-DAQmx is not usable on this machine: {exc}") from None
        if device not in names:
            raise DriverError(f"no NI-DAQmx device {device!r} (channel {channel!r}); devices here: "
                              f"{names or 'none'} (NI MAX can create a simulated device)")
        self.task = None
        self._range, self._rate = 0.0, 0.0
        self._sequence, self._samples = 0, 0

    def configure(self, range_m_s2: float, sample_rate: float) -> None:
        c = self.nidaqmx.constants
        self.close()
        self.task = task = self.nidaqmx.Task(new_task_name="wearbench-accelerometer")
        task.ai_channels.add_ai_accel_chan(
            self.channel, min_val=-range_m_s2, max_val=range_m_s2,
            units=c.AccelUnits.METERS_PER_SECOND_SQUARED,
            sensitivity=self.sensitivity * G0, sensitivity_units=c.AccelSensitivityUnits.VOLTS_PER_G,
            current_excit_source=c.ExcitationSource.INTERNAL, current_excit_val=self.excitation)
        task.timing.cfg_samp_clk_timing(sample_rate, sample_mode=c.AcquisitionType.CONTINUOUS,
                                        samps_per_chan=int(sample_rate * self.buffer))
        self._rate = float(task.timing.samp_clk_rate)  # the rate the hardware really runs at
        self._range = range_m_s2
        self.block = self.block_size or max(1, int(self._rate / 50))
        self._buf = np.zeros(self.block, dtype=np.float64)
        self._reader = self.nidaqmx.stream_readers.AnalogSingleChannelReader(task.in_stream)

    def describe(self) -> tuple[StreamInfo, ...]:
        return (StreamInfo(ACCELERATION, "m/s^2", self._rate, "float32", source=f"NI-DAQmx {self.channel}",
                           extra={"sensitivity_V_per_m_s2": repr(self.sensitivity),
                                  "iepe_excitation_A": repr(self.excitation)}, range=self._range or None),)

    def start(self) -> None:
        self._sequence = self._samples = 0
        self.task.start()

    def stop(self) -> None:
        if self.task is not None:
            self.task.stop()

    def read(self, timeout: float) -> list[Block | Event]:
        errors = self.nidaqmx.errors
        out: list[Block | Event] = []
        deadline = time.monotonic() + timeout
        while True:
            try:
                n = self._reader.read_many_sample(self._buf, number_of_samples_per_channel=self.block,
                                                  timeout=max(0.0, deadline - time.monotonic()))
            except errors.DaqError as exc:
                if exc.error_code == _TIMEOUT:
                    return out
                raise self._error(exc) from None
            t = self._samples / self._rate
            out.append(Block(ACCELERATION, self._sequence, t, self._rate,
                             self._buf[:n].astype(np.float32), time.time()))
            self._sequence += 1
            self._samples += n
            if self.task.in_stream.avail_samp_per_chan < self.block:
                return out

    def _error(self, exc) -> Exception:
        if exc.error_code in _OVERWRITE:
            return DeviceTimeout(f"NI-DAQmx {self.channel}: the host fell behind and samples were "
                                 f"overwritten ({exc.error_code})")
        return DeviceDisconnected(f"NI-DAQmx {self.channel}: {exc}")

    def close(self) -> None:
        if self.task is not None:
            try:
                self.task.close()
            finally:
                self.task = None


class OnlyStreams(AccelerationSource):
    """Another source with only some of its streams (the encoder of the drive's backend)."""

    def __init__(self, source: AccelerationSource, streams: set[str]):
        self.source, self.streams, self.name = source, streams, source.name

    def configure(self, range_m_s2: float, sample_rate: float) -> None:
        self.source.configure(range_m_s2, sample_rate)

    def describe(self) -> tuple[StreamInfo, ...]:
        return tuple(i for i in self.source.describe() if i.name in self.streams)

    def start(self) -> None:
        self.source.start()

    def stop(self) -> None:
        self.source.stop()

    def read(self, timeout: float) -> list[Block | Event]:
        return [i for i in self.source.read(timeout) if not isinstance(i, Block) or i.stream in self.streams]

    def close(self) -> None:
        self.source.close()


def open_rig(bench: Bench, options: Mapping[str, Any]) -> Rig:
    from wearbench.acquisition.backends import open_rig as open_backend

    allowed = {"channel", "drive", "block", "excitation", "buffer"}
    unknown = set(options) - allowed
    if unknown:
        raise ValueError(f"[hardware.nidaqmx]: unknown option(s) {sorted(unknown)}; expected {sorted(allowed)}")
    for key in ("channel", "drive"):
        if key not in options:
            raise ValueError(f"{bench.path or bench.name}: [hardware.nidaqmx] {key} is missing "
                             "(e.g. channel = \"cDAQ1Mod1/ai0\", drive = \"serial\")")
    if options["drive"] not in ("serial", "can", "canopen"):
        raise ValueError(f"[hardware.nidaqmx] drive = {options['drive']!r}: expected serial, can or canopen")
    acc = bench.sensor("accelerometer")
    if acc.sensitivity is None:
        raise ValueError(f"{bench.path or bench.name}: sensor {acc.name!r} needs a sensitivity for an IEPE channel")
    daq = DaqSource(str(options["channel"]), acc.sensitivity, block=options.get("block"),
                    excitation=float(options.get("excitation", 0.004)), buffer=float(options.get("buffer", 5.0)))
    other = open_backend(bench, options["drive"])
    sources = [daq] + [OnlyStreams(s, {ENCODER}) for s in other.sources]
    return Rig("nidaqmx", other.drive, sources, other.clock,
               info={**other.info, "daq_channel": daq.channel, "drive_backend": other.backend})
