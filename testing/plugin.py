"""The pytest plugin (entry point ``pytest11``: active wherever wearbench is installed).

Fixtures: ``wearbench_bench`` (the bench under test), ``serial_bench``, ``can_bench`` and
``canopen_bench`` (factories starting an emulated bench, or pointing at the real one), and
``record_session`` (records from a bench into a temporary MCAP file and reads it back).
Options: ``--wearbench-bench``, ``--wearbench-speedup``, ``--wearbench-port``, ``--wearbench-can``.
Marker: ``realtime(duration)``. Every bench a test started is closed at its teardown, whether it
passed, failed or was interrupted, and again at the end of the run and at exit. A Ctrl-C while a
test with a bench runs stops the run as interrupted (exit code 2), also when the code under test took
it (the recorder stops its session on it and returns); the emulators never take it themselves.
"""

from __future__ import annotations

import contextlib
import math
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:  # the plugin loads with every pytest run: wearbench itself only when a fixture is used
    from wearbench.bench.schema import Bench
    from wearbench.testing.emulated import EmulatedBench
    from wearbench.testing.faults import FaultPlan
    from wearbench.testing.recording import RecordedSession

DEFAULT_BENCH = "ninebar-testbed"


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("wearbench", "wearbench hardware-in-the-loop tests")
    group.addoption("--wearbench-bench", metavar="BENCH.toml", default=None,
                    help=f"bench file of the bench under test (default: the shipped {DEFAULT_BENCH})")
    group.addoption("--wearbench-speedup", metavar="N", type=float, default=1.0,
                    help="run emulated benches N times faster than real time (default 1; ignored on real hardware)")
    group.addoption("--wearbench-port", metavar="PORT", default=None,
                    help="run serial_bench tests against the real bench on this serial port (e.g. /dev/ttyACM0)")
    group.addoption("--wearbench-can", metavar="INTERFACE:CHANNEL", default=None,
                    help="run can_bench/canopen_bench tests against the real bench on this bus (e.g. socketcan:can0)")


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "realtime(duration): the test runs its bench for `duration` s of device "
                            "time in real time (faster with --wearbench-speedup)")
    speedup = config.getoption("--wearbench-speedup", 1.0)
    if not (math.isfinite(speedup) and speedup > 0):
        raise pytest.UsageError(f"--wearbench-speedup {speedup}: expected a finite number > 0")
    config.stash[_REALTIME] = []


def pytest_report_header(config: pytest.Config) -> list[str]:
    port, bus = config.getoption("--wearbench-port"), config.getoption("--wearbench-can")
    target = ", ".join(filter(None, [port and f"serial {port}", bus and f"CAN {bus}"])) or "emulated benches"
    return [f"wearbench: {target}, emulator speed-up {config.getoption('--wearbench-speedup'):g}x"]


_REALTIME = pytest.StashKey[list]()


@pytest.hookimpl(wrapper=True)
def pytest_runtest_setup(item: pytest.Item) -> Iterator[None]:
    return (yield from _heard(item, "setup"))


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item: pytest.Item) -> Iterator[None]:
    marker = item.get_closest_marker("realtime")
    start = time.monotonic()
    try:
        return (yield from _heard(item, "call"))
    finally:
        if marker is not None:
            duration = marker.kwargs.get("duration", marker.args[0] if marker.args else None)
            item.config.stash[_REALTIME].append((item.nodeid, duration, time.monotonic() - start))


@pytest.hookimpl(wrapper=True)
def pytest_runtest_teardown(item: pytest.Item) -> Iterator[None]:
    return (yield from _heard(item, "teardown"))


BENCH_FIXTURES = frozenset({"serial_bench", "can_bench", "canopen_bench", "record_session"})


def _heard(item: pytest.Item, when: str) -> Iterator[None]:
    """Run one phase of a test that uses a bench; a Ctrl-C that reached pytest meanwhile stops the run
    as interrupted (KeyboardInterrupt: pytest's exit code 2), whatever the test made of it. The
    wearbench recorder turns SIGINT into a clean stop of its session and returns (so that the file is
    finished): a lab's recording script under test went on as if nothing had happened, and the run
    ended with exit code 0 or a false failure ("not completed"). Tests without a bench: untouched."""
    watch = _CtrlCWatch() if BENCH_FIXTURES.intersection(getattr(item, "fixturenames", ())) else None
    try:
        result = yield
    except KeyboardInterrupt:
        if watch is not None:
            watch.stop()
        raise
    except BaseException:
        if watch is not None and watch.stop():
            raise KeyboardInterrupt(_taken(item, when)) from None
        raise
    if watch is not None and watch.stop():
        raise KeyboardInterrupt(_taken(item, when))
    return result


def _taken(item: pytest.Item, when: str) -> str:
    return (f"Ctrl-C during {item.nodeid} ({when}); the code under test took it (the recorder stops its "
            "session on it) and went on: the run stops here")


class _CtrlCWatch:
    """Whether SIGINT reached this process from now until :meth:`stop`, whoever's handler took it:
    CPython writes the number of every signal that a Python-level handler receives to the "wakeup
    fd", pointed here at a pipe of this watch's own. In the main thread only, and only while no one
    else (an event loop of the test's) uses the wakeup fd; otherwise it watches nothing."""

    def __init__(self) -> None:
        self.fds: tuple[int, int] | None = None
        if threading.current_thread() is not threading.main_thread():
            return
        read, write = os.pipe()
        os.set_blocking(read, False)
        os.set_blocking(write, False)
        try:
            previous = signal.set_wakeup_fd(write, warn_on_full_buffer=False)
        except (ValueError, OSError):
            previous = None
        if previous != -1:  # not set (not the main interpreter), or in use by someone else
            if previous is not None:
                signal.set_wakeup_fd(previous)
            os.close(read)
            os.close(write)
            return
        self.fds = (read, write)

    def stop(self) -> bool:
        """Stop watching; True if a SIGINT came."""
        if self.fds is None:
            return False
        read, write = self.fds
        self.fds = None
        current = signal.set_wakeup_fd(-1)
        if current != write:  # the test pointed it elsewhere and left it so: leave that as it was
            signal.set_wakeup_fd(current)
        came = b""
        with contextlib.suppress(BlockingIOError):
            while chunk := os.read(read, 512):
                came += chunk
        os.close(read)
        os.close(write)
        return signal.SIGINT in came


def pytest_terminal_summary(terminalreporter, config: pytest.Config) -> None:
    runs = config.stash.get(_REALTIME, [])
    if runs:
        device = sum(d for _, d, _ in runs if d)
        wall = sum(w for *_, w in runs)
        terminalreporter.write_line(f"wearbench: {len(runs)} realtime tests, {device:g} s of bench time in "
                                    f"{wall:.1f} s (speed-up {config.getoption('--wearbench-speedup'):g}x)")


def _close_all() -> None:
    emulated = sys.modules.get("wearbench.testing.emulated")
    if emulated is not None:  # benches were started in this run
        emulated.close_all()


def pytest_sessionfinish(session: pytest.Session) -> None:
    _close_all()


def pytest_keyboard_interrupt(excinfo) -> None:
    _close_all()


@pytest.fixture(scope="session")
def wearbench_bench(pytestconfig: pytest.Config) -> Bench:
    """The bench under test: ``--wearbench-bench BENCH.toml``, else the shipped ninebar test bed.
    Override this fixture in a conftest.py to test another bench."""
    from wearbench.bench.load import load_bench, shipped_bench

    path = pytestconfig.getoption("--wearbench-bench")
    return load_bench(path if path else shipped_bench(DEFAULT_BENCH))


@pytest.fixture
def wearbench_speedup(request: pytest.FixtureRequest) -> float:
    """The emulated benches' speed-up (``--wearbench-speedup``, default 1; real hardware always runs
    in real time)."""
    return float(request.config.getoption("--wearbench-speedup"))


def _factory(bench: Bench, transport: str, hardware: str | None, speedup: float
             ) -> Iterator[Callable[..., EmulatedBench]]:
    from wearbench.testing.emulated import start_bench

    started: list[EmulatedBench] = []

    def start(*, state=None, seed: int | None = None, speed: float | None = None, faults: FaultPlan | None = None,
              signal: str | None = None, table=None, bench: Bench = bench) -> EmulatedBench:
        if hardware is not None and faults is not None and not faults.clean:
            pytest.skip(f"fault injection needs the emulator; this run points at real hardware ({hardware})")
        handle = start_bench(bench, transport, state=state, seed=seed, speed=speed, faults=faults, signal=signal,
                             table=table, speedup=speedup, hardware=hardware)
        started.append(handle)
        return handle

    try:
        yield start
    finally:
        for handle in started:
            handle.close()


@pytest.fixture
def serial_bench(request, wearbench_bench, wearbench_speedup) -> Iterator[Callable[..., EmulatedBench]]:
    """Factory: ``serial_bench(state=, seed=, speed=, faults=, signal=, table=, bench=)`` starts the
    bench emulator on a pseudo-terminal speaking the serial protocol (its own process) and returns an
    :class:`~wearbench.testing.EmulatedBench` (``.port`` is the pty path, ``.open_rig()`` a rig on it,
    ``.sent()`` every block it sent). ``state``: a ``[[state]]`` name or WearState; ``seed``: a
    non-twin truth drawn from the bench's tolerances; ``faults``: a
    :class:`~wearbench.testing.FaultPlan`; ``signal="harmonic"`` skips the model run. With
    ``--wearbench-port`` it is the real bench on that port (tests with faults skip). Closed
    (process ended, pty gone) at teardown, also when the test fails or is interrupted."""
    yield from _factory(wearbench_bench, "serial", request.config.getoption("--wearbench-port"),
                        wearbench_speedup)


@pytest.fixture
def can_bench(request, wearbench_bench, wearbench_speedup) -> Iterator[Callable[..., EmulatedBench]]:
    """Factory like ``serial_bench`` for the bench speaking its raw CAN (FD) frames
    (``hardware/protocol/wearbench.dbc``) on a python-can ``virtual`` bus (``.channel``; in-process).
    With ``--wearbench-can INTERFACE:CHANNEL`` it is the real bench on that bus."""
    yield from _factory(wearbench_bench, "can", request.config.getoption("--wearbench-can"),
                        wearbench_speedup)


@pytest.fixture
def canopen_bench(request, wearbench_bench, wearbench_speedup) -> Iterator[Callable[..., EmulatedBench]]:
    """Factory like ``serial_bench`` for the bench as a CANopen CiA 402 drive (profile velocity mode)
    with the accelerometer's raw frames on the same python-can ``virtual`` bus. With
    ``--wearbench-can INTERFACE:CHANNEL`` it is the real drive on that bus."""
    yield from _factory(wearbench_bench, "canopen", request.config.getoption("--wearbench-can"),
                        wearbench_speedup)


@pytest.fixture
def record_session(tmp_path: Path) -> Callable[..., RecordedSession]:
    """Factory: ``record_session(bench, duration=None, cycles=None, speed=None, name="session",
    **plan)`` records from an :class:`~wearbench.testing.EmulatedBench` with the wearbench recorder
    into ``tmp_path/NAME.mcap`` (``duration`` s of device time or ``cycles`` crank cycles; ``speed``
    rad/s, default the bench handle's; other keywords go to ``SessionPlan``) and returns the
    :class:`~wearbench.testing.RecordedSession` (``.path``, ``.result``, ``.session`` read back).
    The file is finished whatever happens; a Ctrl-C finishes it and stops the run."""

    from wearbench.acquisition.session import SessionPlan
    from wearbench.testing.recording import record

    def run(bench: EmulatedBench, *, duration: float | None = None, cycles: float | None = None,
            speed: float | None = None, name: str = "session", **plan: Any) -> RecordedSession:
        if duration is None and cycles is None:
            raise ValueError("record_session: give duration (s) or cycles")
        out = tmp_path / f"{name}.mcap"
        session_plan = SessionPlan(speed=bench.speed if speed is None else speed, cycles=cycles,
                                   duration=duration, **plan)
        return record(bench.open_rig(), bench.bench, session_plan, out)

    return run
