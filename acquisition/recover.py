"""Restoring a session file that was never finished (a process killed outright, a power cut).

:func:`recover` copies every complete record of the broken file (schemas, channels, metadata, the
bench attachment, and every message of every complete chunk) into a new, finished MCAP, and adds
an event (in the layout of the file's events channel) and a ``recovery`` metadata record saying what
was restored and where the original ended, and removes the ballast file the killed recorder had set
aside. The new file has the session writer's chunking, compression, indexes and CRCs.
Imports mcap and the session scan only.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from mcap.writer import IndexType, Writer
from wearbench.acquisition import layout, layout1
from wearbench.acquisition.drivers import Event
from wearbench.acquisition.layout import TOPICS, ns
from wearbench.acquisition.session_file import scan_mcap
from wearbench.acquisition.session_writer import CHUNK_SIZE, COMPRESSION, PROFILE

__all__ = ["RecoveryReport", "recover"]


@dataclass(frozen=True)
class RecoveryReport:
    source: Path
    out: Path
    chunks: int
    messages: int
    was_finished: bool
    problem: str | None


def recover(broken: str | Path, out: str | Path) -> RecoveryReport:
    """Write every complete record of ``broken`` into a finished MCAP at ``out``."""
    broken, out = Path(broken), Path(out)
    if broken.resolve() == out.resolve():
        raise ValueError(f"{out}: recover writes a new file; give an --out other than the input")
    scan = scan_mcap(broken)
    if not scan.channels and not scan.messages:
        raise ValueError(f"{broken}: nothing to recover ({scan.problem or 'no channels'})")
    with open(out, "wb") as fh:
        w = Writer(fh, chunk_size=CHUNK_SIZE, compression=COMPRESSION, index_types=IndexType.ALL,
                   enable_crcs=True, enable_data_crcs=True)
        w.start(profile=PROFILE, library="wearbench recover")
        schema_ids = {sid: w.register_schema(s.name, s.encoding, s.data) for sid, s in scan.schemas.items()}
        channel_ids = {cid: w.register_channel(c.topic, c.message_encoding, schema_ids.get(c.schema_id, 0),
                                               dict(c.metadata))
                       for cid, c in scan.channels.items()}
        for a in scan.attachments:
            w.add_attachment(a.create_time, a.log_time, a.name, a.media_type, a.data)
        for name, record in scan.metadata.items():
            w.add_metadata(name, record)
        last = 0
        for m in scan.messages:
            if m.channel_id in channel_ids:
                w.add_message(channel_ids[m.channel_id], m.log_time, m.data, m.publish_time, m.sequence)
                last = max(last, m.log_time)
        note = (f"recovered by 'wearbench recover' from {broken.name}: {scan.chunks} complete chunks, "
                f"{len(scan.messages)} messages; the original "
                + ("was finished" if scan.finished else f"was not finished ({scan.problem})"))
        events = [cid for cid, c in scan.channels.items() if c.topic == TOPICS["events"]]
        if events:
            ev = Event("recovered", note, host_time=last / 1e9 if last else time.time())
            legacy = scan.channels[events[0]].message_encoding == layout1.ENCODING
            data = layout1.encode_event(ev) if legacy else layout.encode_event(ev)
            w.add_message(channel_ids[events[0]], ns(ev.host_time), data, 0)
        w.add_metadata("recovery", {"source": str(broken), "chunks": str(scan.chunks),
                                    "messages": str(len(scan.messages)), "was_finished": str(scan.finished),
                                    "problem": scan.problem or "", "recovered_at":
                                    time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())})
        w.finish()
    ballast = broken.with_name(broken.name + ".ballast")  # set aside by the killed recorder
    if ballast.exists():
        ballast.unlink()
    return RecoveryReport(broken, out, scan.chunks, len(scan.messages), scan.finished, scan.problem)
