"""Suite-wide fixtures.

- Every test gets its own result cache (unless a module fixture chose one) and no user compute config.
- Every session file a test writes is opened, at the end of the run, by the readers other tools use
  (``wearbench.testing.mcap_readers``): @mcap/core's indexed reader under node and the Python mcap
  readers with CRC validation, which also hold it to ``mcap doctor --strict-message-order`` (log
  times never go back in file order). Unfinished files (killed or cut on purpose) are left to the tests that
  recover them; the recovered files are checked here too. The node packages go to one folder for the
  whole run (the user's cache, chosen before any test moves ``$WEARBENCH_CACHE``).
"""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest
from wearbench.testing import mcap_readers

NODE_FOLDER = mcap_readers.cache_dir()


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
