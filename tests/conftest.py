"""Suite-wide fixtures.

- The run gets its own result cache and no user compute config (nothing read from or written to the
  user's ~/.cache/wearbench or ~/.config/wearbench).
- Every session file a test writes is opened, at the end of the run, by the readers other tools use
  (``tests/interop/mcap_readers.py``): @mcap/core's indexed reader under node and the Python mcap
  readers with CRC validation. Unfinished files (killed or cut on purpose) are left to the tests that
  recover them; the recovered files are checked here too. The node packages go to one folder for the
  whole run (the user's cache, chosen before any test moves ``$WEARBENCH_CACHE``).
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent / "interop"))
import mcap_readers

NODE_FOLDER = mcap_readers.cache_dir()


@pytest.fixture(scope="session", autouse=True)
def _isolated_compute(tmp_path_factory):
    # session scope: module fixtures and tests that point WEARBENCH_CACHE elsewhere keep their choice
    # (a function-scoped fixture ran after module fixtures and moved their cache away)
    mp = pytest.MonkeyPatch()
    base = tmp_path_factory.mktemp("wearbench-session")
    mp.setenv("WEARBENCH_CACHE", str(base / "cache"))
    mp.setenv("WEARBENCH_CONFIG", str(base / "no-user-config.toml"))
    mp.delenv("WEARBENCH_SCHEDULER", raising=False)
    yield
    mp.undo()


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
