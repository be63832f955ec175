"""A benchmark's result as JSON, for the documentation's results pages (``--json PATH``).

``write_result`` writes one result in the schema ``docs/results/schema.json`` (``wearbench-result/1``):
the question the run answers, the findings the script composes from its own numbers, the script and
the exact command (this process's arguments), the wearbench version and git commit (and whether the
working tree had changes), the seeds, the environment, tables with columns and units, and notes. A
file under ``docs/results/data/`` becomes one page of the documentation; regenerate it by running the
command it names. Imports the standard library only.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import platform
import shlex
import subprocess
import sys
import time
from collections.abc import Mapping, Sequence
from importlib.metadata import version
from pathlib import Path
from typing import Any

__all__ = ["Column", "Run", "column", "table", "write_result"]

ROOT = Path(__file__).resolve().parent.parent
Column = dict[str, Any]


def column(label: str, unit: str | None = None, format: str | None = None, description: str = "") -> Column:
    """One column: its heading, unit (None for text and counts) and the format spec the page applies."""
    out: Column = {"label": label, "unit": unit, "format": format}
    if description:
        out["description"] = description
    return out


def table(title: str, columns: Sequence[Column], rows: Sequence[Sequence[Any]], description: str = "") -> dict:
    """One table of a result; every row holds one value per column, in order."""
    rows = [list(r) for r in rows]
    for r in rows:
        if len(r) != len(columns):
            raise ValueError(f"table {title!r}: a row of {len(r)} values for {len(columns)} columns: {r}")
    out = {"title": title, "columns": list(columns), "rows": rows}
    if description:
        out["description"] = description
    return out


class Run:
    """The clock of a benchmark run: wall and CPU time from construction to :func:`write_result`."""

    def __init__(self) -> None:
        self.wall0, self.cpu0 = time.monotonic(), time.process_time()

    def times(self) -> dict[str, float]:
        return {"wall_s": round(time.monotonic() - self.wall0, 1), "cpu_s": round(time.process_time() - self.cpu0, 1)}


def _git(*args: str) -> str | None:
    try:
        done = subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, timeout=30, check=False)
    except (OSError, subprocess.TimeoutExpired):
        return None
    return done.stdout.strip() if done.returncode == 0 else None


def code_version() -> dict[str, Any]:
    """The installed wearbench's version, the checkout's commit, and whether tracked files had changes
    (other results under ``docs/results/data/`` do not count: a run that writes several is still clean)."""
    commit = _git("rev-parse", "HEAD")
    status = _git("status", "--porcelain", "--untracked-files=no", "--", ".", ":!docs/results/data") if commit else None
    return {"wearbench": version("wearbench"), "commit": commit, "dirty": None if status is None else bool(status)}


def command(script: Path, argv: Sequence[str]) -> str:
    """The command line that ran ``script`` with ``argv``, as run from the repository root (a benchmark
    runs as a module: ``python -m benchmarks.GROUP.NAME``)."""
    module = ".".join(script.resolve().relative_to(ROOT).with_suffix("").parts)
    return shlex.join(["python", "-m", module, *argv])


def environment() -> dict[str, Any]:
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    out: dict[str, Any] = {"python": platform.python_version(), "platform": platform.platform(terse=True),
                           "processor": _processor(), "cpus": cpus}
    if hasattr(os, "getloadavg"):
        out["load_average"] = [round(x, 2) for x in os.getloadavg()]
    return out


def _processor() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def write_result(path: str | Path, *, question: str, script: str | Path, tables: Sequence[dict],
                 seeds: Mapping[str, Any], findings: Sequence[str] = (), notes: Sequence[str] = (),
                 run: Run | None = None, argv: Sequence[str] | None = None) -> Path:
    """Write one result (schema ``wearbench-result/1``) to ``path``, replacing it; returns the path.

    ``script``: the benchmark's ``__file__``; ``argv``: its arguments (default ``sys.argv[1:]``), which
    give the exact command; ``seeds``: every seed the run drew from ({} for none); ``run``: its clock."""
    result: dict[str, Any] = {
        "schema": "wearbench-result/1",
        "question": question,
        "findings": list(findings),
        "benchmark": {"script": Path(script).resolve().relative_to(ROOT).as_posix(),
                      "command": command(Path(script), sys.argv[1:] if argv is None else argv),
                      **(run.times() if run else {})},
        "version": code_version(),
        "seeds": dict(seeds),
        "generated": _dt.datetime.now(_dt.UTC).replace(microsecond=0).isoformat().replace("+00:00", "Z"),
        "environment": environment(),
        "tables": list(tables),
        "notes": list(notes),
    }
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(result, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
    tmp.replace(path)
    return path
