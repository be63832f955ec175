"""Writing one session to MCAP so that whatever happens, what was recorded stays readable.

- Chunks of at most ``CHUNK_SIZE`` bytes, ``COMPRESSION`` compressed, each followed by its message
  indexes (every MCAP reader, including the indexed one viewers use, opens the file), and closed
  at least every ``flush_interval`` seconds and handed to the OS, so a process killed outright loses
  at most that much (``wearbench recover`` restores the rest). Chunk and data-section CRCs are on.
- Metadata and the bench file go in first, so even a killed session says what it was.
- Disk space: a session refuses to start with less than ``MIN_FREE_BYTES`` free, and keeps room for
  its own end reserved *inside the session file*, beyond its end (``fallocate`` with
  ``FALLOC_FL_KEEP_SIZE``: the blocks are the file's, so another program filling the disk cannot
  take them): an eighth of the free space at the start (64 KiB to 4 MiB) plus ``SUMMARY_PER_WRITE``
  bytes per write for the summary's chunk index. The room is renewed after every write; when it
  cannot be (the disk is full), the write reports ``ENOSPC`` and the session stops, and what waits
  (the chunk in progress, capped at half the room; the recorder's queue, capped at a quarter, see
  ``Recorder``; the result record, summary and footer) is written into the room. Where the
  filesystem cannot reserve that way, a ballast file of the same size is set aside beside the
  session and deleted when a write fails.
- Writes go through :class:`DurableFile`, which never leaves half a record behind: a failed
  write (a full disk) is cut back to the last whole record and kept in memory until it can be
  written, so the file can still be finished once space is back.
- A session never silently replaces a file (the output-file policy, ``bench.output_file``): a path
  that exists is refused (``FileExistsError``) unless ``replace=True``, and then the new session is
  written beside it (``NAME.new``) and renamed over the old file only when finished with
  ``finish(replace=True)`` (the recorder: when the session completed its target), so the old file
  stays whole until then. One writer per path: an exclusive ``flock`` on ``.NAME.lock`` beside it
  (released by the OS if the process dies).
- A live view (``live``, see ``acquisition.live``) is offered every message after it went to the
  file; it never blocks and never fails the writer.

Imports mcap and the layout; no backend library.
"""

from __future__ import annotations

import ctypes
import errno
import fcntl
import io
import os
import shutil
import time
from pathlib import Path
from typing import BinaryIO, Protocol

from mcap.writer import CompressionType, IndexType, Writer
from wearbench.acquisition.drivers import Block, BusFrame, Event, MotorState
from wearbench.acquisition.layout import (
    ENCODING,
    METADATA,
    SCHEMAS,
    TOPICS,
    Command,
    CrankAngle,
    encode_block,
    encode_command,
    encode_event,
    encode_frame,
    encode_state,
    ns,
    publish_time,
)
from wearbench.bench.output_file import check_output

__all__ = ["CHUNK_SIZE", "COMPRESSION", "MIN_FREE_BYTES", "PROFILE", "SUMMARY_PER_WRITE", "DurableFile",
           "NotEnoughSpace", "SessionWriter", "ballast_bytes", "check_free_space", "leftover_message", "lock_session_path",
           "unlock_session_path"]

PROFILE = "wearbench-session"
# Chosen by measurement (benchmarks/acquisition/session_format.py, 20 kHz): zstd 148 MB per hour against lz4's
# 248 and none's 377, at the same write CPU (0.4 % of a core); 256 KiB and 1 MiB chunks compress
# alike. The flush interval closes a chunk every 0.5 s (about 48 kB before compression at 20 kHz),
# so CHUNK_SIZE caps a burst (a writer catching up), and with it what a full disk leaves in memory.
CHUNK_SIZE = 256 << 10
COMPRESSION = CompressionType.ZSTD
MIN_FREE_BYTES = 1 << 20
SUMMARY_PER_WRITE = 256  # bytes of summary kept reserved per write (a chunk index is about 170 B)
_FALLOC_FL_KEEP_SIZE = 1


def _keep_size_fallocate():
    """``fallocate(fd, FALLOC_FL_KEEP_SIZE, offset, length)`` from the C library (Linux), or None."""
    try:
        fallocate = ctypes.CDLL(None, use_errno=True).fallocate
    except (OSError, AttributeError):
        return None
    fallocate.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_int64, ctypes.c_int64]
    fallocate.restype = ctypes.c_int

    def reserve(fd: int, offset: int, length: int) -> None:
        if fallocate(fd, _FALLOC_FL_KEEP_SIZE, offset, length) != 0:
            code = ctypes.get_errno()
            raise OSError(code, os.strerror(code))

    return reserve


_reserve_blocks = _keep_size_fallocate()


def ballast_bytes(free: int) -> int:
    """The ballast set aside with ``free`` bytes free: an eighth of it, 64 KiB to 4 MiB."""
    return int(min(4 << 20, max(64 << 10, free // 8)))


class NotEnoughSpace(OSError):
    """Less than ``MIN_FREE_BYTES`` free where the session would be written."""


def check_free_space(path: str | Path) -> int:
    """Bytes free where ``path`` would be written; raises :class:`NotEnoughSpace` below the minimum."""
    folder = Path(path).resolve().parent
    free = shutil.disk_usage(folder).free
    if free < MIN_FREE_BYTES:
        raise NotEnoughSpace(errno.ENOSPC, f"{free / 2**20:.2f} MiB free; a session needs at least "
                             f"{MIN_FREE_BYTES / 2**20:g} MiB to start (about 150 MB per hour at 20 kHz)",
                             str(folder))
    return free


def lock_session_path(path: str | Path) -> int:
    """Take the exclusive lock on writing ``path`` (``flock`` on ``.NAME.lock`` beside it); returns
    the lock's file descriptor (close it to release). Raises ``OSError(EBUSY)`` naming the file when
    another process holds it."""
    path = Path(path)
    lock = _lock_path(path)
    while True:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise OSError(errno.EBUSY, "another recorder is writing this session file", str(path)) from None
        try:  # the holder before us may have removed the lock file: then lock the new one
            if os.stat(lock).st_ino == os.fstat(fd).st_ino:
                return fd
        except FileNotFoundError:
            pass
        os.close(fd)


def leftover_message(new: Path) -> str:
    """Why a forced session does not start over ``NAME.new`` left by an earlier one that did not finish."""
    return (f"{new} is left over from an earlier forced session that did not finish: it is not a session "
            f"of this run, but may hold a recording (check it with 'wearbench inspect {new}', rescue it with "
            "'wearbench recover'), so it is not replaced; move or delete it, then record again")


def _lock_path(path: Path) -> Path:
    return path.with_name(f".{path.name}.lock")


def unlock_session_path(path: str | Path, fd: int) -> None:
    """Release the lock :func:`lock_session_path` took (and remove its file)."""
    try:
        os.unlink(_lock_path(Path(path)))
    except OSError:
        pass
    os.close(fd)


class LiveSink(Protocol):
    def offer(self, key: str, data: bytes, log_time: int) -> None: ...


class DurableFile:
    """An unbuffered binary file that never holds a torn record and never forgets a failed write.

    A write that fails (ENOSPC, EIO) is cut back to the end of the last complete write and kept in
    memory (the backlog); every later write first retries the backlog, so the file stays in order
    and complete up to a record boundary. The failure is not raised into the mcap writer (whose
    state would then be half-updated) but kept in ``error`` for :class:`SessionWriter` to report.
    ``tell()`` counts the backlog, so the mcap indexes stay right once it is written.
    Deliberately not an ``io.RawIOBase`` (mcap would wrap that in a BufferedWriter and split writes).
    """

    def __init__(self, raw: BinaryIO):
        self._raw = raw
        self._good = raw.tell()
        self._backlog = bytearray()
        self.error: OSError | None = None
        self.closed = False
        self._room = 0  # bytes kept reserved beyond the end (see keep_room)
        self._writes = 0
        self._room_lost = False

    def keep_room(self, size: int) -> bool:
        """Keep ``size`` bytes (plus ``SUMMARY_PER_WRITE`` per write so far) reserved in the file beyond
        its end, renewed after every write; False (nothing reserved) where the filesystem cannot."""
        if _reserve_blocks is None:
            return False
        try:
            _reserve_blocks(self.fileno(), self._good, size)
        except (OSError, ValueError, io.UnsupportedOperation):
            return False
        self._room = size
        return True

    @property
    def room(self) -> int:
        """Bytes kept reserved beyond the end (0: none)."""
        return self._room + SUMMARY_PER_WRITE * self._writes if self._room else 0

    def _renew_room(self) -> None:
        """Reserve the room again from the new end; a full disk is reported once (``error``)."""
        try:
            _reserve_blocks(self.fileno(), self._good, self.room)
        except OSError as exc:
            if not self._room_lost:
                self._room_lost = True
                self.error = OSError(exc.errno, f"{exc.strerror}: the room reserved for the end of the "
                                     "session file cannot be renewed; the session stops and ends in that room")

    def _write_all(self, data) -> None:
        view = memoryview(data).cast("B")
        done = 0
        try:
            while done < len(view):
                n = self._raw.write(view[done:])
                if n is None or n <= 0:
                    raise OSError(errno.EIO, "write made no progress")
                done += n
        except OSError:
            try:
                self._raw.seek(self._good)
                if not self._room:  # cutting the file would give the reserved room away
                    self._raw.truncate(self._good)
            except OSError:
                pass
            raise
        self._good += done
        self._writes += 1
        if self._room:
            self._renew_room()

    def write(self, data) -> int:
        with memoryview(data) as view:
            n = view.nbytes
        self._backlog += data
        self.retry()
        return n

    def retry(self) -> bool:
        """Write the backlog; True when nothing is left in memory."""
        if self._backlog:
            try:
                self._write_all(bytes(self._backlog))
                self._backlog.clear()
            except OSError as exc:
                self.error = exc
        return not self._backlog

    @property
    def backlog(self) -> int:
        return len(self._backlog)

    def tell(self) -> int:
        return self._good + len(self._backlog)

    def flush(self) -> None:
        self._raw.flush()

    def fileno(self) -> int:
        return self._raw.fileno()

    def close(self) -> None:
        if not self.closed:
            self.closed = True
            if self._room:  # give the room (and any torn tail) back
                try:
                    self._raw.truncate(self._good)
                except OSError:
                    pass
            self._raw.close()


class SessionWriter:
    """One MCAP session file: ``start``, then ``write_*``, then ``finish``.

    ``out`` is a path or an unbuffered binary file object (tests pass one that fails on purpose).
    A path with less than ``MIN_FREE_BYTES`` free raises :class:`NotEnoughSpace` before anything is
    written; a path that exists raises ``FileExistsError`` unless ``replace`` (then the session is
    written to ``NAME.new`` and ``finish`` renames it over the old file); a path another writer
    holds raises ``OSError(EBUSY)``. ``path`` is where the session file is (after ``finish``: the
    final name, or ``NAME.new`` when ``finish(replace=False)`` kept the old file). ``crank`` (set after ``start``) derives the encoder messages' crank angle and cycle.
    """

    def __init__(self, out: str | Path | BinaryIO, *, chunk_size: int | None = None,
                 compression: CompressionType = COMPRESSION, flush_interval: float = 0.5,
                 ballast: bool = True, live: LiveSink | None = None, replace: bool = False):
        self._ballast = None
        self.reserve = 0  # bytes of ballast set aside
        self._lock: int | None = None
        self._target: Path | None = None  # the name to rename to at finish (replace=True)
        if isinstance(out, (str, Path)):
            self.path: Path | None = Path(out)
            free = check_free_space(self.path)
            self._lock = lock_session_path(self.path)
            new = self.path.with_name(self.path.name + ".new")
            if replace and self.path.exists() and new.exists():  # we hold the lock: its writer died
                self._unlock()
                raise FileExistsError(leftover_message(new))
            try:
                if replace and self.path.exists():
                    self._target, self.path = self.path, new
                    raw = open(self.path, "xb", buffering=0)  # noqa: SIM115 - closed by finish()
                else:
                    raw = open(self.path, "xb", buffering=0)  # noqa: SIM115 - closed by finish()
            except FileExistsError:
                self._unlock()
                check_output(self.path, option="session file", session=True)  # raises the policy's one line
                raise
            except BaseException:
                self._unlock()
                raise
        else:
            self.path, raw = None, out
        self._file = DurableFile(raw)
        if ballast and self.path is not None:
            if self._file.keep_room(ballast_bytes(free)):
                self.reserve = ballast_bytes(free)
            else:
                self._ballast = self.path.with_name(self.path.name + ".ballast")
                self.reserve = self._set_aside(self._ballast, ballast_bytes(free))
        if chunk_size is None:  # a chunk that fails to write must fit in the ballast
            chunk_size = min(CHUNK_SIZE, self.reserve // 2) if self.reserve else CHUNK_SIZE
        self._writer = Writer(self._file, chunk_size=chunk_size, compression=compression,
                              index_types=IndexType.ALL, enable_crcs=True, enable_data_crcs=True)
        self._channels: dict[str, int] = {}
        self._log_time = 0  # ns: the latest log time written (log times never go back in file order)
        self._flush_interval = flush_interval
        self._last_flush = time.monotonic()
        self.live = live
        self.crank: CrankAngle | None = None
        self.finished = False
        self._mcap_finished = False

    @staticmethod
    def _set_aside(path: Path, size: int) -> int:
        """Reserve ``size`` bytes in ``path`` (as much as fits); returns the bytes reserved."""
        try:
            with open(path, "wb") as fh:
                try:
                    os.posix_fallocate(fh.fileno(), 0, size)
                except (OSError, AttributeError):  # no fallocate here: write the bytes
                    zeros = bytes(64 << 10)
                    fh.writelines(zeros for _ in range(0, size, len(zeros)))
        except OSError:
            pass  # what was reserved stays reserved; the session still records
        try:
            return path.stat().st_blocks * 512
        except OSError:
            return 0

    def start(self, metadata: dict[str, dict[str, str]], attachments: dict[str, tuple[str, bytes]]) -> None:
        """Header, schemas, channels, metadata records and attachments ``{name: (media_type, data)}``."""
        self._writer.start(profile=PROFILE, library="wearbench")
        for key in SCHEMAS:
            if key != "frames":  # raw bus frames: registered with the first one (bus backends only)
                self._register(key)
        now = time.time_ns()
        for name, (media_type, data) in attachments.items():
            self._writer.add_attachment(create_time=now, log_time=now, name=name,
                                        media_type=media_type, data=data)
        for name, record in metadata.items():
            self.add_metadata(name, record)
        self.flush()

    def _register(self, key: str) -> int:
        name, schema = SCHEMAS[key]
        sid = self._writer.register_schema(name=name, encoding=ENCODING, data=schema)
        self._channels[key] = self._writer.register_channel(TOPICS[key], ENCODING, sid)
        return self._channels[key]

    def add_metadata(self, name: str, record: dict[str, str]) -> None:
        if name not in METADATA:
            raise ValueError(f"metadata record {name!r}: expected one of the session layout's {sorted(METADATA)}")
        self._writer.add_metadata(name, {str(k): str(v) for k, v in record.items()})
        self._raise()

    def _raise(self) -> None:
        """Report a write that failed (its bytes wait in the file's backlog)."""
        error, self._file.error = self._file.error, None
        if error is not None:
            raise error

    def _add(self, key: str, data: bytes, host_time: float, device_time: float | None,
             sequence: int = 0) -> None:
        log_time = self._log_time = max(ns(host_time), self._log_time)  # log-time order (layout)
        channel = self._channels.get(key) or self._register(key)
        self._writer.add_message(channel, log_time=log_time, data=data,
                                 publish_time=publish_time(device_time, log_time),
                                 sequence=sequence & 0xFFFFFFFF)
        if self.live is not None:
            self.live.offer(key, data, log_time)
        if time.monotonic() - self._last_flush > self._flush_interval:
            self.flush()
        self._raise()

    def write_block(self, block: Block) -> None:
        self._add(block.stream, encode_block(block, self.crank), block.host_time, block.device_time,
                  block.sequence)

    def write_state(self, state: MotorState) -> None:
        self._add("state", encode_state(state), state.host_time, state.device_time)

    def write_command(self, command: Command) -> None:
        self._add("command", encode_command(command), command.host_time, None)

    def write_event(self, event: Event) -> None:
        self._add("events", encode_event(event), event.host_time, event.device_time)

    def write_frame(self, frame: BusFrame) -> None:
        self._add("frames", encode_frame(frame), frame.host_time or frame.time, None)

    def flush(self) -> None:
        """Close the chunk in progress and hand everything to the OS."""
        self._writer.flush()
        self._last_flush = time.monotonic()
        self._raise()

    @property
    def room(self) -> int:
        """Bytes reserved inside the session file for its end (0: none, or a ballast file instead)."""
        return self._file.room

    def release_ballast(self) -> bool:
        """Delete the ballast file (after a full disk); True if there was one."""
        if self._ballast is not None and self._ballast.exists():
            self._ballast.unlink()
            return True
        return False

    def _unlock(self) -> None:
        if self._lock is not None:
            unlock_session_path(self._target or self.path, self._lock)
            self._lock = None

    def finish(self, replace: bool = True) -> None:
        """Write the summary and footer and close. Raises OSError while the file's backlog cannot
        be written (a full disk); call again once there is room: nothing is lost in between.
        A session written beside an existing file (``replace=True`` at creation) is renamed over it
        if ``replace``; otherwise it stays at ``NAME.new`` and the old file is untouched."""
        if self.finished:
            return
        if not self._mcap_finished:
            self._writer.finish()
            self._mcap_finished = True
        if not self._file.retry():
            self._raise()
        self._file.flush()
        try:
            os.fsync(self._file.fileno())
        except (OSError, io.UnsupportedOperation, AttributeError):
            pass
        self.finished = True
        self._file.close()
        self.release_ballast()
        if self._target is not None and replace:
            os.replace(self.path, self._target)
            self.path = self._target
        self._unlock()
