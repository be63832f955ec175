"""Do the ensembles' few settled cycles stand for a long session's later cycles?

Each ensemble realisation keeps 8 cycles after 2 settling revolutions from a random start; a lab
records minutes. If the clearance dynamics drifted over tens of revolutions (a journal slowly
finding another regime in a worn pit), later windows of a long session would leave the ensemble.
This simulates realisations of the test bed's 0.3 mm states (seeds the shipped ensembles never
use) for ``--cycles`` revolutions, identifies every 10-cycle window against the shipped ensembles
and prints the posterior and consistency p-value of the true state per window, and their means
over the first and the last two windows.

    .venv/bin/python -m benchmarks.validation.long_sessions [--draws 4] [--cycles 60]
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np
from wearbench.compute.options import QUIET


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=4, help="realisations per state (4)")
    ap.add_argument("--cycles", type=int, default=60, help="cycles per realisation (60)")
    ap.add_argument("--window", type=int, default=10, help="cycles per identified window (10)")
    args = ap.parse_args()

    from wearbench.bench.load import load_bench, shipped_bench
    from wearbench.compute import Task, run_tasks, task_key
    from wearbench.validation.inference.ensemble import (
        EnsembleSettings,
        build_ensembles,
        realisation_summary,
    )
    from wearbench.validation.inference.identify import fit_states, identify_features
    from wearbench.validation.measurement.features import CycleFeatures

    bench = load_bench(shipped_bench("ninebar-testbed"))
    states = [s for s in bench.states if s.clearances and max(s.clearances.values()) < 0.5e-3]
    settings = EnsembleSettings()
    models = fit_states(build_ensembles(bench, bench.states, settings=settings, compute=QUIET))
    jobs = [(s, 1000 + k) for s in states for k in range(args.draws)]
    long = replace(settings, cycles=args.cycles)  # an ensemble realisation, only longer
    results = run_tasks([Task(realisation_summary, {"bench": bench, "state": s, "seed": seed, "speed": bench.speed,
                                                    "settings": long},
                              task_key("long-realisation", s.name, seed, args.cycles), f"{s.name} #{seed}")
                         for s, seed in jobs], progress="long realisations")
    results = [r["features"] for r in results]
    starts = range(0, args.cycles - args.window + 1, args.window)
    print(f"\n{len(jobs)} realisations of {args.cycles} cycles; p of the true state per {args.window}-cycle window "
          "(consistency p-value in brackets)")
    first, last = [], []
    for (s, seed), x in zip(jobs, results, strict=True):
        rows = [identify_features(CycleFeatures(settings.features, x[a:a + args.window], np.zeros(args.window)),
                                  models) for a in starts]
        p = [r.posterior[s.name] for r in rows]
        print(f"  {s.name:20s} seed {seed}  " + "  ".join(f"{v:.2f} ({r.p_value[s.name]:.2f})" for v, r in zip(p, rows)))
        first += p[:2]
        last += p[-2:]
    print(f"\nmean p of the true state: first two windows {np.mean(first):.3f}, last two windows {np.mean(last):.3f}")


if __name__ == "__main__":
    main()
