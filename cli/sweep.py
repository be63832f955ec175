"""`wearbench sweep`: a grid of clearances, speeds, ... with optional wear and realisations per point."""

from __future__ import annotations

import argparse
import json
import sys

from wearbench.bench.load import load_bench, resolve_bench
from wearbench.bench.output_file import check_output, output_folder
from wearbench.cli.compute import add_compute_arguments, compute_options
from wearbench.cli.options import (
    add_force_argument,
    check_clearances,
    check_motor_speed,
    check_wear_coefficient,
    nonnegative_int,
    nonnegative_number,
    positive_int,
    positive_number,
)
from wearbench.cli.wear import add_plan_arguments, plan_from_args


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "sweep", help="parameter sweep: statistics over a grid of clearance, speed, ... (parquet + plots)",
        description="Run every combination of the --vary values (and each realisation) as a task on a "
        "local cluster or --scheduler: optional wear stages, then the dynamics of every state. Writes "
        "sweep.parquet (one row per run, state and statistic), failures.csv, sweep.json and plots/. "
        "Finished runs are cached: a rerun or an interrupted sweep recomputes only what is missing.",
        epilog="Example: wearbench sweep ninebar.toml --vary clearance=0.1mm..0.6mm:6 "
        "--vary speed=-6pi..-4pi:5 --wear-stages 1 --sim-cycles 5 --out sweep/")
    p.add_argument("bench", metavar="BENCH.toml")
    p.add_argument("--vary", action="append", required=True, metavar="NAME=FROM..TO:N",
                   help="a varied parameter: clearance (every clearance joint), clearance.JOINT, speed or "
                   "wear_coefficient, as FROM..TO:COUNT (ends included) or V1,V2,...; repeat for a grid. "
                   "clearance.JOINT sets that joint over clearance (every joint), in either order")
    p.add_argument("--wear-stages", type=nonnegative_int, default=0, help="wear stages per run before the dynamics "
                   "(default 0: unworn)")
    p.add_argument("--realisations", type=positive_int, default=1,
                   help="runs per point: 1 is the nominal bench; M > 1 draws the bench M times within its "
                   "[tolerances] (seeds --seed, --seed + 1, ...)")
    p.add_argument("--seed", type=int, default=0, help="first realisation seed (default 0)")
    p.add_argument("--dyn-revolutions", type=positive_number, default=5.0,
                   help="revolutions of each dynamics run whose statistics are kept (default 5)")
    p.add_argument("--dyn-settle", type=nonnegative_number, default=1.0,
                   help="revolutions simulated first and not counted (start transient), default 1")
    p.add_argument("--output-rate", type=positive_number, default=5000.0, help="dynamics table rate, Hz (default 5000)")
    add_plan_arguments(p)
    add_compute_arguments(p)
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG figures")
    add_force_argument(p)
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from wearbench.studies.sweep import SweepSpec, axes_from, format_value, run_sweep, write_sweep

    bench = load_bench(resolve_bench(args.bench))
    axes = axes_from(args.vary)
    clearance_names = [j.name for j in bench.clearance_joints]
    for a in axes:  # every value checked as the other commands check it, before any run
        if a.name.startswith("clearance") and not clearance_names:
            raise ValueError(f"--vary {a.name}: {args.bench} has no clearance joints")
        if a.name.startswith("clearance."):
            joint = a.name.partition(".")[2]
            if joint not in clearance_names:
                raise ValueError(f"--vary {a.name}: {args.bench} has no clearance joint {joint!r}; "
                                 f"it has {clearance_names}")
        option = f"--vary {a.name}"
        for value in a.values:
            text = format_value(a.name, value)
            if a.name == "speed":
                check_motor_speed(value, option, text, max_speed=bench.motor.max_speed,
                                  source=str(bench.path or bench.name))
            elif a.name == "wear_coefficient":
                check_wear_coefficient(value, option, text)
            else:
                joints = clearance_names if a.name == "clearance" else [a.name.partition(".")[2]]
                check_clearances(dict.fromkeys(joints, value), bench, option, text)
    spec = SweepSpec(axes=axes, stages=args.wear_stages, realisations=args.realisations, seed=args.seed,
                     plan=plan_from_args(args, bench, max(1, args.wear_stages)), revolutions=args.dyn_revolutions,
                     settle=args.dyn_settle, output_rate=args.output_rate)
    n = len(spec.points()) * spec.realisations
    check_output(args.out, force=args.force, folder=True)  # refused before the runs
    compute = compute_options(args, bench)
    result = run_sweep(bench, spec, progress=f"sweep {bench.name} ({n} runs)", scheduler=compute.scheduler,
                       workers=compute.workers)
    with output_folder(args.out, force=args.force) as tmp:
        summary = write_sweep(result, spec, tmp, plots=not args.no_plots)
    if args.json:
        json.dump(summary, sys.stdout, indent=2, default=float)
        print()
    else:
        print(f"{summary['runs']} runs, {summary['failed']} failed, {summary['rows']} rows in "
              f"{summary['wall_time_s']:.0f} s; wrote {args.out}/ (sweep.parquet, sweep.json"
              f"{', failures.csv' if summary['failed'] else ''}{', plots/' if not args.no_plots else ''})")
    for _, f in result.failures:
        print(f"failed: {f}", file=sys.stderr)
    return 1 if result.failures else 0
