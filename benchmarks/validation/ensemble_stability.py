"""Ensemble stability over rebuilds: at how many realisations the test bed's calibration temperature
and Brier score stop moving when its four state ensembles are rebuilt with other seeds (issue 27 item 4).

Which M realisations an ensemble holds is itself a draw: a rebuild with another first seed moves the
calibration temperature (fitted by ``identify.fit_states`` on the ensembles' held-out realisations)
and every verdict. For each size M and first seed this builds the shipped ensembles' settings
(``EnsembleSettings()`` but ``realisations`` and ``seed``; checked against the shipped file's) on the
compute layer, then judges ONE fixed set of non-twin sessions with every build, so only the build
changes between rows: the identification benchmark's truths (``benchmarks/validation/identify.py``'s naming, so
``identify.py --sessions DIR --seed S`` shares the files), each recorded on a drawn sensor mount and on
the emulator's default path; their seeds (from 46000) never meet the ensembles' (first seed + i).
Issue 27's mark: the temperature's spread (max - min) over three rebuilds <= 0.1.

Realisations are cached by seed in the result cache (``$WEARBENCH_CACHE``, default ~/.cache/wearbench),
so M = 32 is the first half of M = 64 of the same first seed and a rerun only judges again. Each
build's wall and CPU time (workers and this process) count only the realisations it simulated (the
"new" column); the cold cost of a size is extrapolated from the CPU per realisation. Builds are saved
to --out (a scratch folder outside the repository; never the shipped ensembles' folder).

    nice -n 15 .venv/bin/python -m benchmarks.validation.ensemble_stability [--sizes 16,32,64] [--seeds 1,1001,2001]
        [--draws 5] [--cycles 20] [--seed 46000] [--sessions DIR] [--out DIR] [--workers 2]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from wearbench.validation.inference.verdicts import spread, stable_size, verdict_scores

MARK = 0.1  # issue 27: temperature spread over three rebuilds


def print_row(r: dict) -> None:
    """One build's line of the table."""
    print(f"{r['m']:4d}  {r['seed']!s:>7s} {r['new']:4d}  {r['wall']:6.0f}  {r['cpu']:5.0f}   {r['temperature']:11.3f}   "
          f"{r['brier']:5.3f} ({r['brier_drawn']:5.3f} / {r['brier_default']:5.3f})   {r['top1']:5.2f}  "
          f"{r['right']:11.2f}  {r['wrong']:11.2f}  {r['fit_cpu']:9.1f}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="32,64", help="realisations per state, comma separated (32,64)")
    ap.add_argument("--seeds", default="1,1001,2001", help="first realisation seed of each rebuild (1,1001,2001)")
    ap.add_argument("--draws", type=int, default=5, help="truth draws per state, each on both sensor paths (5: 40 sessions)")
    ap.add_argument("--cycles", type=int, default=20, help="cycles per session (20)")
    ap.add_argument("--seed", type=int, default=46000, help="first truth seed (46000)")
    ap.add_argument("--sessions", help="folder of the recorded sessions (kept; a session there is judged, not re-recorded)")
    ap.add_argument("--out", help="folder for each build's .npz (default: a fresh scratch folder)")
    ap.add_argument("--workers", type=int, default=2, help="compute workers (2)")
    args = ap.parse_args()

    from wearbench.bench.load import load_bench, shipped_bench
    from wearbench.compute import Task, compute_client, run_tasks, task_key
    from wearbench.compute.task_cache import MISSING, cache_load
    from wearbench.synthetic.truths import prepare_truth, record_state, slug, truth_revolutions
    from wearbench.validation import load_session
    from wearbench.validation.inference import artefacts
    from wearbench.validation.inference.ensemble import (
        EnsembleSettings,
        build_ensembles,
        ensembles_key,
        load_ensembles,
        realisation_keys,
        save_ensembles,
    )
    from wearbench.validation.inference.identify import (
        IdentifyOptions,
        fit_states,
        identify_features,
    )

    bench = load_bench(shipped_bench("ninebar-testbed"))
    states, names = bench.states, [s.name for s in bench.states]
    sizes = sorted(int(v) for v in args.sizes.split(","))
    seeds = [int(v) for v in args.seeds.split(",")]
    shipped_path = artefacts.shipped_path("ensembles", bench.name)
    out = Path(args.out or tempfile.mkdtemp(prefix="wearbench-stability-"))
    if out.resolve() == shipped_path.parent.resolve():
        raise SystemExit(f"--out {out}: the shipped ensembles' folder; give a scratch folder")
    out.mkdir(parents=True, exist_ok=True)
    shipped = load_ensembles(shipped_path)
    shipped_settings = next(iter(shipped.values())).settings
    as_shipped = EnsembleSettings(realisations=shipped_settings.realisations, seed=shipped_settings.seed)
    if as_shipped != shipped_settings:
        raise SystemExit(f"{shipped_path}: built with settings {shipped_settings}, not EnsembleSettings()'s "
                         "but its size and seed; this benchmark rebuilds with EnsembleSettings()'s")

    folder = Path(args.sessions or tempfile.mkdtemp(prefix="wearbench-stability-sessions-"))
    folder.mkdir(parents=True, exist_ok=True)
    truths = [(s, args.seed + 100 * k + d) for k, s in enumerate(states) for d in range(args.draws)]
    # drawn: SensorSpread's mounts without cross-axis (the sessions its README table was measured on;
    # benchmarks/validation/identify.py --cross-axis off, whose "_drawn" file names these share)
    kinds = {"drawn": {"accelerometer": {"spread": {"cross_axis": [0.0, 0.0]}}}, "default": {}}
    revolutions = truth_revolutions(bench, args.cycles + 1)
    # (kind, truth state, its seed, file): benchmarks/validation/identify.py's file names
    sessions = [(kind, s, seed, folder / f"{slug(s.name)}_{seed}{'_drawn' if kind == 'drawn' else ''}_{args.cycles}.mcap")
                for kind in kinds for s, seed in truths]

    rows = []
    with compute_client(workers=args.workers) as client:
        def cpu() -> float:
            """CPU (s) of this process (client, scheduler, nannies) and of every worker."""
            return time.process_time() + (sum(client.run(time.process_time).values()) if client else 0.0)

        todo = {(s.name, seed): (s, seed) for _, s, seed, path in sessions if not path.exists()}
        run_tasks([Task(prepare_truth, {"bench": bench, "state": s, "seed": seed, "revolutions": revolutions},
                        task_key("bench-truth", s.name, seed), f"truth {s.name} {seed}") for s, seed in todo.values()],
                  cache=False, progress="emulator truths")
        for kind, s, seed, path in sessions:
            if not path.exists():  # one cycle more than analysed: cycles are cut at crank angle 0
                record_state(bench, s, seed, path, backend="sim", cycles=args.cycles + 1, revolutions=revolutions,
                             **kinds[kind])
        spec = EnsembleSettings().features
        feats = [load_session(p).features(spec) for _, _, _, p in sessions]

        def judge(ensembles) -> dict:
            t0 = time.process_time()
            models = fit_states(ensembles, IdentifyOptions())
            results = [identify_features(f, models) for f in feats]
            row = {"temperature": models.temperature, "fit_cpu": time.process_time() - t0}
            for kind in (None, *kinds):
                mine = [i for i, (k, _, _, _) in enumerate(sessions) if kind in (None, k)]
                score = verdict_scores([results[i] for i in mine], [sessions[i][1].name for i in mine], names)
                row.update({f"{key}_{kind}" if kind else key: v for key, v in score.items()})
            return row

        n_drawn = sum(k == "drawn" for k, _, _, _ in sessions)
        print(f"\nrebuilds of the test bed's four ensembles (EnsembleSettings() but M and the first seed; "
              f"{args.workers} workers), judged on the same {len(sessions)} sessions of {args.cycles} cycles "
              f"({n_drawn} on drawn mounts, {len(sessions) - n_drawn} on the default path; truth seeds from "
              f"{args.seed}); new: realisations simulated (not in the result cache), wall and CPU their cost")
        print("   M     seed  new  wall s  CPU s   temperature   Brier (drawn / default)   top-1  named right  "
              "named wrong  fit CPU s", flush=True)
        print_row({"m": shipped_settings.realisations, "seed": "shipped", "new": 0, "wall": 0.0, "cpu": 0.0,
                   **judge(shipped)})
        for m in sizes:
            for seed in seeds:
                settings = EnsembleSettings(realisations=m, seed=seed)
                new = sum(cache_load(k) is MISSING for k in realisation_keys(bench, states, bench.speed, settings))
                t0, c0 = time.perf_counter(), cpu()
                ensembles = build_ensembles(bench, states, settings=settings, cache=True, shipped=False,
                                            label=f"M {m} seed {seed}")
                wall, used = time.perf_counter() - t0, cpu() - c0
                save_ensembles(ensembles, out / f"{bench.name}-M{m}-seed{seed}.npz", bench=bench, states=states,
                               key=ensembles_key(bench, states, bench.speed, settings))
                rows.append({"m": m, "seed": seed, "new": new, "wall": wall, "cpu": used, **judge(ensembles)})
                print_row(rows[-1])

    simulated = sum(r["new"] for r in rows)
    per = sum(r["cpu"] for r in rows) / simulated if simulated else float("nan")
    load = os.getloadavg()[0]
    print(f"\nCPU per realisation (the {simulated} simulated in this run; load average {load:.1f}): {per:.1f} s")
    print("spread over rebuilds (max - min); the temperature's floor is 1 (the held-out log loss wants no tempering):")
    spreads = {}
    for m in sizes:
        sub = [r for r in rows if r["m"] == m]
        spreads[m] = spread([r["temperature"] for r in sub])
        temps = " / ".join(f"{r['temperature']:.2f}" for r in sub)
        print(f"  M = {m:3d}: temperature {temps} (spread {spreads[m]:.3f}; mark <= {MARK})   Brier spread "
              f"{spread([r['brier'] for r in sub]):.3f} (drawn {spread([r['brier_drawn'] for r in sub]):.3f}, default "
              f"{spread([r['brier_default'] for r in sub]):.3f})   top-1 spread {spread([r['top1'] for r in sub]):.2f}"
              f"   cold build {4 * m * per:.0f} s CPU, about {4 * m * per / args.workers / 60:.1f} min on "
              f"{args.workers} idle cores")
    at = stable_size(spreads)
    print(f"temperature spread <= {MARK} from M = {at} on" if at else
          f"temperature spread <= {MARK} at none of the sizes measured")
    print(f"builds saved in {out}; sessions in {folder}")


if __name__ == "__main__":
    main()
