"""Recording with a live view attached: 20 kHz acceleration + 1 kHz encoder, 2 minutes, in real time.

The recorder runs on the ``sim`` backend at real time (``speedup = 1``; ``--speedup`` runs the bench
clock faster) with ``--live`` on 127.0.0.1 and two viewers connected over the Foxglove WebSocket
protocol: one reads everything, one reads a message a second (a slow viewer). What recording
costs is the process CPU less the emulator's own work (metered in its calling thread, as in
``record_throughput.py``) and less the viewers' thread: the WebSocket server's threads are counted
in. Prints a table; exits 1 if the recording dropped a sample.

    python -m benchmarks.acquisition.live_view [--seconds 120] [--rate 20kHz] [--speedup 1]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import sys
import tempfile
import threading
import time
from pathlib import Path

import websockets
from wearbench.acquisition.backends import open_rig
from wearbench.acquisition.live import LiveView
from wearbench.acquisition.recorder import Recorder
from wearbench.acquisition.session import SessionPlan
from wearbench.acquisition.session_writer import SessionWriter
from wearbench.bench.load import parse_bench, shipped_bench
from wearbench.bench.units import parse_quantity

from benchmarks.acquisition.record_throughput import metered


async def _viewer(url: str, stop: threading.Event, counts: dict, name: str, pause: float) -> None:
    async with websockets.connect(url, subprotocols=["foxglove.sdk.v1"], max_queue=4, close_timeout=1) as ws:
        while True:
            msg = json.loads(await ws.recv())
            if msg["op"] == "advertise":
                break
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": [
            {"id": c["id"], "channelId": c["id"]} for c in msg["channels"]]}))
        while not stop.is_set():
            try:
                data = await asyncio.wait_for(ws.recv(), 0.5)
            except TimeoutError:
                continue
            counts[name] += isinstance(data, bytes)
            if pause:
                await asyncio.sleep(pause)


def _viewers(url: str, stop: threading.Event, counts: dict, cpu: list) -> None:
    async def both():
        await asyncio.gather(_viewer(url, stop, counts, "reading", 0.0), _viewer(url, stop, counts, "slow", 1.0))
    asyncio.run(both())
    cpu.append(time.thread_time())


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=120.0)
    ap.add_argument("--rate", default="20kHz", help="accelerometer sample rate")
    ap.add_argument("--speedup", type=float, default=1.0, help="bench clock speed (1: real time)")
    args = ap.parse_args()
    rate = parse_quantity(args.rate, "frequency")
    path = shipped_bench("ninebar-testbed")
    bench = parse_bench(path.read_text().replace('sample_rate = "10 kHz"', f'sample_rate = "{rate:g} Hz"'), path)
    rig = open_rig(bench, "sim", {"speedup": args.speedup, "config": {
        "signal": "harmonic", "cache": False, "accelerometer": {"noise": "0.05 m/s^2"}}})
    emulator: list[float] = []
    metered(rig.drive.device, ("read", "events", "motor_status", "set_speed", "enable", "disable", "stop",
                                "start_stream", "stop_stream", "configure_accelerometer"), emulator)
    counts, viewer_cpu, stop = {"reading": 0, "slow": 0}, [], threading.Event()
    with tempfile.TemporaryDirectory() as tmp, LiveView(port=0) as live:
        out = Path(tmp) / "live.mcap"
        viewers = threading.Thread(target=_viewers, args=(live.url, stop, counts, viewer_cpu), daemon=True)
        viewers.start()
        time.sleep(1.0)  # both connected and subscribed
        wall0, cpu0 = time.perf_counter(), time.process_time()
        try:
            result = Recorder(rig, bench, SessionPlan(speed=2 * math.pi, duration=args.seconds, settle=0.0),
                              out, writer=SessionWriter(out, live=live)).run()
        finally:
            rig.close()
        wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
        stop.set()
        viewers.join(timeout=10)
        size = out.stat().st_size
    recorder = cpu - sum(emulator) - sum(viewer_cpu)
    drops = sum(result.dropped_samples.values())
    rows = [
        ("recorded", f"{result.duration:.1f} s of bench time in {wall:.1f} s wall ({args.speedup:g}x clock)"),
        ("reason", result.reason),
        ("acceleration samples", f"{result.samples['acceleration']:,}"),
        ("dropped samples", f"{drops}"),
        ("file", f"{size / 1e6:.1f} MB"),
        ("live messages", f"{live.published:,} published, {live.dropped} not queued"),
        ("viewer 'reading' got", f"{counts['reading']:,} messages"),
        ("viewer 'slow' got", f"{counts['slow']:,} messages (1 a second; the server drops the rest for it)"),
        ("process CPU", f"{cpu:.2f} s (emulator {sum(emulator):.2f} s, viewers {sum(viewer_cpu):.2f} s subtracted)"),
        ("recorder CPU share", f"{100 * recorder / wall:.1f} % of one core (target < 25 %)"),
    ]
    width = max(len(k) for k, _ in rows)
    print(f"live_view: {rate / 1e3:g} kHz acceleration + 1 kHz encoder, {args.seconds:g} s, two viewers attached")
    for k, v in rows:
        print(f"  {k:<{width}}  {v}")
    return 0 if drops == 0 and result.completed else 1


if __name__ == "__main__":
    sys.exit(main())
