"""Reading a session MCAP back: :func:`read_session` (the shared contract), a tolerant scan, and
the decoded messages of a scan (:func:`blocks`, :func:`events`, :func:`states`, :func:`frames`) in
either layout: the current one (``layout``, protobuf) or the first (``layout1``, JSON), told apart
by each channel's message encoding. Everything that reads sessions goes through here.

The scan walks the file record by record and keeps every complete record: a file cut short by a
killed process, a torn last chunk or a missing summary end the walk, they do not fail it. Chunks
are checked against their CRC, so a damaged chunk is reported, never decoded into garbage.

Imports mcap, pandas and the layout; no backend library.
"""

from __future__ import annotations

import hashlib
import math
import os
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import zstandard
from mcap.records import (
    Attachment,
    Channel,
    Chunk,
    DataEnd,
    Footer,
    Message,
    Metadata,
    Schema,
    Statistics,
)
from mcap.stream_reader import StreamReader, breakup_chunk
from wearbench.acquisition import layout, layout1
from wearbench.acquisition.drivers import (
    ACCELERATION,
    ENCODER,
    Block,
    BusFrame,
    Event,
    MotorState,
    StreamInfo,
)
from wearbench.acquisition.layout import (
    BENCH_ATTACHMENT,
    BENCH_FILES,
    ENCODING,
    SCHEMAS,
    TOPICS,
    clip_level,
    clipped,
    recorded_crank,
    recorded_stream,
    surface_joint,
)
from wearbench.acquisition.sequence import SequenceCheck
from wearbench.bench.content import cache_folder
from wearbench.bench.load import parse_bench
from wearbench.bench.output_file import MCAP_MAGIC
from wearbench.bench.schema import Bench, BenchError

__all__ = [
    "Scan",
    "Session",
    "blocks",
    "check_session",
    "events",
    "frames",
    "read_session",
    "scan_mcap",
    "states",
]



@dataclass
class Scan:
    """Every complete record of an MCAP file, in file order."""

    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    messages: list[Message] = field(default_factory=list)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    attachments: list[Attachment] = field(default_factory=list)
    chunks: int = 0  # complete chunks read
    finished: bool = False  # the footer was reached
    problem: str | None = None  # why the walk ended early, if it did
    path: Path | None = None  # the file scanned

    def topic(self, channel_id: int) -> str:
        return self.channels[channel_id].topic if channel_id in self.channels else f"#{channel_id}"


def _chunk_records(chunk: Chunk) -> list:
    if chunk.compression == "zstd":
        data = zstandard.ZstdDecompressor().decompress(chunk.data, max_output_size=chunk.uncompressed_size)
    elif chunk.compression == "":
        data = chunk.data
    else:
        raise ValueError(f"unsupported chunk compression {chunk.compression!r}")
    if len(data) != chunk.uncompressed_size:
        raise ValueError(f"chunk holds {len(data)} bytes, header says {chunk.uncompressed_size}")
    if chunk.uncompressed_crc and zlib.crc32(data) != chunk.uncompressed_crc:
        raise ValueError("chunk CRC mismatch")
    plain = Chunk(compression="", data=data, message_start_time=chunk.message_start_time,
                  message_end_time=chunk.message_end_time, uncompressed_crc=0,
                  uncompressed_size=len(data))
    return breakup_chunk(plain)


def scan_mcap(path: str | Path) -> Scan:
    """Read every complete record of ``path``; never raises for a truncated or damaged tail."""
    scan = Scan(path=Path(path))
    with open(path, "rb") as fh:
        head = fh.read(len(MCAP_MAGIC))
        if head != MCAP_MAGIC:
            what = "an empty file" if not head else f"it starts with {head!r}"
            raise ValueError(f"{path}: not an MCAP file ({what}; expected the MCAP magic {MCAP_MAGIC!r})")
        fh.seek(0)
        reader = StreamReader(fh, emit_chunks=True, record_size_limit=1 << 30)
        footer = False
        try:
            for record in reader.records:
                inner = [record]
                if isinstance(record, Chunk):
                    try:
                        inner = _chunk_records(record)
                    except Exception as exc:  # noqa: BLE001 - a damaged chunk ends the walk
                        scan.problem = f"damaged chunk at the end of the data: {exc}"
                        break
                    scan.chunks += 1
                for r in inner:
                    if isinstance(r, Schema):
                        scan.schemas[r.id] = r
                    elif isinstance(r, Channel):
                        scan.channels[r.id] = r
                    elif isinstance(r, Message):
                        scan.messages.append(r)
                    elif isinstance(r, Metadata):
                        scan.metadata[r.name] = dict(r.metadata)
                    elif isinstance(r, Attachment):
                        scan.attachments.append(r)
                    elif isinstance(r, (DataEnd, Statistics)):
                        pass
                footer = footer or isinstance(record, Footer)
            scan.finished = footer  # the records end after the footer and the closing magic
        except Exception as exc:  # noqa: BLE001 - truncated record, bad magic, garbage: keep what was read
            scan.problem = f"file ends early ({type(exc).__name__}: {exc})".replace(" ()", "")
    if not scan.finished and scan.problem is None:
        scan.problem = "file ends without a footer"
    return scan


@dataclass
class Session:
    """A recorded session as read back (the layout is `acquisition/layout.py`); times in s, SI values.

    ``streams``: what each stream is, as recorded (``layout.recorded_stream``): the rate its blocks
    were recorded at (Hz; 0 without blocks), and the acceleration stream's range and LSB (m/s^2).
    The ``clipped`` column of ``acceleration`` is the clip rule on them (``clip_level``), applied
    here once: the features take the column."""

    path: Path
    bench: Bench | None
    metadata: dict[str, dict[str, str]]
    clearances: dict[str, float]
    wear_state: dict[str, str]
    acceleration: pd.DataFrame  # time, host_time, acc, sequence, clipped (at or beyond the range)
    encoder: pd.DataFrame  # time, angle, speed, index, sequence
    events: pd.DataFrame  # time, kind, message
    motor: pd.DataFrame  # time, host_time, angle, speed, counts, index_count, enabled, fault
    finished: bool  # False: the file was not finished (killed process); read what was complete
    problem: str | None
    quality: dict[str, dict[str, int]]  # per stream: blocks, samples, dropped, repeated
    origin: float  # device time (s) of time 0
    host_origin: float  # host time (s, Unix) of time 0
    surface_files: dict[str, bytes] = field(default_factory=dict)  # joint -> embedded worn-surface .npz
    streams: dict[str, StreamInfo] = field(default_factory=dict)  # ACCELERATION, ENCODER as recorded
    bench_problem: str | None = None  # why the recorded bench does not load (None: it loads, or none is recorded)

    @property
    def sample_rate(self) -> float:
        """The acceleration's sample rate (Hz) as its blocks recorded it (0 without blocks)."""
        return self.streams[ACCELERATION].sample_rate if ACCELERATION in self.streams else 0.0

    @property
    def clip_level(self) -> float:
        """|a| (m/s^2) from which the ``clipped`` column flags a sample (``layout.clip_level`` of the
        recorded range and LSB; inf when the session recorded no range)."""
        acc = self.streams.get(ACCELERATION)
        return clip_level(acc.range, acc.lsb) if acc is not None else float("inf")


def _messages(scan: Scan, key: str):
    """(message, codec module) of every message on the topic of ``key``, in file order. A channel on
    that topic with another schema (a foreign file reusing the topic) raises one ValueError naming
    the file, topic and schema."""
    codecs = {}
    for cid, c in scan.channels.items():
        if c.topic != TOPICS[key]:
            continue
        schema = scan.schemas.get(c.schema_id)
        if c.message_encoding == layout1.ENCODING:
            codecs[cid] = layout1
        elif c.message_encoding == ENCODING and schema is not None and schema.name == SCHEMAS[key][0]:
            codecs[cid] = layout
        else:
            raise ValueError(f"{scan.path}: {c.topic} is not a wearbench {key} channel (schema "
                             f"{schema.name if schema else 'none'!r}, encoding {c.message_encoding!r}; expected "
                             f"{SCHEMAS[key][0]!r}): expected a session recorded by 'wearbench record'")
    return [(m, codecs[m.channel_id]) for m in scan.messages if m.channel_id in codecs]


def check_session(scan: Scan) -> None:
    """Raise one ValueError naming the file unless ``scan`` is of a wearbench session: every channel
    on a session topic has the session's schema, and it holds the session record or such a channel."""
    ours = [cid for key in TOPICS for cid in {m.channel_id for m, _ in _messages(scan, key)}]
    if "session" not in scan.metadata and not ours:
        raise ValueError(f"{scan.path}: no wearbench session in this file (no session record and no session "
                         f"channel: topics {sorted({c.topic for c in scan.channels.values()})}); expected a "
                         "session recorded by 'wearbench record'")


def _decode(scan: Scan, key: str, decode) -> list:
    """``decode(message, codec)`` of every message of ``key``; a message that is not wearbench's (a
    foreign file reusing the topic with another schema) raises one ValueError naming topic and schema."""
    out = []
    for m, codec in _messages(scan, key):
        try:
            out.append(decode(m, codec))
        except Exception as exc:  # noqa: BLE001 - any decoding failure means the same to the user
            channel = scan.channels[m.channel_id]
            schema = scan.schemas.get(channel.schema_id)
            raise ValueError(f"{scan.path}: {channel.topic}: not a wearbench {key} message (schema "
                             f"{schema.name if schema else 'none'!r}, encoding {channel.message_encoding!r}; "
                             f"expected {SCHEMAS[key][0]!r}): {type(exc).__name__}: {exc}") from None
    return out


def blocks(scan: Scan, stream: str) -> list[Block]:
    """The blocks of ``stream`` (ACCELERATION or ENCODER) in file order."""
    return _decode(scan, stream, lambda m, codec: codec.decode_block(stream, m.data))


def states(scan: Scan) -> list[MotorState]:
    return _decode(scan, "state", lambda m, codec: codec.decode_state(m.data))


def events(scan: Scan) -> list[Event]:
    return _decode(scan, "events", lambda m, codec: layout1.decode_event(m.data) if codec is layout1
                   else layout.decode_event(m.data, m.publish_time, m.log_time))


def frames(scan: Scan) -> list[BusFrame]:
    """Raw bus frames (``/can/frames``; layout 2 only) in file order."""
    return [layout.decode_frame(m.data, m.log_time) for m, _ in _messages(scan, "frames")]


def _dedupe(blocks, stream: str, quality: dict) -> list:
    """Sorted by sequence, repeated sequence numbers kept once; counts gaps and repeats."""
    check, kept = SequenceCheck(), []
    for b in sorted(blocks, key=lambda b: b.sequence):
        repeated = check.repeated
        check.check(stream, b.sequence, len(b.samples))
        if check.repeated == repeated:
            kept.append(b)
    quality[stream] = {"blocks": len(kept), "samples": int(sum(len(b.samples) for b in kept)),
                       "dropped": check.dropped, "repeated": check.repeated}
    return kept


def _recorded_rate(blocks) -> float:
    """The rate (Hz) a stream's blocks were recorded at, as recorded: every block carries it (when
    they differ, a stream reconfigured mid-way, the rate most samples were taken at); 0 without blocks.
    Sample times come from each block's own rate (``_sample_frame``)."""
    samples: dict[float, int] = {}
    for b in blocks:
        samples[float(b.sample_rate)] = samples.get(float(b.sample_rate), 0) + len(b.samples)
    return max(samples, key=samples.__getitem__) if samples else 0.0


def _sample_frame(blocks, origin: float, host_origin: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    if not blocks:
        return np.zeros(0), np.zeros(0), np.zeros(0, dtype=np.int64)
    n = np.array([len(b.samples) for b in blocks])
    start = np.repeat([b.device_time - origin for b in blocks], n)
    rate = np.repeat([b.sample_rate for b in blocks], n)
    first = np.repeat(np.cumsum(n) - n, n)
    pos = np.arange(n.sum()) - first
    time = start + pos / rate
    host = np.repeat([b.host_time - host_origin for b in blocks], n)
    seq = np.repeat([b.sequence for b in blocks], n).astype(np.int64)
    return time, host, seq


def _unwrap_counts(counts: np.ndarray) -> np.ndarray:
    c = counts.astype(np.int64)
    if len(c) < 2:
        return c
    step = np.diff(c)
    step = (step + 2**31) % 2**32 - 2**31  # int32 wrap-around
    return np.concatenate([[c[0]], c[0] + np.cumsum(step)])


def _speed(angle: np.ndarray, t: np.ndarray, half: int = 5) -> np.ndarray:
    """Crank speed (rad/s): central difference over +-``half`` samples (one count of quantisation
    then costs 1/(2 half) of what it costs between neighbours); plain gradient at the ends."""
    if len(t) < 2:
        return np.zeros(len(t))
    speed = np.gradient(angle, t)
    if len(t) > 2 * half:
        speed[half:-half] = (angle[2 * half:] - angle[:-2 * half]) / (t[2 * half:] - t[:-2 * half])
    return speed


def _bench_counts_per_rev(bench: Bench | None) -> float:
    """The encoder's counts per revolution in ``bench`` (0 without a bench or an encoder)."""
    try:
        return float(bench.sensor("encoder").counts_per_rev) if bench is not None else 0.0
    except KeyError:
        return 0.0


def _bench(text: str, meta: dict, path: Path, files: dict[str, bytes]) -> tuple[Bench | None, str | None]:
    """The recorded bench, its relative file names (worn surfaces) taken from where the bench file
    was when recorded, else from beside the session file, else from the copies the session carries
    (``files``, {relative path: bytes}: unpacked once into a folder named by their digest under
    ``$WEARBENCH_CACHE/sessions``); (None, why) if none works, why being the first place's error
    (the bench file where it was recorded, when the session says)."""
    error = None
    for where in (meta.get("session", {}).get("bench_path"), f"{path.parent / BENCH_ATTACHMENT}",
                  _unpacked(text, files) if files else None):
        if where:
            try:
                return parse_bench(text, where), None
            except BenchError as exc:
                error = error or exc
    return None, f"the recorded bench does not load here: {error}"


def _unpacked(text: str, files: dict[str, bytes]) -> str | None:
    """A folder holding the bench file ``text`` and ``files`` at their relative paths; its bench file's
    path (None where it cannot be written)."""
    digest = hashlib.sha256(text.encode())
    for name in sorted(files):
        digest.update(name.encode() + b"\0" + hashlib.sha256(files[name]).digest())
    folder = cache_folder("sessions") / digest.hexdigest()[:32]
    try:
        for name, data in [(BENCH_ATTACHMENT, text.encode()), *files.items()]:
            target = folder / name
            if ".." in Path(name).parts or Path(name).is_absolute():
                continue
            if not target.exists():
                target.parent.mkdir(parents=True, exist_ok=True)
                tmp = target.with_name(f".{target.name}.{os.getpid()}")
                tmp.write_bytes(data)
                os.replace(tmp, target)
    except OSError:
        return None
    return str(folder / BENCH_ATTACHMENT)


def read_session(path: str | Path) -> Session:
    """Read the session MCAP at ``path``; an unfinished file gives everything that was complete.

    Raises ValueError when the file holds no wearbench session at all.
    """
    path = Path(path)
    scan = scan_mcap(path)
    if not scan.channels and not scan.metadata:
        raise ValueError(f"{path}: no wearbench session in this file ({scan.problem or 'empty'})")
    meta = scan.metadata
    bench, problem, bench_problem = None, scan.problem, None
    files = {a.name[len(BENCH_FILES):]: a.data for a in scan.attachments if a.name.startswith(BENCH_FILES)}
    for a in scan.attachments:
        if a.name == BENCH_ATTACHMENT:
            bench, bench_problem = _bench(a.data.decode(), meta, path, files)
            problem = "; ".join(filter(None, (problem, bench_problem))) or None
    clearances = {k: float(v) for k, v in meta.get("clearance", {}).items()}
    wear_state = dict(meta.get("wear", {}))
    calib = meta.get("calibration", {})

    quality: dict[str, dict[str, int]] = {}
    acc_blocks = _dedupe(blocks(scan, ACCELERATION), ACCELERATION, quality)
    enc_blocks = _dedupe(blocks(scan, ENCODER), ENCODER, quality)
    firsts = acc_blocks or enc_blocks
    origin = min((b.device_time for b in firsts), default=0.0)
    host_origin = min((b.host_time for b in firsts), default=0.0)

    streams = {name: recorded_stream(calib, name, _recorded_rate(b))
               for name, b in ((ACCELERATION, acc_blocks), (ENCODER, enc_blocks))}
    t, h, seq = _sample_frame(acc_blocks, origin, host_origin)
    values = np.concatenate([b.samples for b in acc_blocks]).astype(np.float64) if acc_blocks else np.zeros(0)
    acc = streams[ACCELERATION]
    acceleration = pd.DataFrame({"time": t, "host_time": h, "acc": values, "sequence": seq,
                                 "clipped": clipped(values, clip_level(acc.range, acc.lsb))})

    t, h, seq = _sample_frame(enc_blocks, origin, host_origin)
    crank = recorded_crank(calib, _bench_counts_per_rev(bench))
    counts = _unwrap_counts(np.concatenate([b.samples for b in enc_blocks])) if enc_blocks else np.zeros(0)
    angle = counts * (2 * math.pi / crank.counts_per_rev) + crank.offset if crank else counts * np.nan
    speed = _speed(angle, t)
    index = (np.concatenate([b.index for b in enc_blocks]) if enc_blocks else np.zeros(0, dtype=bool))
    encoder = pd.DataFrame({"time": t, "angle": angle, "speed": speed, "index": index.astype(bool),
                            "sequence": seq})

    ev_rows = [{"time": (e.device_time - origin) if e.device_time is not None else e.host_time - host_origin,
                "host_time": e.host_time - host_origin, "kind": e.kind, "message": e.message}
               for e in events(scan)]
    st_rows = [{"time": m.device_time - origin, "host_time": m.host_time - host_origin, "angle": m.angle,
                "speed": m.speed, "counts": m.counts, "index_count": m.index_count, "enabled": m.enabled,
                "fault": m.fault} for m in states(scan)]
    event_frame = pd.DataFrame(ev_rows, columns=["time", "host_time", "kind", "message"])
    motor = pd.DataFrame(st_rows, columns=["time", "host_time", "angle", "speed", "counts", "index_count",
                                           "enabled", "fault"])
    return Session(path=path, bench=bench, metadata=meta, clearances=clearances, wear_state=wear_state,
                   acceleration=acceleration, encoder=encoder, events=event_frame, motor=motor,
                   finished=scan.finished, problem=problem, bench_problem=bench_problem, quality=quality, origin=origin,
                   host_origin=host_origin,
                   surface_files={surface_joint(a.name): a.data for a in scan.attachments
                                  if surface_joint(a.name)}, streams=streams)
