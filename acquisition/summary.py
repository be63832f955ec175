"""A readable summary of a session file: channels, rates, duration, gaps, drops, metadata.

``wearbench inspect`` prints :func:`summarize`. Works on unfinished files (it reads through the
tolerant scan). Imports the session reader and the layout only.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from wearbench.acquisition.drivers import ACCELERATION, ENCODER
from wearbench.acquisition.layout import TOPICS
from wearbench.acquisition.sequence import SequenceCheck, gaps
from wearbench.acquisition.session_file import blocks, events, scan_mcap

__all__ = ["SessionSummary", "StreamSummary", "format_summary", "summarize"]


@dataclass
class StreamSummary:
    topic: str
    messages: int
    samples: int = 0
    duration: float = 0.0  # s, device clock, first sample to the end of the last block
    rate: float = 0.0  # samples (or messages) per second of device time
    dropped_blocks: int = 0
    repeated_blocks: int = 0
    gaps: int = 0  # steps between consecutive blocks' samples longer than 1.5 periods (sequence.gaps)
    longest_gap: float = 0.0  # s
    clipped: int = 0  # acceleration samples at or beyond the range (layout 2 records them per block)


@dataclass
class SessionSummary:
    path: Path
    finished: bool
    problem: str | None
    chunks: int
    streams: list[StreamSummary] = field(default_factory=list)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    attachments: list[str] = field(default_factory=list)
    events: Counter = field(default_factory=Counter)


def _block_stream(topic: str, blocks) -> StreamSummary:
    s = StreamSummary(topic, len(blocks))
    if not blocks:
        return s
    blocks = sorted(blocks, key=lambda b: (b.sequence, b.device_time))
    check = SequenceCheck()
    for b in blocks:
        check.check(topic, b.sequence, len(b.samples))
    s.dropped_blocks, s.repeated_blocks = check.dropped, check.repeated
    s.samples = int(sum(len(b.samples) for b in blocks))
    s.clipped = int(sum(b.clipped for b in blocks))
    start = np.array([b.device_time for b in blocks])
    end = start + np.array([len(b.samples) / b.sample_rate for b in blocks])
    s.duration = float(end[-1] - start[0])
    s.rate = s.samples / s.duration if s.duration > 0 else 0.0
    breaks = start[1:] - end[:-1]
    rate = blocks[0].sample_rate
    s.gaps = int(np.count_nonzero(gaps(breaks + 1.0 / rate, rate)))  # last sample of a block to the next one's first
    s.longest_gap = float(breaks.max()) if len(breaks) else 0.0
    return s


def summarize(path: str | Path) -> SessionSummary:
    scan = scan_mcap(path)
    out = SessionSummary(Path(path), scan.finished, scan.problem, scan.chunks, metadata=scan.metadata,
                         attachments=[a.name for a in scan.attachments])
    by_topic: dict[str, list] = {c.topic: [] for c in scan.channels.values()}
    for m in scan.messages:
        by_topic.setdefault(scan.topic(m.channel_id), []).append(m)
    streams = {TOPICS[ACCELERATION]: ACCELERATION, TOPICS[ENCODER]: ENCODER}
    for topic, msgs in by_topic.items():
        if topic in streams:
            out.streams.append(_block_stream(topic, blocks(scan, streams[topic])))
            continue
        s = StreamSummary(topic, len(msgs))
        if len(msgs) > 1:
            t = np.array([m.log_time for m in msgs]) * 1e-9
            s.duration = float(t.max() - t.min())
            s.rate = (len(msgs) - 1) / s.duration if s.duration > 0 else 0.0
        out.streams.append(s)
        if topic == TOPICS["events"]:
            out.events.update(e.kind for e in events(scan))
    return out


def format_summary(s: SessionSummary) -> str:
    lines = [f"{s.path}: " + ("finished" if s.finished else f"NOT finished: {s.problem}")
             + f", {s.chunks} chunks"]
    lines.append(f"  {'channel':16s} {'messages':>9s} {'samples':>10s} {'duration':>10s} {'rate':>11s} "
                 f"{'dropped':>8s} {'repeated':>8s} {'gaps':>5s} {'longest gap':>12s} {'clipped':>8s}")
    for c in s.streams:
        lines.append(f"  {c.topic:16s} {c.messages:9d} {c.samples:10d} {c.duration:9.3f}s "
                     f"{c.rate:9.1f}Hz {c.dropped_blocks:8d} {c.repeated_blocks:8d} {c.gaps:5d} "
                     f"{c.longest_gap * 1e3:10.2f}ms {c.clipped:8d}")
    if s.events:
        lines.append("  events: " + ", ".join(f"{k} x{n}" for k, n in sorted(s.events.items())))
    if s.attachments:
        lines.append("  attachments: " + ", ".join(s.attachments))
    for name, record in s.metadata.items():
        lines.append(f"  [{name}]")
        lines.extend(f"    {k} = {v}" for k, v in record.items())
    return "\n".join(lines)
