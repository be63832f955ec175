"""Scale-out of one batch of simulations on wearbench.compute: serial loop, 1 and 2 workers.

The batch: ``--tasks`` sweep runs of the nine-bar bench (the nominal bench and realisations drawn
within its tolerances, 0.3 mm clearance, ``--revolutions`` motor revolutions each), the kind of task
theory ensembles and sweeps submit. Measured in one run:

- wall time of the serial in-process loop (``workers=0``), of a 1-worker LocalCluster at Dask's
  default settings and as wearbench configures it (``cluster.LEAN_LOCAL``: fewer timers), and of a
  2-worker LocalCluster (cluster start-up, which includes the numba warm-up on each worker, timed
  apart);
- speed-up 2 vs 1 worker (target >= 1.7x on 2 cores) and overhead of the 1-worker cluster against
  the serial loop (target < 5 %), in wall time and in CPU time (tasks + client + scheduler +
  worker bookkeeping; CPU time holds on a machine that other work keeps busy, wall time does not).
  The serial loop runs before and after the 1-worker runs: their mean is the reference, their
  difference how much the machine drifted meanwhile;
- where the 1-worker cluster's CPU goes: its background CPU while idle (% of one core: client,
  scheduler and nanny in this process, the worker) and the CPU per task of a batch of no-op tasks;
- a rerun of the batch served from the result cache;
- a projection of the wall time for N idle workers from the measured task CPU time and overhead
  (serial speed-up is the serial loop's task time over T(N), so it includes the start-up).

Run: ``nice -n 10 python -m benchmarks.compute.scale_out [--tasks 12] [--revolutions 10]``. Wall times need
idle cores: the load average is printed with the table; "task cpu s" (CPU time inside the tasks)
is what the tasks cost whatever else the machine runs.
"""

from __future__ import annotations

import argparse
import math
import os
import tempfile
import time


def timed_point(bench, seed, spec) -> dict:
    """One sweep run; returns its wall and CPU time (this thread only: a worker's own background
    threads count as the cluster's CPU, not the task's) and the worker's pid."""
    from wearbench.studies.sweep import run_point

    t0, c0 = time.perf_counter(), time.thread_time()
    rows = run_point(bench, {"clearance": 3e-4}, seed, spec)
    return {"compute_s": time.perf_counter() - t0, "cpu_s": time.thread_time() - c0, "pid": os.getpid(),
            "rows": len(rows)}


def noop(i: int) -> int:
    """A task that does nothing: what remains is the cluster's cost of one task."""
    return i


def _burn(n: int) -> float:
    """A pure-Python CPU loop; returns its wall time (s)."""
    t0, x = time.perf_counter(), 0
    for i in range(n):
        x += i
    return time.perf_counter() - t0


def machine_capacity(n: int = 10_000_000) -> float:
    """Cores this machine gives two processes right now: 2 x (one loop alone) / (two loops at once).
    A control without Dask: on a machine that other work keeps busy it is below 2, and no
    scheduler can beat it."""
    import multiprocessing

    with multiprocessing.get_context("spawn").Pool(2) as pool:
        pool.map(_burn, [1000, 1000], chunksize=1)
        t0 = time.perf_counter()
        pool.map(_burn, [n])
        one = time.perf_counter() - t0
        t0 = time.perf_counter()
        pool.map(_burn, [n, n], chunksize=1)
        two = time.perf_counter() - t0
    return 2 * one / two


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tasks", type=int, default=12)
    ap.add_argument("--revolutions", type=float, default=10.0)
    ap.add_argument("--idle", type=float, default=5.0, help="seconds the idle 1-worker cluster is watched")
    ap.add_argument("--noops", type=int, default=200, help="no-op tasks for the per-task cost")
    ap.add_argument("--project", type=int, default=800, help="batch size for the projection (4 states x 200)")
    args = ap.parse_args()

    os.environ["WEARBENCH_CACHE"] = tempfile.mkdtemp(prefix="wearbench-scale-out-")
    from wearbench.bench.load import load_bench, shipped_bench
    from wearbench.compute import Task, cluster, compute_client, run_tasks, task_key
    from wearbench.compute.cluster import usable_cores, warm_up
    from wearbench.studies.sweep import Axis, SweepSpec

    bench = load_bench(shipped_bench("ninebar"))
    spec = SweepSpec(axes=(Axis("clearance", (3e-4,)),), revolutions=args.revolutions, settle=0.5)
    seeds = [None, *range(1, args.tasks)]
    tasks = [Task(timed_point, {"bench": bench, "seed": s, "spec": spec}, task_key("scale-out", s, args.revolutions),
                  f"seed={s}") for s in seeds]
    warm_up()  # the serial loop gets its kernels loaded too, like every worker

    rows, breakdown = [], []

    def worker_cpu(client) -> float:
        return sum(client.run(_process_cpu).values())

    def cluster_cpu(client) -> float:
        """CPU (s) of this process (client, scheduler, nannies) and of every worker."""
        return time.process_time() + worker_cpu(client)

    def measure(name: str, workers: int, dask_defaults: bool = False) -> dict:
        t0 = time.perf_counter()
        if workers == 0:
            start, c0, w0 = 0.0, time.process_time(), 0.0
            t1 = time.perf_counter()
            out = run_tasks(tasks, workers=0, cache=False)
            t2, c1, w1 = time.perf_counter(), time.process_time(), 0.0
        else:
            lean, cluster.LEAN_LOCAL = cluster.LEAN_LOCAL, ({} if dask_defaults else cluster.LEAN_LOCAL)
            try:
                with compute_client(workers=workers) as client:
                    t1 = time.perf_counter()
                    start, c0, w0 = t1 - t0, time.process_time(), worker_cpu(client)
                    out = run_tasks(tasks, cache=False)
                    t2, c1, w1 = time.perf_counter(), time.process_time(), worker_cpu(client)
                    if workers == 1:  # where the CPU goes: background while idle, and per no-op task
                        a, ta = cluster_cpu(client), time.perf_counter()
                        time.sleep(args.idle)
                        idle = (cluster_cpu(client) - a) / (time.perf_counter() - ta)
                        noops = [Task(noop, {"i": i}, task_key("noop", i), "noop") for i in range(args.noops)]
                        a = cluster_cpu(client)
                        run_tasks(noops, cache=False)
                        per_task = (cluster_cpu(client) - a) / args.noops
                        breakdown.append((name, idle, per_task))
            finally:
                cluster.LEAN_LOCAL = lean
        failed = [r for r in out if not isinstance(r, dict)]
        if failed:
            raise SystemExit(f"{name}: {len(failed)} tasks failed: {failed[0]}")
        task_cpu = sum(r["cpu_s"] for r in out)
        # CPU spent on anything but the tasks: this process (client, and the scheduler and nannies
        # of a LocalCluster, which run here) plus the workers' own bookkeeping
        over_cpu = (c1 - c0) + (w1 - w0) - task_cpu
        row = {"name": name, "workers": workers, "start_s": start, "wall_s": t2 - t1,
               "compute_s": sum(r["compute_s"] for r in out), "cpu_s": task_cpu, "over_cpu_s": over_cpu,
               "pids": len({r["pid"] for r in out})}
        rows.append(row)
        return row

    capacity = [machine_capacity()]
    serials = [measure("serial loop (workers=0)", 0)]
    default = measure("1 worker, Dask defaults", 1, dask_defaults=True)
    one = measure("1 worker (wearbench)", 1)
    serials.append(measure("serial loop, again", 0))  # brackets the 1-worker runs: drift of the load
    serial = {k: (serials[0][k] + serials[1][k]) / 2 for k in ("wall_s", "cpu_s", "over_cpu_s")}
    capacity.append(machine_capacity())
    two = measure("2 workers (wearbench)", 2)
    capacity.append(machine_capacity())

    # the result cache: fill, then rerun (nothing submitted)
    run_tasks(tasks, workers=0)
    t0 = time.perf_counter()
    run_tasks(tasks, workers=2)
    cached = time.perf_counter() - t0

    n = len(tasks)
    print(f"\nbatch: {n} sweep runs of {bench.name} ({args.revolutions:g} + 0.5 revolutions, realisations), "
          f"usable cores {usable_cores()}, load average {os.getloadavg()[0]:.1f}\n")
    print(f"{'mode':<26} {'start-up s':>10} {'batch wall s':>12} {'task wall s':>11} {'task cpu s':>10} "
          f"{'other cpu s':>11} {'other cpu/task ms':>17} {'processes':>9}")
    for r in rows:
        print(f"{r['name']:<26} {r['start_s']:>10.2f} {r['wall_s']:>12.2f} {r['compute_s']:>11.2f} "
              f"{r['cpu_s']:>10.2f} {r['over_cpu_s']:>11.2f} {r['over_cpu_s'] / n * 1e3:>17.1f} {r['pids']:>9}")
    speedup = one["wall_s"] / two["wall_s"]
    print(f"\nspeed-up 2 vs 1 worker (wall): {speedup:.2f}x (target >= 1.7x); the machine gave two plain "
          f"processes {min(capacity):.2f}-{max(capacity):.2f} cores around these runs (control, no Dask)")
    spread = abs(serials[1]["wall_s"] - serials[0]["wall_s"]) / serial["wall_s"]
    print(f"against the mean of the two serial loops (which differ by {spread * 100:.1f} % in wall time, "
          f"{abs(serials[1]['cpu_s'] - serials[0]['cpu_s']) / serial['cpu_s'] * 100:.1f} % in task CPU):")
    for r in (default, one):
        wall_over = (r["wall_s"] - serial["wall_s"]) / serial["wall_s"]
        cpu_over = (r["cpu_s"] + r["over_cpu_s"]) / (serial["cpu_s"] + serial["over_cpu_s"]) - 1
        print(f"  {r['name']}: wall {wall_over * 100:+.1f} %, CPU {cpu_over * 100:+.1f} % (target < 5 %); "
              f"cluster CPU alone {r['over_cpu_s'] / serial['cpu_s'] * 100:+.1f} % of the tasks' CPU")
    print("where a 1-worker cluster's CPU goes (client + scheduler + nanny + worker):")
    for name, idle, per_task in breakdown:
        print(f"  {name:<26} idle {idle * 100:.1f} % of a core; {per_task * 1e3:.1f} ms per no-op task "
              f"({args.noops} tasks)")
    print(f"rerun from the result cache (2 workers asked, nothing submitted): {cached:.3f} s for {n} tasks")
    # projection from CPU: a task costs its CPU time on an idle core, plus the cluster's CPU per task
    t_task = serial["cpu_s"] / n
    o_task = max(one["over_cpu_s"], 0.0) / n
    start = two["start_s"]
    print(f"\nprojection, {args.project} tasks of {t_task:.2f} s CPU (+{o_task * 1e3:.0f} ms cluster CPU per task), "
          f"start-up {start:.1f} s:\nT(N) = start + ceil(tasks / N) x (task + overhead), idle cores assumed")
    print(f"{'workers':>8} {'wall s':>10} {'speed-up':>9}")
    t1 = args.project * t_task
    for w in (1, 2, 4, 8, 16, 32, 64, 128):
        tn = start + math.ceil(args.project / w) * (t_task + o_task)
        print(f"{w:>8} {tn:>10.1f} {t1 / tn:>9.1f}")


def _process_cpu() -> float:
    """CPU time (s) of the calling process, all threads (run on each worker)."""
    return time.process_time()


if __name__ == "__main__":
    main()
