"""The ``canopen`` backend: a CiA 402 drive in profile-velocity mode through the ``canopen`` library,
with the acceleration (and encoder blocks) from the bench's raw CAN frames on the same bus.

Start-up as a CANopen master does it: NMT pre-operational, read the drive's PDO mapping by SDO and
map what the recorder needs (RPDO1 controlword + target velocity, TPDO1 statusword + velocity
actual, TPDO2 position actual + error code + mode display) where the drive differs, modes of
operation = 3 (profile velocity), NMT operational, then the 402 state machine (shutdown ->
switch on -> enable operation) through RPDO1, checked against the statusword from TPDO1.
Units on the wire (``hardware/protocol/CAN.md``): mrad/s, mrad/s^2, encoder counts.
Options (``[hardware.canopen]``): those of ``can`` plus ``node_id`` (default 5), ``eds`` (default the
shipped ``cia402_drive.eds``). Imports python-can, canopen and the ``can`` backend.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Mapping
from typing import Any

import can
import canopen
from wearbench.acquisition.backends.canbus import (
    BUS_OPTIONS,
    BenchFrames,
    CanSource,
    _check,
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
from wearbench.hardware.bench import Bench
from wearbench.hardware.protocol.can_frames import EDS_PATH

__all__ = ["STATES", "Cia402Drive", "open_rig"]

CONTROLWORD, STATUSWORD, MODE, MODE_DISPLAY = 0x6040, 0x6041, 0x6060, 0x6061
POSITION, VELOCITY, TARGET_VELOCITY, ERROR_CODE = 0x6064, 0x606C, 0x60FF, 0x603F
PROFILE_ACC, PROFILE_DEC, RESOLUTION = 0x6083, 0x6084, 0x608F
PROFILE_VELOCITY = 3
# statusword (value, mask) of the CiA 402 states
STATES = {"switch on disabled": (0x0040, 0x004F), "ready to switch on": (0x0021, 0x006F),
          "switched on": (0x0023, 0x006F), "operation enabled": (0x0027, 0x006F),
          "fault": (0x0008, 0x004F), "fault reaction active": (0x000F, 0x004F)}
_MAPPING = {("rpdo", 1): (CONTROLWORD, TARGET_VELOCITY), ("tpdo", 1): (STATUSWORD, VELOCITY),
            ("tpdo", 2): (POSITION, ERROR_CODE, MODE_DISPLAY)}
_FAULTS = {0x7121: "stall"}


def state_of(statusword: int) -> str:
    for name, (value, mask) in STATES.items():
        if statusword & mask == value:
            return name
    return f"statusword 0x{statusword:04X}"


class Cia402Drive(MotorDrive):
    """A CiA 402 drive (profile velocity mode) on a ``canopen.Network``."""

    name = "cia402-drive"

    def __init__(self, network: canopen.Network, node: canopen.RemoteNode, frames: BenchFrames,
                 reply_timeout: float):
        self.network, self.node, self.frames = network, node, frames
        self.reply_timeout = reply_timeout
        self._cond = threading.Condition()
        self._tpdo = {"statusword": None, "velocity": 0, "position": 0, "error": 0, "mode": 0}
        self._tpdo_count = 0

    # ---- start-up ---------------------------------------------------------------------------

    def _sdo(self, index: int, value: int) -> None:
        """Write ``value`` to object ``index`` by SDO."""
        try:
            self.node.sdo[index].raw = value
        except canopen.SdoAbortedError as exc:
            raise DriverError(f"CANopen node {self.node.id}: SDO 0x{index:04X}: {exc}") from None
        except canopen.SdoCommunicationError as exc:
            raise DeviceTimeout(f"CANopen node {self.node.id}: SDO 0x{index:04X}: {exc}") from None

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
        for n in (1, 2):
            node.tpdo[n].add_callback(self._on_tpdo)
        node.emcy.add_callback(self._on_emcy)
        self._sdo(MODE, PROFILE_VELOCITY)
        try:  # 0x608F is optional; without it the bench file's counts per revolution stand
            cpr = self.node.sdo[RESOLUTION][1].raw
        except (canopen.SdoAbortedError, canopen.SdoCommunicationError, KeyError):
            cpr = 0
        if cpr:
            self.frames.counts_per_rev = int(cpr)
        node.nmt.state = "OPERATIONAL"
        self._wait_tpdo(lambda t: t["statusword"] is not None, "TPDO1 statusword")
        self._wait_tpdo(lambda t: t["mode"] == PROFILE_VELOCITY, "mode display = profile velocity")

    def _on_tpdo(self, pdo) -> None:
        with self._cond:
            for var in pdo.map:
                key = {STATUSWORD: "statusword", VELOCITY: "velocity", POSITION: "position",
                       ERROR_CODE: "error", MODE_DISPLAY: "mode"}.get(var.index)
                if key:
                    self._tpdo[key] = var.raw
            self._tpdo_count += 1
            self._cond.notify_all()

    def _on_emcy(self, emcy) -> None:
        self.frames.inbox.put(Event(_FAULTS.get(emcy.code, "emcy"),
                                    f"EMCY from node {self.node.id}: code 0x{emcy.code:04X}"))

    def _wait_tpdo(self, predicate, what: str) -> dict:
        with self._cond:
            count = self._tpdo_count
            ok = self._cond.wait_for(lambda: self._tpdo_count > count and predicate(self._tpdo),
                                     self.reply_timeout)
            if not ok:
                raise DeviceTimeout(f"CANopen node {self.node.id}: no {what} within {self.reply_timeout:g} s "
                                    f"(last statusword {self._tpdo['statusword']})")
            return dict(self._tpdo)

    # ---- CiA 402 state machine ----------------------------------------------------------------

    def _control(self, controlword: int, velocity: int | None = None) -> None:
        rpdo = self.node.rpdo[1]
        rpdo[CONTROLWORD].raw = controlword
        if velocity is not None:
            rpdo[TARGET_VELOCITY].raw = velocity
        try:
            rpdo.transmit()
        except (can.CanError, OSError) as exc:
            raise DeviceDisconnected(f"CANopen node {self.node.id}: {exc}") from None

    def _goto(self, controlword: int, state: str) -> None:
        self._control(controlword)
        value, mask = STATES[state]
        self._wait_tpdo(lambda t: t["statusword"] is not None and t["statusword"] & mask == value,
                        f"state {state!r}")

    def enable(self) -> None:
        sw = self._wait_tpdo(lambda t: t["statusword"] is not None, "statusword")["statusword"]
        if state_of(sw) in ("fault", "fault reaction active"):
            self._goto(0x0080, "switch on disabled")  # fault reset (rising edge of bit 7)
        self._control(0x0000, 0)
        self._goto(0x0006, "ready to switch on")
        self._goto(0x0007, "switched on")
        self._goto(0x000F, "operation enabled")

    def disable(self) -> None:
        self._control(0x0006, 0)  # shutdown: leaves operation enabled, the drive stops and unpowers

    def set_speed(self, speed: float, acceleration: float | None = None) -> None:
        if acceleration:
            mrad = round(abs(acceleration) * 1000)
            self._sdo(PROFILE_ACC, mrad)
            self._sdo(PROFILE_DEC, mrad)
        self._control(0x000F, round(speed * 1000))

    def stop(self, acceleration: float | None = None) -> None:
        self.set_speed(0.0, acceleration)

    def state(self) -> MotorState:
        t = self._wait_tpdo(lambda t: t["statusword"] is not None, "TPDO")
        f = self.frames
        with f.cond:  # while streaming, position and time from one encoder block (TPDO2 has no time)
            enc_time, index = f.encoder_time, f.index_count
            counts = f.counts if enc_time is not None else int(t["position"])
        sw = t["statusword"]
        fault = None
        if state_of(sw) in ("fault", "fault reaction active"):
            fault = _FAULTS.get(t["error"], f"error code 0x{t['error']:04X}")
        return MotorState(device_time=enc_time if enc_time is not None else 0.0,
                          angle=f.angle(counts), speed=t["velocity"] / 1000.0,
                          counts=counts, index_count=index, enabled=state_of(sw) == "operation enabled",
                          fault=fault, host_time=time.time())


def open_rig(bench: Bench, options: Mapping[str, Any]) -> Rig:
    reply_timeout = _check(bench, options, BUS_OPTIONS | {"node_id", "eds"}, "canopen")
    node_id = int(options.get("node_id", 5))
    eds = str(options.get("eds", EDS_PATH))
    bus = open_bus(options)
    frames = BenchFrames.for_bench(bench)
    network = canopen.Network(bus)
    network.listeners.append(frames)
    network.NOTIFIER_CYCLE = 0.1
    network.connect()
    closed = {"done": False}

    def close() -> None:
        if not closed["done"]:
            closed["done"] = True
            network.disconnect()

    try:
        node = network.add_node(node_id, eds)
        drive = Cia402Drive(network, node, frames, reply_timeout)
        drive.setup()
        source = CanSource(bus, frames, bench, reply_timeout)
    except Exception:
        close()
        raise
    drive.close = source.close = close  # type: ignore[method-assign]
    return Rig("canopen", drive, [source], info={"bus": str(bus.channel_info), "node_id": str(node_id),
                                                 "eds": eds, "profile": "CiA 402 profile velocity"})
