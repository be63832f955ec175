"""How much a rebuild of the test bed's ensembles moves the identification: temperature and Brier score
over rebuilds with other realisation seeds, at several ensemble sizes.

Which M realisations an ensemble holds is itself a draw: a rebuild with other seeds moves the fitted
calibration temperature and the accuracy of every verdict. Issue 27's mark: the temperature's spread
(max - min) over three rebuilds <= 0.1 at the shipped size. Each rebuild is scored on the same
non-twin sessions (the identification benchmark's drawn truths, on drawn sensor mounts unless
``--default-path``; their seeds never meet the ensembles'). Realisations are cached by seed, so the
sizes of one rebuild share their runs (M = 16 is the first half of M = 32).

    .venv/bin/python benchmarks/ensemble_rebuilds.py [--sizes 16,32] [--seeds 1,1001,2001] [--draws 3]
        [--cache ~/.cache/wearbench] [--sessions DIR] [--workers 2]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="16,32", help="realisations per state, comma separated (16,32)")
    ap.add_argument("--seeds", default="1,1001,2001", help="first realisation seed of each rebuild (1,1001,2001)")
    ap.add_argument("--ensemble-cycles", type=int, default=8, help="cycles per realisation (8)")
    ap.add_argument("--draws", type=int, default=3, help="truth draws per state (3)")
    ap.add_argument("--cycles", type=int, default=20, help="cycles per truth session (20)")
    ap.add_argument("--seed", type=int, default=9000, help="first truth seed (9000, the identification benchmark's)")
    ap.add_argument("--default-path", action="store_true", help="truths on the emulator's default sensor path")
    ap.add_argument("--sessions", help="folder to keep (and reuse) the recorded sessions")
    ap.add_argument("--cache", help="cache folder (default: a fresh one)")
    ap.add_argument("--workers", type=int, default=None)
    args = ap.parse_args()
    os.environ["WEARBENCH_CACHE"] = args.cache or tempfile.mkdtemp(prefix="wearbench-rebuilds-")

    from wearbench.bench.load import load_bench, shipped_bench
    from wearbench.compute import compute_client
    from wearbench.testing.truths import record_state, slug, truth_revolutions
    from wearbench.validation import load_session
    from wearbench.validation.assess import session_features
    from wearbench.validation.ensemble import EnsembleSettings, build_ensembles
    from wearbench.validation.identify import IdentifyOptions, fit_states, identify_features

    bench = load_bench(shipped_bench("ninebar-testbed"))
    states, names = bench.states, [s.name for s in bench.states]
    sizes = sorted(int(v) for v in args.sizes.split(","))
    seeds = [int(v) for v in args.seeds.split(",")]
    out = Path(args.sessions or tempfile.mkdtemp(prefix="wearbench-rebuilds-sessions-"))
    out.mkdir(parents=True, exist_ok=True)
    emulator = {} if args.default_path else {"accelerometer": {"spread": {}}}  # the emulator's drawn mounts
    truths = [(s, args.seed + 100 * k + d) for k, s in enumerate(states) for d in range(args.draws)]
    paths = []
    for s, seed in truths:
        paths.append(out / f"{'default' if args.default_path else 'drawn'}_{slug(s.name)}_{seed}.mcap")
        if not paths[-1].exists():
            record_state(bench, s, seed, paths[-1], backend="sim", cycles=args.cycles + 1,
                         revolutions=truth_revolutions(args.cycles + 1), **emulator)
    spec = EnsembleSettings().features
    feats = [session_features(load_session(p), spec) for p in paths]
    truth_names = [s.name for s, _ in truths]

    rows = []
    with compute_client(workers=args.workers):
        for seed in seeds:
            for m in sizes:
                settings = EnsembleSettings(realisations=m, cycles=args.ensemble_cycles, seed=seed)
                t0 = time.perf_counter()
                ensembles = build_ensembles(bench, states, settings=settings, cache=True, shipped=False,
                                            progress=f"rebuild seed {seed} M {m}")
                built = time.perf_counter() - t0
                models = fit_states(ensembles, IdentifyOptions())
                ids = [identify_features(f, models) for f in feats]
                brier = np.mean([sum((r.posterior[s] - (s == t)) ** 2 for s in names)
                                 for r, t in zip(ids, truth_names, strict=True)])
                top1 = np.mean([max(r.posterior, key=r.posterior.get) == t for r, t in zip(ids, truth_names, strict=True)])
                right = np.mean([r.verdict == t for r, t in zip(ids, truth_names, strict=True)])
                wrong = np.mean([r.verdict in names and r.verdict != t for r, t in zip(ids, truth_names, strict=True)])
                rows.append((m, seed, models.temperature, brier, top1, right, wrong, built))

    print(f"\nrebuilds of the test bed's ensembles ({args.ensemble_cycles} cycles per realisation), scored on "
          f"{len(feats)} {'default-path' if args.default_path else 'drawn-mount'} sessions of {args.cycles} cycles")
    print("   M   first seed   temperature   Brier   top-1   named right   named wrong   build (s, cached runs reused)")
    for m, seed, temp, brier, top1, right, wrong, built in rows:
        print(f"{m:4d}   {seed:10d}   {temp:11.2f}   {brier:5.3f}   {top1:5.2f}   {right:11.2f}   {wrong:11.2f}   "
              f"{built:6.0f}")
    print("\nspread over rebuilds (max - min):")
    for m in sizes:
        sub = [r for r in rows if r[0] == m]
        temps, briers = [r[2] for r in sub], [r[3] for r in sub]
        print(f"  M = {m:3d}: temperature {min(temps):.2f}-{max(temps):.2f} (spread {np.ptp(temps):.2f}; mark <= 0.1)"
              f"   Brier {min(briers):.3f}-{max(briers):.3f} (spread {np.ptp(briers):.3f})")


if __name__ == "__main__":
    main()
