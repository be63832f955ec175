"""The MCAP layout of a session: topics, JSON schemas, and the encoding of each message.

One channel per stream, JSON-schema encoded so Foxglove opens the file:

- ``/acceleration`` and ``/encoder``: one message per device block. The samples travel as
  base64 of little-endian float32 (acceleration, m/s^2) or int32 (encoder counts), not as JSON
  arrays of numbers: it is exact (the file holds bit for bit what the device sent), 4/3 of the raw
  size instead of ~12 bytes per sample, and costs a ``b64encode`` instead of formatting 20,000
  floats a second. JSON Schema's ``contentEncoding: base64`` tells viewers so.
- ``/motor/state`` (polled drive state, plain numbers, plottable), ``/motor/command`` and ``/events``.

``log_time`` is the host time of arrival (ns since the Unix epoch); ``publish_time`` the device
time (ns on the device clock). Imports numpy and the driver dataclasses only.
"""

from __future__ import annotations

import base64
import json
from dataclasses import dataclass

import numpy as np
from wearbench.acquisition.drivers import ACCELERATION, ENCODER, Block, Event, MotorState

__all__ = [
    "SCHEMAS",
    "TOPICS",
    "Command",
    "decode_block",
    "encode_block",
    "encode_command",
    "encode_event",
    "encode_state",
    "ns",
]

TOPICS = {ACCELERATION: "/acceleration", ENCODER: "/encoder", "state": "/motor/state",
          "command": "/motor/command", "events": "/events"}

_TIMES = {
    "device_time": {"type": "number", "description": "device clock, s (first sample of a block)"},
    "host_time": {"type": "number", "description": "host clock at arrival, s since the Unix epoch"},
}
_BLOCK = {
    "sequence": {"type": "integer", "description": "device block counter, unwrapped"},
    **_TIMES,
    "sample_rate": {"type": "number", "description": "Hz; sample i at device_time + i/sample_rate"},
    "count": {"type": "integer", "description": "samples in the block"},
}


def _schema(title: str, props: dict) -> bytes:
    return json.dumps({"title": title, "type": "object", "properties": props}).encode()


SCHEMAS: dict[str, tuple[str, bytes]] = {
    ACCELERATION: ("wearbench.AccelerationBlock", _schema("wearbench.AccelerationBlock", {
        **_BLOCK,
        "unit": {"type": "string"},
        "samples": {"type": "string", "contentEncoding": "base64",
                    "description": "little-endian float32 acceleration samples, m/s^2"},
    })),
    ENCODER: ("wearbench.EncoderBlock", _schema("wearbench.EncoderBlock", {
        **_BLOCK,
        "counts": {"type": "string", "contentEncoding": "base64",
                   "description": "little-endian int32 encoder counts per sample"},
        "index_at": {"type": "array", "items": {"type": "integer"},
                     "description": "sample positions where the index pulse is high"},
    })),
    "state": ("wearbench.MotorState", _schema("wearbench.MotorState", {
        **_TIMES, "angle": {"type": "number", "description": "crank angle, rad, unwrapped"},
        "speed": {"type": "number", "description": "rad/s"}, "counts": {"type": "integer"},
        "index_count": {"type": "integer"}, "enabled": {"type": "boolean"},
        "fault": {"type": ["string", "null"]},
    })),
    "command": ("wearbench.MotorCommand", _schema("wearbench.MotorCommand", {
        "host_time": _TIMES["host_time"],
        "command": {"type": "string", "enum": ["enable", "disable", "set_speed", "stop"]},
        "speed": {"type": ["number", "null"], "description": "rad/s"},
        "acceleration": {"type": ["number", "null"], "description": "rad/s^2"},
    })),
    "events": ("wearbench.Event", _schema("wearbench.Event", {
        **_TIMES, "kind": {"type": "string"}, "message": {"type": "string"},
    })),
}


def ns(seconds: float) -> int:
    """Seconds to non-negative integer nanoseconds (MCAP times are unsigned)."""
    return max(0, round(seconds * 1e9))


@dataclass(frozen=True)
class Command:
    command: str
    speed: float | None = None
    acceleration: float | None = None
    host_time: float = 0.0


def _dump(obj: dict) -> bytes:
    return json.dumps(obj, separators=(",", ":")).encode()


def encode_block(block: Block, unit: str = "") -> bytes:
    if block.stream == ACCELERATION:
        samples = np.ascontiguousarray(block.samples, dtype="<f4")
        body = {"unit": unit or "m/s^2", "samples": base64.b64encode(samples.data).decode()}
    elif block.stream == ENCODER:
        counts = np.ascontiguousarray(block.samples, dtype="<i4")
        index = [] if block.index is None else np.flatnonzero(block.index).tolist()
        body = {"counts": base64.b64encode(counts.data).decode(), "index_at": index}
    else:
        raise ValueError(f"unknown stream {block.stream!r}; expected {ACCELERATION!r} or {ENCODER!r}")
    return _dump({"sequence": int(block.sequence), "device_time": float(block.device_time),
                  "host_time": float(block.host_time), "sample_rate": float(block.sample_rate),
                  "count": len(block.samples), **body})


def decode_block(stream: str, data: bytes) -> Block:
    """The :class:`Block` a message holds (inverse of :func:`encode_block`)."""
    m = json.loads(data)
    if stream == ACCELERATION:
        samples = np.frombuffer(base64.b64decode(m["samples"]), dtype="<f4")
        index = None
    else:
        samples = np.frombuffer(base64.b64decode(m["counts"]), dtype="<i4")
        index = np.zeros(len(samples), dtype=bool)
        index[m.get("index_at", [])] = True
    if len(samples) != m["count"]:
        raise ValueError(f"{stream} block {m['sequence']}: {len(samples)} samples, header says {m['count']}")
    return Block(stream=stream, sequence=m["sequence"], device_time=m["device_time"],
                 sample_rate=m["sample_rate"], samples=samples, host_time=m["host_time"], index=index)


def encode_state(s: MotorState) -> bytes:
    return _dump({"device_time": s.device_time, "host_time": s.host_time, "angle": s.angle,
                  "speed": s.speed, "counts": int(s.counts), "index_count": int(s.index_count),
                  "enabled": bool(s.enabled), "fault": s.fault})


def encode_event(e: Event) -> bytes:
    return _dump({"device_time": e.device_time, "host_time": e.host_time, "kind": e.kind,
                  "message": e.message})


def encode_command(c: Command) -> bytes:
    return _dump({"host_time": c.host_time, "command": c.command, "speed": c.speed,
                  "acceleration": c.acceleration})
