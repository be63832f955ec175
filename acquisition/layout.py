"""The MCAP layout of a session (layout 2): topics, protobuf schemas, and the encoding of each message.

One channel per stream, protobuf encoded, every schema a ``FileDescriptorSet`` in the file, so a
viewer (Foxglove, ``mcap cat``, protobufjs) decodes and plots the fields with no conversion:

- ``/acceleration`` (``wearbench.AccelerationBlock``): one message per device block; ``acceleration``
  is a packed float32 array (m/s^2, bit for bit what the device sent), ``clipped`` the samples of the
  block at or beyond the accelerometer's range (within one LSB).
- ``/encoder`` (``wearbench.EncoderBlock``): ``counts`` (exact), the derived ``crank_angle`` (rad,
  wrapped to [0, 2 pi)) and ``cycle`` (index pulses since the recording started) per sample, and the
  index pulse positions ``index_at``.
- ``/motor/state`` (``wearbench.MotorState``), ``/motor/command`` (``wearbench.MotorCommand``; a speed
  or acceleration not given is NaN), ``/can/frames`` (``wearbench.CanFrame``, raw bus frames of the
  CAN backends in both directions: ``transmitted`` marks the host's own frames, ``host_time`` the
  host clock at arrival or sending) and ``/events`` (the well-known ``foxglove.Log``: ``name`` is the event kind).

Protobuf over JSON numeric arrays by measurement (``benchmarks/acquisition/session_format.py``, 20 kHz, zstd):
148 against 161 MB per hour and 2.6x less write CPU; besides, float32 samples stay exact and a NaN
sample stays a valid message (JSON has no NaN). Layout 1 (JSON, base64 samples) is read by
``layout1``. ``log_time`` is the host time of arrival (ns since the Unix epoch), made non-decreasing
in file order (a message that reaches the writer after a later-stamped one gets that one's log time;
its own arrival time stays in its ``host_time`` field), as ``mcap doctor --strict-message-order``
demands; ``publish_time`` the device time (ns on the device clock; equal to ``log_time`` for a
message that has none).

The metadata records (:data:`METADATA`) are written and read back by name here too:
:func:`session_records`, :func:`record_crank`, :func:`record_stream` and :func:`result_record` for
the recorder, :func:`recorded_crank` and :func:`recorded_stream` for the reader and ``recover``. The
clip rule (:func:`clip_level`, :func:`clipped`) is here, applied where samples enter: by the recorder
to each block (its ``clipped`` count) and by the reader to each sample (its ``clipped`` column).
Imports numpy, protobuf, foxglove's schemas and the driver dataclasses (the bench and the session
records for types only).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from importlib.metadata import version
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from foxglove.messages import Log, LogLevel, Timestamp
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from wearbench.acquisition.drivers import (
    ACCELERATION,
    ENCODER,
    Block,
    BusFrame,
    Event,
    MotorState,
    StreamInfo,
)
from wearbench.hardware.protocol.taps import TAP_EVENT

if TYPE_CHECKING:
    from wearbench.acquisition.session import SessionPlan, SessionResult
    from wearbench.bench.schema import Bench

__all__ = [
    "BENCH_ATTACHMENT",
    "BENCH_FILES",
    "ENCODING",
    "METADATA",
    "SCHEMAS",
    "TOPICS",
    "Command",
    "CrankAngle",
    "bench_files",
    "calibration_number",
    "clip_level",
    "clipped",
    "count_clipped",
    "decode_block",
    "decode_command",
    "decode_event",
    "decode_frame",
    "decode_state",
    "encode_block",
    "encode_command",
    "encode_event",
    "encode_frame",
    "encode_state",
    "log_level",
    "ns",
    "publish_time",
    "record_crank",
    "record_stream",
    "recorded_crank",
    "recorded_stream",
    "result_record",
    "session_records",
    "surface_attachment",
    "surface_joint",
]

# metadata records of a session file, by name: what each holds (every value a string)
METADATA = {
    "session": "bench, bench_sha256, bench_path, operator, software, backend, speed_rad_s, started_at, target, "
               "cycles_run (cycles the bench had run before the session, when given)",
    "clearance": "radial clearance (m, repr) per clearance joint as mounted",
    "wear": "wear state per clearance joint: a label or the worn-surface file",
    "calibration": "sensor names and rates, accelerometer axis/sensitivity/mount, encoder joint, "
                   "counts_per_rev and angle_offset, each stream's description, and the acceleration "
                   "stream's range and lsb (m/s^2, as the device runs it)",
    "hardware": "backend and what the rig reports of itself",
    "result": "how the session ended: reason, completed, cycles, duration_s, counts per stream",
    "recovery": "written by `wearbench recover`: the broken source and what was restored",
}
BENCH_ATTACHMENT = "bench.toml"  # the bench file as recorded (application/toml)


def surface_attachment(joint: str) -> str:
    """Attachment name of the worn-surface file (.npz) a session's wear state names for ``joint``."""
    return f"wear/{joint}.npz"


def surface_joint(name: str) -> str | None:
    """The joint of a worn-surface attachment ``name`` (None for another attachment)."""
    return name[5:-4] if name.startswith("wear/") and name.endswith(".npz") else None


BENCH_FILES = "bench/"  # attachment prefix of the files the bench file names by a relative path


def bench_files(bench: Bench) -> dict[str, Path]:
    """The files ``bench`` names by a path relative to its bench file (worn surfaces of its clearance
    joints and of its [[state]]s), {relative posix path: file}; a session carries them as attachments
    ``BENCH_FILES + relative path`` so its bench loads wherever the session is."""
    if bench.path is None:
        return {}
    folder = Path(bench.path).resolve().parent
    named = [j.clearance.surfaces for j in bench.joints if j.clearance is not None and j.clearance.surfaces]
    named += [p for s in bench.states for p in s.surfaces.values()]
    out = {}
    for p in named:
        try:
            out[Path(p).resolve().relative_to(folder).as_posix()] = Path(p)
        except ValueError:  # outside the bench file's folder: named by an absolute path
            pass
    return out


def session_records(bench: Bench, plan: SessionPlan, backend: str, info: Mapping[str, str],
                    started_at: str) -> dict[str, dict[str, str]]:
    """The records "session", "clearance", "wear", "hardware" and the sensors' part of
    "calibration" of a session of ``plan`` on ``bench`` through ``backend`` (``info``: what the rig
    reports of itself)."""
    b, p = bench, plan
    session = {"bench": b.name, "bench_sha256": b.sha256, "operator": p.operator,
               "software": f"wearbench {version('wearbench')}", "backend": backend,
               "speed_rad_s": repr(p.speed), "started_at": started_at}
    session["target"] = (f"{p.taps} taps at rest, {p.tap_interval!r} s apart" if p.taps
                         else f"{p.cycles} cycles" if p.cycles is not None else f"{p.duration} s")
    if p.cycles_run is not None:
        session["cycles_run"] = repr(float(p.cycles_run))
    if b.path is not None:
        session["bench_path"] = str(Path(b.path).resolve())
    clearance = {j.name: repr(p.clearances.get(j.name, j.clearance.radial_clearance)) for j in b.clearance_joints}
    clearance.update({k: repr(v) for k, v in p.clearances.items()})
    wear = {j.name: p.wear.get(j.name, str(j.clearance.surfaces) if j.clearance.surfaces else "new")
            for j in b.clearance_joints}
    wear.update(p.wear)
    calibration: dict[str, str] = {}
    for s in b.sensors:
        calibration.update({f"{s.kind}.name": s.name, f"{s.kind}.sample_rate": repr(s.sample_rate)})
        if s.kind == "accelerometer":
            calibration.update({"accelerometer.axis": repr(s.axis),
                                "accelerometer.sensitivity": repr(s.sensitivity),
                                "accelerometer.body": s.body, "accelerometer.point": s.point})
        else:
            calibration.update({"encoder.joint": s.joint, "encoder.counts_per_rev": str(s.counts_per_rev)})
    return {"session": session, "clearance": clearance, "wear": wear, "calibration": calibration,
            "hardware": {"backend": backend, **info}}


def record_crank(calibration: dict[str, str], state: MotorState | Exception) -> CrankAngle | None:
    """Write the encoder's angle offset into ``calibration`` from the drive's ``state`` at the start
    (or why it is unknown); the crank angle of the counts, None without counts per revolution."""
    if isinstance(state, Exception):
        calibration["encoder.angle_offset"] = f"unknown ({state})"
        return None
    cpr = float(calibration.get("encoder.counts_per_rev", 0) or 0)
    if not cpr:
        return None
    offset = state.angle - state.counts * 2 * math.pi / cpr
    calibration["encoder.angle_offset"] = repr(offset)
    return CrankAngle(cpr, offset)


def record_stream(calibration: dict[str, str], info: StreamInfo, source: str) -> None:
    """Write what stream ``info`` of source ``source`` holds into ``calibration``: its description
    (``NAME.stream``), its extras, and its range and LSB (``NAME.range``, ``NAME.lsb``, m/s^2, exact
    reprs): the one record of them, which :func:`recorded_stream` reads back."""
    calibration[f"{info.name}.stream"] = (f"{info.unit} {info.dtype}{list(info.shape) or ''} "
                                          f"at {info.sample_rate:g} Hz from {info.source or source}")
    calibration.update({f"{info.name}.{k}": v for k, v in info.extra.items()})
    calibration.update({f"{info.name}.{what}": repr(value) for what in ("range", "lsb")
                        if (value := getattr(info, what)) is not None})


def result_record(r: SessionResult, lost: int) -> dict[str, str]:
    """The "result" record of a session that ended with ``r`` (``lost``: items the writer could not encode)."""
    return {"reason": r.reason, "completed": str(r.completed), "cycles": repr(r.cycles),
            "duration_s": repr(r.duration), "malformed_frames": str(r.malformed),
            "lost_items": str(lost), "acceleration.clipped_samples": str(r.clipped),
            **{f"{k}.{name}": str(v) for name, d in (("blocks", r.blocks), ("samples", r.samples),
                                                      ("dropped_blocks", r.dropped_blocks),
                                                      ("dropped_samples", r.dropped_samples),
                                                      ("repeated_blocks", r.repeated_blocks))
               for k, v in d.items()}}


def calibration_number(calibration: Mapping[str, str], key: str, default: float = 0.0) -> float:
    """The number the calibration record holds at ``key``; ``default`` when absent or not a number."""
    try:
        return float(calibration[key])
    except (KeyError, ValueError):
        return default


def _recorded_scale(calibration: Mapping[str, str], key: str) -> float | None:
    """The positive number recorded at ``key`` (m/s^2); None when absent or not one."""
    value = calibration_number(calibration, key, math.nan)
    return value if 0 < value < math.inf else None


# unit and dtype of the samples the layout stores per stream (``encode_block``)
_SAMPLES = {ACCELERATION: ("m/s^2", "float32"), ENCODER: ("counts", "int32")}


def recorded_stream(calibration: Mapping[str, str], name: str, sample_rate: float = 0.0) -> StreamInfo:
    """Stream ``name`` (ACCELERATION or ENCODER) as a session recorded it, the inverse of
    :func:`record_stream`: the unit and dtype of the layout's messages, ``sample_rate`` (Hz: the rate
    its blocks were recorded at, which the reader gives; 0 when not known), the source its description
    names, and its range and LSB (m/s^2) typed. Its extras stay in the calibration record.

    Sessions recorded before the stream info carried the range typed read alike (the keys are the
    same). One whose stream recorded no range gets the accelerometer's range from the bench file
    (``accelerometer.range``, which sessions then recorded too), as the recorder then did; an LSB not
    recorded stays None (the clip rule takes range/32768, as it always did)."""
    unit, dtype = _SAMPLES[name]
    source = calibration.get(f"{name}.stream", "").partition(" from ")[2]
    key = f"{name}.range" if f"{name}.range" in calibration or name != ACCELERATION else "accelerometer.range"
    full_scale = _recorded_scale(calibration, key)
    return StreamInfo(name, unit, float(sample_rate), dtype, source=source, range=full_scale,
                      lsb=_recorded_scale(calibration, f"{name}.lsb"))


def recorded_crank(calibration: Mapping[str, str], counts_per_rev: float = 0.0) -> CrankAngle | None:
    """The crank angle of the recorded counts (``counts_per_rev`` when the record lacks it); None
    without counts per revolution."""
    cpr = calibration_number(calibration, "encoder.counts_per_rev") or counts_per_rev
    return CrankAngle(cpr, calibration_number(calibration, "encoder.angle_offset")) if cpr else None


TOPICS = {ACCELERATION: "/acceleration", ENCODER: "/encoder", "state": "/motor/state",
          "command": "/motor/command", "events": "/events", "frames": "/can/frames"}
ENCODING = "protobuf"  # channel message encoding and schema encoding

_F = descriptor_pb2.FieldDescriptorProto
_DOUBLE, _FLOAT, _U64, _S64, _U32, _S32, _BOOL, _STR, _BYTES = (
    _F.TYPE_DOUBLE, _F.TYPE_FLOAT, _F.TYPE_UINT64, _F.TYPE_SINT64, _F.TYPE_UINT32, _F.TYPE_SINT32,
    _F.TYPE_BOOL, _F.TYPE_STRING, _F.TYPE_BYTES)
_R = "repeated"
_TIMES = [("device_time", _DOUBLE), ("host_time", _DOUBLE)]  # s: device clock; host clock (Unix)
_BLOCK = [("sequence", _U64), *_TIMES, ("sample_rate", _DOUBLE)]
# message -> fields in field-number order; units are in the module docstring and the README
_MESSAGES: dict[str, list[tuple]] = {
    "AccelerationBlock": [*_BLOCK, ("acceleration", _FLOAT, _R), ("clipped", _U32)],
    "EncoderBlock": [*_BLOCK, ("counts", _S32, _R), ("crank_angle", _FLOAT, _R), ("cycle", _U32, _R),
                     ("index_at", _U32, _R)],
    "MotorState": [*_TIMES, ("angle", _DOUBLE), ("speed", _DOUBLE), ("counts", _S64),
                   ("index_count", _S64), ("enabled", _BOOL), ("fault", _STR)],
    "MotorCommand": [("host_time", _DOUBLE), ("command", _STR), ("speed", _DOUBLE), ("acceleration", _DOUBLE)],
    "CanFrame": [("time", _DOUBLE), ("id", _U32), ("data", _BYTES), ("extended", _BOOL), ("fd", _BOOL),
                 ("bitrate_switch", _BOOL), ("error", _BOOL), ("remote", _BOOL), ("transmitted", _BOOL),
                 ("host_time", _DOUBLE)],
}
_KEYS = {ACCELERATION: "AccelerationBlock", ENCODER: "EncoderBlock", "state": "MotorState",
         "command": "MotorCommand", "frames": "CanFrame"}


def _file() -> descriptor_pb2.FileDescriptorProto:
    f = descriptor_pb2.FileDescriptorProto(name="wearbench/session.proto", package="wearbench", syntax="proto3")
    for name, fields in _MESSAGES.items():
        m = f.message_type.add(name=name)
        for number, (field, kind, *rep) in enumerate(fields, 1):
            m.field.add(name=field, number=number, type=kind,
                        label=_F.LABEL_REPEATED if rep else _F.LABEL_OPTIONAL)
    return f


def _build() -> tuple[dict[str, tuple[str, bytes]], dict[str, type]]:
    pool = descriptor_pool.DescriptorPool()
    log_schema = Log.get_schema()
    log_files = descriptor_pb2.FileDescriptorSet.FromString(log_schema.data)
    for f in log_files.file:
        pool.Add(f)
    ours = _file()
    pool.Add(ours)
    schemas = {key: (f"wearbench.{name}", descriptor_pb2.FileDescriptorSet(file=[ours]).SerializeToString())
               for key, name in _KEYS.items()}
    schemas["events"] = (log_schema.name, bytes(log_schema.data))
    classes = {key: message_factory.GetMessageClass(pool.FindMessageTypeByName(name))
               for key, (name, _) in schemas.items()}
    return schemas, classes


SCHEMAS, _CLASSES = _build()  # key -> (schema name, FileDescriptorSet); key -> message class


def ns(seconds: float) -> int:
    """Seconds to non-negative integer nanoseconds (MCAP times are unsigned)."""
    return max(0, round(seconds * 1e9))


def clip_level(full_scale: float | None, lsb: float | None = None) -> float:
    """|a| (m/s^2) from which a sample counts as clipped: one LSB below the range (the largest
    int16 count is ``full_scale - lsb``, where a saturated ADC sits; the protocols' LSB is
    range/32768, taken when ``lsb`` is None), less float32 rounding. ``inf`` when the range is
    unknown (None). The recorder and the reader call it with a stream's ``range`` and ``lsb``."""
    if full_scale is None or not full_scale > 0:
        return math.inf
    lsb = full_scale / 32768 if lsb is None else lsb
    return float(np.float32(full_scale - lsb)) * (1 - 1e-6)


def clipped(samples: np.ndarray, level: float) -> np.ndarray:
    """Which samples are at or beyond ``level`` (:func:`clip_level`): the one clip rule, applied where
    samples enter: the recorder's per-block count (and ``recover``'s for a layout-1 file) and the
    reader's per-sample ``clipped`` column, which the features take."""
    return np.abs(np.asarray(samples)) >= level


def count_clipped(samples: np.ndarray, level: float) -> int:
    """Samples of a block at or beyond ``level`` (:func:`clip_level`)."""
    return int(np.count_nonzero(clipped(samples, level))) if len(samples) else 0


@dataclass
class CrankAngle:
    """Derives the encoder message's crank angle and cycle index from the counts, across blocks.

    ``counts_per_rev`` and ``offset`` (rad at count 0) are the session's calibration metadata;
    the cycle index counts rising edges of the index pulse since the first block it saw."""

    counts_per_rev: float
    offset: float = 0.0
    pulses: int = 0
    _high: bool = False

    def __call__(self, counts: np.ndarray, index: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        angle = np.mod(self.offset + counts.astype(np.float64) * (2 * math.pi / self.counts_per_rev), 2 * math.pi)
        high = np.zeros(len(counts), dtype=bool) if index is None else np.asarray(index, dtype=bool)
        rising = high & ~np.concatenate([[self._high], high[:-1]]) if len(high) else high
        cycle = self.pulses + np.cumsum(rising)
        if len(high):
            self.pulses, self._high = int(cycle[-1]), bool(high[-1])
        return angle.astype(np.float32), cycle


@dataclass(frozen=True)
class Command:
    command: str
    speed: float | None = None
    acceleration: float | None = None
    host_time: float = 0.0


def encode_block(block: Block, crank: CrankAngle | None = None) -> bytes:
    head = {"sequence": int(block.sequence), "device_time": float(block.device_time),
            "host_time": float(block.host_time), "sample_rate": float(block.sample_rate)}
    if block.stream == ACCELERATION:
        samples = np.asarray(block.samples, dtype=np.float32)
        return _CLASSES[ACCELERATION](**head, acceleration=samples.tolist(),
                                      clipped=int(block.clipped)).SerializeToString()
    if block.stream == ENCODER:
        counts = np.asarray(block.samples, dtype=np.int32)
        extra = {}
        if crank is not None and crank.counts_per_rev:
            angle, cycle = crank(counts, block.index)
            extra = {"crank_angle": angle.tolist(), "cycle": cycle.tolist()}
        index = [] if block.index is None else np.flatnonzero(block.index).tolist()
        return _CLASSES[ENCODER](**head, counts=counts.tolist(), index_at=index, **extra).SerializeToString()
    raise ValueError(f"unknown stream {block.stream!r}; expected {ACCELERATION!r} or {ENCODER!r}")


def decode_block(stream: str, data: bytes) -> Block:
    """The :class:`Block` a message holds (inverse of :func:`encode_block`)."""
    m = _CLASSES[stream].FromString(data)
    if stream == ACCELERATION:
        samples, index = np.asarray(m.acceleration, dtype=np.float32), None
    else:
        samples = np.asarray(m.counts, dtype=np.int32)
        index = np.zeros(len(samples), dtype=bool)
        index[list(m.index_at)] = True
    return Block(stream=stream, sequence=m.sequence, device_time=m.device_time, sample_rate=m.sample_rate,
                 samples=samples, host_time=m.host_time, index=index,
                 clipped=m.clipped if stream == ACCELERATION else 0)


def encode_state(s: MotorState) -> bytes:
    return _CLASSES["state"](device_time=s.device_time, host_time=s.host_time, angle=s.angle, speed=s.speed,
                             counts=int(s.counts), index_count=int(s.index_count), enabled=bool(s.enabled),
                             fault=s.fault or "").SerializeToString()


def decode_state(data: bytes) -> MotorState:
    m = _CLASSES["state"].FromString(data)
    return MotorState(device_time=m.device_time, angle=m.angle, speed=m.speed, counts=m.counts,
                      index_count=m.index_count, enabled=m.enabled, fault=m.fault or None, host_time=m.host_time)


def encode_command(c: Command) -> bytes:
    nan = float("nan")
    return _CLASSES["command"](host_time=c.host_time, command=c.command,
                               speed=nan if c.speed is None else c.speed,
                               acceleration=nan if c.acceleration is None else c.acceleration).SerializeToString()


def decode_command(data: bytes) -> Command:
    m = _CLASSES["command"].FromString(data)
    return Command(m.command, None if math.isnan(m.speed) else m.speed,
                   None if math.isnan(m.acceleration) else m.acceleration, m.host_time)


_INFO = {"phase", "stop", "recovered", "event", "info", TAP_EVENT}
_ERROR = {"error", "fault", "stall", "overspeed", "bus_off", "disconnect", "emcy"}


def log_level(kind: str) -> LogLevel:
    """The ``foxglove.Log`` level of an event kind: INFO for the session's course, ERROR for
    failures and drive faults, WARNING for the rest (drops, malformed frames, clipping, interrupts)."""
    if kind in _INFO:
        return LogLevel.Info
    if kind in _ERROR:
        return LogLevel.Error
    return LogLevel.Warning


def encode_event(e: Event) -> bytes:
    t = ns(e.host_time)
    return Log(timestamp=Timestamp(t // 1_000_000_000, t % 1_000_000_000), level=log_level(e.kind),
               message=e.message, name=e.kind).encode()


def publish_time(device_time: float | None, log_time: int) -> int:
    """A message's MCAP ``publish_time``: its device time (ns), or ``log_time`` when it has none."""
    return log_time if device_time is None else ns(device_time)


def decode_event(data: bytes, publish: int, log_time: int) -> Event:
    """The :class:`Event` of a ``foxglove.Log`` message and its record's publish and log times."""
    m = _CLASSES["events"].FromString(data)
    host = m.timestamp.seconds + m.timestamp.nanos * 1e-9
    return Event(m.name, m.message, host_time=host, device_time=None if publish == log_time else publish * 1e-9)


def encode_frame(f: BusFrame) -> bytes:
    return _CLASSES["frames"](time=f.time, id=f.arbitration_id, data=bytes(f.data), extended=f.is_extended,
                              fd=f.is_fd, bitrate_switch=f.bitrate_switch, error=f.is_error,
                              remote=f.is_remote, transmitted=f.transmitted,
                              host_time=f.host_time).SerializeToString()


def decode_frame(data: bytes, log_time: int = 0) -> BusFrame:
    m = _CLASSES["frames"].FromString(data)
    return BusFrame(time=m.time, arbitration_id=m.id, data=bytes(m.data), is_extended=m.extended, is_fd=m.fd,
                    bitrate_switch=m.bitrate_switch, is_error=m.error, is_remote=m.remote,
                    host_time=m.host_time or log_time * 1e-9, transmitted=m.transmitted)
