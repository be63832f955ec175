"""One execution layer for every batch of simulations: ensembles, studies, wear convergence, sweeps.

A batch is a list of :class:`Task` (a pure, importable function, its keyword arguments and a content
address). :func:`run_tasks` serves what the result cache already holds, submits the rest to
``dask.distributed`` (a LocalCluster of processes on this machine by default, or a running cluster
at a scheduler address) and returns results in task order; a failed task yields a
:class:`TaskFailure` in its slot and never hides the others. Results are pickled to the cache as
they arrive on the client, so a rerun, a restarted cluster or a Ctrl-C loses nothing finished.

Content addresses and the result cache are :mod:`~wearbench.compute.task_cache`'s, the scheduler
and the client :mod:`~wearbench.compute.cluster`'s; their public names are exported here too, so a
batch's code imports one module. Imports the standard library, numpy, rich and
``dask.distributed`` (lazily); no CLI code.
"""

from __future__ import annotations

import dataclasses
import os
import pickle
import sys
import time
import traceback as tb
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Self

import numpy as np
from wearbench.compute.cluster import active_client, compute_client, resolve_scheduler, usable_cores
from wearbench.compute.task_cache import (
    LAYOUT_VERSION,
    MISSING,
    cache_dir,
    cache_load,
    cache_store,
    cached,
    task_key,
)
from wearbench.model.digest import model_source_digest

if TYPE_CHECKING:
    from distributed import Client

__all__ = ["LAYOUT_VERSION", "ProgressLines", "Task", "TaskFailure", "cache_dir", "cached", "compute_client",
           "resolve_scheduler", "run_tasks", "task_key", "usable_cores"]

RETRIES = 1  # Dask retries of a task whose error escaped the task wrapper (lost data, a dead worker)


@dataclass(frozen=True)
class Task:
    """One unit of work: ``fn(**kwargs)``; ``key`` is its content address (hex) and cache file name."""

    fn: Callable[..., Any]        # pure, importable top-level function (picklable)
    kwargs: Mapping[str, Any]     # picklable arguments
    key: str                      # content address (hex); also the cache file name
    label: str = ""               # shown in progress and failure reports
    revolutions: float = 0.0      # motor revolutions it simulates, about (what it costs: compute.cost)


@dataclass(frozen=True)
class TaskFailure:
    """A task that raised (or whose worker died too often): what it was and what went wrong."""

    label: str
    key: str
    params: Mapping[str, Any]     # short, printable summary of kwargs (no arrays)
    error: str                    # one line: exception type and message
    traceback: str

    def __str__(self) -> str:
        params = ", ".join(f"{k}={v}" for k, v in self.params.items())
        return f"{self.label or self.key[:12]} ({params}): {self.error}"


# ----------------------------------------------------------------------------------------------
# running one task (on a worker or in-process)


@dataclass(frozen=True)
class _Raised:
    """What a task raised, made on the worker (the exception itself need not pickle)."""

    error: str
    traceback: str


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _call(fn: Callable[..., Any], kwargs: Mapping[str, Any]) -> Any:
    """Run ``fn(**kwargs)``; an exception comes back as a :class:`_Raised` value, not retried."""
    try:
        return fn(**kwargs)
    except Exception as exc:  # noqa: BLE001 - any error of one task is reported in its slot
        return _Raised(_one_line(exc), tb.format_exc())


def _call_pickled(payload: bytes, model: str) -> Any:
    """:func:`_call` on ``(fn, kwargs)`` pickled by the client: a function a worker cannot import
    becomes this task's failure instead of a stalled worker connection. ``model``: the client's
    model source digest; a worker with other model code refuses (its result would be cached under
    the client's key)."""
    if model != model_source_digest():
        return _Raised(f"worker {os.uname().nodename} runs other wearbench model code (digest "
                       f"{model_source_digest()[:12]}, client {model[:12]}): install the same version on "
                       "every worker", "")
    try:
        fn, kwargs = pickle.loads(payload)
    except Exception as exc:  # noqa: BLE001 - e.g. the task's module is not installed on this worker
        return _Raised(f"cannot load the task on worker: {_one_line(exc)}", tb.format_exc())
    return _call(fn, kwargs)


def _summary(value: Any, depth: int = 0) -> Any:
    """A short printable stand-in for one argument (no arrays, no benches in full)."""
    if value is None or isinstance(value, (bool, int, str)):
        return value if not isinstance(value, str) or len(value) <= 60 else value[:57] + "..."
    if isinstance(value, float):
        return float(f"{value:.6g}")
    if isinstance(value, np.generic):
        return _summary(value.item(), depth)
    if isinstance(value, np.ndarray):
        return f"<array {'x'.join(map(str, value.shape))} {value.dtype}>"
    if isinstance(value, Path):
        return str(value)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        name = getattr(value, "name", None)
        return f"<{type(value).__name__} {name!r}>" if isinstance(name, str) else f"<{type(value).__name__}>"
    if isinstance(value, Mapping) and depth < 2 and len(value) <= 8:
        return {str(k): _summary(v, depth + 1) for k, v in value.items()}
    if isinstance(value, (list, tuple)) and depth < 2 and len(value) <= 8:
        return [_summary(v, depth + 1) for v in value]
    size = f" of {len(value)}" if hasattr(value, "__len__") else ""
    return f"<{type(value).__name__}{size}>"


def _failure(task: Task, error: str, trace: str) -> TaskFailure:
    return TaskFailure(task.label, task.key, {k: _summary(v) for k, v in task.kwargs.items()}, error, trace)


# ----------------------------------------------------------------------------------------------
# progress


class ProgressLines:
    """Progress for a log file (stderr is not a terminal), with the calls of rich's ``Progress`` that
    wearbench uses (``add_task``, ``update``, a context): one line when a task starts, one each time
    another tenth of it is done (at most every ``every`` s otherwise), and one when it ends."""

    def __init__(self, stream=None, every: float = 30.0):
        self.stream, self.every = stream or sys.stderr, every
        self.tasks: list[dict] = []

    def add_task(self, description: str, total: float | None = None, info: str = "", **_: Any) -> int:
        self.tasks.append({"description": description, "total": total, "completed": 0.0, "info": info,
                           "start": time.monotonic(), "said": -1.0, "said_at": 0.0})
        self._say(self.tasks[-1], "start")
        return len(self.tasks) - 1

    def update(self, task: int, *, completed: float | None = None, advance: float | None = None,
               description: str | None = None, info: str | None = None, **_: Any) -> None:
        t = self.tasks[task]
        t["completed"] = completed if completed is not None else t["completed"] + (advance or 0)
        t["description"] = description if description is not None else t["description"]
        t["info"] = info if info is not None else t["info"]
        step = (t["total"] or 0) / 10
        now = time.monotonic()
        if (step and t["completed"] >= t["said"] + step) or now - t["said_at"] >= self.every:
            self._say(t)

    def advance(self, task: int, advance: float = 1) -> None:
        self.update(task, advance=advance)

    def _say(self, t: dict, state: str = "") -> None:
        t["said"], t["said_at"] = t["completed"], time.monotonic()
        total = f"/{t['total']:g}" if t["total"] else ""
        progress = "started" if state == "start" else f"{t['completed']:.4g}{total}"
        print(f"{t['description'].strip()}: {progress}  {t['info']}  ({time.monotonic() - t['start']:.0f} s)".rstrip(),
              file=self.stream, flush=True)

    def stop(self) -> None:
        """The last line of every task not said yet."""
        for t in self.tasks:
            if t["said"] != t["completed"]:
                self._say(t)

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


class _Progress:
    """A rich bar "label  [bar]  done N  failed F  remaining R" on a terminal; off one,
    :class:`ProgressLines` (a line per tenth of the batch)."""

    def __init__(self, label: str | None, total: int):
        self.total, self.done, self.failed = total, 0, 0
        self.bar: Any = None
        if label is None:
            return
        if sys.stderr.isatty():
            from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

            self.bar = Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.fields[info]}"),
                                TimeElapsedColumn(), transient=False,
                                refresh_per_second=2)  # tasks take seconds: 2 redraws a second, not 10
            self.bar.start()
        else:
            self.bar = ProgressLines()
        self.task = self.bar.add_task(label, total=total, info=self._info())

    def _info(self) -> str:
        return f"done {self.done}  failed {self.failed}  remaining {self.total - self.done - self.failed}"

    def update(self, failed: bool) -> None:
        if self.bar is None:
            return
        self.failed += failed
        self.done += not failed
        self.bar.update(self.task, advance=1, info=self._info())

    def close(self) -> None:
        if self.bar is not None:
            self.bar.stop()


# ----------------------------------------------------------------------------------------------
# running a batch


def run_tasks(tasks: Sequence[Task], *, scheduler: str | None = None, workers: int | None = None,
              cache: bool = True, progress: str | None = None,
              on_result: Callable[[int, Any], None] | None = None) -> list[Any]:
    """Run ``tasks``; return their results in task order, a :class:`TaskFailure` where one failed.

    cache: serve results stored under :func:`cache_dir` by key (a cached task is not submitted) and
    store new ones as they arrive. scheduler/workers: as :func:`compute_client`; inside an active
    :func:`compute_client` block its client is used; ``workers=0`` runs in this process, serially.
    progress: a label shows a progress bar (done / failed / remaining) on a terminal.
    on_result(i, result): called as each task finishes (cached ones first), in this process.
    """
    results: list[Any] = [MISSING] * len(tasks)
    bar = _Progress(progress, len(tasks))
    try:
        def finish(i: int, value: Any, store: bool) -> None:
            if isinstance(value, _Raised):
                value = _failure(tasks[i], value.error, value.traceback)
            elif store and cache:
                cache_store(tasks[i].key, value)
            results[i] = value
            bar.update(isinstance(value, TaskFailure))
            if on_result is not None:
                on_result(i, value)

        todo: list[int] = []
        for i, task in enumerate(tasks):
            hit = cache_load(task.key) if cache else MISSING
            if hit is MISSING:
                todo.append(i)
            else:
                finish(i, hit, store=False)
        if todo:
            session = active_client()
            if workers == 0 or (session is not None and session.client is None and workers is None
                                and scheduler is None):
                for i in todo:
                    finish(i, _call(tasks[i].fn, tasks[i].kwargs), store=True)
            elif session is not None and session.client is not None:
                _run_on(session.client, tasks, todo, finish)
            else:
                with compute_client(scheduler, workers) as client:
                    _run_on(client, tasks, todo, finish)
    finally:
        bar.close()
    return results


def _run_on(client: Client, tasks: Sequence[Task], todo: list[int],
            finish: Callable[[int, Any, bool], None]) -> None:
    import cloudpickle
    from distributed import as_completed

    futures = {}
    model = model_source_digest()
    for i in todo:
        t = tasks[i]
        payload = cloudpickle.dumps((t.fn, dict(t.kwargs)), protocol=pickle.HIGHEST_PROTOCOL)
        # a unique Dask key per submission: equal content keys in one batch still run as separate slots
        key = f"{t.label or 'task'}-{t.key[:16]}-{i}-{time.time_ns()}"
        f = client.submit(_call_pickled, payload, model, key=key, pure=False, retries=RETRIES)
        futures[f] = i
    try:
        for f in as_completed(list(futures)):
            i = futures.pop(f)
            try:
                value = f.result()
            except Exception as exc:  # noqa: BLE001 - the worker died too often (KilledWorker), lost data
                value = _Raised(_one_line(exc), "".join(tb.format_exception(exc)))
            f.release()
            finish(i, value, True)
    finally:
        if futures:  # interrupted: stop what is queued or running; finished results are cached
            client.cancel(list(futures), force=True)
