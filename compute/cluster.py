"""Where a batch runs: the scheduler to use, and a Dask client on a running cluster or a LocalCluster.

Scheduler, first that is set (:func:`resolve_scheduler`): the ``scheduler`` argument,
``$WEARBENCH_SCHEDULER``, ``[compute] scheduler`` in the bench file (commands on a bench pass it),
``[compute] scheduler`` in the user config (``$WEARBENCH_CONFIG``, default
``~/.config/wearbench/config.toml``); "local" or nothing set: a LocalCluster.

A LocalCluster starts shielded from Ctrl-C (:mod:`~wearbench.compute.interrupts`): the program hears
it at once, its workers never; after a Ctrl-C the cluster is closed within ``CLOSE_INTERRUPTED`` s and
what is left of its workers is killed. On a cold kernel cache the model compiles in this process
first, once, instead of in every worker at the same time.

Imports the standard library, ``dask.distributed`` (lazily) and the model (lazily: the warm-up and
its kernel cache); no CLI code.
"""

from __future__ import annotations

import contextlib
import contextvars
import logging
import os
import threading
import tomllib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from wearbench.compute.interrupts import end_processes, running_processes, start_shielded

if TYPE_CHECKING:
    from distributed import Client
    from wearbench.bench.schema import Bench

__all__ = ["LEAN_LOCAL", "ActiveClient", "active_client", "compute_client", "kernels_compiled", "resolve_scheduler",
           "usable_cores", "warm_up"]


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


def warm_up() -> None:
    """Load (or compile) the model's numba kernels once in this process: a tiny clearance run."""
    from wearbench.bench.load import load_bench, shipped_bench
    from wearbench.model import build_scene, simulate

    scene = build_scene(load_bench(shipped_bench("slider-crank")))
    simulate(scene, revolutions=0.05, output_rate=1000.0, method="dopri5", record_contacts=True)


def kernels_compiled() -> bool:
    """True if the model's numba kernels are in their on-disk cache (a warm-up loads them in about a
    second; otherwise it compiles them, about a minute)."""
    from wearbench.model import jit_cache

    return any(jit_cache.numba_cache_dir().rglob("integrators.run_loop-*.nbi"))


def _warm_up_plugin():
    from distributed import WorkerPlugin

    class ModelWarmUp(WorkerPlugin):
        """Each worker (also one restarted after a crash) loads the numba kernels before its first task."""

        name = "wearbench-model-warm-up"

        def setup(self, worker) -> None:
            warm_up()

    return ModelWarmUp()


# A local cluster's background work, trimmed (Dask's own settings). While a batch runs, the event
# loops of scheduler, nannies and workers wake up on timers whatever the tasks do; at Dask's defaults
# that cost 7 % of a core, about 100 ms per 1.4 s task (benchmarks/compute/scale_out.py). Here:
# - the event-loop health tick every 1 s, not 20 ms (it only measures how long a loop was blocked);
# - the memory monitors of workers and nannies every 1 s, not 100 ms (simulations grow slowly);
# - no statistical profiler sampling each worker's stack every 10 ms (it feeds the dashboard, off);
# - the system monitor every 2 s, not 0.5 s;
# - no work stealing (a balancing pass every 1 s): with worker-saturation 1.0 the scheduler hands a
#   worker a task only when its thread is free, so there is nothing queued on a worker to steal
#   and the tail of a batch balances itself.
# Idle cluster of 1 worker: 0.69 -> 0.11 s CPU per 10 s (client + scheduler + nanny, worker).
LEAN_LOCAL = {"distributed.admin.tick.interval": "1s", "distributed.worker.memory.monitor-interval": "1s",
               "distributed.worker.profile.enabled": False, "distributed.admin.system-monitor.interval": "2s",
               "distributed.scheduler.work-stealing": False, "distributed.scheduler.worker-saturation": 1.0}


@dataclass
class ActiveClient:
    """The client of the innermost :func:`compute_client` block."""

    client: Client | None  # None: run in-process, serially


_ACTIVE: contextvars.ContextVar[ActiveClient | None] = contextvars.ContextVar("wearbench_compute", default=None)


def active_client() -> ActiveClient | None:
    """The client of the :func:`compute_client` block this code runs in; None outside one."""
    return _ACTIVE.get()


@contextlib.contextmanager
def compute_client(scheduler: str | None = None, workers: int | None = None) -> Iterator[Client | None]:
    """A client that ``run_tasks`` calls inside this block share (None when ``workers=0``: serial).

    scheduler: a running cluster's address ("tcp://HOST:PORT"); None: ``$WEARBENCH_SCHEDULER``, the
    user config, else a LocalCluster of ``workers`` (default: the usable cores) single-threaded
    processes on 127.0.0.1, dashboard off. The cluster (if started here) is closed on exit, also on
    Ctrl-C; results already cached stay cached.
    """
    if workers is not None and workers < 0:
        raise ValueError(f"workers = {workers}: expected 0 (in-process) or more")
    if workers == 0:
        token = _ACTIVE.set(ActiveClient(None))
        try:
            yield None
        finally:
            _ACTIVE.reset(token)
        return
    address = resolve_scheduler(scheduler)
    if address is None and not kernels_compiled():
        warm_up()  # compiled once, here (a program's compile note says so), not in every worker at once
    life = _Life(address, workers)
    within = CLOSE_INTERRUPTED
    client = life.start()
    try:
        token = _ACTIVE.set(ActiveClient(client))
        try:
            yield client
            within = CLOSE_WITHIN
        finally:
            _ACTIVE.reset(token)
    finally:
        life.shut_down(client, within)
        life.release_logs()


_WORKER = "Dask Worker process"  # the name distributed's nannies give their worker processes
CLOSE_WITHIN = 60.0  # s: a cluster's close after its work; then its workers are killed
CLOSE_INTERRUPTED = 2.0  # s: the same after a Ctrl-C or an error


class _UnlessStopping(logging.Filter):
    """Passes a log record only while the end is not forced. A LocalCluster's ``silence_logs`` holds its
    handlers at CRITICAL only until its close, and a scheduler whose workers were killed can report
    their closed connections after it (a Ctrl-C as the workers warmed up printed a CommClosedError's
    traceback at INFO): what it says then is not the user's."""

    def __init__(self, stopping: threading.Event):
        super().__init__()
        self.stopping = stopping

    def filter(self, record: logging.LogRecord) -> bool:
        return not self.stopping.is_set()


class _Life:
    """The life cycle of one :func:`compute_client` block's cluster: a LocalCluster it starts
    (``address`` None) or a running cluster it connects to, and their end."""

    def __init__(self, address: str | None, workers: int | None):
        self.address, self.workers = address, workers
        self.before = frozenset(running_processes(_WORKER))  # another block's workers: never killed here
        self.stopping = threading.Event()  # set when the end is forced: what the cluster's loop reports
        # then (a killed worker's closed connections) is not the user's
        self.cluster: Any = None  # the LocalCluster, once it runs
        self.quiet = _UnlessStopping(self.stopping)

    def start(self) -> Client:
        """Start shielded (:func:`start_shielded`): a Ctrl-C meanwhile is heard at once, the workers
        spawned so far are killed (the start-up then gives up at once), and the workers never take a
        Ctrl-C themselves."""
        return start_shielded(self._local if self.address is None else self._connect, name="cluster start-up",
                              close=lambda client: self.shut_down(client, CLOSE_INTERRUPTED), abort=self._kill)

    def _local(self) -> Client:
        """A LocalCluster of ``workers`` single-threaded processes and its client, the model loaded on
        every worker."""
        import dask
        from distributed import Client, LocalCluster

        for handler in logging.getLogger("distributed").handlers:
            handler.addFilter(self.quiet)

        with dask.config.set(LEAN_LOCAL):  # nannies pass the config on
            cluster = LocalCluster(n_workers=self.workers or usable_cores(), threads_per_worker=1, processes=True,
                                   host="127.0.0.1", dashboard_address=None, worker_dashboard_address=None,
                                   # a worker's heartbeat racing the scheduler's close logs a traceback
                                   # at ERROR; task errors come back as TaskFailure, not through logs
                                   silence_logs=logging.CRITICAL,
                                   # dashboard off; the scheduler's health/metrics endpoint on a free
                                   # loopback port (its default 8787 clashes with other clusters)
                                   scheduler_kwargs={"dashboard_address": "127.0.0.1:0"})
        self.cluster = cluster
        loop = cluster.loop.asyncio_loop
        loop.set_exception_handler(lambda loop, context: None if self.stopping.is_set()
                                   else loop.default_exception_handler(context))
        try:
            client = Client(cluster)
            client.register_plugin(_warm_up_plugin())
        except BaseException:
            cluster.close()
            raise
        return client

    def _connect(self) -> Client:
        from distributed import Client

        try:
            client = Client(self.address, timeout="10s")
        except OSError as exc:
            raise OSError(f"scheduler {self.address}: cannot connect ({exc}); start one with 'dask scheduler' "
                          "or leave the scheduler unset for a local cluster") from None
        try:
            client.register_plugin(_warm_up_plugin())
        except BaseException:
            client.close()
            raise
        return client

    def _kill(self, wait: float = 0.0) -> None:
        """Kill the workers this block started that still run, their nannies told first not to start
        new ones (they close instead); wait up to ``wait`` s for them to be gone."""
        self.stopping.set()
        for nanny in list(getattr(self.cluster, "workers", {}).values()):
            with contextlib.suppress(Exception):
                nanny.close_gracefully(reason="wearbench: interrupted")
        end_processes(self.before, name=_WORKER, wait=wait)

    def release_logs(self) -> None:
        """distributed's log handlers without this block's filter, unless the end was forced: then its
        loop may report the killed workers' connections until the process ends."""
        if not self.stopping.is_set():
            for handler in logging.getLogger("distributed").handlers:
                handler.removeFilter(self.quiet)

    def shut_down(self, client: Client, within: float) -> None:
        """Close ``client`` and the LocalCluster it owns (if any) within ``within`` s, in a helper
        thread; when the time is up, or at a Ctrl-C meanwhile, kill the workers that are left and let
        the close finish in the background."""
        cluster = getattr(client, "cluster", None)  # a LocalCluster started here; None: a running cluster's
        closed = threading.Event()  # not Thread.join: interrupted, it takes the thread for ended (3.11)

        def close() -> None:
            try:
                client.close(timeout=within)
            finally:
                try:
                    if cluster is not None:
                        cluster.close(timeout=within)
                finally:
                    closed.set()

        closing = threading.Thread(target=close, name="wearbench cluster shutdown", daemon=True)
        try:  # started inside: its close may take a Ctrl-C to this thread before start() returns here
            closing.start()
            closed.wait(within)
        finally:
            if not closed.is_set():
                self._kill(wait=1.0)
