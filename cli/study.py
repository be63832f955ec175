"""`wearbench study`: the paper's wear study and clearance study on a bench (section 5), as ensembles."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from wearbench.bench.load import load_bench, resolve_bench
from wearbench.bench.output_file import output_folder
from wearbench.cli.compute import add_compute_arguments, compute_options
from wearbench.cli.options import add_force_argument, positive_int
from wearbench.cli.wear import add_plan_arguments, plan_from_args

_SIZES = ("realisations", "cycles", "wear_runs", "seed")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "study", help="the paper's wear and clearance studies as ensembles: Table 3 with intervals, trend verdicts",
        description="Wear study: 0.6 mm at -5 pi rad/s, two wear stages. Clearance study: 0.1 / 0.3 / "
        "0.45 mm at -6 pi rad/s before and after one wear stage. Every cell is a statistic of the per-cycle "
        "maxima of realisations drawn within the bench's tolerances with random starts (the geometric mean of "
        "each realisation's max, the paper's 'max' of one run, and of its median cycle, with Student-t "
        "intervals); each wear stage is worn --wear-runs times from drawn benches and starts, and after wear "
        "the runs are the interval's units; each of the paper's trends gets a verdict (agrees / disagrees / "
        "not resolved) from the intervals of its ratios. Writes table3.md (the report), table3.csv, cells.csv, "
        "trends.csv, peaks.csv, wear_runs.csv, study.json, surfaces and figures. Runs on the compute layer (a "
        "local cluster by default, or --scheduler); finished tasks are cached, so a rerun is quick.")
    p.add_argument("bench", metavar="BENCH.toml")
    add_plan_arguments(p)
    p.add_argument("--realisations", type=positive_int, default=None,
                   help="realisations per state, after wear spread over the wear runs (default 40; --quick 4)")
    p.add_argument("--cycles", type=positive_int, default=None,
                   help="crank cycles kept per realisation (default 8; --quick 3)")
    p.add_argument("--wear-runs", type=positive_int, default=None,
                   help="wear runs per case from drawn benches and starts (default 20; --quick 2)")
    p.add_argument("--seed", type=int, default=None, help="first seed (default 1): realisation i uses seed + i")
    p.add_argument("--quick", action="store_true",
                   help="cut-down study for tests: one surface update per stage, 2 wear runs, 4 realisations "
                   "of 3 cycles per state")
    add_compute_arguments(p)
    p.add_argument("--out", default="study", help="output directory (default ./study; an existing one with files "
                   "only with --force)")
    add_force_argument(p)
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from wearbench.studies.study import StudyConfig, run_study

    bench = load_bench(resolve_bench(args.bench))
    if len(bench.clearance_joints) == 0:
        raise ValueError(f"{args.bench}: no clearance joints, nothing to study")
    if args.realisations is not None and args.realisations < 2:
        raise ValueError(f"--realisations {args.realisations}: expected at least 2 realisations per state")
    plan = plan_from_args(args, bench, 1)
    sizes = {k: getattr(args, k) for k in _SIZES if getattr(args, k) is not None}
    config = StudyConfig.quick(plan, **sizes) if args.quick else StudyConfig(plan=plan, **sizes)
    compute = compute_options(args, bench)
    config = replace(config, scheduler=compute.scheduler, workers=compute.workers)
    with output_folder(args.out, force=args.force) as out:
        summary = run_study(bench, out, config)
    if args.json:
        json.dump(summary, sys.stdout, indent=2, default=float)
        print()
    else:
        print(Path(args.out, "table3.md").read_text())
        print(f"wrote {args.out}/ in {summary['wall_time_s']:.0f} s")
    return 0
