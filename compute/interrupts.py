"""Ctrl-C and the processes a program starts: one handling for the local cluster
(:func:`~wearbench.compute.cluster.compute_client`), the emulated benches of the pytest plugin
(``wearbench.testing.emulated``) and the command line's exit (``wearbench.cli``).

A terminal's Ctrl-C is a SIGINT to every process of the foreground group. Only the program may act
on it: a cluster worker or an emulator that takes it dies mid-task, prints a traceback or looks like
a broken device ("device disconnected"). And the program must hear every one: ignoring SIGINT while
a start-up spawns processes (SIG_IGN, the disposition children inherit) loses the Ctrl-Cs typed
meanwhile, and a start-up that takes the KeyboardInterrupt half-way loses what it started.

- :func:`start_shielded` runs a start-up in a helper thread with SIGINT *blocked*: a thread's signal
  mask passes to the threads it starts and to the processes they spawn, across exec, so nothing
  started there ever sees the terminal's Ctrl-C. The calling thread waits and takes the
  KeyboardInterrupt within :data:`POLL` s; what the start-up made is closed once it exists.
- :func:`running_processes` and :func:`end_processes`: the processes this program started through
  multiprocessing that still run, and SIGKILL for them (what a shutdown does when its time is up, and
  the command line before its ``os._exit(130)``, which skips multiprocessing's own exit clean-up).
- :func:`end_children`: SIGKILL for every child process that still runs, listed by the kernel
  (Linux), multiprocessing's resource tracker excepted: also a child whose start another thread had
  not finished (spawned, its start-up data not yet sent: multiprocessing does not list it yet, and
  left alone it reads the end of the pipe and prints an ``EOFError`` traceback to the terminal).
- :func:`track_resources` and :func:`release_resources`: what this process has told multiprocessing's
  resource tracker it holds (the named semaphores of a local cluster's queues), so that an
  ``os._exit`` while another thread closes a queue (its semaphore unlinked, the tracker not yet told)
  leaves the tracker nothing to warn about ("leaked semaphore objects").

Imports the standard library only.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Collection
from typing import Any, TypeVar

__all__ = ["POLL", "end_children", "end_processes", "release_resources", "running_processes", "start_shielded",
           "track_resources"]

T = TypeVar("T")

POLL = 0.1  # s: a waiting thread looks this often for a Ctrl-C that the kernel gave another thread
_NOTHING = object()


def start_shielded(start: Callable[[], T], *, close: Callable[[T], Any], name: str, grace: float = 3.0,
                   abort: Callable[[], Any] | None = None) -> T:
    """``start()`` run so that this program hears a Ctrl-C at once and what ``start`` spawns never does.

    ``start`` runs in a helper thread with SIGINT blocked; this thread waits. A KeyboardInterrupt (or
    any exception) while it waits is raised again after at most ``grace`` s: meanwhile ``abort()``
    (if given) is called every :data:`POLL` s until the start-up has ended (it ends what the start-up
    has begun, so that it gives up), and whatever the start-up returns is closed with
    ``close(result)``, here or in the helper thread, whichever has it. An exception of ``start``
    itself is raised here.
    """
    from multiprocessing import resource_tracker

    # launched from here: launching it from the helper thread would unblock SIGINT there (the
    # tracker's start-up blocks and then unblocks it in the calling thread)
    resource_tracker.ensure_running()
    track_resources()
    lock = threading.Lock()
    done = threading.Event()
    box: dict[str, Any] = {}

    def run() -> None:
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            value = start()
        except BaseException as exc:  # noqa: BLE001 - handed to the waiting thread
            box["error"] = exc
            done.set()
            return
        with lock:
            box["value"] = value
            abandoned = box.get("abandoned", False)
        try:
            if abandoned:  # the caller was interrupted meanwhile: nobody else will close it
                close(value)
        finally:
            done.set()

    helper = threading.Thread(target=run, name=f"wearbench {name}", daemon=True)
    try:
        helper.start()  # inside: a Ctrl-C while it starts may come when start() runs already
        while not done.wait(POLL):
            pass
    except BaseException:
        if helper.ident is None:  # never started: nothing to close
            raise
        with lock:
            box["abandoned"] = True
            value = box.get("value", _NOTHING)
        if value is not _NOTHING:
            close(value)
        else:
            deadline = time.monotonic() + grace
            while not done.is_set() and time.monotonic() < deadline:
                if abort is not None:
                    abort()
                done.wait(min(POLL, max(0.0, deadline - time.monotonic())))
        raise
    if "error" in box:
        raise box["error"]
    return box["value"]


def running_processes(name: str = "") -> dict[int, Any]:
    """The processes this program started through multiprocessing that still run, by pid (those
    whose name starts with ``name``)."""
    active = getattr(sys.modules.get("multiprocessing"), "active_children", None)
    if active is None:  # not imported (nothing was started through it), or being imported now
        return {}
    return {p.pid: p for p in active() if p.name.startswith(name) and p.pid is not None}


def end_processes(keep: Collection[int] = (), *, name: str = "", wait: float = 0.0) -> list[int]:
    """SIGKILL the processes :func:`running_processes` lists (``name``), except the pids in ``keep``;
    wait up to ``wait`` s for them to be gone. Returns their pids."""
    ended = {pid: p for pid, p in running_processes(name).items() if pid not in keep}
    for p in ended.values():
        try:
            p.kill()
        except (OSError, ValueError):  # gone already, or closed
            pass
    if wait > 0 and ended:
        from multiprocessing.connection import wait as wait_for

        sentinels = []
        for p in ended.values():
            try:
                sentinels.append(p.sentinel)
            except ValueError:  # closed
                pass
        deadline = time.monotonic() + wait
        while sentinels and time.monotonic() < deadline:
            ready = wait_for(sentinels, max(0.0, deadline - time.monotonic()))
            sentinels = [s for s in sentinels if s not in ready]
    return list(ended)


def _children() -> set[int]:
    """The pids of this process's children that the kernel lists (``/proc``; none where it has none)."""
    me, found = os.getpid(), set()
    try:
        entries = os.listdir("/proc")
    except OSError:
        return found
    for entry in entries:
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat", "rb") as fh:
                stat = fh.read()
        except OSError:  # ended meanwhile, or not ours to read
            continue
        fields = stat[stat.rfind(b")") + 2:].split()  # after "pid (name) ": state, ppid, ...
        if len(fields) > 2 and int(fields[1]) == me and fields[0] != b"Z":
            found.add(int(entry))
    return found


def end_children() -> list[int]:
    """SIGKILL every child process of this one that the kernel lists, except multiprocessing's resource
    tracker (it unlinks what the program leaves once the program is gone); looks again until no new
    one has appeared (another thread may be starting one). Returns the pids signalled."""
    tracker = getattr(getattr(sys.modules.get("multiprocessing.resource_tracker"), "_resource_tracker", None),
                      "_pid", None)
    ended: set[int] = set()
    while new := _children() - ended - {tracker}:
        for pid in new:
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:  # gone already
                pass
        ended |= new
    return sorted(ended)


_SENDS = threading.Lock()  # held around each message to the resource tracker, and for good by release_resources
_HELD: set[tuple[str, str]] = set()  # (name, type) registered with the tracker and not unregistered


def track_resources() -> None:
    """From now on, record what this process registers with multiprocessing's resource tracker (each
    message sent under one lock, so :func:`release_resources` sees an exact set). Idempotent."""
    from multiprocessing import resource_tracker

    tracker = resource_tracker._resource_tracker
    send = tracker._send
    if getattr(send, "wearbench_tracked", False):
        return

    def tracked(cmd: str, name: str, rtype: str) -> None:
        with _SENDS:
            send(cmd, name, rtype)
            if cmd == "REGISTER":
                _HELD.add((name, rtype))
            elif cmd == "UNREGISTER":
                _HELD.discard((name, rtype))

    tracked.wearbench_tracked = True  # type: ignore[attr-defined]
    tracker._send = tracked


def release_resources(timeout: float = 1.0) -> None:
    """Before ``os._exit``: stop every further message to the resource tracker (the lock is kept), then
    unlink the semaphores this process still holds and tell the tracker so. A thread caught between
    unlinking a semaphore and saying so never gets to say it twice."""
    if not _SENDS.acquire(timeout=timeout):  # a message stuck for a second: leave it to the tracker
        return
    from multiprocessing import resource_tracker

    tracker = resource_tracker._resource_tracker
    for name, rtype in sorted(_HELD):
        try:
            if rtype == "semaphore":
                import _multiprocessing

                _multiprocessing.sem_unlink(name)
        except OSError:
            pass  # unlinked already (by the thread that was closing it)
        try:
            os.write(tracker._fd, f"UNREGISTER:{name}:{rtype}\n".encode("ascii"))
        except (OSError, TypeError):
            return  # no tracker to tell
    _HELD.clear()
