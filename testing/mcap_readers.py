"""Reading session files with the readers other tools use: ``@mcap/core``'s indexed reader under node
(the reader Foxglove opens files with; messages decoded by protobufjs) and the Python ``mcap``
readers with CRC validation, and the log-time order ``mcap doctor --strict-message-order`` demands
(every message's log time at or after every earlier message's, in file order, across channels).
Used by :func:`wearbench.testing.assert_valid_mcap`, the project suite's check of every file it
writes (``tests/conftest.py``) and ``tests/interop/test_readers.py``.

The node packages are installed with npm into a cache folder outside the repository
(``$WEARBENCH_CACHE/node``, default ``~/.cache/wearbench/node``), once per package set, under a
file lock (pytest-xdist workers share it). No ``node``: :class:`NodeMissing` (tests skip with the
reason); ``npm`` failing (registry unreachable, ...): :class:`NodeSetupError` (tests fail).
"""

from __future__ import annotations

import fcntl
import json
import shutil
import subprocess
from pathlib import Path

from mcap.reader import NonSeekingReader, SeekingReader
from wearbench.bench.content import cache_folder

PACKAGES = ("@mcap/core@2.2.2", "@mcap/support@1.1.0", "@mcap/nodejs@1.0.2", "protobufjs@7.6.6")
SCRIPT = Path(__file__).with_name("read_mcap.mjs")
MAGIC = b"\x89MCAP0\r\n"


class NodeMissing(RuntimeError):
    """``node`` is not on PATH."""


class NodeSetupError(RuntimeError):
    """The node packages could not be installed."""


def cache_dir() -> Path:
    return cache_folder("node")


def install(folder: Path | None = None, packages: tuple[str, ...] = PACKAGES,
            scripts: tuple[Path, ...] = (SCRIPT,)) -> Path:
    """The folder holding ``packages`` and ``scripts``, installing what is missing (one package set
    per folder: another set in the same folder is installed over it)."""
    if shutil.which("node") is None:
        raise NodeMissing("node is not on PATH: the @mcap/core reader check needs Node.js (>= 18)")
    folder = folder or cache_dir()
    folder.mkdir(parents=True, exist_ok=True)
    marker = folder / "installed.txt"
    with open(folder / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not (marker.exists() and marker.read_text() == " ".join(packages)):
            npm = shutil.which("npm")
            if npm is None:
                raise NodeSetupError("npm is not on PATH: cannot install " + " ".join(packages))
            if not (folder / "package.json").exists():
                (folder / "package.json").write_text('{"private": true, "type": "module"}\n')
            r = subprocess.run([npm, "install", "--no-audit", "--no-fund", "--loglevel=error", *packages],
                               cwd=folder, capture_output=True, text=True, timeout=600, check=False)
            if r.returncode:
                raise NodeSetupError(f"npm install {' '.join(packages)} into {folder} failed "
                                     f"(exit {r.returncode}): {r.stderr.strip()[-2000:]}")
            marker.write_text(" ".join(packages))
        for script in scripts:
            shutil.copyfile(script, folder / script.name)  # beside node_modules, so its imports resolve
    return folder


def read_with_node(paths: list[Path], folder: Path) -> list[dict]:
    """One result per file from ``read_mcap.mjs`` (see its header for the fields)."""
    if not paths:
        return []
    # --single-threaded (a V8 flag): no background compile jobs, which can deadlock node's exit (a
    # worker waits for a main-thread GC while the main thread joins it: nodejs/node#54918; seen in CI)
    try:
        r = subprocess.run(["node", "--single-threaded", str(folder / SCRIPT.name), *map(str, paths)], cwd=folder,
                           capture_output=True, text=True, timeout=300, check=False)
    except subprocess.TimeoutExpired as exc:
        printed = (exc.stdout or b"")[-300:]
        raise RuntimeError(f"node {SCRIPT.name} on {len(paths)} file(s) ({paths[0]}, ...) did not exit within "
                           f"{exc.timeout:.0f} s; it had printed {printed!r}") from None
    if r.returncode:
        raise RuntimeError(f"node {SCRIPT.name} exited {r.returncode}: {r.stderr.strip()[-2000:]}")
    return json.loads(r.stdout)


class OutOfOrder(ValueError):
    """A message whose log time is before an earlier message's (``mcap doctor --strict-message-order``)."""


def read_with_python(path: Path) -> dict[str, int]:
    """Messages per topic through the summary and indexes (chunk CRCs checked), after a record-
    by-record pass that checks every chunk CRC, the data-section CRC and that log times never go
    back in file order (:class:`OutOfOrder`). Raises on any mismatch."""
    latest, late = 0, []
    with open(path, "rb") as fh:
        for _, channel, message in NonSeekingReader(fh, validate_crcs=True).iter_messages(log_time_order=False):
            if message.log_time < latest:
                late.append((channel.topic, (latest - message.log_time) * 1e-9))
            latest = max(latest, message.log_time)
    if late:
        worst = max(late, key=lambda t: t[1])
        raise OutOfOrder(f"{len(late)} messages logged before an earlier message's log time (mcap doctor "
                         f"--strict-message-order rejects the file); first on {late[0][0]!r}, worst "
                         f"{worst[1] * 1e3:.1f} ms on {worst[0]!r}")
    counts: dict[str, int] = {}
    with open(path, "rb") as fh:
        for _, channel, _ in SeekingReader(fh, validate_crcs=True).iter_messages(log_time_order=False):
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
    return counts


def is_finished_mcap(path: Path) -> bool:
    """Starts and ends with the MCAP magic (unfinished or cut files are checked after recovery)."""
    size = path.stat().st_size
    if size < 2 * len(MAGIC):
        return False
    with open(path, "rb") as fh:
        head = fh.read(len(MAGIC))
        fh.seek(size - len(MAGIC))
        return head == MAGIC and fh.read() == MAGIC


def check(paths: list[Path], folder: Path | None) -> list[str]:
    """Problems of finished session files: a reader that fails, or readers that disagree on the
    messages per topic. ``folder`` None: Python readers only (node absent)."""
    paths = [p for p in paths if is_finished_mcap(p)]
    problems, python = [], {}
    for p in paths:
        try:
            python[p] = read_with_python(p)
        except Exception as exc:  # noqa: BLE001 - every failing file is reported
            problems.append(f"{p}: Python mcap reader with CRC validation: {type(exc).__name__}: {exc}")
    if folder is not None:
        for result in read_with_node(paths, folder):
            p = Path(result["path"])
            if not result["ok"]:
                problems.append(f"{p}: @mcap/core McapIndexedReader: {result.get('error')}")
                continue
            node = {t: v["messages"] for t, v in result["topics"].items()}
            if p in python and node != python[p]:
                problems.append(f"{p}: messages per topic differ: node {node}, Python {python[p]}")
    return problems
