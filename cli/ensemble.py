"""`wearbench ensemble`: build (or refresh) the theory ensembles of a bench's candidate states.

Identification builds ensembles on demand and caches them; this command builds them ahead of time
(e.g. on a cluster, ``--scheduler``) and saves them to one file that ``identify --ensembles`` reads.
"""

from __future__ import annotations

import argparse

from wearbench.cli.compute import add_compute_arguments, compute_options
from wearbench.cli.options import (
    add_ensemble_size_arguments,
    add_force_argument,
    check_realisations,
    motor_speed,
)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "ensemble", help="simulate the theory ensembles of candidate states and save them",
        description="Simulate --realisations realisations of every candidate state (benches drawn within the "
        "bench file's [tolerances], random start states), reduce each to cycle statistics and save them.")
    p.add_argument("bench", metavar="BENCH.toml", help="bench file (or the name of a shipped bench)")
    p.add_argument("--candidates", metavar="STATES.toml", help="[[state]] tables (default: the bench's own)")
    p.add_argument("--speed", help="commanded motor speed, e.g. 2pi or 60rpm (default: the bench's)")
    add_ensemble_size_arguments(p)
    p.add_argument("--sensor-paths", choices=("drawn", "none"), default="drawn",
                   help="each realisation seen through its own drawn sensor path: a mount/carriage mode 0.3-3 x the "
                   "top impact band's edge (0.3-3 kHz for the test bed), "
                   "damping 0.02-0.1, sensitivity +/-5 %% (drawn, the default) or the model's acceleration as it is "
                   "(none: ensembles of versions before drawn paths; identification then trusts the bench file's "
                   "sensor path)")
    p.add_argument("--out", metavar="FILE.npz", help="where to save (default: BENCHNAME-ensembles.npz)")
    add_force_argument(p)
    p.add_argument("--ship", action="store_true",
                   help="save where wearbench looks for a shipped bench's precomputed ensembles (maintainers: only "
                   "in a source checkout, and replacing the shipped file only with --force)")
    add_compute_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from wearbench.bench.load import load_bench, load_states, resolve_bench
    from wearbench.bench.output_file import check_output, output_file
    from wearbench.validation.inference import artefacts
    from wearbench.validation.inference.ensemble import (
        EnsembleSettings,
        build_ensembles,
        ensembles_key,
        save_ensembles,
    )

    bench = load_bench(resolve_bench(args.bench))
    states = load_states(args.candidates, bench) if args.candidates else bench.states
    if not states:
        raise ValueError(f"{bench.name}: no [[state]] tables; give --candidates STATES.toml")
    speed = (motor_speed(args.speed, max_speed=bench.motor.max_speed, source=str(bench.path or bench.name))
             if args.speed else bench.speed)
    settings = EnsembleSettings.for_bench(bench, speed, realisations=check_realisations(args.realisations),
                                          cycles=args.cycles, sensor_paths=args.sensor_paths == "drawn")
    replaced = None
    if args.ship:  # a maintainer's: only in a source checkout, replacing the shipped file only with --force
        out, replaced = artefacts.ship_target("ensembles", bench.name, force=args.force)
    else:
        out = check_output(Path(args.out or f"{bench.name}-ensembles.npz"), force=args.force)
    # built fresh (no shipped file is consulted), so --ship really refreshes it
    ensembles = build_ensembles(bench, states, speed=speed, settings=settings, shipped=False,
                                compute=compute_options(args, bench))
    with output_file(out, force=args.force, option="--ship" if args.ship else "--out") as tmp:
        save_ensembles(ensembles, tmp, key=ensembles_key(bench, states, speed, settings), bench=bench, states=states)
    for name, e in ensembles.items():
        failed = f", {len(e.failures)} failed" if e.failures else ""
        print(f"{name}: {e.realisations} realisations x {e.features.shape[1]} cycles{failed}")
    print(f"sensor paths: {'drawn per realisation' if settings.sensor_paths else 'none (the model as it is)'}")
    print(f"saved: {out}" + (f" (replaced the shipped {replaced.describe()}, key {replaced.key[:12]})"
                             if replaced else ""))
    return 0
