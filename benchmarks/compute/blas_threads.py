"""What one BLAS thread per process saves: the inference a command runs, with numpy's and scipy's
default thread teams against ``wearbench.compute.threads.one_blas_thread``.

The work is what ``identify`` and ``estimate`` compute once per bench and speed on the test bed's
shipped artefacts: the state statistics with their held-out nulls and every state's window theory
(``fit_states`` and ``window_theory`` on the shipped ensembles), and the estimator's fit
(``fit_estimator`` on the shipped estimator). Nothing is simulated and nothing comes from the
result cache. Each setting runs in fresh processes, alone and as two at once (two commands, or the
test suite's two workers, on the same cores); each reports its wall time, its CPU time (user and
system, every thread) and a digest of what it computed, which must not depend on the setting beyond
rounding (the largest relative difference is printed).

    python -m benchmarks.compute.blas_threads [--repeat 1] [--json docs/results/data/blas-threads.json]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import subprocess
import sys
import time

import numpy as np

from benchmarks.result_json import Run, column, table, write_result

BENCH = "ninebar-testbed"
SETTINGS = {"default": "numpy's and scipy's default BLAS threads", "one": "one_blas_thread()"}


def work() -> dict:
    """The inference on the shipped artefacts, in this process; its times and a summary of its output."""
    from wearbench.bench.load import load_bench, shipped_bench
    from wearbench.validation.comparison.windows import WindowOptions, window_theory
    from wearbench.validation.estimation.estimate import fit_estimator, load_estimator
    from wearbench.validation.inference.artefacts import shipped_path
    from wearbench.validation.inference.ensemble import load_ensembles
    from wearbench.validation.inference.identify import IdentifyOptions, fit_states

    bench = load_bench(shipped_bench(BENCH))
    ensembles = load_ensembles(shipped_path("ensembles", BENCH))
    estimator = load_estimator(shipped_path("estimator", BENCH))
    wall, cpu = time.monotonic(), time.process_time()
    options = WindowOptions()
    models = fit_states(ensembles, IdentifyOptions(), window_cycles=options.cycles)
    crank = next(iter(ensembles.values())).speed * bench.encoder_driver.ratio
    theories = [window_theory(e, crank_speed=crank, models=models, options=options) for e in ensembles.values()]
    fitted = fit_estimator(estimator)
    out = [models.temperature, *(float(np.sum(s.within + s.between)) for s in models.stats.values()),
           *(float(np.sum(t.null["features"])) for t in theories), fitted.temperature,
           float(np.sum(fitted.grid_mean)), float(np.sum(fitted.discrepancy))]
    return {"wall": time.monotonic() - wall, "cpu": time.process_time() - cpu, "values": out}


def child(setting: str) -> None:
    from wearbench.compute.threads import one_blas_thread

    with one_blas_thread() if setting == "one" else contextlib.nullcontext():
        print(json.dumps(work()))


def run(setting: str, processes: int) -> list[dict]:
    """``processes`` children of ``setting`` started together; their results."""
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")}
    procs = [subprocess.Popen([sys.executable, "-m", "benchmarks.compute.blas_threads", "--child", setting],
                              stdout=subprocess.PIPE, text=True, env=env) for _ in range(processes)]
    out = []
    for p in procs:
        stdout, _ = p.communicate()
        if p.returncode != 0:
            raise SystemExit(f"blas_threads: the {setting} child failed (exit {p.returncode})")
        out.append(json.loads(stdout.strip().splitlines()[-1]))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=1, help="runs of each setting and process count (default 1)")
    ap.add_argument("--json", help="write the result (schema wearbench-result/1) to this path")
    ap.add_argument("--child", choices=tuple(SETTINGS), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(args.child)
        return
    clock = Run()
    rows, values, by = [], {}, {}
    for processes in (1, 2):
        for _ in range(args.repeat):
            for setting in SETTINGS:
                results = run(setting, processes)
                by.setdefault((setting, processes), []).extend(results)
                values.setdefault(setting, results[0]["values"])
    mean = {k: (float(np.mean([r["wall"] for r in v])), float(np.mean([r["cpu"] for r in v]))) for k, v in by.items()}
    for (setting, processes), (wall, cpu) in mean.items():
        base_wall, base_cpu = mean[("default", processes)]
        rows.append([SETTINGS[setting], processes, wall, cpu, cpu / base_cpu, wall / base_wall])
    a, b = np.asarray(values["default"]), np.asarray(values["one"])
    rel = float(np.max(np.abs(a - b) / np.maximum(np.abs(a), 1e-300)))
    cols = [column("BLAS threads"), column("processes at once"), column("wall per process", "s", ".1f"),
            column("CPU per process", "s", ".1f"), column("CPU against default", None, ".2f"),
            column("wall against default", None, ".2f")]
    print(f"{'setting':<42} {'procs':>5} {'wall s':>8} {'CPU s':>8} {'CPU x':>6} {'wall x':>6}")
    for r in rows:
        print(f"{r[0]:<42} {r[1]:>5} {r[2]:>8.1f} {r[3]:>8.1f} {r[4]:>6.2f} {r[5]:>6.2f}")
    print(f"largest relative difference of the outputs between the settings: {rel:.1e}")
    if args.json:
        alone, two = (next(r for r in rows if r[0] == SETTINGS["one"] and r[1] == n) for n in (1, 2))
        findings = [(f"With one BLAS thread the inference costs {alone[4]:.2f}x the CPU of the default alone "
                     f"({alone[5]:.2f}x the wall time), and {two[4]:.2f}x the CPU with two processes at once "
                     f"({two[5]:.2f}x the wall time), on {os.cpu_count()} cores."),
                    f"The outputs differ between the settings by at most {rel:.1e} (relative)."]
        note = ("Each row's processes start together in fresh interpreters; their times exclude the imports "
                "and the loading of the artefacts.")
        write_result(args.json, question="What does one BLAS thread per process save?", script=__file__,
                     tables=[table("the inference of identify and estimate on the test bed's shipped artefacts",
                                   cols, rows, "mean over the processes and repeats of each row")],
                     seeds={}, findings=findings, run=clock, notes=[note])


if __name__ == "__main__":
    main()
