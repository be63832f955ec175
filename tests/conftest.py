"""Suite-wide fixtures.

- Test files run heaviest first (``tests/durations.json``, written by
  ``benchmarks/compute/suite_durations.py --schedule``): with ``-n``, xdist hands whole files to the
  workers in this order (``--dist loadfile --no-loadscope-reorder``), so the long files start at
  once and the short ones fill in at the end. A file not listed yet runs after the listed ones.
- With ``-n`` on a fresh checkout, the model's kernels are compiled once, in a process of its own,
  while the workers collect and run the tests that compile kernels of their own (``own_kernels``: an
  empty numba cache, another commit's model) and the tests that use none (``no_kernels``); every
  other test waits for it. Otherwise every worker, and the commands the tests start, would compile
  them at once: about a minute and a half of CPU each. Workers that start during that compile run at
  a lower priority, so it has a core to itself.
- Every test gets its own result cache (unless a module fixture chose one) and no user compute config.
- Each test's CPU goes into the JUnit XML as the property ``cpu`` (``--junitxml``), beside its time.
- Every session file a test writes is opened, at the end of the run, by the readers other tools use
  (``wearbench.testing.mcap_readers``): @mcap/core's indexed reader under node and the Python mcap
  readers with CRC validation, which also hold it to ``mcap doctor --strict-message-order`` (log
  times never go back in file order). Unfinished files (killed or cut on purpose) are left to the tests that
  recover them; the recovered files are checked here too. The node packages go to one folder for the
  whole run (the user's cache, chosen before any test moves ``$WEARBENCH_CACHE``).
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from wearbench.testing import mcap_readers

NODE_FOLDER = mcap_readers.cache_dir()
DURATIONS = Path(__file__).with_name("durations.json")
KERNELS_READY = "WEARBENCH_TEST_KERNELS_READY"  # a file that exists once the run's shared compile is done
_CPU_AT_SETUP = pytest.StashKey[float]()
_COMPILE_FOLDER = pytest.StashKey[Path]()  # the shared compile's folder, on the controller that made it


def _compiling() -> bool:
    """Whether this run's shared compile is still running (its done-file named but not there yet)."""
    done = os.environ.get(KERNELS_READY)
    return bool(done) and not os.path.exists(done)


def _waits(item: pytest.Item) -> bool:
    """Whether a test waits for the shared compile: not if it compiles its own kernels or uses none."""
    return not (item.get_closest_marker("own_kernels") or item.get_closest_marker("no_kernels"))


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Whole files: first those none of whose tests waits for the shared compile (they run while it
    compiles), then the rest; each group heaviest first by their recorded seconds; within a file, its
    ``own_kernels`` tests first, then the tests' own order."""
    seconds = json.loads(DURATIONS.read_text(encoding="utf-8")) if DURATIONS.exists() else {}
    first, waiting_files = {}, set()
    for i, item in enumerate(items):
        file = item.nodeid.split("::")[0]
        first.setdefault(file, i)
        if _waits(item):
            waiting_files.add(file)
    rank = {id(item): i for i, item in enumerate(items)}

    def key(item: pytest.Item) -> tuple[bool, float, int, bool, int]:
        file = item.nodeid.split("::")[0]
        return (file in waiting_files, -seconds.get(file, 0.0), first[file],
                not item.get_closest_marker("own_kernels"), rank[id(item)])

    items.sort(key=key)


def pytest_configure(config: pytest.Config) -> None:
    """On the controller of a run with workers, when the kernels are not in their on-disk cache:
    compile them in a process of its own, and tell the workers where it will say it is done. A worker
    that starts while that compile runs lowers its own priority (nice 5, it and what it starts, for the
    run), so the compile has a core of its own: the tests that wait for it start sooner."""
    if hasattr(config, "workerinput"):
        if _compiling():
            os.nice(5)
        return
    if not config.getoption("numprocesses", None):
        return
    from wearbench.compute.cluster import kernels_compiled

    if kernels_compiled():
        return
    done = Path(tempfile.mkdtemp(prefix="wearbench-kernels-")) / "done"
    config.stash[_COMPILE_FOLDER] = done.parent
    warming = subprocess.Popen([sys.executable, "-c", "from wearbench.compute.cluster import warm_up\nwarm_up()\n"])
    threading.Thread(target=lambda: (warming.wait(), done.touch()), daemon=True).start()
    os.environ[KERNELS_READY] = str(done)  # the workers start after this hook, with this environment


def pytest_unconfigure(config: pytest.Config) -> None:
    """The controller that made the compile's folder removes it (not a worker, nor a pytest a test runs,
    which inherit its name: removed under the workers, the compile could never say it is done)."""
    if _COMPILE_FOLDER in config.stash:
        shutil.rmtree(config.stash[_COMPILE_FOLDER], ignore_errors=True)


def _cpu_seconds() -> float:
    """User and system CPU of this process and of every process it started and waited for."""
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item: pytest.Item) -> None:
    item.stash[_CPU_AT_SETUP] = _cpu_seconds()


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo):
    """Each test's CPU from its setup to its teardown, as the JUnit XML property ``cpu`` (s), for
    ``benchmarks/compute/suite_durations.py``: a worker's own and that of the commands and clusters the
    test started and waited for (not a process it killed before reaping it, nor a Dask worker's)."""
    report = yield
    if call.when == "teardown" and _CPU_AT_SETUP in item.stash:
        report.user_properties.append(("cpu", round(_cpu_seconds() - item.stash[_CPU_AT_SETUP], 3)))
    return report


@pytest.hookimpl(wrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem):
    """A test waits for the shared compile unless it compiles kernels of its own (``own_kernels``) or
    uses none (``no_kernels``); before its setup, so the wait is no test's duration."""
    while _waits(item) and _compiling():
        time.sleep(0.2)
    return (yield)


@pytest.fixture(scope="session", autouse=True)
def _one_blas_thread() -> Iterator[None]:
    """The tests' own linear algebra on one BLAS thread, as the commands' and the workflows' (two
    workers each with a spinning team of BLAS threads cost about 30 % more CPU on two cores)."""
    from wearbench.compute.threads import one_blas_thread

    with one_blas_thread():
        yield


@pytest.fixture(scope="session", autouse=True)
def _ctrl_c_heard() -> None:
    """Ctrl-C heard as in a terminal's run: a suite started in the background of a shell inherits
    SIGINT ignored (POSIX), and so would every process the interrupt tests start and signal."""
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture(scope="session", autouse=True)
def _session_compute(tmp_path_factory) -> str:
    """No user compute config for the run, and a run-wide result cache (its path is returned)."""
    mp = pytest.MonkeyPatch()
    base = tmp_path_factory.mktemp("wearbench-session")
    mp.setenv("WEARBENCH_CACHE", str(base / "cache"))
    mp.setenv("WEARBENCH_CONFIG", str(base / "no-user-config.toml"))
    mp.setenv("WEARBENCH_CALIBRATIONS", str(base / "calibrations"))
    mp.delenv("WEARBENCH_SCHEDULER", raising=False)
    yield str(base / "cache")
    mp.undo()


@pytest.fixture(autouse=True)
def _isolated_compute(_session_compute, tmp_path, monkeypatch):
    """Each test its own result cache, unless a module fixture already chose one (function-scoped
    autouse fixtures run after module fixtures, so overriding theirs would move their cache away)."""
    if os.environ.get("WEARBENCH_CACHE") == _session_compute:
        monkeypatch.setenv("WEARBENCH_CACHE", str(tmp_path / "wearbench-cache"))
        # and its own sensor-path calibrations: one a test stores is never found by another's identify
        monkeypatch.setenv("WEARBENCH_CALIBRATIONS", str(tmp_path / "calibrations"))


@pytest.fixture(scope="session")
def node_readers() -> Path:
    """The node folder with @mcap/core and the reader script; skips only when node is absent."""
    try:
        return mcap_readers.install(NODE_FOLDER)
    except mcap_readers.NodeMissing as exc:
        pytest.skip(str(exc))
    except mcap_readers.NodeSetupError as exc:
        pytest.fail(str(exc), pytrace=False)


@pytest.fixture(scope="session", autouse=True)
def every_session_file_opens(tmp_path_factory):
    yield
    files = sorted(tmp_path_factory.getbasetemp().rglob("*.mcap"))
    if not files:
        return
    try:
        folder = mcap_readers.install(NODE_FOLDER)
    except mcap_readers.NodeMissing:
        folder = None  # Python readers only; test_readers.py says why node was skipped
    problems = mcap_readers.check(files, folder)
    assert not problems, "session files other readers cannot open:\n" + "\n".join(problems)
