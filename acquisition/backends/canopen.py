"""The ``canopen`` backend: a CiA 402 drive in profile-velocity mode through the ``canopen`` library,
with the acceleration (and encoder blocks) from the bench's raw CAN frames on the same bus.

Start-up as a CANopen master does it: NMT pre-operational, read the drive's PDO mapping by SDO and
map what the recorder needs (RPDO1 controlword + target velocity, TPDO1 statusword + velocity
actual, TPDO2 position actual + error code + mode display) where the drive differs, modes of
operation = 3 (profile velocity), NMT operational, then the 402 state machine (shutdown ->
switch on -> enable operation) by canopen's ``BaseNode402``, controlword through RPDO1, checked
against the statusword from TPDO1.
Units on the wire (``hardware/protocol/CAN.md``): mrad/s, mrad/s^2, encoder counts.
Options (``[hardware.canopen]``): those of ``can`` plus ``node_id`` (default 5), ``eds`` (default the
shipped ``cia402_drive.eds``). Imports python-can, canopen and the ``can`` backend.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator, Mapping
from typing import Any

import can
import canopen
from canopen.profiles.p402 import BaseNode402, State402
from wearbench.acquisition.backends.can import (
    BUS_OPTIONS,
    BenchFrames,
    CanSource,
    check_bus_options,
    frame_log,
    open_bus,
)
from wearbench.acquisition.drivers import (
    DeviceDisconnected,
    DeviceTimeout,
    DriverError,
    Event,
    MotorDrive,
    MotorState,
    Rig,
)
from wearbench.bench.schema import Bench
from wearbench.hardware.protocol.can_frames import EDS_PATH
from wearbench.hardware.protocol.taps import TAP_EVENT, tap_message

__all__ = ["Cia402Drive", "open_rig"]

CONTROLWORD, STATUSWORD, MODE, MODE_DISPLAY = 0x6040, 0x6041, 0x6060, 0x6061
POSITION, VELOCITY, TARGET_VELOCITY, ERROR_CODE = 0x6064, 0x606C, 0x60FF, 0x603F
PROFILE_ACC, PROFILE_DEC, RESOLUTION = 0x6083, 0x6084, 0x608F
TOUCH_PROBE_FUNCTION, TOUCH_PROBE_STATUS, TOUCH_PROBE_TIME, TAPPER = 0x60B8, 0x60B9, 0x60D1, 0x2100
_MAPPING = {("rpdo", 1): (CONTROLWORD, TARGET_VELOCITY), ("tpdo", 1): (STATUSWORD, VELOCITY),
            ("tpdo", 2): (POSITION, ERROR_CODE, MODE_DISPLAY)}
_FAULTS = {0x7121: "stall"}
_FAULT_STATES = ("FAULT", "FAULT REACTION ACTIVE")


class Cia402Drive(MotorDrive):
    """A CiA 402 drive (profile velocity mode): the state machine is canopen's ``BaseNode402``."""

    name = "cia402-drive"

    def __init__(self, network: canopen.Network, node: BaseNode402, frames: BenchFrames,
                 reply_timeout: float):
        self.network, self.node, self.frames = network, node, frames
        self.reply_timeout = reply_timeout
        self._taps = 0  # taps fired through the touch probe so far
        # BaseNode402's waits, scaled to the bus's reply timeout (its defaults assume an idle host)
        node.TIMEOUT_SWITCH_STATE_SINGLE = node.TIMEOUT_SWITCH_OP_MODE = reply_timeout
        node.TIMEOUT_SWITCH_STATE_FINAL = 4 * reply_timeout
        node.TIMEOUT_CHECK_TPDO = node.TIMEOUT_RESET_FAULT = reply_timeout

    # ---- start-up ---------------------------------------------------------------------------

    @contextlib.contextmanager
    def _sdo_errors(self, index: int) -> Iterator[None]:
        """An SDO transfer of object ``index``: an abort is a DriverError, no answer a DeviceTimeout."""
        try:
            yield
        except canopen.SdoAbortedError as exc:
            raise DriverError(f"CANopen node {self.node.id}: SDO 0x{index:04X}: {exc}") from None
        except canopen.SdoCommunicationError as exc:
            raise DeviceTimeout(f"CANopen node {self.node.id}: SDO 0x{index:04X}: {exc}") from None

    def _sdo(self, index: int, value: int, subindex: int | None = None) -> None:
        """Write ``value`` to object ``index`` (its ``subindex``) by SDO."""
        with self._sdo_errors(index):
            obj = self.node.sdo[index]
            (obj if subindex is None else obj[subindex]).raw = value

    def _read(self, index: int) -> int:
        """Read object ``index`` by SDO."""
        with self._sdo_errors(index):
            return int(self.node.sdo[index].raw)

    def setup(self) -> None:
        node = self.node
        node.nmt.state = "PRE-OPERATIONAL"
        try:
            node.tpdo.read()
            node.rpdo.read()
        except (canopen.SdoCommunicationError, canopen.SdoAbortedError) as exc:
            raise DeviceTimeout(f"CANopen node {node.id}: reading the PDO mapping: {exc}") from None
        for (kind, n), objects in _MAPPING.items():
            pdo = getattr(node, kind)[n]
            if tuple(v.index for v in pdo.map) != objects or not pdo.enabled:
                pdo.clear()
                for index in objects:
                    pdo.add_variable(index)
                pdo.enabled = True
                if kind == "tpdo":
                    pdo.trans_type, pdo.event_timer = 255, 10
                pdo.save()
        node.setup_402_state_machine(read_pdos=False)  # statusword and mode display from the TPDOs
        node.emcy.add_callback(self._on_emcy)
        try:  # 0x608F is optional; without it the bench file's counts per revolution stand
            cpr = node.sdo[RESOLUTION][1].raw
        except (canopen.SdoAbortedError, canopen.SdoCommunicationError, KeyError):
            cpr = 0
        if cpr:
            self.frames.counts_per_rev = int(cpr)
        node.nmt.state = "OPERATIONAL"
        self._fresh()
        node.op_mode = "PROFILED VELOCITY"  # by SDO (0x6060 is not in an RPDO), confirmed by TPDO2
        if node.op_mode != "PROFILED VELOCITY":
            raise DriverError(f"CANopen node {node.id}: mode of operation is {node.op_mode!r}, expected "
                              "'PROFILED VELOCITY' (does object 0x6502 list it?)")

    def _on_emcy(self, emcy) -> None:
        self.frames.inbox.put(Event(_FAULTS.get(emcy.code, "emcy"),
                                    f"EMCY from node {self.node.id}: code 0x{emcy.code:04X}"))

    def _fresh(self) -> None:
        """Wait for the next TPDO1 (statusword, velocity): the drive is alive and the values current."""
        if self.node.tpdo[1].wait_for_reception(self.reply_timeout) is None:
            raise DeviceTimeout(f"CANopen node {self.node.id}: no TPDO1 within {self.reply_timeout:g} s "
                                f"(last statusword 0x{self.node.statusword:04X})")

    # ---- CiA 402 state machine (BaseNode402) --------------------------------------------------

    def _state(self, target: str) -> None:
        try:
            self.node.state = target  # walks the transitions, controlword through RPDO1
        except RuntimeError as exc:
            raise DeviceTimeout(f"CANopen node {self.node.id}: {target!r} not reached within "
                                f"{self.node.TIMEOUT_SWITCH_STATE_FINAL:g} s ({exc}; state {self.node.state!r})") from None
        except ValueError as exc:
            raise DriverError(f"CANopen node {self.node.id}: {exc}") from None
        except (can.CanError, OSError) as exc:
            raise DeviceDisconnected(f"CANopen node {self.node.id}: {exc}") from None

    def enable(self) -> None:
        self._fresh()
        self.node.rpdo[1][TARGET_VELOCITY].raw = 0
        self._state("OPERATION ENABLED")  # from FAULT through a fault reset (controlword 0x80)

    def disable(self) -> None:
        self.node.rpdo[1][TARGET_VELOCITY].raw = 0
        self._state("READY TO SWITCH ON")  # shutdown: the drive stops and unpowers

    def set_speed(self, speed: float, acceleration: float | None = None) -> None:
        if acceleration:
            mrad = round(abs(acceleration) * 1000)
            self._sdo(PROFILE_ACC, mrad)
            self._sdo(PROFILE_DEC, mrad)
        self.node.rpdo[1][TARGET_VELOCITY].raw = round(speed * 1000)
        try:
            self.node.controlword = State402.CW_OPERATION_ENABLED  # sends RPDO1 with the new target
        except (can.CanError, OSError) as exc:
            raise DeviceDisconnected(f"CANopen node {self.node.id}: {exc}") from None

    def stop(self, acceleration: float | None = None) -> None:
        self.set_speed(0.0, acceleration)

    def tap(self, after: float = 0.01, width: float = 2e-4, peak: float = 1000.0) -> None:
        """Arm touch probe 1 (0x60B8: first positive edge of input 1), set and fire the tapper (0x2100:
        pulse width ns, peak 0.01 m/s^2, fire after us), wait for the latch (0x60B9 bit 1) and read its
        time stamp (0x60D1, us of the drive's clock, 32 bits: unwrapped against the encoder's time)."""
        self._sdo(TAPPER, round(width * 1e9), 1)
        self._sdo(TAPPER, round(peak * 100), 2)
        self._sdo(TOUCH_PROBE_FUNCTION, 0x0011)
        self._sdo(TAPPER, round(after * 1e6), 3)
        end = time.monotonic() + after + 4 * self.reply_timeout
        while not self._read(TOUCH_PROBE_STATUS) & 0x02:
            if time.monotonic() > end:
                raise DeviceTimeout(f"CANopen node {self.node.id}: touch probe 1 latched no tap within "
                                    f"{after + 4 * self.reply_timeout:g} s (is the tapper's trigger on input 1?)")
            time.sleep(0.005)
        stamp = self._read(TOUCH_PROBE_TIME) * 1e-6
        wrap = 2.0**32 * 1e-6
        ref = self.frames.encoder_time if self.frames.encoder_time is not None else stamp
        latch = stamp + wrap * round((ref - stamp) / wrap)
        self.frames.inbox.put(Event(TAP_EVENT, "device: " + tap_message(self._taps, width, peak), time.time(), latch))
        self._taps += 1

    def state(self) -> MotorState:
        self._fresh()
        node, f = self.node, self.frames
        t = node.tpdo_values
        with f.cond:  # while streaming, position and time from one encoder block (TPDO2 has no time)
            enc_time, index = f.encoder_time, f.index_count
            counts = f.counts if enc_time is not None else int(t.get(POSITION, 0))
        state = node.state
        fault = None
        if state in _FAULT_STATES:
            code = int(t.get(ERROR_CODE, 0))
            fault = _FAULTS.get(code, f"error code 0x{code:04X}")
        return MotorState(device_time=enc_time if enc_time is not None else 0.0,
                          angle=f.angle(counts), speed=int(t.get(VELOCITY, 0)) / 1000.0,
                          counts=counts, index_count=index, enabled=state == "OPERATION ENABLED",
                          fault=fault, host_time=time.time())


def open_rig(bench: Bench, options: Mapping[str, Any]) -> Rig:
    reply_timeout = check_bus_options(bench, options, BUS_OPTIONS | {"node_id", "eds"}, "canopen")
    node_id = int(options.get("node_id", 5))
    eds = str(options.get("eds", EDS_PATH))
    bus = open_bus(options)
    frames = BenchFrames.for_bench(bench)
    network = canopen.Network(bus)
    log = frame_log(options)
    network.listeners += [frames, *([log] if log else [])]
    if log is not None:
        log.attach(bus)  # SDO requests, RPDOs and NMT commands go to /can/frames too
    network.NOTIFIER_CYCLE = 0.1
    network.connect()
    closed = {"done": False}

    def close() -> None:
        if not closed["done"]:
            closed["done"] = True
            network.disconnect()

    try:
        node = network.add_node(BaseNode402(node_id, eds))
        drive = Cia402Drive(network, node, frames, reply_timeout)
        drive.setup()
        source = CanSource(bus, frames, bench, reply_timeout, log)
    except Exception:
        close()
        raise
    drive.close = source.close = close  # type: ignore[method-assign]
    return Rig("canopen", drive, [source], info={"bus": str(bus.channel_info), "node_id": str(node_id),
                                                 "eds": eds, "profile": "CiA 402 profile velocity"})
