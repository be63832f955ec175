"""The live view: a session served over the Foxglove WebSocket protocol while it is recorded.

:class:`LiveView` starts a ``foxglove-sdk`` WebSocket server (its own context: no global state),
advertises one channel per session topic with the session's own schemas, and publishes the
messages the :class:`~wearbench.acquisition.session_writer.SessionWriter` offers it, bytes as they
went to the file. The recording never waits for a viewer: ``offer`` puts into a bounded queue and
counts what does not fit, a thread of its own hands messages to the server, and the server keeps a
bounded backlog per client and drops the oldest for a slow one.

Subprotocols: the SDK's server speaks ``foxglove.sdk.v1`` only, which Foxglove (the app, since the
SDK's protocol) connects with; Lichtblick, Foxglove Studio before the SDK and clients built on
``@foxglove/ws-protocol`` offer ``foxglove.websocket.v1``, the same protocol under its older name.
So the address the user is given is a :class:`SubprotocolBridge` (``websockets``) that accepts
either name and relays each viewer, frame for frame, to the SDK server on a loopback port of its
own. The relay reads from the server only as fast as the viewer takes, so a slow viewer still
meets the server's bounded backlog, never a queue of the relay's. Imports foxglove, websockets and
the layout.
"""

from __future__ import annotations

import asyncio
import contextlib
import queue
import threading
from typing import Self

import foxglove
from wearbench.acquisition.layout import ENCODING, SCHEMAS, TOPICS
from websockets.asyncio.client import connect
from websockets.asyncio.server import ServerConnection, serve
from websockets.exceptions import ConnectionClosed

__all__ = ["DEFAULT_ADDRESS", "SUBPROTOCOLS", "LiveView", "SubprotocolBridge", "parse_address"]

DEFAULT_ADDRESS = "127.0.0.1:8765"
SDK_SUBPROTOCOL = "foxglove.sdk.v1"
SUBPROTOCOLS = (SDK_SUBPROTOCOL, "foxglove.websocket.v1")  # the same protocol under both names


def parse_address(text: str) -> tuple[str, int]:
    """``HOST:PORT``, ``[IPv6]:PORT``, ``:PORT`` or ``PORT`` (host 127.0.0.1) as (host, port)."""
    host, sep, port = text.rpartition(":")
    if not sep:
        host, port = "", text
    host = host.strip("[]") or "127.0.0.1"
    try:
        number = int(port)
    except ValueError:
        number = -1
    if not 0 <= number <= 65535:
        raise ValueError(f"--live {text!r}: expected HOST:PORT with a port from 0 to 65535 (e.g. 127.0.0.1:8765)")
    return host, number


class SubprotocolBridge:
    """A WebSocket server on ``host:port`` accepting every name in :data:`SUBPROTOCOLS`, relaying
    each client to the SDK server at ``ws://127.0.0.1:upstream`` (which speaks only
    ``foxglove.sdk.v1``). Runs its own event loop thread; ``port`` 0 picks a free port."""

    def __init__(self, host: str, port: int, upstream: int):
        self._upstream = f"ws://127.0.0.1:{upstream}"
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, name="live-view-bridge", daemon=True)
        self._thread.start()
        try:
            self._server = asyncio.run_coroutine_threadsafe(self._start(host, port), self._loop).result(10)
        except BaseException:
            self._stop_loop()
            raise
        self.port = self._server.sockets[0].getsockname()[1]

    async def _start(self, host: str, port: int):
        return await serve(self._relay, host, port, subprotocols=list(SUBPROTOCOLS),
                           max_size=None, max_queue=16, compression=None)

    async def _relay(self, viewer: ServerConnection) -> None:
        try:
            async with connect(self._upstream, subprotocols=[SDK_SUBPROTOCOL], max_size=None, max_queue=16,
                               compression=None) as server:
                async def pump(source, sink) -> None:
                    with contextlib.suppress(ConnectionClosed):
                        async for message in source:
                            await sink.send(message)  # waits while the viewer's socket is full

                tasks = [asyncio.ensure_future(pump(viewer, server)), asyncio.ensure_future(pump(server, viewer))]
                await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
                for task in tasks:
                    task.cancel()
        except (OSError, ConnectionClosed):
            pass  # the SDK server is gone (the view is closing) or the viewer left

    def _stop_loop(self) -> None:
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(timeout=2.0)

    def close(self) -> None:
        async def shut() -> None:
            self._server.close()
            await self._server.wait_closed()

        with contextlib.suppress(Exception):
            asyncio.run_coroutine_threadsafe(shut(), self._loop).result(3)
        self._stop_loop()


class LiveView:
    """A Foxglove WebSocket server for one session; ``port`` 0 picks a free port (see ``.port``).
    Viewers connect with either subprotocol of :data:`SUBPROTOCOLS` (module docstring)."""

    def __init__(self, host: str = "127.0.0.1", port: int = 8765, *, name: str = "wearbench",
                 queue_size: int = 4096, backlog: int = 1024):
        self._context = foxglove.Context()
        try:
            self.server = foxglove.start_server(name=name, host="127.0.0.1", port=0, context=self._context,
                                                message_backlog_size=backlog)
        except Exception as exc:  # noqa: BLE001 - the SDK raises its own error type for a port in use
            raise OSError(f"live view: cannot start the Foxglove server: {exc}") from None
        try:
            self.bridge = SubprotocolBridge(host, port, self.server.port)
        except OSError as exc:
            self.server.stop()
            raise OSError(f"live view: cannot serve on {host}:{port}: {exc}") from None
        self.host, self.port = host, self.bridge.port
        self._channels = {
            key: foxglove.Channel(TOPICS[key], schema=foxglove.Schema(name=name_, encoding=ENCODING, data=data),
                                  message_encoding=ENCODING, context=self._context)
            for key, (name_, data) in SCHEMAS.items()}
        self._queue: queue.Queue = queue.Queue(maxsize=queue_size)
        self.offered = self.dropped = self.published = self.errors = 0
        self._thread = threading.Thread(target=self._run, name="live-view", daemon=True)
        self._thread.start()

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"ws://{host}:{self.port}"

    def offer(self, key: str, data: bytes, log_time: int) -> None:
        """Publish a message if there is room; never blocks, never raises."""
        self.offered += 1
        try:
            self._queue.put_nowait((key, data, log_time))
        except queue.Full:
            self.dropped += 1

    def _run(self) -> None:
        while True:
            item = self._queue.get()
            if item is None:
                return
            key, data, log_time = item
            try:
                self._channels[key].log(data, log_time=log_time)
                self.published += 1
            except Exception:  # noqa: BLE001 - a viewer problem never reaches the recording
                self.errors += 1

    def close(self) -> None:
        """Publish what is queued (1 s at most), then stop the server."""
        try:
            self._queue.put(None, timeout=1.0)
        except queue.Full:
            pass
        self._thread.join(timeout=1.0)
        for channel in self._channels.values():
            channel.close()
        self.bridge.close()
        self.server.stop()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
