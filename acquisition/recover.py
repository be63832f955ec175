"""Restoring a session file that was never finished (a process killed outright, a power cut).

:func:`recover` copies every complete record of the broken file (schemas, channels, metadata, the
bench attachment, and every message of every complete chunk) into a new, finished MCAP, and adds
an event and a ``recovery`` metadata record saying what was restored and where the original ended,
and removes the ballast file the killed recorder had set aside. The new file has the session
writer's chunking, compression, indexes and CRCs. A file in layout 1 (JSON, base64 samples) comes
out in the current layout, every message re-encoded (same samples, bit for bit; the derived crank
angle, cycle and clipped counts added from its calibration), so a viewer plots it.
Imports mcap, the layouts and the session scan only.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from mcap.writer import IndexType, Writer
from wearbench.acquisition import layout, layout1
from wearbench.acquisition.drivers import ACCELERATION, ENCODER, Event
from wearbench.acquisition.layout import (
    ENCODING,
    SCHEMAS,
    TOPICS,
    clip_level,
    count_clipped,
    ns,
    publish_time,
    recorded_crank,
    recorded_stream,
)
from wearbench.acquisition.session_file import check_session, scan_mcap
from wearbench.acquisition.session_writer import CHUNK_SIZE, COMPRESSION, PROFILE
from wearbench.bench.output_file import check_output, output_file

__all__ = ["RecoveryReport", "recover"]


@dataclass(frozen=True)
class RecoveryReport:
    source: Path
    out: Path
    chunks: int
    messages: int
    was_finished: bool
    problem: str | None
    upgraded: bool = False  # layout 1 rewritten in the current layout


def _upgraders(calibration: dict[str, str]) -> dict[str, Callable[[bytes], bytes]]:
    """Layout-1 message -> current-layout message, per channel key."""

    crank = recorded_crank(calibration)
    acc = recorded_stream(calibration, ACCELERATION)
    level = clip_level(acc.range, acc.lsb)  # the recorder's count, as it would have recorded it

    def acceleration(data: bytes) -> bytes:
        block = layout1.decode_block(ACCELERATION, data)
        block.clipped = count_clipped(block.samples, level)
        return layout.encode_block(block)

    return {ACCELERATION: acceleration,
            ENCODER: lambda data: layout.encode_block(layout1.decode_block(ENCODER, data), crank),
            "state": lambda data: layout.encode_state(layout1.decode_state(data)),
            "command": lambda data: layout.encode_command(layout1.decode_command(data)),
            "events": lambda data: layout.encode_event(layout1.decode_event(data))}


def recover(broken: str | Path, out: str | Path, *, force: bool = False) -> RecoveryReport:
    """Write every complete record of ``broken`` into a finished MCAP at ``out`` (an existing ``out``
    only with ``force``, by the output-file policy: written beside it, renamed when complete)."""
    broken, out = Path(broken), Path(out)
    if broken.resolve() == out.resolve():
        raise ValueError(f"{out}: recover writes a new file; give an --out other than the input")
    check_output(out, force=force, session=True)
    scan = scan_mcap(broken)
    if not scan.channels and not scan.messages:
        raise ValueError(f"{broken}: nothing to recover ({scan.problem or 'no channels'})")
    check_session(scan)
    with output_file(out, force=force, session=True) as tmp, open(tmp, "wb") as fh:
        w = Writer(fh, chunk_size=CHUNK_SIZE, compression=COMPRESSION, index_types=IndexType.ALL,
                   enable_crcs=True, enable_data_crcs=True)
        w.start(profile=PROFILE, library="wearbench recover")
        keys = {topic: key for key, topic in TOPICS.items()}
        upgrade = _upgraders(scan.metadata.get("calibration", {}))
        convert: dict[int, Callable[[bytes], bytes]] = {}  # layout-1 channel -> re-encoder
        schema_ids, channel_ids = {}, {}
        for cid, c in scan.channels.items():
            key = keys.get(c.topic)
            if c.message_encoding == layout1.ENCODING and key in upgrade:
                name, data = SCHEMAS[key]
                sid = w.register_schema(name, ENCODING, data)
                channel_ids[cid] = w.register_channel(c.topic, ENCODING, sid, dict(c.metadata))
                convert[cid] = upgrade[key]
                continue
            if c.schema_id and c.schema_id not in schema_ids and c.schema_id in scan.schemas:
                s = scan.schemas[c.schema_id]
                schema_ids[c.schema_id] = w.register_schema(s.name, s.encoding, s.data)
            channel_ids[cid] = w.register_channel(c.topic, c.message_encoding, schema_ids.get(c.schema_id, 0),
                                                  dict(c.metadata))
        for a in scan.attachments:
            w.add_attachment(a.create_time, a.log_time, a.name, a.media_type, a.data)
        for name, record in scan.metadata.items():
            w.add_metadata(name, record)
        last = 0
        for m in scan.messages:
            if m.channel_id in channel_ids:
                data, publish = m.data, m.publish_time
                if m.channel_id in convert:
                    try:
                        data = convert[m.channel_id](m.data)
                    except Exception as exc:  # noqa: BLE001 - another tool's JSON on a session topic
                        raise ValueError(f"{broken}: a message on {scan.channels[m.channel_id].topic} is not a "
                                         f"wearbench session message ({type(exc).__name__}: {exc}); expected a "
                                         "session recorded by 'wearbench record'") from None
                    if scan.channels[m.channel_id].topic == TOPICS["events"]:  # layout 1: 0 for none
                        publish = publish_time(layout1.decode_event(m.data).device_time, m.log_time)
                w.add_message(channel_ids[m.channel_id], m.log_time, data, publish, m.sequence)
                last = max(last, m.log_time)
        note = (f"recovered by 'wearbench recover' from {broken.name}: {scan.chunks} complete chunks, "
                f"{len(scan.messages)} messages; the original "
                + ("was finished" if scan.finished else f"was not finished ({scan.problem})"))
        events = [cid for cid, c in scan.channels.items() if c.topic == TOPICS["events"]]
        if events:
            ev = Event("recovered", note, host_time=last / 1e9 if last else time.time())
            t = ns(ev.host_time)
            w.add_message(channel_ids[events[0]], t, layout.encode_event(ev), publish_time(None, t))
        w.add_metadata("recovery", {"source": str(broken), "chunks": str(scan.chunks),
                                    "messages": str(len(scan.messages)), "was_finished": str(scan.finished),
                                    "problem": scan.problem or "", "recovered_at":
                                    time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
                                    "layout": "rewritten from layout 1 (JSON)" if convert else "as recorded"})
        w.finish()
    ballast = broken.with_name(broken.name + ".ballast")  # set aside by the killed recorder
    if ballast.exists():
        ballast.unlink()
    return RecoveryReport(broken, out, scan.chunks, len(scan.messages), scan.finished, scan.problem,
                          bool(convert))
