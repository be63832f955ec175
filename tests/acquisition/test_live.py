"""The live view: a WebSocket client speaking the Foxglove protocol watches a session on the
emulator and receives its acceleration blocks, bit for bit what the file holds, while a viewer that
never reads and one that disconnects cost the recording nothing."""

from __future__ import annotations

import asyncio
import base64
import json
import struct
import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from wearbench.acquisition.backends import open_rig
from wearbench.acquisition.drivers import ACCELERATION, Event
from wearbench.acquisition.layout import TOPICS, decode_block, decode_event, encode_event
from wearbench.acquisition.live import SUBPROTOCOLS, LiveView, parse_address
from wearbench.acquisition.recorder import Recorder
from wearbench.acquisition.session import SessionPlan
from wearbench.acquisition.session_writer import SessionWriter
from wearbench.testing import mcap_readers

from .conftest import FAST, HARMONIC, assert_same_blocks, recorded_blocks, sent_from_device

websockets = pytest.importorskip("websockets")
SUBPROTOCOL = "foxglove.sdk.v1"


async def _subscribe(ws, topics: list[str]) -> dict[int, str]:
    """Wait for the channels to be advertised and subscribe to ``topics``; {subscription: topic}."""
    while True:
        msg = json.loads(await asyncio.wait_for(ws.recv(), 5))
        if msg["op"] == "advertise":
            break
    ids = {c["topic"]: c["id"] for c in msg["channels"]}
    subs = {i: t for i, t in enumerate(topics, 1)}
    await ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": i, "channelId": ids[t]}
                                                                  for i, t in subs.items()]}))
    return subs


async def _viewers(url: str, recording: threading.Thread) -> dict[str, list]:
    """A viewer that reads everything, one that never reads and one that leaves early."""
    got: dict[str, list] = {"/acceleration": [], "/events": []}
    async with websockets.connect(url, subprotocols=[SUBPROTOCOL]) as good, \
            websockets.connect(url, subprotocols=[SUBPROTOCOL], max_queue=1, close_timeout=0.5) as slow:
        subs = await _subscribe(good, list(got))
        await _subscribe(slow, ["/acceleration", "/encoder", "/motor/state"])  # and never reads again
        leaving = await websockets.connect(url, subprotocols=[SUBPROTOCOL])
        await _subscribe(leaving, ["/acceleration"])
        left = False
        while recording.is_alive() or got["/acceleration"] == []:
            try:
                data = await asyncio.wait_for(good.recv(), 0.5)
            except TimeoutError:
                if not recording.is_alive():
                    break
                continue
            if isinstance(data, bytes) and data[0] == 1:  # message data: op, subscription, time, payload
                sub, _ = struct.unpack_from("<IQ", data, 1)
                got[subs[sub]].append(data[13:])
            if not left and len(got["/acceleration"]) > 5:
                await leaving.close()  # a viewer closing mid-session
                left = True
    return got


def test_live_view_streams_the_session(bench, tmp_path):
    rig = open_rig(bench, "sim", {"speedup": 1.0, "config": HARMONIC})  # real time, as on a bench
    sent = sent_from_device(rig.drive.device)
    out = tmp_path / "live.mcap"
    results = []
    with LiveView(port=0, backlog=256) as live:
        writer = SessionWriter(out, live=live)
        recorder = Recorder(rig, bench, SessionPlan(speed=FAST, duration=2.0, settle=0.2), out, writer=writer)
        recording = threading.Thread(target=lambda: results.append(recorder.run()))
        recording.start()
        try:
            got = asyncio.run(_viewers(live.url, recording))
        finally:
            recording.join(timeout=60)
            rig.close()
    result = results[0]
    assert result.completed, result.reason
    assert sum(result.dropped_samples.values()) == 0
    assert_same_blocks(out, sent)
    # the viewer saw most blocks while they were recorded, each exactly as the file holds it
    file_blocks = recorded_blocks(out)[ACCELERATION]
    seen = [decode_block(ACCELERATION, d) for d in got["/acceleration"]]
    assert len(seen) >= len(file_blocks) // 2
    for b in seen:
        np.testing.assert_array_equal(b.samples, file_blocks[b.sequence].samples)
    kinds = [decode_event(d, 0, 0).kind for d in got["/events"]]
    assert "phase" in kinds


def test_parse_address():
    assert parse_address("127.0.0.1:8765") == ("127.0.0.1", 8765)
    assert parse_address("[::1]:9000") == ("::1", 9000)
    assert parse_address(":0") == ("127.0.0.1", 0)
    assert parse_address("8766") == ("127.0.0.1", 8766)
    with pytest.raises(ValueError, match="expected HOST:PORT"):
        parse_address("localhost:http")


def test_record_cli_live(tmp_path):
    import sys

    config = tmp_path / "emulator.json"
    config.write_text(json.dumps(HARMONIC))
    out = tmp_path / "cli-live.mcap"
    r = subprocess.run([sys.executable, "-m", "wearbench.cli", "record", "ninebar-testbed", "--backend", "sim",
                        "--option", "speedup=inf", "--option", f"config={config}", "--speed", f"{FAST}rad/s",
                        "--cycles", "3", "--out", str(out), "--live", "127.0.0.1:0"],
                       capture_output=True, text=True, timeout=120, check=False)
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("live view: ws://127.0.0.1:") and "completed" in r.stdout
    published = int(r.stdout.split("live view: ")[2].split()[0])
    assert published > 30  # every message went to the (viewerless) server too


# ---- the subprotocols viewers offer -----------------------------------------------------------

WS_PACKAGES = ("@foxglove/ws-protocol@0.8.0", "ws@8.18.3")
WS_SCRIPT = Path(__file__).parents[1] / "interop" / "ws_client.mjs"
WS_FOLDER = mcap_readers.cache_dir().with_name("node-ws")  # the user's cache, chosen at import (as conftest)


def _publishing(live: LiveView, stop: threading.Event) -> list[bytes]:
    """Offer numbered /events messages every 10 ms until ``stop``; returns what was offered."""
    offered: list[bytes] = []

    def run():
        i = 0
        while not stop.is_set():
            data = encode_event(Event("phase", f"message {i}", device_time=i * 0.01))
            offered.append(data)
            live.offer("events", data, time.time_ns())
            i += 1
            time.sleep(0.01)

    threading.Thread(target=run, daemon=True).start()
    return offered


@pytest.mark.parametrize("subprotocol", SUBPROTOCOLS)
def test_a_websockets_client_connects_with_either_subprotocol(subprotocol):
    """Foxglove (the SDK's foxglove.sdk.v1) and Lichtblick / Foxglove Studio before the SDK
    (foxglove.websocket.v1) both get the session; a name the view does not speak is refused."""

    async def watch(url: str) -> tuple[str, list[bytes]]:
        async with websockets.connect(url, subprotocols=[subprotocol]) as ws:
            subs = await _subscribe(ws, ["/events"])
            got = []
            while len(got) < 5:
                data = await asyncio.wait_for(ws.recv(), 5)
                if isinstance(data, bytes) and data[0] == 1:
                    assert struct.unpack_from("<I", data, 1)[0] in subs
                    got.append(data[13:])
            return ws.subprotocol, got

    stop = threading.Event()
    with LiveView(port=0) as live:
        offered = _publishing(live, stop)
        try:
            agreed, got = asyncio.run(watch(live.url))
            with pytest.raises(websockets.InvalidStatus, match="400"):
                asyncio.run(websockets.connect(live.url, subprotocols=["foxglove.websocket.v2"]).__aenter__())
        finally:
            stop.set()
    assert agreed == subprotocol
    assert all(g in offered for g in got)
    assert [decode_event(g, 0, 0).message for g in got] == sorted({decode_event(g, 0, 0).message for g in got},
                                                                 key=lambda m: int(m.split()[1]))


@pytest.mark.parametrize("subprotocol", SUBPROTOCOLS)
def test_the_foxglove_ws_protocol_client_connects(subprotocol):
    """@foxglove/ws-protocol's FoxgloveClient (npm), the viewers' own client library, offering each
    subprotocol: it agrees on it, sees the session's topics and gets the messages as published."""
    try:
        folder = mcap_readers.install(WS_FOLDER, WS_PACKAGES, (WS_SCRIPT,))
    except mcap_readers.NodeMissing as exc:
        pytest.skip(str(exc))
    stop = threading.Event()
    with LiveView(port=0) as live:
        offered = _publishing(live, stop)
        try:
            r = subprocess.run(["node", "--single-threaded", str(folder / WS_SCRIPT.name), live.url, subprotocol, "/events", "5"],
                               cwd=folder, capture_output=True, text=True, timeout=60, check=False)
        finally:
            stop.set()
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert "error" not in out, out
    assert out["subprotocol"] == subprotocol and out["server"] == "wearbench"
    assert {"/acceleration", "/encoder", "/events"} <= set(out["topics"]) <= set(TOPICS.values())
    got = [base64.b64decode(m) for m in out["messages"]]
    assert len(got) == 5 and all(g in offered for g in got)
