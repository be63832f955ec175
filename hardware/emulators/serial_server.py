"""The serial emulator: a :class:`BenchDevice` speaking the framed protocol on a pseudo-terminal.

:func:`serve` answers on a new pty until SIGTERM/SIGINT or an injected disconnect (``wearbench
emulate BENCH.toml --serial`` runs it and prints the port path). :func:`start_serial_emulator` runs
it in its own process from Python (multiprocessing, no command line) and returns (process, port path). Injected faults: late replies
(``reply_delay``), corrupted frames (``corrupt_rate``: one byte of the frame flipped), dropped blocks
(by the device), a disconnect ``disconnect_after`` s into streaming (the pty closes, the process
exits with code 3), a stalled motor (EVENT frame), a burst of ``garbage_bytes`` random bytes at
``garbage_at``, a hung firmware at ``freeze_at`` (silence; the pty stays open) and a lost index
pulse (by the device). ``speedup`` runs the device clock that many times faster than real time. ``sent_log`` receives every byte written, so a
test can parse exactly what was sent. Imports the device, config and the protocol; POSIX only.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import select
import shutil
import signal
import sys
import tempfile
import time
import tty
from collections.abc import Mapping
from pathlib import Path
from typing import BinaryIO

import numpy as np
from wearbench.bench.content import bench_key
from wearbench.bench.load import load_bench
from wearbench.bench.schema import Bench
from wearbench.hardware.emulators.config import EmulatorConfig
from wearbench.hardware.emulators.device import (
    AccelBlock,
    BenchDevice,
    DeviceError,
    EncoderBlock,
    MonotonicClock,
)
from wearbench.hardware.protocol import messages as m
from wearbench.hardware.protocol.frames import FrameParser
from wearbench.hardware.protocol.truth import announce

__all__ = ["DISCONNECT_EXIT", "EmulatorProcess", "SerialEmulator", "serve", "start_serial_emulator"]

DISCONNECT_EXIT = 3
_OUT_LIMIT = 8 << 20  # bytes queued for a host that does not read before the device overruns


class SerialEmulator:
    """The protocol engine: host bytes in, device bytes out (no I/O; :func:`serve` does the pty)."""

    def __init__(self, device: BenchDevice):
        self.device = device
        self.parser = FrameParser()
        self._seq = 0
        self._delayed: list[tuple[float, bytes]] = []
        cfg = device.config
        self._rng = np.random.default_rng([cfg.seed, 3])
        self.disconnected = False
        self._garbage_sent = False
        # INFO's device name: the marks of the truth, so a host can check its labels (protocol/truth.py)
        self.name = announce(device.bench.name, device.config.truth.marks(device.bench))

    def _frame(self, msg: m.Message, corruptible: bool = True) -> bytes:
        data = msg.frame(self._seq)
        self._seq = (self._seq + 1) & 0xFFFF
        rate = self.device.config.faults.corrupt_rate
        if corruptible and rate and self._rng.random() < rate:
            buf = bytearray(data)
            i = int(self._rng.integers(len(buf)))
            buf[i] ^= 1 << int(self._rng.integers(8))
            data = bytes(buf)
        return data

    def receive(self, data: bytes) -> bytes:
        """Handle host bytes; returns the replies due now (late ones are queued)."""
        out = bytearray()
        now = time.monotonic()
        if self.device.frozen:  # a hung firmware reads nothing and answers nothing
            return b""
        for frame in self.parser.feed(data):
            replies = b"".join(self._frame(r) for r in self._handle(frame))
            delay = self.device.config.faults.reply_delay
            if delay:
                self._delayed.append((now + delay, replies))
            else:
                out += replies
        return bytes(out)

    def _handle(self, frame) -> list[m.Message]:
        d = self.device
        try:
            msg = m.decode(frame)
        except m.ProtocolError:
            known = frame.type in m.MessageType._value2member_map_
            code = m.ErrorCode.BAD_LENGTH if known else m.ErrorCode.UNKNOWN_COMMAND
            return [m.Ack(frame.type, frame.sequence, code)]
        replies: list[m.Message] = []
        try:
            if isinstance(msg, m.GetInfo):
                replies.append(m.Info(m.PROTOCOL_VERSION, d.counts_per_rev, d.config.accel_block,
                                      d.config.encoder_block, self.name))
            elif isinstance(msg, m.Enable):
                d.enable()
            elif isinstance(msg, m.Disable):
                d.disable()
            elif isinstance(msg, m.SetSpeed):
                d.set_speed(msg.speed, msg.acceleration or None)
            elif isinstance(msg, m.SetProfile):
                d.set_profile(list(msg.times), list(msg.speeds), msg.acceleration or None)
            elif isinstance(msg, m.Stop):
                d.stop()
            elif isinstance(msg, m.ConfigureAccel):
                d.configure_accelerometer(msg.range, msg.sample_rate)
            elif isinstance(msg, m.StartStream):
                d.start_stream(accel=bool(msg.mask & 1), encoder=bool(msg.mask & 2))
            elif isinstance(msg, m.StopStream):
                d.stop_stream()
            elif isinstance(msg, m.GetStatus):
                replies.append(self.status())
            elif isinstance(msg, m.ClearFault):
                d.clear_fault()
            elif isinstance(msg, m.Tap):
                d.tap(msg.after, msg.width, msg.peak)
            else:
                return [m.Ack(frame.type, frame.sequence, m.ErrorCode.UNKNOWN_COMMAND)]
        except DeviceError as exc:
            return [m.Ack(frame.type, frame.sequence, exc.code)]
        return replies + [m.Ack(frame.type, frame.sequence, m.ErrorCode.OK)]

    def status(self) -> m.Status:
        d = self.device
        s = d.motor_status()
        acc, enc = d.streaming
        flags = int(s.enabled) | int(acc) << 1 | int(enc) << 2
        fault = m.FaultCode[s.fault.upper()] if s.fault else m.FaultCode.NONE
        return m.Status(s.time, s.angle, s.speed, s.counts, s.index_count, flags, fault, d.range, d.sample_rate)

    def block_message(self, block: AccelBlock | EncoderBlock) -> m.Message:
        if isinstance(block, EncoderBlock):
            return m.EncoderData(block.sequence, block.time, block.sample_rate, block.counts, block.index)
        cfg = self.device.config.accelerometer
        lsb = self.device.lsb
        if not cfg.adc_bits:
            return m.AccelData(block.sequence, block.time, block.sample_rate, 1.0, m.SampleFormat.FLOAT32,
                               block.samples)
        counts = np.rint(block.samples.astype(np.float64) / float(np.float32(lsb)))
        fmt = m.SampleFormat.INT16 if cfg.clipping else m.SampleFormat.INT32
        return m.AccelData(block.sequence, block.time, block.sample_rate, lsb, fmt, counts)

    def poll(self) -> bytes:
        """Stream blocks, events and late replies that are due now."""
        out = bytearray()
        now = time.monotonic()
        if self.device.frozen:
            return b""
        while self._delayed and self._delayed[0][0] <= now:
            out += self._delayed.pop(0)[1]
        for block in self.device.read():
            out += self._frame(self.block_message(block))
        for ev in self.device.events():
            out += self._frame(m.Event(ev.time, ev.code, ev.message))
        f = self.device.config.faults
        if not self._garbage_sent and self.device.fault_due(f.garbage_at):
            self._garbage_sent = True  # line noise between two frames
            out += self._rng.integers(0, 256, f.garbage_bytes, dtype=np.uint8).tobytes()
        after = self.device.config.faults.disconnect_after
        st = self.device.stream_time()
        if after is not None and st is not None and st >= after:
            out += self._frame(m.Event(self.device.clock(), m.FaultCode.DISCONNECT, "link going down (injected)"),
                               corruptible=False)
            self.disconnected = True
        return bytes(out)


def serve(bench: Bench, config: EmulatorConfig | None = None, *, announce=print,
          sent_log: BinaryIO | None = None, period: float = 0.002, speedup: float = 1.0) -> int:
    """Run the serial emulator on a new pty until SIGTERM/SIGINT (returns 0) or an injected disconnect (3)."""
    device = BenchDevice(bench, config, MonotonicClock(speedup))
    device.prepare(bench.speed)
    master, slave = os.openpty()
    tty.setraw(slave)
    os.set_blocking(master, False)
    engine = SerialEmulator(device)
    stop = {"flag": False}

    def on_signal(signum, frame):
        stop["flag"] = True

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    announce(os.ttyname(slave))
    out = bytearray()
    try:
        while not stop["flag"]:
            r, _w, _ = select.select([master], [master] if out else [], [], period)
            if r:
                try:
                    data = os.read(master, 65536)
                except (BlockingIOError, InterruptedError):
                    data = b""
                if data:
                    out += engine.receive(data)
            out += engine.poll()
            if len(out) > _OUT_LIMIT:  # host not reading: the device's UART buffer overruns
                del out[:len(out) - _OUT_LIMIT // 2]
            if out:
                try:
                    n = os.write(master, out)
                except (BlockingIOError, InterruptedError):
                    n = 0
                if sent_log is not None and n:
                    sent_log.write(out[:n])
                    sent_log.flush()  # readable while the emulator runs (a test compares it mid-session)
                del out[:n]
            if engine.disconnected and not out:
                time.sleep(0.2)  # let the host read the last frames before the port vanishes
                return DISCONNECT_EXIT
        return 0
    finally:
        if sent_log is not None:
            sent_log.flush()
        os.close(master)
        os.close(slave)


class EmulatorProcess:
    """A serial emulator running in its own process (see :func:`start_serial_emulator`).

    ``port`` is the pty path; ``terminate``/``kill`` stop it, ``wait`` returns its exit code
    (0 when stopped, :data:`DISCONNECT_EXIT` after an injected disconnect)."""

    def __init__(self, process: multiprocessing.process.BaseProcess, port: str):
        self._process, self.port = process, port

    @property
    def pid(self) -> int | None:
        return self._process.pid

    @property
    def returncode(self) -> int | None:
        return self._process.exitcode

    def poll(self) -> int | None:
        return self._process.exitcode

    def terminate(self) -> None:
        self._process.terminate()

    def kill(self) -> None:
        self._process.kill()

    def wait(self, timeout: float | None = None) -> int:
        self._process.join(timeout)
        if self._process.exitcode is None:
            raise TimeoutError(f"serial emulator (pid {self.pid}) still running after {timeout} s")
        return self._process.exitcode


def _serve_from_file(bench_path: str, table: dict | None, sent_log: str | None, conn, speedup: float) -> None:
    """Child process: read the bench file, build the device, serve; the port path goes to ``conn``."""
    bench = load_bench(bench_path)
    config = (EmulatorConfig.from_table(table, bench=bench, source="start_serial_emulator")
              if table is not None else EmulatorConfig.from_bench(bench))

    def announce(path: str) -> None:
        conn.send(path)
        conn.close()

    if sent_log is None:
        sys.exit(serve(bench, config, announce=announce, speedup=speedup))
    with open(sent_log, "ab") as log:
        sys.exit(serve(bench, config, announce=announce, sent_log=log, speedup=speedup))


def start_serial_emulator(bench: Bench, config: EmulatorConfig | Mapping | None = None, *,
                          sent_log: str | Path | None = None, timeout: float = 120.0, speedup: float = 1.0
                          ) -> tuple[EmulatorProcess, str]:
    """Run :func:`serve` for ``bench`` in its own process; returns (process, port path).

    ``config`` (an :class:`EmulatorConfig` or a raw ``[emulator]`` table) replaces the bench file's
    table. The caller terminates the process (``proc.terminate(); proc.wait()``). ``timeout`` covers
    the first model signal table, which may be computed at start-up. The process reads the bench
    from its file, so a bench changed in memory is refused (its file would not hold the change).
    """
    if bench.path is not None:
        file_bench = load_bench(bench.path)
        on_file = {j.name: j.clearance for j in file_bench.clearance_joints}
        if on_file != {j.name: j.clearance for j in bench.clearance_joints}:
            raise ValueError(f"{bench.path}: the bench was changed in memory (clearances); the emulator process "
                             "reads the file, so give the device its clearances with [emulator.truth] instead")
        if bench_key(file_bench) != bench_key(bench):
            raise ValueError(f"{bench.path}: the bench was changed in memory (masses, geometry, contact or "
                             "tolerances); the emulator process reads the file: save the bench to a file first")
    tmp = Path(tempfile.mkdtemp(prefix="wearbench-emu-"))
    bench_path = bench.path if bench.path is not None else tmp / f"{bench.name}.toml"
    if bench.path is None:
        bench_path.write_text(bench.source)
    table = None
    if config is not None:  # as a JSON file would carry it
        table = json.loads(json.dumps(config.to_table() if isinstance(config, EmulatorConfig) else dict(config)))
    # not fork: the caller may hold threads (a recorder per session, a compute client). A fork
    # server (one clean process, this module imported once) forks each emulator in milliseconds
    # where spawn imports numpy and scipy again for every one (seconds).
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload([__name__])
    receive, send = context.Pipe(duplex=False)
    process = context.Process(target=_serve_from_file, name=f"wearbench-emulator-{bench.name}", daemon=True,
                              args=(str(bench_path), table, None if sent_log is None else str(sent_log), send,
                                    float(speedup)))
    try:
        process.start()
    except OSError as exc:  # the fork server listens on a socket in the temporary folder
        shutil.rmtree(tmp, ignore_errors=True)
        if "AF_UNIX path too long" not in str(exc):
            raise
        raise RuntimeError(f"serial emulator for {bench.name}: multiprocessing's fork server could not open its socket "
                           f"in the temporary folder {tempfile.gettempdir()!r} ({exc}); a socket's path holds at "
                           "most 107 bytes: set TMPDIR to a shorter folder") from None
    send.close()
    port = ""
    try:
        if receive.poll(timeout):
            port = receive.recv()
    except EOFError:  # the child ended before it announced a port
        pass
    finally:
        receive.close()
        shutil.rmtree(tmp, ignore_errors=True)  # read at start-up only
    if not port.startswith("/dev/"):
        process.kill()
        process.join(10)
        raise RuntimeError(f"serial emulator for {bench.name} did not start within {timeout:g} s (exit code "
                           f"{process.exitcode}); run `wearbench emulate {bench_path} --serial` to see why")
    return EmulatorProcess(process, port), port
