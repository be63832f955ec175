"""Reading sessions recorded in the first layout (before the protobuf layout of ``layout``).

Layout 1 put every message in JSON (``jsonschema`` schemas, channel encoding ``json``): block samples
as base64 of little-endian float32 (acceleration, m/s^2) or int32 (encoder counts) inside the JSON,
the index pulse as ``index_at`` positions, events as ``wearbench.Event`` {kind, message, times}.
Nothing records it any more; sessions already recorded stay readable through these decoders, and
``wearbench recover`` rewrites them in the current layout. Imports numpy, the driver dataclasses
and ``layout.Command``.
"""

from __future__ import annotations

import base64
import json

import numpy as np
from wearbench.acquisition.drivers import ACCELERATION, Block, Event, MotorState
from wearbench.acquisition.layout import Command

__all__ = ["ENCODING", "decode_block", "decode_command", "decode_event", "decode_state"]

ENCODING = "json"  # the channel message encoding of every layout-1 channel


def decode_block(stream: str, data: bytes) -> Block:
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


def decode_state(data: bytes) -> MotorState:
    s = json.loads(data)
    return MotorState(device_time=s["device_time"], angle=s["angle"], speed=s["speed"], counts=s["counts"],
                      index_count=s["index_count"], enabled=s["enabled"], fault=s["fault"],
                      host_time=s["host_time"])


def decode_command(data: bytes) -> Command:
    c = json.loads(data)
    return Command(c["command"], c.get("speed"), c.get("acceleration"), c.get("host_time", 0.0))


def decode_event(data: bytes) -> Event:
    e = json.loads(data)
    return Event(e["kind"], e["message"], host_time=e["host_time"], device_time=e.get("device_time"))

