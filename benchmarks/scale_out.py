"""Scale-out of one batch of simulations on wearbench.model.compute: serial loop, 1 and 2 workers.

The batch: ``--tasks`` sweep runs of the nine-bar bench (the nominal bench and realisations drawn
within its tolerances, 0.3 mm clearance, ``--revolutions`` motor revolutions each), the kind of task
theory ensembles and sweeps submit. Measured in one run:

- wall time of the serial in-process loop (``workers=0``), of a 1-worker and a 2-worker LocalCluster
  (cluster start-up, which includes the numba warm-up on each worker, timed apart);
- speed-up 2 vs 1 worker (target >= 1.7x on 2 cores) and per-task overhead of the 1-worker cluster
  against the serial loop (target < 5 %);
- a rerun of the batch served from the result cache;
- a projection of the wall time for N workers from the measured task time and overhead.

Run: ``nice -n 10 python benchmarks/scale_out.py [--tasks 12] [--revolutions 3]``. Wall times need
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
    """One sweep run; returns its compute time on the worker (s) and the worker's pid."""
    from wearbench.model.sweep import run_point

    t0, c0 = time.perf_counter(), time.process_time()
    rows = run_point(bench, {"clearance": 3e-4}, seed, spec)
    return {"compute_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0, "pid": os.getpid(),
            "rows": len(rows)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tasks", type=int, default=12)
    ap.add_argument("--revolutions", type=float, default=3.0)
    ap.add_argument("--project", type=int, default=800, help="batch size for the projection (4 states x 200)")
    args = ap.parse_args()

    os.environ["WEARBENCH_CACHE"] = tempfile.mkdtemp(prefix="wearbench-scale-out-")
    from wearbench.hardware.bench import load_bench, shipped_bench
    from wearbench.model.compute import Task, compute_client, run_tasks, task_key, usable_cores
    from wearbench.model.compute import _warm_up as warm_up
    from wearbench.model.sweep import Axis, SweepSpec

    bench = load_bench(shipped_bench("ninebar"))
    spec = SweepSpec(axes=(Axis("clearance", (3e-4,)),), revolutions=args.revolutions, settle=0.5)
    seeds = [None, *range(1, args.tasks)]
    tasks = [Task(timed_point, {"bench": bench, "seed": s, "spec": spec}, task_key("scale-out", s, args.revolutions),
                  f"seed={s}") for s in seeds]
    warm_up()  # the serial loop gets its kernels loaded too, like every worker

    rows = []

    def measure(name: str, workers: int) -> dict:
        t0 = time.perf_counter()
        if workers == 0:
            start = 0.0
            t1 = time.perf_counter()
            out = run_tasks(tasks, workers=0, cache=False)
        else:
            with compute_client(workers=workers):
                t1 = time.perf_counter()
                start = t1 - t0
                out = run_tasks(tasks, cache=False)
                t2 = time.perf_counter()
        t2 = time.perf_counter() if workers == 0 else t2
        failed = [r for r in out if not isinstance(r, dict)]
        if failed:
            raise SystemExit(f"{name}: {len(failed)} tasks failed: {failed[0]}")
        compute = sum(r["compute_s"] for r in out)
        row = {"name": name, "workers": workers, "start_s": start, "wall_s": t2 - t1, "compute_s": compute,
               "cpu_s": sum(r["cpu_s"] for r in out), "pids": len({r["pid"] for r in out})}
        rows.append(row)
        return row

    serial = measure("serial loop (workers=0)", 0)
    one = measure("LocalCluster, 1 worker", 1)
    two = measure("LocalCluster, 2 workers", 2)

    # the result cache: fill, then rerun (nothing submitted)
    run_tasks(tasks, workers=0)
    t0 = time.perf_counter()
    run_tasks(tasks, workers=2)
    cached = time.perf_counter() - t0

    n = len(tasks)
    print(f"\nbatch: {n} sweep runs of {bench.name} ({args.revolutions:g} + 0.5 revolutions, realisations), "
          f"usable cores {usable_cores()}, load average {os.getloadavg()[0]:.1f}\n")
    print(f"{'mode':<26} {'start-up s':>10} {'batch wall s':>12} {'sum task s':>10} {'task cpu s':>10} "
          f"{'per task s':>10} {'overhead/task ms':>16} {'processes':>9}")
    for r in rows:
        per = r["wall_s"] / n
        over = (r["wall_s"] * max(1, r["workers"]) - r["compute_s"]) / n
        print(f"{r['name']:<26} {r['start_s']:>10.2f} {r['wall_s']:>12.2f} {r['compute_s']:>10.2f} "
              f"{r['cpu_s']:>10.2f} {per:>10.3f} "
              f"{over * 1e3:>16.1f} {r['pids']:>9}")
    speedup = one["wall_s"] / two["wall_s"]
    overhead = (one["wall_s"] - serial["wall_s"]) / serial["wall_s"]
    # overhead the cluster adds per task: what the 1-worker wall time holds beyond the task compute
    o_task = (one["wall_s"] - one["compute_s"]) / n
    t_task = serial["compute_s"] / n
    print(f"\nspeed-up 2 vs 1 worker: {speedup:.2f}x (target >= 1.7x)")
    print(f"1-worker batch vs serial loop: {overhead * 100:+.1f} % (target < 5 %); dispatch overhead "
          f"{o_task * 1e3:.1f} ms per task")
    print(f"rerun from the result cache (2 workers asked, nothing submitted): {cached:.3f} s for {n} tasks")
    start = two["start_s"]
    print(f"\nprojection, {args.project} tasks of {t_task:.2f} s (+{o_task * 1e3:.0f} ms overhead), "
          f"start-up {start:.1f} s: T(N) = start + ceil(tasks/N) x (task + overhead)")
    print(f"{'workers':>8} {'wall s':>10} {'speed-up':>9}")
    t1 = start + args.project * (t_task + o_task)
    for w in (1, 2, 4, 8, 16, 32, 64, 128):
        tn = start + math.ceil(args.project / w) * (t_task + max(o_task, 0.0))
        print(f"{w:>8} {tn:>10.1f} {t1 / tn:>9.1f}")


if __name__ == "__main__":
    main()
