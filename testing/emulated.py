"""Emulated benches a test records from: on a pseudo-terminal, on a python-can ``virtual`` bus (raw
DBC frames), or as a CANopen CiA 402 drive on a virtual bus; or the real bench behind the same handle.

:func:`start_bench` starts one and returns an :class:`EmulatedBench`: the backend and options to
open a rig with (:meth:`EmulatedBench.open_rig`, or hand ``backend`` and ``options`` to the lab's
own code), the emulator's truth and faults, and what the emulator sent (:meth:`EmulatedBench.sent`).
Every bench started is registered until :meth:`EmulatedBench.close`; :func:`close_all` closes what
is left (the pytest plugin calls it after every test, at the end of the run and at exit), so no
process, pty or bus outlives the test, also when it fails or is interrupted. A serial emulator's
process starts shielded from Ctrl-C (``wearbench.compute.interrupts``): a terminal's Ctrl-C is for the
test run, which closes it. Imports the bench, the emulators, the acquisition backends and the
compute layer's interrupt handling.
"""

from __future__ import annotations

import atexit
import contextlib
import itertools
import os
import shutil
import tempfile
import threading
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Self

from wearbench.acquisition.backends import open_rig
from wearbench.acquisition.drivers import Rig
from wearbench.bench.schema import Bench, WearState
from wearbench.compute.interrupts import end_processes, running_processes, start_shielded
from wearbench.hardware.emulators.config import EmulatorConfig, emulator_config
from wearbench.testing.faults import FaultPlan
from wearbench.testing.recording import Sent, sent_from_blocks, sent_from_serial_log

__all__ = ["TRANSPORTS", "EmulatedBench", "close_all", "open_benches", "start_bench"]

TRANSPORTS = ("serial", "can", "canopen")
_OPEN: dict[int, EmulatedBench] = {}
_LOCK = threading.Lock()
_CHANNELS = itertools.count(1)
_EMULATOR = "wearbench-emulator"  # serial emulator processes are named so (serial_server)


@dataclass(eq=False)
class EmulatedBench:
    """A bench to record from. ``backend`` and ``options`` open it (``open_rig``); ``config`` is the
    emulator's (None: real hardware, see ``emulated``); ``speed`` the motor speed (rad/s) to run."""

    bench: Bench
    backend: str
    options: dict[str, Any]
    speed: float
    faults: FaultPlan = field(default_factory=FaultPlan)
    config: EmulatorConfig | None = None
    speedup: float = 1.0
    _process: Any = None  # serial: the emulator process
    _emulator: Any = None  # CAN: the in-process CanEmulator
    _sent_log: Path | None = None
    _tmp: Path | None = None
    _sent: Sent | None = None  # the serial log, parsed when the bench closes (the log goes with it)
    closed: bool = False

    @property
    def emulated(self) -> bool:
        """False when the handle points at real hardware (``--wearbench-port``/``--wearbench-can``)."""
        return self.config is not None

    @property
    def port(self) -> str | None:
        """The serial port (pty path of the emulator), or None on a CAN bench."""
        return self.options.get("port")

    @property
    def channel(self) -> str | None:
        """The CAN channel, or None on a serial bench."""
        return self.options.get("channel")

    @property
    def pid(self) -> int | None:
        """The emulator process's id (serial), else None."""
        return None if self._process is None else self._process.pid

    def open_rig(self, **options: Any) -> Rig:
        """A rig on this bench (``options`` added to the backend's)."""
        return open_rig(self.bench, self.backend, {**self.options, **options})

    def sent(self) -> Sent | None:
        """Every block the emulator sent, ``{stream: {sequence: (time, rate, samples, index)}}``;
        None on real hardware (nothing to compare with)."""
        if self._emulator is not None:
            return sent_from_blocks(self._emulator.sent)
        if self._sent is None and self._sent_log is not None:
            return sent_from_serial_log(self._sent_log)
        return self._sent

    def exit_code(self, timeout: float = 10.0) -> int | None:
        """The serial emulator's exit code once it ended (3 after an injected link drop)."""
        if self._process is None:
            return None
        try:
            return self._process.wait(timeout)
        except TimeoutError:
            return None

    def close(self) -> None:
        """Stop the emulator: the process (terminate, then kill) and its pty, or the bus. Idempotent;
        a Ctrl-C while it waits for the process kills the process before it is raised."""
        if self.closed:
            return
        self.closed = True
        with _LOCK:
            _OPEN.pop(id(self), None)
        try:
            if self._process is not None:
                ended = False
                try:
                    self._process.terminate()
                    self._process.wait(10)
                    ended = True
                except TimeoutError:
                    pass
                finally:
                    if not ended:  # not in time, or interrupted while waiting
                        self._process.kill()
                        with contextlib.suppress(TimeoutError):
                            self._process.wait(10)
            if self._emulator is not None:
                self._emulator.stop()
        finally:
            if self._sent_log is not None and self._sent_log.exists():
                self._sent = sent_from_serial_log(self._sent_log)
            if self._tmp is not None:
                shutil.rmtree(self._tmp, ignore_errors=True)

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _table(bench: Bench, state: WearState | str | None, seed: int | None, signal: str | None,
           faults: FaultPlan, table: Mapping[str, Any] | None) -> EmulatorConfig:
    base = dict(bench.emulator if table is None else table)
    if signal is not None:
        base["signal"] = signal
    config = emulator_config(bench, state, seed, table=base)
    return EmulatorConfig.from_table(faults.apply(config.to_table()), bench=bench)


def start_bench(bench: Bench, transport: str = "serial", *, state: WearState | str | None = None,
                seed: int | None = None, speed: float | None = None, faults: FaultPlan | None = None,
                signal: str | None = None, table: Mapping[str, Any] | None = None, speedup: float = 1.0,
                hardware: str | None = None) -> EmulatedBench:
    """Start an emulated ``bench`` on ``transport`` ("serial": a pty; "can": raw DBC frames on a
    python-can virtual bus; "canopen": the CiA 402 drive on a virtual bus).

    ``state``: a ``[[state]]`` name of the bench or a :class:`WearState` (None: its own clearances,
    no wear); ``seed``: a non-twin truth drawn from the bench's ``[tolerances]`` (None: the nominal
    model, a twin); ``speed`` (rad/s, default the bench's); ``faults``: a :class:`FaultPlan`;
    ``signal``: "model" (physics), "harmonic" (a test pattern, no model run), "white" or "none"
    (default the bench file's); ``table``: an ``[emulator]`` table replacing the bench file's;
    ``speedup``: the device clock runs that many times faster than real time.
    ``hardware``: the real bench instead (serial: the port; CAN: ``interface:channel``); then no
    emulator starts, and a fault plan is refused (faults need the emulator).
    """
    if transport not in TRANSPORTS:
        raise ValueError(f"transport {transport!r}: expected one of {TRANSPORTS}")
    faults = faults or FaultPlan()
    speed = float(bench.speed if speed is None else speed)
    if hardware is not None:
        if not faults.clean:
            raise ValueError(f"a fault plan needs the emulator; {hardware} is real hardware")
        if transport == "serial":
            options: dict[str, Any] = {"port": hardware}
        else:
            interface, sep, channel = hardware.partition(":")
            if not sep or not interface or not channel:
                raise ValueError(f"CAN bus {hardware!r}: expected INTERFACE:CHANNEL (e.g. socketcan:can0)")
            options = {"interface": interface, "channel": channel}
        return _register(EmulatedBench(bench, transport, options, speed, faults))
    config = _table(bench, state, seed, signal, faults, table)
    if transport == "serial":
        from wearbench.hardware.emulators.serial_server import start_serial_emulator

        def start() -> EmulatedBench:
            tmp = Path(tempfile.mkdtemp(prefix="wearbench-hil-"))
            log = tmp / "sent.bin"
            try:
                process, port = start_serial_emulator(bench, config, sent_log=log, speedup=speedup)
            except BaseException:
                shutil.rmtree(tmp, ignore_errors=True)
                raise
            return _register(EmulatedBench(bench, "serial", {"port": port}, speed, faults, config, speedup,
                                           _process=process, _sent_log=log, _tmp=tmp))

        # shielded: a terminal's Ctrl-C reaches the test run alone, never the emulator process (which
        # would die and show the recorder a lost device); a Ctrl-C during the start ends the emulator
        # being started, so the start gives up at once and leaves nothing behind
        before = running_processes(_EMULATOR)
        return start_shielded(start, close=EmulatedBench.close, name=f"serial emulator {bench.name}",
                              abort=lambda: end_processes(before, name=_EMULATOR), grace=10.0)
    from wearbench.hardware.emulators.can_server import CanEmulator
    from wearbench.hardware.emulators.device import MonotonicClock

    channel = f"wearbench-hil-{os.getpid()}-{next(_CHANNELS)}"
    emulator = CanEmulator(bench, channel=channel, config=config, clock=MonotonicClock(speedup))
    handle = _register(EmulatedBench(bench, transport, {"interface": "virtual", "channel": channel}, speed,
                                     faults, emulator.config, speedup, _emulator=emulator))
    try:
        emulator.start()
    except BaseException:
        handle.close()
        raise
    return handle


def _register(handle: EmulatedBench) -> EmulatedBench:
    with _LOCK:
        _OPEN[id(handle)] = handle
    return handle


def open_benches() -> list[EmulatedBench]:
    """The benches started and not closed yet."""
    with _LOCK:
        return list(_OPEN.values())


def close_all() -> list[str]:
    """Close every bench still open, each also when closing another was interrupted; returns a line
    per bench closed (empty: nothing was left)."""
    closed, stopped = [], None
    for handle in open_benches():
        closed.append(f"{handle.backend} bench {handle.port or handle.channel}")
        try:
            handle.close()
        except BaseException as exc:  # noqa: BLE001 - a Ctrl-C here: the others are closed first
            stopped = stopped or exc
    if stopped is not None:
        raise stopped
    return closed


atexit.register(close_all)
