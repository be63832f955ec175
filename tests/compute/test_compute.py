"""The execution layer: content keys, the result cache, failures in their slots, a 2-worker
LocalCluster (a batch, a killed worker), and process clean-up."""

from __future__ import annotations

import os
import signal
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import cloudpickle
import numpy as np
import psutil
import pytest
from wearbench.compute import Task, TaskFailure, compute_client, run_tasks, task_cache, task_key

from wearbench import compute

# the test module is imported by path (importlib mode), so workers get its functions by value
cloudpickle.register_pickle_by_value(sys.modules[__name__])


def square(x: float, log: str, delay: float = 0.0) -> float:
    """x^2, logging each execution (one line per call) so tests can count what really ran."""
    with open(log, "a") as f:
        f.write(f"{x} {os.getpid()}\n")
    time.sleep(delay)
    if x < 0:
        raise ValueError(f"negative x = {x}")
    return x * x


def executions(log: Path) -> int:
    return len(log.read_text().splitlines()) if log.exists() else 0


def batch(xs, log: Path, delay: float = 0.0) -> list[Task]:
    return [Task(square, {"x": x, "log": str(log), "delay": delay}, task_key("square", x), f"sq{x}") for x in xs]


@pytest.fixture(autouse=True)
def _cache(tmp_path, monkeypatch):
    monkeypatch.setenv("WEARBENCH_CACHE", str(tmp_path / "cache"))
    monkeypatch.delenv("WEARBENCH_SCHEDULER", raising=False)
    monkeypatch.setenv("WEARBENCH_CONFIG", str(tmp_path / "no-config.toml"))


@dataclass(frozen=True)
class _Point:
    clearance: float
    joints: tuple[str, ...]


def test_task_key_is_a_content_address(monkeypatch):
    a = np.linspace(0, 1, 5)
    k = task_key("run", a, _Point(1e-4, ("A", "B")), {"b": 1, "a": Path("x/y")}, np.float64(2.0))
    assert k == task_key("run", a.copy(), _Point(1e-4, ("A", "B")), {"a": Path("x/y"), "b": 1}, 2.0)
    assert len(k) == 64 and int(k, 16) >= 0
    changed = a.copy()
    changed[3] += 1e-15
    assert task_key("run", changed, _Point(1e-4, ("A", "B")), {"b": 1, "a": Path("x/y")}, 2.0) != k
    assert task_key("run", a, _Point(1e-4, ("A",)), {"b": 1, "a": Path("x/y")}, 2.0) != k
    assert task_key("run", a.astype(np.float32), _Point(1e-4, ("A", "B")), {"b": 1, "a": Path("x/y")}, 2.0) != k
    # a changed model (its results digest) changes every key
    monkeypatch.setattr(task_cache, "model_results_digest", lambda: "0" * 64)
    assert task_key("run", a, _Point(1e-4, ("A", "B")), {"b": 1, "a": Path("x/y")}, 2.0) != k
    with pytest.raises(TypeError, match="cannot address a object"):
        task_key(object())


def test_serial_results_in_order_failure_in_its_slot_and_cache(tmp_path):
    log = tmp_path / "log"
    seen = []
    tasks = batch([3.0, -1.0, 2.0], log)
    out = run_tasks(tasks, workers=0, on_result=lambda i, r: seen.append(i))
    assert out[0] == 9.0 and out[2] == 4.0
    fail = out[1]
    assert isinstance(fail, TaskFailure)
    assert fail.params["x"] == -1.0 and fail.label == "sq-1.0" and fail.key == tasks[1].key
    assert fail.error == "ValueError: negative x = -1.0"
    assert "raise ValueError" in fail.traceback
    assert "x=-1.0" in str(fail) and "ValueError" in str(fail)
    assert sorted(seen) == [0, 1, 2] and executions(log) == 3
    # rerun: the two results come from the cache, the failure is tried again
    again = run_tasks(tasks, workers=0)
    assert again[0] == 9.0 and again[2] == 4.0 and isinstance(again[1], TaskFailure)
    assert executions(log) == 4
    assert len(list((tmp_path / "cache" / "results").rglob("*.pkl"))) == 2
    # cache=False runs everything
    run_tasks(tasks, workers=0, cache=False)
    assert executions(log) == 7


def test_a_corrupt_cache_file_is_recomputed(tmp_path):
    log = tmp_path / "log"
    tasks = batch([5.0], log)
    run_tasks(tasks, workers=0)
    path = next((tmp_path / "cache" / "results").rglob("*.pkl"))
    assert path.name == f"{tasks[0].key}.pkl" and path.parent.name == tasks[0].key[:2]
    path.write_bytes(b"\x80truncated")
    assert run_tasks(tasks, workers=0) == [25.0] and executions(log) == 2


def test_scheduler_from_argument_env_and_user_config(tmp_path, monkeypatch):
    assert compute.resolve_scheduler() is None
    cfg = tmp_path / "config.toml"
    cfg.write_text('[compute]\nscheduler = "tcp://127.0.0.1:8786"\n')
    monkeypatch.setenv("WEARBENCH_CONFIG", str(cfg))
    assert compute.resolve_scheduler() == "tcp://127.0.0.1:8786"
    monkeypatch.setenv("WEARBENCH_SCHEDULER", "tcp://127.0.0.1:9000")
    assert compute.resolve_scheduler() == "tcp://127.0.0.1:9000"
    assert compute.resolve_scheduler("local") is None
    with pytest.raises(ValueError, match="scheduler = '127.0.0.1:1'.*expected 'local' or a Dask scheduler address"):
        compute.resolve_scheduler("127.0.0.1:1")
    cfg.write_text("[compute\n")
    monkeypatch.delenv("WEARBENCH_SCHEDULER")
    with pytest.raises(ValueError, match="config.toml: not valid TOML"):
        compute.resolve_scheduler()


def test_a_bench_files_scheduler_ranks_below_argument_and_env_above_user_config(tmp_path, monkeypatch):
    from wearbench.bench.load import load_bench, parse_bench, shipped_bench
    from wearbench.bench.schema import BenchError

    text = shipped_bench("slider-crank").read_text()
    path = tmp_path / "bench.toml"
    path.write_text(text + '\n[compute]\nscheduler = "tcp://127.0.0.1:8791"\n')
    bench = load_bench(path)
    assert bench.scheduler == "tcp://127.0.0.1:8791"
    cfg = tmp_path / "config.toml"
    cfg.write_text('[compute]\nscheduler = "tcp://127.0.0.1:8786"\n')
    monkeypatch.setenv("WEARBENCH_CONFIG", str(cfg))
    assert compute.resolve_scheduler(bench=bench) == "tcp://127.0.0.1:8791"  # bench file over user config
    assert compute.resolve_scheduler(bench=load_bench(shipped_bench("slider-crank"))) == "tcp://127.0.0.1:8786"
    local = parse_bench(text + '\n[compute]\nscheduler = "local"\n', path)
    assert compute.resolve_scheduler(bench=local) is None  # "local" in the bench file stops the search
    monkeypatch.setenv("WEARBENCH_SCHEDULER", "tcp://127.0.0.1:9000")
    assert compute.resolve_scheduler(bench=bench) == "tcp://127.0.0.1:9000"  # env over bench file
    assert compute.resolve_scheduler("tcp://127.0.0.1:9001", bench=bench) == "tcp://127.0.0.1:9001"
    # the bench's physics digest ignores where its batches run
    from wearbench.bench.content import bench_key

    assert bench_key(bench) == bench_key(local) == bench_key(load_bench(shipped_bench("slider-crank")))
    for table, key, value in (('scheduler = "10.0.0.5:8786"', "compute.scheduler", "'10.0.0.5:8786'"),
                              ("scheduler = 8786", "compute.scheduler", "8786"),
                              ("workers = 4", "compute.workers", "4")):
        with pytest.raises(BenchError) as err:
            parse_bench(text + f"\n[compute]\n{table}\n", path)
        assert str(err.value).startswith(f"{path}: {key} = {value}: ") and "expected" in str(err.value)


@pytest.fixture(scope="module")
def client():
    before = {p.pid for p in psutil.Process().children(recursive=True)}
    with compute_client(workers=2) as c:
        yield c
    # no orphaned workers or nannies: every process the cluster started is gone (multiprocessing's
    # resource tracker stays with this process by design and ends with it)
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        left = [p for p in psutil.Process().children(recursive=True) if p.pid not in before and p.is_running()
                and p.status() != psutil.STATUS_ZOMBIE and "resource_tracker" not in " ".join(p.cmdline())]
        if not left:
            break
        time.sleep(0.2)
    assert not left, f"processes left after the cluster closed: {left}"


def test_cluster_batch_runs_on_both_workers_and_rerun_is_served_from_cache(client, tmp_path):
    assert len(client.scheduler_info()["workers"]) == 2
    log = tmp_path / "log"
    tasks = batch([1.0, 2.0, 3.0, -4.0, 5.0, 6.0], log, delay=0.2)
    out = run_tasks(tasks)
    assert [out[i] for i in (0, 1, 2, 4, 5)] == [1.0, 4.0, 9.0, 25.0, 36.0]
    assert isinstance(out[3], TaskFailure) and out[3].params["x"] == -4.0
    assert "negative x = -4.0" in out[3].error
    pids = {line.split()[1] for line in log.read_text().splitlines()}
    assert len(pids) == 2 and str(os.getpid()) not in pids  # ran on the two workers
    n = executions(log)
    assert n == 6
    t0 = time.perf_counter()
    ok = batch([1.0, 2.0, 3.0, 5.0, 6.0], log, delay=0.2)
    assert run_tasks(ok) == [1.0, 4.0, 9.0, 25.0, 36.0]
    assert executions(log) == n  # nothing submitted
    assert time.perf_counter() - t0 < 0.5


def test_a_killed_worker_is_survived(client, tmp_path):
    log = tmp_path / "log"
    tasks = batch([float(x) for x in range(1, 9)], log, delay=0.4)
    pids = client.run(os.getpid)
    killed = []

    def kill_one(i, result):
        if not killed:  # mid-batch: one finished, the others queued or running
            pid = next(iter(pids.values()))
            os.kill(pid, signal.SIGKILL)
            killed.append(pid)

    out = run_tasks(tasks, on_result=kill_one)
    assert killed and out == [float(x) ** 2 for x in range(1, 9)]
    assert not psutil.pid_exists(killed[0]) or psutil.Process(killed[0]).status() == psutil.STATUS_ZOMBIE
    client.wait_for_workers(2, timeout=30)  # the nanny restarted it
    assert executions(log) >= 8


def test_ctrl_c_keeps_finished_results_and_the_rest_runs_later(client, tmp_path):
    log = tmp_path / "log"
    tasks = batch([float(x) for x in range(10, 16)], log, delay=0.3)
    first = []

    def interrupt(i, result):
        first.append(i)
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_tasks(tasks, on_result=interrupt)
    assert len(first) == 1
    done_x = tasks[first[0]].kwargs["x"]
    out = run_tasks(tasks)
    assert out == [float(x) ** 2 for x in range(10, 16)]
    ran = [float(line.split()[0]) for line in log.read_text().splitlines()]
    assert ran.count(done_x) == 1  # the finished task came from the cache


def test_a_worker_with_other_model_code_refuses(client, tmp_path, monkeypatch):
    log = tmp_path / "log"
    monkeypatch.setattr(compute, "model_source_digest", lambda: "f" * 64)  # the client's model differs
    out = run_tasks(batch([7.0], log), cache=False)
    assert isinstance(out[0], TaskFailure) and "runs other wearbench model code" in out[0].error
    assert executions(log) == 0
