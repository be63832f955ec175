"""What `wearbench study` costs at full size, from the CPU time of its tasks, and its wall time on N workers.

The study is two batches on the compute layer: (1) every case's wear runs and its before-wear
realisations, (2) the realisations on each wear run's worn surfaces. This script runs one task of
each kind per case in this process, on a fresh seed (so nothing comes from the result cache), and
times it in CPU seconds (``time.process_time``: what the task costs whatever else the machine runs).
From those costs and the task counts of a study size (``StudyConfig``'s defaults, or --wear-runs /
--realisations) it gives the total CPU and the wall time on N workers: each batch scheduled
longest task first onto the first free worker (the tasks are independent; a batch waits for the
previous one), plus the start-up each worker pays once (a first, one-cycle realisation that loads
the compiled kernels, timed apart). One seed per task kind: the 0.1 mm wear runs' cost varies by about +/-30 % between
seeds (84-158 s seen), so read the projection to that.

    nice -n 10 .venv/bin/python -m benchmarks.compute.study_cost [--seed 900001] [--workers 2 8 32 128]
"""

from __future__ import annotations

import argparse
import heapq
import time

from wearbench.bench.load import load_bench, resolve_bench
from wearbench.model.wear_stages import StagePlan
from wearbench.studies.study import StudyConfig, study_realisation, wear_realisation


def makespan(costs: list[float], workers: int) -> float:
    """Wall time of independent tasks of ``costs`` (s) on ``workers``, longest first to the first free."""
    free = [0.0] * workers
    for c in sorted(costs, reverse=True):
        heapq.heapreplace(free, free[0] + c)
    return max(free)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("bench", nargs="?", default="hardware/benches/ninebar.toml")
    ap.add_argument("--seed", type=int, default=900_001, help="the tasks' seed (fresh: not in the cache)")
    ap.add_argument("--wear-runs", type=int, default=None, help="study size (default: StudyConfig's)")
    ap.add_argument("--realisations", type=int, default=None, help="study size (default: StudyConfig's)")
    ap.add_argument("--workers", type=int, nargs="+", default=[2, 8, 32, 128])
    args = ap.parse_args()

    bench = load_bench(resolve_bench(args.bench))
    sizes = {k: v for k, v in (("wear_runs", args.wear_runs), ("realisations", args.realisations)) if v}
    cfg = StudyConfig(plan=StagePlan.from_bench(bench, stages=1), **sizes)
    joints = [j.name for j in bench.clearance_joints]
    t0 = time.process_time()
    case = cfg.wear_case
    study_realisation(bench, {j: case.clearance for j in joints}, None, args.seed, case.speed, 1, 0.0,
                      cfg.output_rate, False)
    startup = time.process_time() - t0
    batch1, batch2, rows = [], [], []
    for case in (cfg.wear_case, *cfg.clearance_cases):
        clear = {j: case.clearance for j in joints}
        t = time.process_time()
        run = wear_realisation(bench, cfg.plan, case, args.seed)
        wear = time.process_time() - t
        t = time.process_time()
        study_realisation(bench, clear, None, args.seed, case.speed, cfg.cycles, cfg.settle, cfg.output_rate, False)
        new = time.process_time() - t
        t = time.process_time()
        study_realisation(bench, clear, run.states[-1][1], args.seed, case.speed, cfg.cycles, cfg.settle,
                          cfg.output_rate, False)
        worn = time.process_time() - t
        batch1 += [wear] * cfg.wear_runs + [new] * cfg.realisations
        batch2 += [worn] * (cfg.wear_runs * case.stages * cfg.per_run)
        rows.append((case.name, case.stages, wear, new, worn))
    total = time.process_time() - t0
    print(f"study of {bench.name}: {cfg.wear_runs} wear runs per case, {cfg.realisations} realisations before wear, "
          f"{cfg.per_run} per wear run and stage after; tasks at seed {args.seed}, CPU s")
    print(f"{'case':<14}{'stages':>7}{'wear run':>10}{'new':>8}{'worn':>8}")
    for name, stages, wear, new, worn in rows:
        print(f"{name:<14}{stages:>7}{wear:>10.1f}{new:>8.1f}{worn:>8.1f}")
    work = sum(batch1) + sum(batch2)
    print(f"\n{len(batch1)} + {len(batch2)} tasks, {work:.0f} CPU s ({work / 60:.1f} min); start-up {startup:.0f} s "
          f"per worker; this script {total:.0f} s")
    print(f"{'workers':>8}{'wall, min':>11}{'batch 1':>9}{'batch 2':>9}{'busy':>7}")
    for n in args.workers:
        a, b = makespan(batch1, n), makespan(batch2, n)
        wall = startup + a + b
        print(f"{n:>8}{wall / 60:>11.1f}{a / 60:>9.1f}{b / 60:>9.1f}{work / (n * wall):>7.0%}")


if __name__ == "__main__":
    main()
