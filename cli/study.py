"""`wearbench study`: the paper's wear study and clearance study on a bench (section 5)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from wearbench.bench.load import load_bench, resolve_bench
from wearbench.bench.output_file import output_folder
from wearbench.cli.compute import add_compute_arguments, compute_options
from wearbench.cli.options import add_force_argument, positive_number
from wearbench.cli.wear import add_plan_arguments, plan_from_args


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "study", help="the paper's wear and clearance studies: Table 3, peaks, figures 6-32",
        description="Wear study: 0.6 mm at -5 pi rad/s, two wear stages. Clearance study: 0.1 / 0.3 / "
        "0.45 mm at -6 pi rad/s before and after one wear stage. Writes table3.csv/.md (ours beside the "
        "paper's), peaks.csv, trends, study.json, surfaces and figures. Cases run as parallel tasks (a local "
        "cluster by default, or --scheduler); finished cases are cached, so a rerun is quick.")
    p.add_argument("bench", metavar="BENCH.toml")
    add_plan_arguments(p)
    p.add_argument("--dyn-revolutions", type=positive_number, default=None,
                   help="revolutions of each before/after dynamics run (default 10; Poincare maps get one "
                   "point per revolution)")
    p.add_argument("--quick", action="store_true",
                   help="cut-down study for tests: 2 simulated cycles per stage, 1-revolution dynamics")
    add_compute_arguments(p)
    p.add_argument("--out", default="study", help="output directory (default ./study; an existing one with files "
                   "only with --force)")
    add_force_argument(p)
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from wearbench.cli.progress import note_compiling, progress
    from wearbench.studies.study import StudyConfig, run_study

    bench = load_bench(resolve_bench(args.bench))
    note_compiling()
    if len(bench.clearance_joints) == 0:
        raise ValueError(f"{args.bench}: no clearance joints, nothing to study")
    plan = plan_from_args(args, bench, 1)
    config = StudyConfig.quick(plan) if args.quick else StudyConfig(plan=plan)
    if args.dyn_revolutions:
        config = replace(config, dyn_revolutions=args.dyn_revolutions)
    config = replace(config, **compute_options(args, bench))
    cases = 1 + len(config.clearance_cases)
    with output_folder(args.out, force=args.force) as out, progress() as bar:
        task = bar.add_task(f"study {bench.name}", total=cases, info="")
        summary = run_study(bench, out, config,
                            on_case=lambda r: bar.update(task, advance=1, info=f"{r.case.name} ({r.wall_time:.0f} s)"))
    if args.json:
        json.dump(summary, sys.stdout, indent=2, default=float)
        print()
    else:
        print(Path(args.out, "table3.md").read_text())
        print(f"wrote {args.out}/ in {summary['wall_time_s']:.0f} s")
    return 0
