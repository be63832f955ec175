"""One execution layer for every batch of simulations: ensembles, studies, wear convergence, sweeps.

A batch is a list of :class:`Task` (a pure, importable function, its keyword arguments and a content
address). :func:`run_tasks` serves what the result cache already holds, submits the rest to
``dask.distributed`` (a LocalCluster of processes on this machine by default, or a running cluster
at a scheduler address) and returns results in task order; a failed task yields a
:class:`TaskFailure` in its slot and never hides the others. Results are pickled to the cache as
they arrive on the client, so a rerun, a restarted cluster or a Ctrl-C loses nothing finished.

Scheduler, first that is set (:func:`resolve_scheduler`): the ``scheduler`` argument,
``$WEARBENCH_SCHEDULER``, ``[compute] scheduler`` in the bench file (commands on a bench pass it),
``[compute] scheduler`` in the user config (``$WEARBENCH_CONFIG``, default
``~/.config/wearbench/config.toml``); "local" or nothing set: a LocalCluster.

Imports the standard library, numpy, rich and ``dask.distributed`` (lazily), and the model only in
the worker warm-up; no CLI code.
"""

from __future__ import annotations

import contextlib
import contextvars
import dataclasses
import enum
import hashlib
import json
import math
import os
import pickle
import sys
import tempfile
import time
import tomllib
import traceback as tb
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from wearbench.model.digest import model_source_digest

if TYPE_CHECKING:
    from distributed import Client
    from wearbench.bench.schema import Bench

__all__ = ["LAYOUT_VERSION", "Task", "TaskFailure", "cache_dir", "compute_client", "resolve_scheduler",
           "run_tasks", "task_key", "usable_cores"]

LAYOUT_VERSION = 1  # bump when the cached result layout changes: every key changes with it
RETRIES = 1  # Dask retries of a task whose error escaped the task wrapper (lost data, a dead worker)


@dataclass(frozen=True)
class Task:
    """One unit of work: ``fn(**kwargs)``; ``key`` is its content address (hex) and cache file name."""

    fn: Callable[..., Any]        # pure, importable top-level function (picklable)
    kwargs: Mapping[str, Any]     # picklable arguments
    key: str                      # content address (hex); also the cache file name
    label: str = ""               # shown in progress and failure reports


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
# content addresses


def _canonical(x: Any) -> Any:
    """``x`` as plain JSON data that is equal exactly when the inputs are (arrays by digest)."""
    if x is None or isinstance(x, (bool, str, int)):
        return x
    if isinstance(x, float):
        return x if math.isfinite(x) else {"__float__": repr(x)}
    if isinstance(x, np.generic):
        return _canonical(x.item())
    if isinstance(x, np.ndarray):
        a = np.ascontiguousarray(x)
        return {"__ndarray__": hashlib.sha256(a.tobytes()).hexdigest(), "dtype": a.dtype.str,
                "shape": list(a.shape)}
    if isinstance(x, Path):
        return {"__path__": x.as_posix()}
    if isinstance(x, enum.Enum):
        return {"__enum__": f"{type(x).__qualname__}.{x.name}"}
    if isinstance(x, (bytes, bytearray)):
        return {"__bytes__": hashlib.sha256(x).hexdigest()}
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        return {"__dataclass__": f"{type(x).__module__}.{type(x).__qualname__}",
                **{f.name: _canonical(getattr(x, f.name)) for f in dataclasses.fields(x)}}
    if isinstance(x, Mapping):
        items = [(_canonical(k), _canonical(v)) for k, v in x.items()]
        if all(isinstance(k, str) for k, _ in items):
            return {"__map__": dict(sorted(items))}
        return {"__map__": sorted(([k, v] for k, v in items), key=lambda kv: json.dumps(kv, sort_keys=True))}
    if isinstance(x, (list, tuple)):
        return [_canonical(v) for v in x]
    if isinstance(x, (set, frozenset)):
        return {"__set__": sorted((_canonical(v) for v in x), key=lambda v: json.dumps(v, sort_keys=True))}
    if callable(x) and hasattr(x, "__qualname__"):
        return {"__callable__": f"{x.__module__}.{x.__qualname__}"}
    raise TypeError(f"task_key: cannot address a {type(x).__name__} ({x!r:.60}); expected numbers, text, "
                    "paths, numpy arrays, dataclasses, mappings or sequences of these")


def task_key(*parts: Any) -> str:
    """SHA-256 (hex) over the canonical JSON of ``parts``, the model source digest and the cache
    layout version: equal keys mean the same computation by the same model code."""
    doc = {"layout": LAYOUT_VERSION, "model": model_source_digest(), "parts": [_canonical(p) for p in parts]}
    return hashlib.sha256(json.dumps(doc, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


# ----------------------------------------------------------------------------------------------
# result cache


def cache_dir() -> Path:
    """``$WEARBENCH_CACHE`` (default ``~/.cache/wearbench``)``/results``."""
    return Path(os.environ.get("WEARBENCH_CACHE", Path.home() / ".cache" / "wearbench")) / "results"


def _cache_path(key: str) -> Path:
    return cache_dir() / key[:2] / f"{key}.pkl"


_MISSING = object()


def _cache_load(key: str) -> Any:
    path = _cache_path(key)
    try:
        with path.open("rb") as f:
            return pickle.load(f)
    except FileNotFoundError:
        return _MISSING
    except Exception:  # noqa: BLE001 - a truncated or stale file is a miss: recomputed and rewritten
        return _MISSING


def _cache_store(key: str, value: Any) -> None:
    path = _cache_path(key)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{key[:12]}-", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            pickle.dump(value, f, protocol=pickle.HIGHEST_PROTOCOL)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


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
# clusters


def usable_cores() -> int:
    """Cores this process may run on (the affinity mask where the OS has one)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def _user_config() -> tuple[Path, dict]:
    """The user config's path and its ``[compute]`` table (empty when the file does not exist)."""
    path = Path(os.environ.get("WEARBENCH_CONFIG", Path.home() / ".config" / "wearbench" / "config.toml"))
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return path, {}
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{path}: not valid TOML: {exc}") from None
    compute = data.get("compute", {})
    if not isinstance(compute, dict):
        raise ValueError(f"{path}: [compute] = {compute!r}: expected a table")  # noqa: TRY004 - a user error
    return path, compute


def resolve_scheduler(scheduler: str | None = None, *, bench: Bench | None = None) -> str | None:
    """The scheduler address to use, first that is set: the argument, ``$WEARBENCH_SCHEDULER``,
    ``bench``'s ``[compute] scheduler``, the user config's ``[compute] scheduler``. None (also for
    "local" at any level, which stops the search there) means a LocalCluster on this machine."""

    def sources() -> Iterator[tuple[str, Any]]:
        yield "scheduler", scheduler
        yield "WEARBENCH_SCHEDULER", os.environ.get("WEARBENCH_SCHEDULER")
        if bench is not None:
            yield f"{bench.path or bench.name}: compute.scheduler", bench.scheduler
        path, table = _user_config()
        yield f"{path}: compute.scheduler", table.get("scheduler")

    for source, value in sources():
        if value:
            if not isinstance(value, str) or not (value.strip().lower() == "local" or "://" in value):
                raise ValueError(f"{source} = {value!r}: expected 'local' or a Dask scheduler address such as "
                                 "'tcp://10.0.0.5:8786'")
            return None if value.strip().lower() == "local" else value.strip()
    return None


def _warm_up() -> None:
    """Load (or compile) the model's numba kernels once in this process: a tiny clearance run."""
    from wearbench.bench.load import load_bench, shipped_bench
    from wearbench.model import build_scene, simulate

    scene = build_scene(load_bench(shipped_bench("slider-crank")))
    simulate(scene, revolutions=0.05, output_rate=1000.0, method="dopri5", record_contacts=True)


def _warm_up_plugin():
    from distributed import WorkerPlugin

    class ModelWarmUp(WorkerPlugin):
        """Each worker (also one restarted after a crash) loads the numba kernels before its first task."""

        name = "wearbench-model-warm-up"

        def setup(self, worker) -> None:
            _warm_up()

    return ModelWarmUp()


# A local cluster's background work, trimmed (Dask's own settings). While a batch runs, the event
# loops of scheduler, nannies and workers wake up on timers whatever the tasks do; at Dask's defaults
# that cost 7 % of a core, about 100 ms per 1.4 s task (benchmarks/scale_out.py). Here:
# - the event-loop health tick every 1 s, not 20 ms (it only measures how long a loop was blocked);
# - the memory monitors of workers and nannies every 1 s, not 100 ms (simulations grow slowly);
# - no statistical profiler sampling each worker's stack every 10 ms (it feeds the dashboard, off);
# - the system monitor every 2 s, not 0.5 s;
# - no work stealing (a balancing pass every 1 s): with worker-saturation 1.0 the scheduler hands a
#   worker a task only when its thread is free, so there is nothing queued on a worker to steal
#   and the tail of a batch balances itself.
# Idle cluster of 1 worker: 0.69 -> 0.11 s CPU per 10 s (client + scheduler + nanny, worker).
_LEAN_LOCAL = {"distributed.admin.tick.interval": "1s", "distributed.worker.memory.monitor-interval": "1s",
               "distributed.worker.profile.enabled": False, "distributed.admin.system-monitor.interval": "2s",
               "distributed.scheduler.work-stealing": False, "distributed.scheduler.worker-saturation": 1.0}


@dataclass
class _Session:
    client: Client | None  # None: run in-process, serially


_ACTIVE: contextvars.ContextVar[_Session | None] = contextvars.ContextVar("wearbench_compute", default=None)


@contextlib.contextmanager
def compute_client(scheduler: str | None = None, workers: int | None = None) -> Iterator[Client | None]:
    """A client that :func:`run_tasks` calls inside this block share (None when ``workers=0``: serial).

    scheduler: a running cluster's address ("tcp://HOST:PORT"); None: ``$WEARBENCH_SCHEDULER``, the
    user config, else a LocalCluster of ``workers`` (default: the usable cores) single-threaded
    processes on 127.0.0.1, dashboard off. The cluster (if started here) is closed on exit, also on
    Ctrl-C; results already cached stay cached.
    """
    if workers is not None and workers < 0:
        raise ValueError(f"workers = {workers}: expected 0 (in-process) or more")
    if workers == 0:
        token = _ACTIVE.set(_Session(None))
        try:
            yield None
        finally:
            _ACTIVE.reset(token)
        return
    import logging

    import dask
    from distributed import Client, LocalCluster

    address = resolve_scheduler(scheduler)
    cluster = None
    try:
        if address is None:
            with dask.config.set(_LEAN_LOCAL):  # the nannies pass this config on to their workers
                cluster = LocalCluster(n_workers=workers or usable_cores(), threads_per_worker=1, processes=True,
                                       host="127.0.0.1", dashboard_address=None, worker_dashboard_address=None,
                                       # a worker's heartbeat racing the scheduler's close logs a traceback
                                       # at ERROR; task errors come back as TaskFailure, not through logs
                                       silence_logs=logging.CRITICAL,
                                       # dashboard off; the scheduler's health/metrics endpoint on a free
                                       # loopback port (its default 8787 clashes with other clusters)
                                       scheduler_kwargs={"dashboard_address": "127.0.0.1:0"})
            client = Client(cluster)
        else:
            try:
                client = Client(address, timeout="10s")
            except OSError as exc:
                raise OSError(f"scheduler {address}: cannot connect ({exc}); start one with 'dask scheduler' "
                              "or leave the scheduler unset for a local cluster") from None
        try:
            client.register_plugin(_warm_up_plugin())
            token = _ACTIVE.set(_Session(client))
            try:
                yield client
            finally:
                _ACTIVE.reset(token)
        finally:
            client.close()
    finally:
        if cluster is not None:
            cluster.close()


# ----------------------------------------------------------------------------------------------
# progress


class _Progress:
    """A rich bar "label  [bar]  done N  failed F  remaining R"; silent unless stderr is a terminal."""

    def __init__(self, label: str | None, total: int):
        self.bar = None
        if label is None or not sys.stderr.isatty():
            return
        from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

        self.bar = Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.fields[info]}"),
                            TimeElapsedColumn(), transient=False,
                            refresh_per_second=2)  # tasks take seconds: 2 redraws a second, not 10
        self.total, self.done, self.failed = total, 0, 0
        self.task = self.bar.add_task(label, total=total, info=self._info())
        self.bar.start()

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
    results: list[Any] = [_MISSING] * len(tasks)
    bar = _Progress(progress, len(tasks))
    try:
        def finish(i: int, value: Any, store: bool) -> None:
            if isinstance(value, _Raised):
                value = _failure(tasks[i], value.error, value.traceback)
            elif store and cache:
                _cache_store(tasks[i].key, value)
            results[i] = value
            bar.update(isinstance(value, TaskFailure))
            if on_result is not None:
                on_result(i, value)

        todo: list[int] = []
        for i, task in enumerate(tasks):
            hit = _cache_load(task.key) if cache else _MISSING
            if hit is _MISSING:
                todo.append(i)
            else:
                finish(i, hit, store=False)
        if todo:
            session = _ACTIVE.get()
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
