"""The emulated bench: motor drive with encoder, and the accelerometer (the device contract).

:class:`BenchDevice` is transport-free: the serial and CAN emulators wrap it, the ``sim`` backend
uses it directly. Time comes from ``clock`` (seconds, monotonic); :meth:`BenchDevice.read` returns
every block completed up to the clock's now, so the device runs in real time under a wall clock and
as fast as a test likes under a :class:`ManualClock`.

Motor: the nominal (commanded) speed ramps to the commanded speed at the acceleration limit; the
true motor turns at ``s`` times it with a speed ripple of relative amplitude r at harmonic k of the
motor angle and phase phi. With ``psi = k sigma s theta_n + phi`` (sigma: the sign of the bench's
speed) the closed form is ``theta = s theta_n + sigma (r/k)(cos phi - cos psi)``,
``omega = s omega_n (1 + r sin psi)``. A twin truth has s = 1, phi = 0 and the ``[emulator.motor]``
ripple; a truth with a seed takes s, r, phi (k = 1) from its realisation
(:func:`wearbench.model.realisation.draw_realisation`), the same motion its model run was simulated
with, so the encoder and the acceleration belong to one motion. The encoder and the motor status
report the true motion.
Accelerometer: the model signal at the true motor angle of each instant (minus the truth delay) at
the sensor chain's internal rate, then the chain of :mod:`wearbench.hardware.emulators.sensor`
(mounting resonance, cross-axis part, anti-alias filter, sampling, bias, noise, clipping, ADC); with
cross-axis on, the model table's lateral force is played at the same instants (zero for the test
signals). The sample clock runs
at ``rate (1 + drift)`` while blocks are stamped at the nominal rate. Clipped samples are counted
(:attr:`BenchDevice.clipped_samples`) and reported as INFO events, at most one a second.
Taps (:meth:`BenchDevice.tap`, the tap test): a half-sine pulse added to the sensor body's acceleration
before the same sensor chain and delay as the mechanism's signal, its trigger edge latched on the
encoder's clock (to 1 us, jittered within it) and reported as a TAP event (hardware/protocol/taps.py).
Faults of the device itself: dropped blocks, a stalled motor, a hung firmware (``freeze_at``: no
blocks and no events from then on; the transports stop replying too) and a lost index pulse
(``index_lost_at``: the encoder blocks carry no index pulse from then on).
Imports the bench, the protocol records and codes, config, signal and sensor, lazily the model's
realisation; not the transports.
"""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass

import numpy as np
from wearbench.bench.schema import Bench, Sensor
from wearbench.hardware.emulators.config import EmulatorConfig
from wearbench.hardware.emulators.sensor import SensorChain
from wearbench.hardware.emulators.signal import SignalTable, signal_table
from wearbench.hardware.protocol.blocks import AccelBlock, EncoderBlock, MotorStatus
from wearbench.hardware.protocol.messages import ErrorCode, FaultCode
from wearbench.hardware.protocol.taps import LATCH_RESOLUTION, MAX_TAP_WIDTH, tap_message

__all__ = [
    "MAX_SAMPLE_RATE",
    "MIN_SAMPLE_RATE",
    "AccelBlock",
    "BenchDevice",
    "DeviceError",
    "DeviceEvent",
    "EncoderBlock",
    "ManualClock",
    "MonotonicClock",
    "MotorStatus",
    "Tap",
    "table_speed",
]

TWO_PI = 2 * math.pi
MAX_SAMPLE_RATE = 200_000.0
MIN_SAMPLE_RATE = 100.0


class DeviceError(RuntimeError):
    """A command the device refuses; ``code`` is the protocol :class:`ErrorCode`."""

    def __init__(self, code: ErrorCode, message: str):
        self.code = ErrorCode(code)
        super().__init__(f"{self.code.name}: {message}")


@dataclass(frozen=True)
class DeviceEvent:
    """A fault or event at device ``time`` (s)."""

    time: float
    code: FaultCode
    message: str


class ManualClock:
    """A clock tests move by hand: ``clock.advance(0.5)``."""

    def __init__(self, start: float = 0.0):
        self.now = float(start)

    def __call__(self) -> float:
        return self.now

    def advance(self, dt: float) -> float:
        self.now += float(dt)
        return self.now


class MonotonicClock:
    """Seconds since construction, from ``time.monotonic``, ``speedup`` times faster than real time."""

    def __init__(self, speedup: float = 1.0) -> None:
        if not (math.isfinite(speedup) and speedup > 0):
            raise ValueError(f"speedup = {speedup!r}: expected a finite number > 0")
        self._t0, self.speedup = time.monotonic(), float(speedup)

    def __call__(self) -> float:
        return (time.monotonic() - self._t0) * self.speedup


@dataclass
class _Segment:
    """Nominal motion from ``t0``: ramp from ``omega0`` to ``target`` at ``accel`` (inf = at once)."""

    t0: float
    theta0: float
    omega0: float
    target: float
    accel: float
    table_speed: float  # speed of the signal table used (the last non-zero target)

    def state(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        dt = np.asarray(t, dtype=np.float64) - self.t0
        diff = self.target - self.omega0
        if diff == 0 or math.isinf(self.accel):
            return self.theta0 + self.target * dt, np.full_like(dt, self.target)
        s = math.copysign(self.accel, diff)
        tr = abs(diff) / self.accel
        ramp = dt < tr
        d1 = np.where(ramp, dt, tr)
        theta = self.theta0 + self.omega0 * d1 + 0.5 * s * d1**2 + self.target * (dt - d1)
        return theta, np.where(ramp, self.omega0 + s * dt, self.target)


@dataclass(frozen=True)
class Tap:
    """A tap on the accelerometer's body: a half-sine acceleration pulse of ``width`` s peaking at ``peak`` m/s^2
    that starts at device time ``time`` (the trigger edge); ``latch`` is that edge as the drive's
    touch probe stamps it (``LATCH_RESOLUTION`` steps of the encoder's clock)."""

    number: int
    time: float
    latch: float
    width: float
    peak: float

    def pulse(self, t: np.ndarray) -> np.ndarray:
        """The pulse's acceleration (m/s^2) at physical times ``t`` (s)."""
        u = (np.asarray(t) - self.time) / self.width
        return np.where((u >= 0) & (u <= 1), self.peak * np.sin(np.pi * np.clip(u, 0.0, 1.0)), 0.0)


@dataclass
class _Stream:
    start: float      # device time of sample 0
    rate: float       # nominal Hz
    true_rate: float  # Hz of the clock that really samples
    block: int
    next_sample: int = 0
    sequence: int = 0


@dataclass
class _Scheduled:
    time: float
    kind: str  # "speed" | "stall"
    target: float = 0.0
    accel: float = 0.0


def table_speed(speed: float) -> float:
    """The motor speed (rad/s) whose model table the device plays at ``speed``: rounded to 5
    significant digits, so 2 pi, its float32 and its 1e-4 CAN encoding share one table."""
    return float(f"{float(speed):.5g}")


def _sensor(bench: Bench, kind: str, default: Sensor) -> Sensor:
    """The bench's first sensor of ``kind``; a bench without one gets ``default`` (encoder on the
    first driver: 4000 counts/rev at 1 kHz; accelerometer: 50 g at 10 kHz)."""
    try:
        return bench.sensor(kind)
    except KeyError:
        return default


class BenchDevice:
    """The emulated bench (see the module docstring; the wire contract is hardware/protocol/SERIAL.md and CAN.md)."""

    def __init__(self, bench: Bench, config: EmulatorConfig | None = None, clock=None):
        self.bench = bench
        self.config = config if config is not None else EmulatorConfig.from_bench(bench)
        self.clock = clock if clock is not None else MonotonicClock()
        cfg = self.config
        self._rng = np.random.default_rng([cfg.seed, 1])
        self._fault_rng = np.random.default_rng([cfg.seed, 2])
        enc = _sensor(bench, "encoder", Sensor("encoder", "encoder", 1000.0, counts_per_rev=4000))
        acc = _sensor(bench, "accelerometer", Sensor("accelerometer", "accelerometer", 10000.0))
        self.counts_per_rev = int(enc.counts_per_rev or 4000)
        self.encoder_rate = float(enc.sample_rate)
        driver = bench.encoder_driver
        self._ratio, self._phase = float(driver.ratio), float(driver.phase)
        self.range = float(acc.range or 50 * 9.80665)
        self.sample_rate = float(acc.sample_rate)
        self.enabled = False
        self.fault: str | None = None
        self._events: list[DeviceEvent] = []
        self._scheduled: list[_Scheduled] = []
        self._tables: dict[float, SignalTable] = {}
        self._segments = [_Segment(0.0, 0.0, 0.0, 0.0, math.inf, float(bench.speed))]
        self._accel: _Stream | None = None
        self._encoder: _Stream | None = None
        self._enc_last_k = 0
        self._index_pulses = 0  # index pulses of the segments before the current one
        self._first_stream: float | None = None
        self._motion_params = self._true_motion_params()
        self._chain = self._build_chain()
        self._clipped_reported = (0, -math.inf)  # (count, device time) of the last clipping event
        self._taps: list[Tap] = []  # taps whose pulse a stream may still sample
        self._taps_pending: list[Tap] = []  # fired taps whose latch is not yet reported
        self._tap_count = 0
        self._tap_rng = np.random.default_rng([cfg.seed, 3])  # trigger jitter within the latch step

    def _true_motion_params(self) -> tuple[float, float, int, float, int]:
        """(speed scale s, ripple r, harmonic k, phase phi, sigma) of the true motor (module docstring)."""
        truth, motor = self.config.truth, self.config.motor
        if truth.seed is None:
            return 1.0, motor.ripple, motor.ripple_harmonic, 0.0, 1
        from wearbench.model.realisation import draw_realisation

        real = draw_realisation(self.bench, truth.seed)
        return real.speed_scale, real.ripple, 1, real.ripple_phase, 1 if self.bench.speed >= 0 else -1

    # ---- motor --------------------------------------------------------------------------------

    def enable(self) -> None:
        self._catch_up()
        if self.fault:
            raise DeviceError(ErrorCode.FAULT_ACTIVE, f"fault {self.fault!r} latched; clear it first")
        self.enabled = True

    def disable(self) -> None:
        """Ramp to 0 at the maximum deceleration and unpower."""
        self._catch_up()
        self.enabled = False
        self._command(self.clock(), 0.0, self.bench.motor.max_acceleration)

    def stop(self) -> None:
        """Ramp to 0 at the maximum deceleration (stays enabled); cancels a running profile."""
        self._catch_up()
        self._scheduled = [s for s in self._scheduled if s.kind != "speed"]
        self._command(self.clock(), 0.0, self.bench.motor.max_acceleration)

    def clear_fault(self) -> None:
        self._catch_up()
        self.fault = None

    def set_speed(self, rad_per_s: float, acceleration: float | None = None) -> None:
        """Ramp the motor to ``rad_per_s`` at ``acceleration`` (rad/s^2, default and cap: the motor's max)."""
        self._catch_up()
        speed, accel = self._check_motion(rad_per_s, acceleration)
        self._scheduled = [s for s in self._scheduled if s.kind != "speed"]
        self._command(self.clock(), speed, accel)

    def set_profile(self, times: list[float], speeds: list[float], acceleration: float | None = None) -> None:
        """Speed profile: at ``times[i]`` s from now ramp to ``speeds[i]`` rad/s."""
        self._catch_up()
        if len(times) != len(speeds) or not times:
            raise DeviceError(ErrorCode.BAD_VALUE, "profile needs equal, non-empty lists of times and speeds")
        if any(b < a for a, b in itertools.pairwise(times)) or times[0] < 0:
            raise DeviceError(ErrorCode.BAD_VALUE, f"profile times {list(times)}: expected ascending, >= 0")
        checked = [self._check_motion(v, acceleration) for v in speeds]
        now = self.clock()
        self._scheduled = [s for s in self._scheduled if s.kind != "speed"]
        self._scheduled += [_Scheduled(now + t, "speed", v, a) for t, (v, a) in zip(times, checked)]
        self._scheduled.sort(key=lambda s: s.time)
        self._catch_up()

    def motor_status(self) -> MotorStatus:
        now = self._catch_up()
        theta, omega = self._motion(np.array([now]))
        counts, _ = self._encoder_state(theta)
        seg = self._segments[-1]
        index_count = self._index_pulses + self._pulses_in(seg, seg.t0, now) if self.config.encoder.index else 0
        return MotorStatus(time=now, angle=float(self._phase + self._ratio * theta[0]),
                           speed=float(self._ratio * omega[0]), counts=int(counts[0]),
                           index_count=index_count, enabled=self.enabled, fault=self.fault)

    def tap(self, after: float = 0.01, width: float = 2e-4, peak: float = 1000.0) -> Tap:
        """Fire the tapper ``after`` s from now (plus a jitter below the latch step): a half-sine
        pulse of ``width`` s peaking at ``peak`` m/s^2 on the accelerometer's body. Its latch is reported as a TAP
        event once the device's clock passes the trigger."""
        now = self._catch_up()
        if not (math.isfinite(after) and 0 <= after <= 10):
            raise DeviceError(ErrorCode.BAD_VALUE, f"tap after {after!r} s: expected 0..10 s")
        if not (math.isfinite(width) and 0 < width <= MAX_TAP_WIDTH):
            raise DeviceError(ErrorCode.BAD_VALUE, f"tap width {width!r} s: expected 0 < width <= {MAX_TAP_WIDTH:g} s")
        if not (math.isfinite(peak) and 0 < peak <= 1e6):
            raise DeviceError(ErrorCode.BAD_VALUE, f"tap peak {peak!r} m/s^2: expected 0 < peak <= 1e6")
        t = now + after + float(self._tap_rng.uniform(0.0, LATCH_RESOLUTION))
        latch = math.floor(t / LATCH_RESOLUTION + 1e-9) * LATCH_RESOLUTION
        tap = Tap(self._tap_count, t, latch, float(width), float(peak))
        self._tap_count += 1
        self._taps.append(tap)
        self._taps_pending.append(tap)
        return tap

    def prepare(self, speed: float) -> SignalTable:
        """Compute (or load) the signal table for motor ``speed`` now, so commanding it later is instant.

        Speeds that agree to 5 significant digits share one table (computed at the rounded speed and
        scaled by (speed/table speed)^2), so 2 pi, its float32 and its 1e-4 CAN encoding are one table.
        """
        key = table_speed(speed)
        if key not in self._tables:
            kind = self.config.signal if self.config.signal != "white" else "none"
            rate = max(20000.0, 2 * self.sample_rate)
            self._tables[key] = signal_table(kind, self.bench, self.config.truth, key or 1.0,
                                             revolutions=self.config.revolutions, settle=self.config.settle,
                                             rate=rate, cache=self.config.cache)
        return self._tables[key]

    @property
    def signal_description(self) -> str:
        return self.prepare(self._segments[-1].table_speed).source

    # ---- accelerometer ------------------------------------------------------------------------

    def configure_accelerometer(self, range_m_s2: float, sample_rate_hz: float) -> None:
        if self._accel is not None:
            raise DeviceError(ErrorCode.BUSY, "stop the accelerometer stream before configuring it")
        if not (math.isfinite(range_m_s2) and 0 < range_m_s2 <= 1e6):
            raise DeviceError(ErrorCode.BAD_VALUE, f"range {range_m_s2!r} m/s^2: expected 0 < range <= 1e6")
        if not (math.isfinite(sample_rate_hz) and MIN_SAMPLE_RATE <= sample_rate_hz <= MAX_SAMPLE_RATE):
            raise DeviceError(ErrorCode.BAD_VALUE, f"sample rate {sample_rate_hz!r} Hz: expected "
                              f"{MIN_SAMPLE_RATE:g}..{MAX_SAMPLE_RATE:g} Hz")
        old = self.range, self.sample_rate
        self.range, self.sample_rate = float(range_m_s2), float(sample_rate_hz)
        try:
            self._chain = self._build_chain()
        except DeviceError:
            self.range, self.sample_rate = old
            raise

    @property
    def lsb(self) -> float:
        """m/s^2 per 16-bit count (range / 32768); an ADC with fewer bits steps in multiples of it."""
        return self.range / 32768.0

    def start_stream(self, accel: bool = True, encoder: bool = True) -> None:
        now = self._catch_up()
        if self._first_stream is None:
            self._first_stream = now
            f = self.config.faults
            if f.stall_at is not None:
                self._scheduled.append(_Scheduled(now + f.stall_at, "stall"))
                self._scheduled.sort(key=lambda s: s.time)
        if accel and self._accel is None:
            drift = self.config.accelerometer.drift
            self._accel = _Stream(now, self.sample_rate, self.sample_rate * (1 + drift), self.config.accel_block)
            self._chain.reset()
        if encoder and self._encoder is None:
            self._encoder = _Stream(now, self.encoder_rate, self.encoder_rate, self.config.encoder_block)
            self._enc_last_k = int(self._encoder_state(self._motion(np.array([now]))[0])[1][0])

    def stop_stream(self) -> None:
        self._catch_up()
        self._accel = self._encoder = None

    @property
    def streaming(self) -> tuple[bool, bool]:
        """(accelerometer, encoder) streaming."""
        return self._accel is not None, self._encoder is not None

    def stream_time(self) -> float | None:
        """Seconds since the first START_STREAM (fault times count from there), or None."""
        return None if self._first_stream is None else self.clock() - self._first_stream

    def stream_time_of(self, t: float) -> float | None:
        """Device time ``t`` (a block's) in seconds since the first START_STREAM, or None."""
        return None if self._first_stream is None else t - self._first_stream

    def fault_due(self, after: float | None) -> bool:
        """Whether a fault set ``after`` s into streaming (None: never) is due now."""
        st = self.stream_time()
        return after is not None and st is not None and st >= after

    @property
    def frozen(self) -> bool:
        """The firmware hangs (``freeze_at``): no blocks, no events, no replies from now on."""
        return self.fault_due(self.config.faults.freeze_at)

    def read(self) -> list[AccelBlock | EncoderBlock]:
        """Every block completed up to the clock's now, in time order (dropped blocks leave gaps);
        nothing once the device is :attr:`frozen`."""
        now = self._catch_up()
        if self.frozen:
            return []
        out: list[AccelBlock | EncoderBlock] = []
        if self._accel is not None:
            out += self._read_accel(now)
        if self._encoder is not None:
            out += self._read_encoder(now)
        out.sort(key=lambda b: b.time)
        self._trim(now)
        return out

    def events(self) -> list[DeviceEvent]:
        """Faults and events since the last call (none once the device is :attr:`frozen`)."""
        self._catch_up()
        if self.frozen:
            return []
        ev, self._events = self._events, []
        return ev

    # ---- internals ----------------------------------------------------------------------------

    def _check_motion(self, speed: float, acceleration: float | None) -> tuple[float, float]:
        if self.fault:
            raise DeviceError(ErrorCode.FAULT_ACTIVE, f"fault {self.fault!r} latched; clear it first")
        if not self.enabled:
            raise DeviceError(ErrorCode.NOT_ENABLED, "enable the drive first")
        m = self.bench.motor
        if not (math.isfinite(speed) and abs(speed) <= m.max_speed * (1 + 1e-9)):
            raise DeviceError(ErrorCode.BAD_VALUE, f"speed {speed!r} rad/s: expected |speed| <= {m.max_speed:g}")
        accel = m.max_acceleration if not acceleration else float(acceleration)
        if not (math.isfinite(accel) and accel > 0):
            raise DeviceError(ErrorCode.BAD_VALUE, f"acceleration {acceleration!r} rad/s^2: expected > 0")
        if speed != 0:
            self.prepare(speed)
        return float(speed), min(accel, m.max_acceleration)

    def _pulses_in(self, seg: _Segment, a: float, b: float) -> int:
        """Index pulses while ``seg`` runs from ``a`` to ``b``: every crossing counts, both directions
        (the angle turns back only where a ramp passes through zero speed)."""
        times = [a, b]
        if not math.isinf(seg.accel) and seg.omega0 * seg.target < 0:
            tz = seg.t0 + abs(seg.omega0) / seg.accel
            if a < tz < b:
                times.insert(1, tz)
        theta, _ = self._true(*seg.state(np.array(times)))
        return int(np.abs(np.diff(self._encoder_state(theta)[1])).sum())

    def _command(self, t: float, target: float, accel: float) -> None:
        theta, omega = self._motion(np.array([t]))
        last = self._segments[-1]
        self._index_pulses += self._pulses_in(last, last.t0, t)
        table_speed = target if target != 0 else last.table_speed
        self._segments.append(_Segment(t, float(theta[0]), float(omega[0]), target, accel, table_speed))

    def _catch_up(self) -> float:
        """Apply scheduled profile points and faults that are due; returns now."""
        now = self.clock()
        while self._scheduled and self._scheduled[0].time <= now:
            s = self._scheduled.pop(0)
            if s.kind == "stall":
                self._command(s.time, 0.0, math.inf)
                self.fault, self.enabled = "stall", False
                self._scheduled = [x for x in self._scheduled if x.kind != "speed"]
                self._events.append(DeviceEvent(s.time, FaultCode.STALL, "motor stalled: speed collapsed "
                                                "while commanded; drive disabled"))
            elif not self.fault:
                self._command(s.time, s.target, s.accel)
        while self._taps_pending and self._taps_pending[0].time <= now:
            tap = self._taps_pending.pop(0)
            self._events.append(DeviceEvent(tap.latch, FaultCode.TAP, tap_message(tap.number, tap.width, tap.peak)))
        return now

    def _nominal(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        starts = np.array([s.t0 for s in self._segments])
        idx = np.searchsorted(starts, t, side="right") - 1
        idx = np.clip(idx, 0, len(self._segments) - 1)
        theta = np.empty_like(t)
        omega = np.empty_like(t)
        tspeed = np.empty_like(t)
        for i in np.unique(idx):
            m = idx == i
            seg = self._segments[i]
            theta[m], omega[m] = seg.state(t[m])
            tspeed[m] = seg.table_speed
        return theta, omega, tspeed

    def _motion(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """True motor angle (rad, 0 at power-up) and speed (rad/s) at device times ``t``."""
        theta, omega, _ = self._nominal(np.asarray(t, dtype=np.float64))
        return self._true(theta, omega)

    def _true(self, theta: np.ndarray, omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Nominal (commanded) motion to the true motion: speed error and ripple (module docstring)."""
        s, r, k, phi, sigma = self._motion_params
        if s != 1.0:
            theta, omega = s * theta, s * omega
        if r:
            psi = (k * sigma) * theta + phi
            theta, omega = theta + (sigma * r / k) * (math.cos(phi) - np.cos(psi)), omega * (1 + r * np.sin(psi))
        return theta, omega

    def encoder_counts(self, t: float) -> int:
        """The encoder's count at device time ``t`` (what a touch probe latches with a time stamp)."""
        return int(self._encoder_state(self._motion(np.array([t]))[0])[0][0])

    @property
    def clipped_samples(self) -> int:
        """Accelerometer samples clipped at the range since the chain was last configured."""
        return self._chain.clipped

    def _encoder_state(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        counts = np.floor(self._ratio * theta * (self.counts_per_rev / TWO_PI) + 1e-9).astype(np.int64)
        phi = self._phase + self._ratio * theta
        k = np.floor((phi - self.config.encoder.index_angle) / TWO_PI).astype(np.int64)
        return counts, k

    def _trim(self, now: float) -> None:
        """Forget motion segments no stream will evaluate again (all pending samples are later)."""
        t = now
        for s in (self._accel, self._encoder):
            if s is not None:
                t = min(t, s.start + s.next_sample / s.true_rate)
        t -= self.config.truth.accel_delay + 0.01
        while len(self._segments) > 1 and self._segments[1].t0 <= t:
            self._segments.pop(0)
        self._taps = [tap for tap in self._taps if tap.time + tap.width >= t]

    def _blocks_due(self, s: _Stream, now: float) -> int:
        """Complete blocks whose last sample's true time is <= now, after handling an overrun."""
        available = math.floor((now - s.start) * s.true_rate + 1e-9) + 1 if now >= s.start else 0
        due = available // s.block - s.sequence
        keep = max(1, math.ceil(self.config.buffer * s.rate / s.block))
        if due > keep:
            lost = due - keep
            s.sequence += lost
            s.next_sample += lost * s.block
            self._events.append(DeviceEvent(now, FaultCode.OVERRUN,
                                            f"device buffer overrun: {lost} blocks of {s.block} samples lost"))
            if s is self._accel:
                self._chain.reset()
            due = keep
        return max(0, due)

    def _dropped(self) -> bool:
        rate = self.config.faults.drop_rate
        return bool(rate) and self._fault_rng.random() < rate

    def _read_accel(self, now: float) -> list[AccelBlock]:
        s = self._accel
        due = self._blocks_due(s, now)
        out = []
        chunk = max(1, 20000 // s.block)
        while due > 0:
            nb = min(due, chunk)
            n = nb * s.block
            values = self._accel_samples(s, s.next_sample, n)
            for b in range(nb):
                seq = s.sequence + b
                if self._dropped():
                    continue
                t = round((s.start + (s.next_sample + b * s.block) / s.rate) * 1e9) / 1e9
                out.append(AccelBlock(seq, t, s.rate, values[b * s.block:(b + 1) * s.block]))
            s.sequence += nb
            s.next_sample += n
            due -= nb
        self._report_clipping(now)
        return out

    def _accel_samples(self, s: _Stream, first: int, n: int) -> np.ndarray:
        """Samples ``first .. first + n - 1`` of stream ``s``: the physics at the chain's internal
        rate (the last internal instant of each group is the sample's true instant), then the chain."""
        m = self._chain.oversample
        j = np.arange(first * m, (first + n) * m) - (m - 1)
        t_true = s.start + j / (s.true_rate * m) if m > 1 else s.start + j / s.true_rate
        t = t_true - self.config.truth.accel_delay
        lateral = np.zeros_like(t) if self._chain.lateral else None
        if self.config.signal == "white":
            x = self._rng.normal(0.0, self.config.accelerometer.white_level, t_true.size)
        else:
            theta_n, omega_n, tspeed = self._nominal(t)
            theta, omega = self._true(theta_n, omega_n)
            # a run holds its own speed error and ripple: scale it by the commanded speed only
            scale_speed = omega if self.config.truth.seed is None else omega_n
            x = np.zeros_like(t)
            for sp in np.unique(tspeed):
                sel = (tspeed == sp) & (scale_speed != 0)  # at rest the signal is 0: no table needed
                if np.any(sel):
                    table = self.prepare(sp)
                    x[sel] = table.at(theta[sel], scale_speed[sel])
                    if lateral is not None and self.config.signal == "model":
                        lateral[sel] = table.lateral_at(theta[sel], scale_speed[sel])
        for tap in self._taps:  # a tap reaches the sensor through the mechanism signal's own delay and chain
            x += tap.pulse(t)
        return self._chain.process(x, lateral)

    def _report_clipping(self, now: float) -> None:
        count, when = self._clipped_reported
        if self._chain.clipped > count and now - when >= 1.0:
            self._events.append(DeviceEvent(now, FaultCode.INFO, f"accelerometer clipped at +/-{self.range:g} m/s^2: "
                                            f"{self._chain.clipped} samples so far"))
            self._clipped_reported = (self._chain.clipped, now)

    def _build_chain(self) -> SensorChain:
        try:
            return SensorChain(self.config.accelerometer, self.sample_rate, self.range, self._rng)
        except ValueError as exc:
            raise DeviceError(ErrorCode.BAD_VALUE, str(exc)) from None

    def _read_encoder(self, now: float) -> list[EncoderBlock]:
        s = self._encoder
        due = self._blocks_due(s, now)
        if not due:
            return []
        n = due * s.block
        k = s.next_sample + np.arange(n)
        t = s.start + k / s.rate
        theta, _ = self._motion(t)
        counts, idx_k = self._encoder_state(theta)
        prev = np.concatenate(([self._enc_last_k], idx_k[:-1]))
        index = (idx_k != prev) & self.config.encoder.index
        lost = self.config.faults.index_lost_at
        if lost is not None:  # a broken index line: the pulse never reaches the counter again
            index &= t < self._first_stream + lost
        self._enc_last_k = int(idx_k[-1])
        out = []
        for b in range(due):
            sl = slice(b * s.block, (b + 1) * s.block)
            seq = s.sequence + b
            if self._dropped():
                continue
            t0 = round((s.start + (s.next_sample + b * s.block) / s.rate) * 1e9) / 1e9
            out.append(EncoderBlock(seq, t0, s.rate, counts[sl].astype(np.int32), index[sl].copy()))
        s.sequence += due
        s.next_sample += n
        return out

