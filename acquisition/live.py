"""The live view: a session served over the Foxglove WebSocket protocol while it is recorded.

:class:`LiveView` starts a ``foxglove-sdk`` WebSocket server (its own context: no global state),
advertises one channel per session topic with the session's own schemas, and publishes the
messages the :class:`~wearbench.acquisition.session_writer.SessionWriter` offers it, bytes as they
went to the file. The recording never waits for a viewer: ``offer`` puts into a bounded queue and
counts what does not fit, a thread of its own hands messages to the server, and the server keeps a
bounded backlog per client and drops the oldest for a slow one. Imports foxglove and the layout.
"""

from __future__ import annotations

import queue
import threading
from typing import Self

import foxglove
from wearbench.acquisition.layout import ENCODING, SCHEMAS, TOPICS

__all__ = ["DEFAULT_ADDRESS", "LiveView", "parse_address"]

DEFAULT_ADDRESS = "127.0.0.1:8765"


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


class LiveView:
    """A Foxglove WebSocket server for one session; ``port`` 0 picks a free port (see ``.port``)."""

    def __init__(self, host: str = "127.0.0.1", port: int = 8765, *, name: str = "wearbench",
                 queue_size: int = 4096, backlog: int = 1024):
        self._context = foxglove.Context()
        try:
            self.server = foxglove.start_server(name=name, host=host, port=port, context=self._context,
                                                message_backlog_size=backlog)
        except Exception as exc:  # noqa: BLE001 - the SDK raises its own error type for a port in use
            raise OSError(f"live view: cannot serve on {host}:{port}: {exc}") from None
        self.host, self.port = host, self.server.port
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
        self.server.stop()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
