"""The CAN emulator: a :class:`BenchDevice` on the python-can ``virtual`` bus (in-process).

It speaks the raw frames of ``wearbench.dbc`` (motor commands and status, stream control, CAN FD
accelerometer and encoder blocks, events) and, on the same bus, is a CANopen CiA 402 drive in
profile velocity mode: a ``canopen.LocalNode`` built from ``cia402_drive.eds`` with the state
machine Switch-on-disabled -> Ready-to-switch-on -> Switched-on -> Operation-enabled (controlword
0x6040, statusword 0x6041), target velocity 0x60FF and TPDOs of statusword, velocity and position.
Injected faults: dropped blocks (device), corrupted frames (an error frame replaces the frame),
bus-off (an error frame, then silence for ``bus_off_duration``, then an Event), disconnect and hung
firmware (``freeze_at``; both silence from then on), stalled motor (latched fault, EMCY 0x7121),
late replies, garbage (``garbage_bytes`` / 8 classic frames of random bytes on the AccelBlock
identifier, which the host must refuse as malformed) and a lost index pulse (by the device). ``sent`` holds every block
as the host must decode it. Only the ``virtual`` interface is allowed.
"""

from __future__ import annotations

import dataclasses
import threading
import time
from collections.abc import Callable, Mapping
from typing import Self

import can
import canopen
import numpy as np
from canopen.sdo.exceptions import SdoAbortedError
from wearbench.bench.schema import Bench
from wearbench.hardware.emulators.config import EmulatorConfig
from wearbench.hardware.emulators.device import (
    AccelBlock,
    BenchDevice,
    DeviceError,
    EncoderBlock,
    MonotonicClock,
)
from wearbench.hardware.protocol import can_frames as cf
from wearbench.hardware.protocol.messages import ErrorCode, FaultCode, counts_to_m_s2
from wearbench.hardware.protocol.taps import parse_tap_message

__all__ = ["CAN_ERR_BUSOFF", "CAN_ERR_PROT", "CIA402_STATES", "CanEmulator"]

CAN_ERR_PROT = 0x008
CAN_ERR_BUSOFF = 0x040
MOTOR_BLOCKED = 0x7121
# CiA 402 state -> statusword (bit 4 voltage enabled, bit 5 quick stop not active)
CIA402_STATES = {
    "SWITCH ON DISABLED": 0x0040,
    "READY TO SWITCH ON": 0x0021,
    "SWITCHED ON": 0x0023,
    "OPERATION ENABLED": 0x0027,
    "QUICK STOP ACTIVE": 0x0007,
    "FAULT": 0x0008,
}
_PV_MODE = 3


class CanEmulator:
    """Context manager running the bench on virtual CAN ``channel`` (see module docstring)."""

    def __init__(self, bench: Bench, channel: str = "wearbench", config: EmulatorConfig | Mapping | None = None,
                 *, node_id: int = 5, interface: str = "virtual", status_period: float = 0.01,
                 period: float = 0.002, clock=None):
        if interface != "virtual":
            raise ValueError(f"CanEmulator: interface {interface!r}: only the in-process 'virtual' bus is allowed")
        if config is None:
            config = EmulatorConfig.from_bench(bench)
        elif not isinstance(config, EmulatorConfig):
            config = EmulatorConfig.from_table(config, bench=bench)
        config = dataclasses.replace(config, accel_block=cf.ACCEL_PER_FRAME,
                                     encoder_block=min(config.encoder_block, cf.ENCODER_PER_FRAME))
        self.bench, self.channel, self.node_id, self.config = bench, channel, node_id, config
        self.device = BenchDevice(bench, config, clock if clock is not None else MonotonicClock())
        acc = bench.sensor("accelerometer")
        self.device.configure_accelerometer(round(self.device.range, 2), float(round(acc.sample_rate)))
        self.status_period, self.period = status_period, period
        self.sent: list[AccelBlock | EncoderBlock] = []
        self.error_frames = 0
        self.state = "SWITCH ON DISABLED"
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._delayed: list[tuple[float, Callable[[], None]]] = []
        self._alive = 0
        self._ack = (0, 0)
        self._bus_off_over = False
        self._bus_off_done = False
        self._silent = False
        self._garbage_sent = False
        self._rng = np.random.default_rng([config.seed, 4])
        self._last_controlword = 0
        self._raw_taps: set[int] = set()  # taps fired by a TapCommand frame: their latch goes out as TapLatch
        self._probe = {0x60B9: 0, 0x60BA: 0, 0x60D1: 0}  # touch probe 1: status, position, time stamp (us)
        self.bus: can.BusABC | None = None
        self.network: canopen.Network | None = None
        self.node: canopen.LocalNode | None = None

    # ---- life cycle ---------------------------------------------------------------------------

    def __enter__(self) -> Self:
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def start(self) -> None:
        self.device.prepare(self.bench.speed)
        self.bus = can.Bus(interface="virtual", channel=self.channel, fd=True, receive_own_messages=False)
        self.network = canopen.Network(self.bus)
        node = canopen.LocalNode(self.node_id, str(cf.EDS_PATH))
        self.network.add_node(node)
        self.node = node
        node.sdo[0x608F][1].raw = self.device.counts_per_rev
        node.add_write_callback(self._on_write)
        node.add_read_callback(self._on_read)
        node.tpdo.read(from_od=True)
        node.rpdo.read(from_od=True)
        for rpdo in node.rpdo.values():
            if rpdo.enabled:
                rpdo.add_callback(self._on_rpdo)
                rpdo.subscribe()
        self.network.subscribe(cf.load_dbc().get_message_by_name("MotorCommand").frame_id, self._on_motor_command)
        self.network.subscribe(cf.load_dbc().get_message_by_name("StreamControl").frame_id, self._on_stream_control)
        self.network.subscribe(cf.load_dbc().get_message_by_name("TapCommand").frame_id, self._on_tap_command)
        self.network.connect()
        node.nmt.send_command(0x80)  # boot-up -> pre-operational; the host starts it (NMT start)
        self._thread = threading.Thread(target=self._run, name=f"can-emulator-{self.channel}", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
        if self.network is not None:
            self.network.disconnect()
        self.network = self.bus = None

    # ---- sending ------------------------------------------------------------------------------

    def _off(self, at: float | None = None) -> bool:
        """Silent now, or off the bus at stream time ``at`` (default now: a block's is when it was sampled)."""
        return self._silent or self.device.frozen or self._bus_off(self.device.stream_time() if at is None else at)

    def _bus_off(self, st: float | None) -> bool:
        """Whether stream time ``st`` lies in the bus-off span (device time: on a busy host the blocks
        sampled then are lost however late the emulator gets to them)."""
        f = self.config.faults
        return f.bus_off_at is not None and st is not None and f.bus_off_at <= st < f.bus_off_at + f.bus_off_duration

    def _send(self, msg: can.Message, corruptible: bool = False, at: float | None = None) -> bool:
        if self._off(at) or self.bus is None:
            return False
        rate = self.config.faults.corrupt_rate
        if corruptible and rate and self._rng.random() < rate:
            msg = can.Message(arbitration_id=CAN_ERR_PROT, is_error_frame=True, data=bytes(8))
            self.error_frames += 1
            self.bus.send(msg)
            return False
        self.bus.send(msg)
        return True

    def _reply(self, action: Callable[[], None]) -> None:
        """Run the reply ``action`` now, or ``reply_delay`` late (the ack is not visible before)."""
        delay = self.config.faults.reply_delay
        if delay:
            self._delayed.append((time.monotonic() + delay, action))
        else:
            action()

    def _motor_status(self) -> can.Message:
        s = self.device.motor_status()
        acc, enc = self.device.streaming
        self._alive = (self._alive + 1) & 0xFF
        fault = FaultCode[s.fault.upper()] if s.fault else FaultCode.NONE
        return cf.encode_frame("MotorStatus", {
            "Speed": round(s.speed, 4), "Enabled": int(s.enabled), "AccelStreaming": int(acc),
            "EncoderStreaming": int(enc), "Fault": int(fault), "AckCounter": self._ack[0],
            "AckError": self._ack[1], "Alive": self._alive})

    def _stream_status(self, error: int) -> can.Message:
        acc, enc = self.device.streaming
        return cf.encode_frame("StreamStatus", {"Error": error, "Streaming": int(acc) | int(enc) << 1,
                                                "Range": self.device.range, "SampleRate": self.device.sample_rate})

    def _event(self, code: int, t: float, detail: int = 0) -> None:
        self._send(cf.encode_frame("Event", {"Code": int(code), "TimeMs": int(t * 1000) & 0xFFFFFFFF,
                                             "Detail": min(int(detail), 0xFFFFFF)}))

    def _send_block(self, block: AccelBlock | EncoderBlock) -> None:
        if isinstance(block, AccelBlock):
            lsb = self.device.lsb
            msg = cf.accel_frame(block, lsb)
            wire = AccelBlock(block.sequence, round(block.time * 1e9) / 1e9, block.sample_rate,
                              counts_to_m_s2(cf.to_counts(block.samples, lsb), lsb))
        else:
            msg = cf.encoder_frame(block)
            wire = EncoderBlock(block.sequence, round(block.time * 1e9) / 1e9, block.sample_rate,
                                block.counts, block.index)
        if self._send(msg, corruptible=True, at=self.device.stream_time_of(block.time)):  # lost if sampled off the bus
            self.sent.append(wire)

    def _run(self) -> None:
        next_status = 0.0
        while not self._stop.wait(self.period):
            now = time.monotonic()
            with self._lock:
                self._faults()
                while self._delayed and self._delayed[0][0] <= now:
                    self._delayed.pop(0)[1]()
                for block in self.device.read():
                    self._send_block(block)
                for ev in self.device.events():
                    if ev.code == FaultCode.TAP:
                        self._latch(ev)
                        continue
                    self._event(ev.code, ev.time)
                    if ev.code == FaultCode.STALL:
                        self._enter_fault()
                if now >= next_status:
                    next_status = now + self.status_period
                    self._send(self._motor_status())
                    self._transmit_pdos()

    def _faults(self) -> None:
        f = self.config.faults
        st = self.device.stream_time()
        if st is None:
            return
        if f.disconnect_after is not None and st >= f.disconnect_after:
            self._silent = True
        if not self._garbage_sent and self.device.fault_due(f.garbage_at) and not self._off():
            self._garbage_sent = True
            frame_id = cf.load_dbc().get_message_by_name("AccelBlock").frame_id
            noise = self._rng.integers(0, 256, max(8, f.garbage_bytes), dtype=np.uint8).tobytes()
            for i in range(0, len(noise) - 7, 8):
                self.bus.send(can.Message(arbitration_id=frame_id, data=noise[i:i + 8], is_extended_id=False))
        if f.bus_off_at is not None and st >= f.bus_off_at and not self._bus_off_done:
            self._bus_off_done = True
            self.bus.send(can.Message(arbitration_id=CAN_ERR_BUSOFF, is_error_frame=True, data=bytes(8)))
            self.error_frames += 1
        if self._bus_off_done and not self._bus_off_over and st >= f.bus_off_at + f.bus_off_duration:
            self._bus_off_over = True
            self._event(FaultCode.BUS_OFF, self.device.clock(), round(f.bus_off_duration * 1000))

    # ---- raw DBC commands ---------------------------------------------------------------------

    def _on_motor_command(self, can_id: int, data: bytearray, timestamp: float) -> None:
        if self._off():
            return
        values = cf.load_dbc().get_message_by_frame_id(can_id).decode(bytes(data))  # commands by DBC name
        cmd, counter = str(values["Command"]), int(values["Counter"])
        d = self.device
        error = ErrorCode.OK
        with self._lock:
            try:
                if cmd == "ENABLE":
                    d.enable()
                elif cmd == "DISABLE":
                    d.disable()
                elif cmd == "SET_SPEED":
                    d.set_speed(float(values["TargetSpeed"]), float(values["Acceleration"]) or None)
                elif cmd == "STOP":
                    d.stop()
                elif cmd == "CLEAR_FAULT":
                    d.clear_fault()
                elif cmd not in ("NONE", "GET_STATUS"):
                    error = ErrorCode.UNKNOWN_COMMAND
            except DeviceError as exc:
                error = exc.code

            def ack() -> None:
                self._ack = (counter, int(error))
                self._send(self._motor_status())

            self._reply(ack)

    def _latch(self, ev) -> None:
        """A tap's trigger: a TapLatch frame (to the ns; an Event frame's ms would not do) for a tap
        fired by TapCommand, else touch probe 1 (0x60B8) latches it when armed for a positive edge."""
        pulse = parse_tap_message(ev.message)
        if pulse.number in self._raw_taps:
            self._send(cf.encode_frame("TapLatch", {"TimeNs": max(0, round(ev.time * 1e9)),
                                                    "Number": pulse.number & 0xFFFF,
                                                    "Width": pulse.width, "Peak": pulse.peak}))
            return
        function = self._od(0x60B8)
        if function & 0x11 == 0x11 and not (self._probe[0x60B9] & 0x02 and not function & 0x02):
            self._probe.update({0x60B9: 0x03, 0x60BA: self.device.encoder_counts(ev.time),
                                0x60D1: round(ev.time * 1e6) & 0xFFFFFFFF})

    def _on_tap_command(self, can_id: int, data: bytearray, timestamp: float) -> None:
        if self._off():
            return
        values = cf.load_dbc().get_message_by_frame_id(can_id).decode(bytes(data))
        error = ErrorCode.OK
        with self._lock:
            try:
                tap = self.device.tap(float(values["After"]), float(values["Width"]), float(values["Peak"]))
                self._raw_taps.add(tap.number)
            except DeviceError as exc:
                error = exc.code

            def ack() -> None:
                self._ack = (int(values["Counter"]), int(error))
                self._send(self._motor_status())

            self._reply(ack)

    def _on_stream_control(self, can_id: int, data: bytearray, timestamp: float) -> None:
        if self._off():
            return
        values = cf.load_dbc().get_message_by_frame_id(can_id).decode(bytes(data))  # commands by DBC name
        cmd, mask = str(values["Command"]), int(values["Mask"])
        error = ErrorCode.OK
        with self._lock:
            try:
                if cmd == "STOP":
                    self.device.stop_stream()
                elif cmd == "START":
                    self.device.start_stream(accel=bool(mask & 1), encoder=bool(mask & 2))
                elif cmd == "CONFIGURE":
                    self.device.configure_accelerometer(float(values["Range"]), float(values["SampleRate"]))
                else:
                    error = ErrorCode.UNKNOWN_COMMAND
            except DeviceError as exc:
                error = exc.code
            reply = self._stream_status(int(error))
            self._reply(lambda: self._send(reply))

    # ---- CANopen CiA 402 drive ----------------------------------------------------------------

    def _od(self, index: int, subindex: int = 0) -> int:
        obj = self.node.object_dictionary[index]
        if subindex or not isinstance(obj, canopen.objectdictionary.ODVariable):
            obj = obj[subindex]
        raw = self.node.data_store.get(index, {}).get(subindex)
        return obj.decode_raw(raw) if raw is not None else obj.default

    def statusword(self) -> int:
        sw = CIA402_STATES[self.state] | 0x0200  # bit 9 remote
        if self.state == "OPERATION ENABLED":
            s = self.device.motor_status()
            target = self._od(0x60FF) / 1000.0
            if abs(s.speed - target) < 0.01 * max(1.0, abs(target)):
                sw |= 0x0400  # bit 10 target reached
            if abs(s.speed) < 1e-3:
                sw |= 0x1000  # bit 12 (pv): speed = 0
        return sw

    def _on_read(self, index: int, subindex: int, od, **kwargs):
        with self._lock:
            if index == 0x6041:
                return self.statusword()
            if index in (0x606C, 0x6064):
                s = self.device.motor_status()
                return round(s.speed * 1000) if index == 0x606C else s.counts
            if index == 0x603F:
                return MOTOR_BLOCKED if self.device.fault == "stall" else 0
            if index == 0x6061:
                return self._od(0x6060)
            if index in self._probe:
                return self._probe[index] if self._od(0x60B8) & 0x01 else 0
        return None

    def _on_rpdo(self, pdo_map) -> None:
        for var in pdo_map.map:
            try:
                self.node.set_data(var.index, var.subindex, var.get_data())
            except SdoAbortedError:
                pass

    def _on_write(self, index: int, subindex: int, od, data: bytes) -> None:
        if self._off():
            raise SdoAbortedError(0x08000020)
        with self._lock:
            if index == 0x6060:
                if od.decode_raw(data) != _PV_MODE:
                    raise SdoAbortedError(0x06090030)  # value range exceeded: only pv mode
            elif index == 0x6040:
                self._controlword(od.decode_raw(data))
            elif index == 0x60B8:  # (re-)arming touch probe 1 clears what it stored
                self._probe.update({0x60B9: od.decode_raw(data) & 0x01, 0x60BA: 0, 0x60D1: 0})
            elif index == 0x2100 and subindex == 3:  # the tapper: fire after this many us
                try:
                    self.device.tap(od.decode_raw(data) * 1e-6, self._od(0x2100, 1) * 1e-9, self._od(0x2100, 2) * 0.01)
                except DeviceError:
                    raise SdoAbortedError(0x06090030) from None  # value range exceeded
            elif index == 0x60FF and self.state == "OPERATION ENABLED":
                self._apply_target(od.decode_raw(data))

    def _apply_target(self, target_mrad: int) -> None:
        if self._last_controlword & 0x0100:  # halt
            self.device.stop()
            return
        accel = self._od(0x6083) / 1000.0
        try:
            self.device.set_speed(target_mrad / 1000.0, accel or None)
        except DeviceError as exc:
            raise SdoAbortedError(0x06090030 if exc.code == ErrorCode.BAD_VALUE else 0x08000022) from None

    def _controlword(self, cw: int) -> None:
        prev, self._last_controlword = self._last_controlword, cw
        state = self.state
        if state == "FAULT":
            if cw & 0x80 and not prev & 0x80:
                self.device.clear_fault()
                self.state = "SWITCH ON DISABLED"
            return
        if not cw & 0x02:  # disable voltage
            new = "SWITCH ON DISABLED"
        elif not cw & 0x04:  # quick stop
            new = "QUICK STOP ACTIVE" if state == "OPERATION ENABLED" else "SWITCH ON DISABLED"
        elif cw & 0x0F == 0x06:  # shutdown
            new = "READY TO SWITCH ON"
        elif cw & 0x0F == 0x07:  # switch on / disable operation
            new = "SWITCHED ON" if state in ("READY TO SWITCH ON", "SWITCHED ON", "OPERATION ENABLED") else state
        elif cw & 0x0F == 0x0F:  # enable operation
            new = "OPERATION ENABLED" if state in ("SWITCHED ON", "OPERATION ENABLED") else state
            if state == "READY TO SWITCH ON":
                new = "OPERATION ENABLED"  # switch on + enable operation in one go (CiA 402 transition 3+4)
        else:
            new = state
        if new == "OPERATION ENABLED" and state != new:
            try:
                self.device.enable()
            except DeviceError:
                new = "FAULT"
            else:
                self._apply_target(self._od(0x60FF))
        elif new == "OPERATION ENABLED":
            self._apply_target(self._od(0x60FF))
        elif state == "OPERATION ENABLED" and new == "QUICK STOP ACTIVE":
            self.device.stop()
        elif state in ("OPERATION ENABLED", "QUICK STOP ACTIVE") and new != state:
            self.device.disable()
        self.state = new

    def _enter_fault(self) -> None:
        self.state = "FAULT"
        if self.node is not None and not self._off():
            self.node.emcy.network = self.network
            self.node.emcy.send(MOTOR_BLOCKED, 0x01)

    def _transmit_pdos(self) -> None:
        node = self.node
        if node is None or node.nmt.state != "OPERATIONAL" or self._off():
            return
        s = self.device.motor_status()
        values = {0x6041: self.statusword(), 0x606C: round(s.speed * 1000), 0x6064: s.counts,
                  0x603F: MOTOR_BLOCKED if self.device.fault == "stall" else 0, 0x6061: self._od(0x6060)}
        for tpdo in node.tpdo.values():
            if not tpdo.enabled:
                continue
            for var in tpdo.map:
                if var.index in values:
                    var.raw = values[var.index]
            tpdo.transmit()

