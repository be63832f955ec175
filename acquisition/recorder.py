"""The session recorder: warm-up, steady speed, record, ramp down, and a valid MCAP whatever happens.

Threads: one reader per acceleration source (``source.read`` -> bounded queue; blocks the device
stamped before a completed session's end are kept, after any other stop every block until the
stream stops, also those still waiting in the source when it halts), one writer (queue
-> :class:`SessionWriter`, counts dropped and repeated block sequence numbers), and the calling
thread, which commands the drive, polls its state and watches the stop conditions. Any thread
that fails calls :meth:`Recorder.stop` with the reason; the first reason wins, is written as an
event, and every path ends in ``SessionWriter.finish``. Imports no backend library.
"""

from __future__ import annotations

import errno
import math
import queue
import signal
import threading
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import BinaryIO

import numpy as np
from wearbench.acquisition.drivers import (
    ACCELERATION,
    ENCODER,
    Block,
    BusFrame,
    DeviceDisconnected,
    DeviceTimeout,
    Event,
    MotorState,
    Rig,
)
from wearbench.acquisition.layout import (
    BENCH_ATTACHMENT,
    BENCH_FILES,
    Command,
    bench_files,
    clip_level,
    count_clipped,
    record_crank,
    record_stream,
    result_record,
    session_records,
    surface_attachment,
)
from wearbench.acquisition.sequence import SequenceCheck
from wearbench.acquisition.session import Progress, SessionPlan, SessionResult
from wearbench.acquisition.session_writer import SessionWriter
from wearbench.bench.schema import Bench
from wearbench.hardware.protocol.taps import TAP_EVENT

__all__ = ["Recorder", "record_session", "revolutions_played"]

_PULSE_MARGIN = 0.05  # revolutions recorded past the index pulse that closes the last cycle
_PULSE_WAIT = 2.0  # revolutions past the planned ones the drive may turn while the closing pulse is awaited
_SPEED_POLLS = 0.1  # s past the ramp before the recorder sees the motor at speed (0.05 measured at 5000 rpm)
_FINISH_TRIES = 5  # attempts at finishing a file whose disk is full, 0.2 s, 0.4 s, ... apart
_DRAIN_LIMIT = 2.0  # s a tap session waits past its last interval for the accelerometer stream to catch up


def revolutions_played(bench: Bench, plan: SessionPlan) -> float:
    """The most motor revolutions a session of ``plan``'s ``cycles`` turns from the motor's start to its
    last recorded sample: the ramp to speed, the polls until the recorder sees the speed, the hold at
    speed (``settle``), then up to one crank turn to the first index pulse, the cycles, the margin
    past the closing pulse and the wait for a late one (a stream without pulses ends sooner)."""
    if plan.cycles is None:
        raise ValueError("revolutions_played: the plan records a duration, not cycles")
    w = abs(plan.speed)
    start = w * (w / (2 * (plan.acceleration or bench.motor.max_acceleration)) + _SPEED_POLLS + plan.settle)
    return start / (2 * math.pi) + (plan.cycles + 1 + _PULSE_MARGIN + _PULSE_WAIT) / abs(bench.encoder_driver.ratio)


def _failure_reason(exc: Exception, what: str) -> str:
    """The stop reason recorded when `exc` ends a session inside `what`."""
    if isinstance(exc, DeviceDisconnected):
        return f"device disconnected: {exc}"
    if isinstance(exc, DeviceTimeout):
        return f"device stopped answering: {exc}"
    return f"{what} failed: {type(exc).__name__}: {exc}"


class Recorder:
    """Runs one session on ``rig`` and writes it to ``out`` (a path or an unbuffered binary file).

    ``queue_size`` (items between the readers and the writer; default: a quarter of the writer's
    ballast at 1 KiB an item, 64 to 4096) bounds what waits in memory when the disk fills."""

    def __init__(self, rig: Rig, bench: Bench, plan: SessionPlan, out: str | Path | BinaryIO, *,
                 on_progress: Callable[[Progress], None] | None = None, queue_size: int | None = None,
                 writer: SessionWriter | None = None):
        self.rig, self.bench, self.plan = rig, bench, plan
        self.writer = writer or SessionWriter(out)
        self.on_progress = on_progress
        if queue_size is None:
            reserve = getattr(self.writer, "reserve", 0)
            queue_size = min(4096, max(64, reserve // 4 // 1024)) if reserve else 4096
        self._queue: queue.Queue = queue.Queue(maxsize=queue_size)
        self._stop = threading.Event()  # the session should end
        self._halt = threading.Event()  # the readers should end (after the ramp-down)
        self._reason: str | None = None
        self._reason_lock = threading.Lock()
        self._recording = threading.Event()
        self._writer_done = threading.Event()
        self._checks = {ACCELERATION: SequenceCheck(), ENCODER: SequenceCheck()}
        self._malformed = 0
        self._events = 0
        self._cpu: dict[str, float] = {}
        self._acc_rate = (0.0, time.monotonic(), 0)  # (rate, t, samples at t)
        self._acc_end = -math.inf  # device time just after the last acceleration sample handed to the writer
        self._latches: list[float] = []  # device times of the taps the drive latched (tap events)
        self._device_now: float | None = None  # latest device time seen (drive state)
        self._recorded_until = -math.inf  # device time: blocks stamped before it are kept after recording ends
        self._overflow: list = []
        self._lost = 0  # items the writer could not encode
        self._signal: str | None = None  # SIGINT/SIGTERM seen by the handler
        self._clip_level = math.inf  # |a| from which an acceleration sample is clipped
        self._clipping = False  # the last acceleration block had clipped samples
        self._clipped = 0
        self._write_failures = 0
        self._pulses = 0  # index pulses (rising edges) in the recorded encoder blocks
        self._index_high: bool | None = None  # the last recorded encoder sample's index flag (None: none yet)
        self._pulses_needed = 0  # the pulse that closes the last planned cycle (0: none planned)
        self._margin_time = 0.0  # s the crank takes to turn _PULSE_MARGIN
        self._cut = math.inf  # device time: that pulse's own time plus the margin; no block from it is recorded

    # ---- stopping ---------------------------------------------------------------------------

    def stop(self, reason: str, kind: str = "stop") -> None:
        """Ask the session to stop; the first reason is the one recorded."""
        with self._reason_lock:
            if self._reason is None:
                self._reason = reason
                self._post(Event(kind, reason, device_time=self._device_now))
        self._stop.set()

    def _on_signal(self, signum: int, frame: object) -> None:
        self._signal = signal.Signals(signum).name

    def _check_signal(self) -> None:
        if self._signal is not None:
            self.stop(f"interrupted ({self._signal})", "interrupt")

    @property
    def reason(self) -> str | None:
        return self._reason

    def _post(self, item: object) -> None:
        """Queue an item for the writer; never blocks (events and states are small)."""
        try:
            self._queue.put_nowait(item)
        except queue.Full:
            self._overflow.append(item)  # written by _finish

    # ---- threads ----------------------------------------------------------------------------

    def _reader(self, source) -> None:
        last_block = self.rig.clock.now()  # silence counts on the bench's clock (sim: device time)
        drain_until: float | None = None  # monotonic deadline of the last reads after the halt
        try:
            while True:
                if drain_until is None and self._halt.is_set():  # what the source still holds from
                    drain_until = time.monotonic() + 2.0  # before the stop is recorded too (bounded)
                items = source.read(timeout=0.1 if drain_until is None else 0.0)
                now, got_blocks = self.rig.clock.now(), any(isinstance(i, Block) for i in items)
                drained = drain_until is not None and (not got_blocks or time.monotonic() > drain_until)
                if got_blocks:
                    last_block = now
                elif drain_until is None and now - last_block > self.plan.silence_timeout:
                    raise DeviceTimeout(f"{source.name}: no data for {now - last_block:.1f} s")
                recording, until = self._recording.is_set(), self._recorded_until
                for item in items:
                    if isinstance(item, Block):
                        if item.host_time == 0.0:
                            item.host_time = time.time()
                        if not (recording or item.device_time < until) or not item.device_time < self._cut:
                            continue  # kept: what was queued before the stop and reaches no further than the cut
                        if item.stream == ENCODER and item.index is not None and len(item.index):
                            self._count_pulses(item)
                    elif isinstance(item, Event) and item.device_time is None:
                        item.device_time = self._device_now
                    elif isinstance(item, Event) and item.kind == TAP_EVENT:
                        self._latches.append(item.device_time)
                    if isinstance(item, Event) and item.kind == "malformed":
                        self._malformed += 1
                        if self._malformed > self.plan.max_malformed:
                            self._post(item)
                            self.stop(f"{source.name}: more than {self.plan.max_malformed} malformed "
                                      f"frames ({item.message})", "error")
                            return
                    try:
                        self._queue.put(item, timeout=self.plan.silence_timeout)
                    except queue.Full:
                        self.stop("the writer cannot keep up: the recording queue stayed full", "error")
                        return
                if drained:
                    return
        except Exception as exc:  # noqa: BLE001 - any failure ends the session cleanly
            self.stop(_failure_reason(exc, f"{source.name} reader"), "error")
        finally:
            self._cpu[f"reader:{source.name}"] = time.thread_time()

    def _count_pulses(self, block: Block) -> None:
        """Count the index pulses (rising edges) of a recorded encoder block; at the pulse that closes the
        last planned cycle, set the cut on the stream's own clock (its edge's time plus the margin), so a
        stream that lags the drive records no more, and a drive state that lags it ends nothing early.
        The first recorded sample is no edge, flagged or not: its pulse fired before it, where nothing was
        recorded, so no cycle of the session starts there (``validation.measurement.cycles`` places a pulse
        between its sample and the one before)."""
        high = np.asarray(block.index, dtype=bool)
        before = high[0] if self._index_high is None else self._index_high
        edges = np.flatnonzero(high & ~np.concatenate([[before], high[:-1]]))
        self._index_high = bool(high[-1])
        closing = self._pulses_needed - self._pulses - 1
        if 0 <= closing < len(edges):
            self._cut = block.device_time + edges[closing] / block.sample_rate + self._margin_time
        self._pulses += len(edges)

    def _clip_check(self, block: Block) -> Event | None:
        """Count the block's clipped samples; the warning event when clipping starts."""
        block.clipped = count_clipped(block.samples, self._clip_level)
        self._clipped += block.clipped
        starts, self._clipping = block.clipped > 0 and not self._clipping, block.clipped > 0
        if not starts:
            return None
        self._events += 1
        return Event("clipping", f"acceleration clipping: {block.clipped} of {len(block.samples)} samples of "
                     f"block {block.sequence} at or beyond the range (|a| >= {self._clip_level:.6g} m/s^2)",
                     device_time=block.device_time)

    def _write(self, item: object) -> None:
        """Hand ``item`` (and the events it causes) to the writer. The writer keeps what it was
        handed even when the file write fails (OSError: the bytes wait in memory), so every part
        is handed over before the first such error is raised."""
        w = self.writer
        if isinstance(item, Block):
            broken = self._checks[item.stream].check(item.stream, item.sequence, len(item.samples))
            events = [None]
            if item.stream == ACCELERATION:
                events = [self._clip_check(item)]
                self._acc_end = max(self._acc_end, item.device_time + len(item.samples) / item.sample_rate)
            if broken:
                self._events += 1
                events.append(Event(broken.kind, broken.note, device_time=item.device_time))
            error = None
            for part in (item, *filter(None, events)):
                try:
                    if part is item:
                        w.write_block(item)
                    else:
                        w.write_event(part)
                except OSError as exc:
                    error = error or exc
            if error is not None:
                raise error
        elif isinstance(item, MotorState):
            w.write_state(item)
        elif isinstance(item, Command):
            w.write_command(item)
        elif isinstance(item, Event):
            self._events += 1
            w.write_event(item)
        elif isinstance(item, BusFrame):
            w.write_frame(item)

    def _write_failed(self, exc: OSError) -> None:
        """A write failed (its bytes wait in memory): the first failure stops the session with
        ``disk full`` (ENOSPC) or ``writing the session failed`` and gives the ballast back."""
        self._write_failures += 1
        if self._write_failures > 1:
            return
        what = "disk full" if exc.errno == errno.ENOSPC else "writing the session failed"
        self.stop(f"{what}: {exc}", "error")
        freed = self.writer.release_ballast()
        room = getattr(self.writer, "room", 0)
        how = ("released the ballast file and " if freed else
               f"in the {room / 1024:.0f} KiB reserved inside the file: " if room else "")
        self._post(Event("error", f"{what}; {how}finishing the file with what was recorded",
                         device_time=self._device_now))

    def _writer_loop(self) -> None:
        try:
            while True:
                try:
                    item = self._queue.get(timeout=0.1)
                except queue.Empty:
                    if self._writer_done.is_set():
                        break
                    continue
                try:
                    self._write(item)
                except OSError as exc:  # the item is in the writer; the failed bytes wait in memory
                    self._write_failed(exc)
                except Exception as exc:  # noqa: BLE001 - one bad item must not end the writer
                    self._lost += 1
                    self.stop(f"writer failed: {type(exc).__name__}: {exc}", "error")
        finally:
            self._cpu["writer"] = time.thread_time()

    # ---- the session ------------------------------------------------------------------------

    def _metadata(self) -> dict[str, dict[str, str]]:
        """The session's metadata records; sets the writer's crank angle and the clip level (of the
        acceleration stream's range and LSB, recorded with it by ``record_stream``)."""
        rig = self.rig
        records = session_records(self.bench, self.plan, rig.backend, rig.info,
                                  time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()))
        calibration = records["calibration"]
        try:
            state: MotorState | Exception = self._poll()
        except Exception as exc:  # noqa: BLE001 - a drive that cannot answer shows up again in _run
            state = exc
        crank = record_crank(calibration, state)
        if crank is not None:
            self.writer.crank = crank
        for source in rig.sources:
            for info in source.describe():
                if info.name == ACCELERATION:
                    if info.range is None:  # a device that does not say: the range it was configured with
                        info = replace(info, range=self.bench.sensor("accelerometer").range)
                    self._clip_level = clip_level(info.range, info.lsb)  # what the reader applies too
                record_stream(calibration, info, source.name)
        return records

    def _command(self, command: str, speed: float | None = None, acceleration: float | None = None) -> None:
        self._post(Command(command, speed, acceleration, time.time()))
        drive = self.rig.drive
        if command == "enable":
            drive.enable()
        elif command == "disable":
            drive.disable()
        elif command == "stop":
            drive.stop(acceleration)
        else:
            drive.set_speed(speed, acceleration)

    def _poll(self) -> MotorState:
        s = self.rig.drive.state()
        if s.host_time == 0.0:
            s = MotorState(**{**s.__dict__, "host_time": time.time()})
        self._device_now = s.device_time
        self._post(s)
        return s

    def _progress(self, prog: Progress) -> None:
        rate, t0, n0 = self._acc_rate
        now, n = time.monotonic(), self._checks[ACCELERATION].samples
        if now - t0 > 0.5:
            rate = (n - n0) / (now - t0)
            self._acc_rate = (rate, now, n)
        prog.sample_rate = rate
        prog.dropped = sum(c.dropped_samples for c in self._checks.values())
        if self.on_progress:
            self.on_progress(prog)

    def _wait(self, seconds: float, prog: Progress, until: Callable[[MotorState], bool] | None = None) -> MotorState | None:
        """Poll the drive for ``seconds`` of the rig's clock (or until ``until``); None if stopped."""
        clock = self.rig.clock
        end = clock.now() + seconds
        while True:
            self._check_signal()
            if self._stop.is_set():
                return None
            s = self._poll()
            if s.fault:
                self.stop(f"drive fault: {s.fault}", "fault")
                return None
            self._progress(prog)
            if (until is not None and until(s)) or clock.now() >= end:
                return s
            clock.sleep(self.plan.state_interval)

    def _surface_attachments(self) -> dict[str, tuple[str, bytes]]:
        """The worn-surface files the wear state and the bench file name, embedded so the session is
        self-contained (its bench loads wherever the session is moved)."""
        out = {}
        for joint, state in self.plan.wear.items():
            if Path(state).suffix == ".npz" and Path(state).is_file():
                out[surface_attachment(joint)] = ("application/x-npz", Path(state).read_bytes())
        for relative, path in bench_files(self.bench).items():
            out[BENCH_FILES + relative] = ("application/x-npz", path.read_bytes())
        return out

    def _crank_ratio(self) -> float:
        """Speed ratio of the encoder's crank to the motor."""
        return self.bench.encoder_driver.ratio

    def _run_taps(self, prog: Progress) -> None:
        """The tap test: cranks at rest, ``plan.taps`` taps ``tap_interval`` apart, each latched by the
        drive (its latch arrives as a "tap" event from the sources), then one interval to let the last die away."""
        p, rig = self.plan, self.rig
        peak = p.tap_peak or 0.25 * float(self.bench.sensor("accelerometer").range or 50 * 9.80665)
        prog.target = p.taps * p.tap_interval  # s; the cranks stay at rest (no cycles)
        self._command("enable")  # the drive holds the cranks at rest
        for source in rig.sources:
            source.start()
        if self._wait(p.settle, prog) is None:
            return
        prog.phase = "record"
        self._recording.set()
        start = self._poll().device_time
        self._post(Event("phase", f"record: {p.taps} taps at rest, {p.tap_interval:g} s apart (half-sine "
                         f"{p.tap_width * 1e3:g} ms, peak {peak:g} m/s^2)", device_time=start))
        for _ in range(p.taps):
            rig.drive.tap(0.25 * p.tap_interval, p.tap_width, peak)
            s = self._wait(p.tap_interval, prog)
            if s is None:
                return
            prog.elapsed = s.device_time - start
        # On a busy host the tap latches late after its command and the stream lags the drive's state:
        # record until the accelerometer's samples reach as far past the last latch as the plan gives a
        # tap (three quarters of an interval), so the last tap keeps its whole response (within a bound).
        def covered(_: MotorState) -> bool:
            return len(self._latches) >= p.taps and self._acc_end >= self._latches[-1] + 0.75 * p.tap_interval

        if self._wait(_DRAIN_LIMIT, prog, until=covered) is None:
            return
        self.stop("completed", "phase")

    def _run(self, prog: Progress) -> None:
        p, rig = self.plan, self.rig
        if p.taps:
            self._run_taps(prog)
            return
        acc = p.acceleration or self.bench.motor.max_acceleration
        prog.target = p.cycles if p.cycles is not None else p.duration
        self._command("enable")
        for source in rig.sources:
            source.start()
        prog.phase = "warm-up"
        self._post(Event("phase", f"warm-up: ramp to {p.speed:.4g} rad/s at {acc:.4g} rad/s^2",
                         device_time=self._device_now))
        self._command("set_speed", p.speed, acc)
        ramp = abs(p.speed) / acc
        crank = self._crank_ratio() * p.speed  # the drive reports the encoder crank's speed
        s = self._wait(2 * ramp + 5.0, prog,
                       until=lambda s: abs(s.speed - crank) <= p.speed_tolerance * abs(crank))
        if s is None:
            return
        if abs(s.speed - crank) > p.speed_tolerance * abs(crank):
            self.stop(f"the motor did not reach {p.speed:.4g} rad/s within {2 * ramp + 5:.3g} s "
                      f"(crank speed {s.speed:.4g} rad/s, expected {crank:.4g}): stalled?", "fault")
            return
        if self._wait(p.settle, prog) is None:
            return
        prog.phase = "record"
        # Cycles run from index pulse to index pulse (validation.cycles), so `cycles` complete ones
        # need ceil(cycles) + 1 pulses in the recorded encoder blocks, counted by the reader, which
        # ends the recording a margin past the last one's own time (the drive's state may lag the
        # stream or run ahead of it). A stream without index pulses records one revolution more by
        # the drive's count; one whose pulses stop waits a bounded number of revolutions for them.
        self._pulses_needed = math.ceil(p.cycles) + 1 if p.cycles is not None else 0
        self._margin_time = _PULSE_MARGIN * 2 * math.pi / abs(crank)
        self._recording.set()
        start = self._poll()
        self._post(Event("phase", f"record: steady at {start.speed:.4g} rad/s", device_time=start.device_time))
        while not self._stop.is_set():
            s = self._wait(0.0, prog)
            if s is None:
                return
            prog.cycles = abs(s.angle - start.angle) / (2 * math.pi)  # revolutions of the encoder crank
            prog.elapsed = s.device_time - start.device_time
            beyond = prog.cycles - (p.cycles or 0.0) - 1 - _PULSE_MARGIN  # revolutions past a pulseless stream's end
            if (p.cycles is not None and (self._cut < math.inf or beyond >= (_PULSE_WAIT if self._pulses else 0.0))) or (
                    p.duration is not None and prog.elapsed >= p.duration):
                self.stop("completed", "phase")
                return
            rig.clock.sleep(p.state_interval)

    def _shutdown(self, prog: Progress) -> None:
        if self._recording.is_set():  # what the device sent up to the stop is still recorded; after
            # a fault or an interruption also what comes until the stream stops (the data around a
            # fault is what a lab looks at first; the drive may report it before the blocks arrive)
            completed = self._reason == "completed" and self._device_now is not None
            # at the cut when the closing pulse came, which the drive's state may lag
            self._recorded_until = (self._cut if self._cut < math.inf else self._device_now) if completed else math.inf
        self._recording.clear()
        prog.phase = "ramp-down"
        drive, clock = self.rig.drive, self.rig.clock
        acc = self.plan.acceleration or self.bench.motor.max_acceleration
        ramp = abs(self.plan.speed) / acc
        try:
            self._command("stop", None, acc)
            end, clock_end = time.monotonic() + ramp + 3.0, clock.now() + ramp + 1.0
            while time.monotonic() < end and clock.now() < clock_end:  # bounded on both clocks
                if abs(self._poll().speed) < 1e-3:
                    break
                clock.sleep(self.plan.state_interval)
            self._command("disable")
        except Exception as exc:  # noqa: BLE001 - a dead drive cannot ramp down; the file still gets finished
            self._post(Event("error", f"ramp-down: {type(exc).__name__}: {exc}", device_time=self._device_now))
            try:
                drive.disable()
            except Exception as exc2:  # noqa: BLE001 - any failure ends the session cleanly
                self._post(Event("error", f"disable: {type(exc2).__name__}: {exc2}"))
        for source in self.rig.sources:
            try:
                source.stop()
            except Exception as exc:  # noqa: BLE001 - any failure ends the session cleanly
                self._post(Event("error", f"{source.name}: stopping the stream: {type(exc).__name__}: {exc}"))

    def run(self) -> SessionResult:
        """Record the session; returns why it ended. Installs SIGINT/SIGTERM handlers when on
        the main thread so Ctrl-C stops the session cleanly instead of tearing it."""
        old = {}
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):  # the handler only notes the signal: it
                old[sig] = signal.signal(sig, self._on_signal)  # must not take a lock the main thread holds
        try:
            prog = Progress()
            try:  # before the metadata, which records the streams as configured (range, LSB, rate)
                accel = self.bench.sensor("accelerometer")
                for source in self.rig.sources:
                    source.configure(accel.range, accel.sample_rate)
            except Exception as exc:  # noqa: BLE001 - the file still records what happened
                self.stop(_failure_reason(exc, "configuring the stream"), "error")
            try:
                self.writer.start(self._metadata(), {BENCH_ATTACHMENT: ("application/toml",
                                                                        self.bench.source.encode()),
                                                     **self._surface_attachments()})
            except OSError as exc:  # a full disk already: nothing to record, the file still gets finished
                self._write_failed(exc)
            readers = [threading.Thread(target=self._reader, args=(s,), name=f"reader-{s.name}", daemon=True)
                       for s in self.rig.sources]
            writer = threading.Thread(target=self._writer_loop, name="writer", daemon=True)
            writer.start()
            started = False
            try:
                if not self._stop.is_set():
                    for t in readers:
                        t.start()
                    started = True
                    self._run(prog)
            except KeyboardInterrupt:
                self.stop("interrupted (KeyboardInterrupt)", "interrupt")
            except Exception as exc:  # noqa: BLE001 - any failure ends the session cleanly
                self.stop(_failure_reason(exc, "session"), "error")
            self._check_signal()
            self.stop("stopped", "stop")  # no-op when a reason is already set
            self._shutdown(prog)
            self._halt.set()
            if started:
                for t in readers:
                    t.join(timeout=5.0)
            self._writer_done.set()
            writer.join(timeout=30.0)
            return self._finish(prog)
        finally:
            for sig, handler in old.items():
                signal.signal(sig, handler)

    def _result(self, prog: Progress) -> SessionResult:
        c = self._checks
        return SessionResult(
            path=self.writer.path, reason=self._reason or "stopped", completed=self._reason == "completed",
            cycles=prog.cycles, duration=prog.elapsed,
            blocks={k: v.blocks for k, v in c.items()}, samples={k: v.samples for k, v in c.items()},
            dropped_blocks={k: v.dropped for k, v in c.items()},
            dropped_samples={k: v.dropped_samples for k, v in c.items()},
            repeated_blocks={k: v.repeated for k, v in c.items()}, malformed=self._malformed,
            events=self._events, clipped=self._clipped, writer_cpu=self._cpu.get("writer", 0.0),
            reader_cpu=sum(v for k, v in self._cpu.items() if k.startswith("reader")))

    def _finish(self, prog: Progress) -> SessionResult:
        """Write what is still queued, the result record and the summary; a full disk gets one
        more try after the ballast is released."""
        w = self.writer
        pending = []
        while True:
            try:
                pending.append(self._queue.get_nowait())
            except queue.Empty:
                break
        pending += self._overflow
        while pending:
            item = pending.pop(0)
            try:
                self._write(item)
            except OSError:
                pass  # accepted: its bytes wait in the file's backlog for w.finish()
            except Exception:  # noqa: BLE001 - an item that cannot be encoded is counted, not fatal
                self._lost += 1
        r = self._result(prog)
        try:
            w.add_metadata("result", result_record(r, self._lost))
        except OSError:
            pass  # accepted, as above
        for attempt in range(_FINISH_TRIES):  # space may come back (the ballast, another process)
            try:  # a forced session replaces the old file only when it recorded its whole target
                w.finish(replace=r.completed)
                r.path = w.path
                return r
            except OSError as exc:
                w.release_ballast()
                if attempt == _FINISH_TRIES - 1:
                    raise OSError(exc.errno, f"{r.reason}; the session file could not be finished ({exc}); "
                                  "it holds every chunk written: run 'wearbench recover' on it",
                                  str(w.path) if w.path else None) from exc
                time.sleep(0.2 * (attempt + 1))
        raise AssertionError("unreachable")


def record_session(rig: Rig, bench: Bench, plan: SessionPlan, out: str | Path | BinaryIO,
                   **kwargs) -> SessionResult:
    """Record one session on ``rig`` to ``out`` and close the rig."""
    try:
        return Recorder(rig, bench, plan, out, **kwargs).run()
    finally:
        rig.close()
